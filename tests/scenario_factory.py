"""Scenarios for tests: :func:`auv_scenario` (the two built FMUs with chosen start values and
recorded columns, for tests that need a Scenario object, like the Rerun sink) and
:func:`loop_toml` (the master tests' integrator under a sampled gain, tests/fmus, built by
the ``test_fmu_dir`` fixture)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from cosim.scenario.spec import Scenario, scenario_from_toml

K, H, X0 = 2.0, 0.1, 1.0  # the loop's gain, step (s) and initial state


def auv_scenario(
    fmu_dir: Path,
    scenario_id: str,
    columns: list[str] | tuple[str, ...] | None = None,
    plant: str = "",
    controller: str | None = "",
) -> Scenario:
    """Plant (+ autopilot unless ``controller`` is None) built in ``fmu_dir``; ``plant`` and
    ``controller`` are TOML lines of start values; ``columns`` replace the recorded ones
    (unchecked, so a test can record what no FMU has)."""
    text = f'id = "{scenario_id}"\nstop_time = 1.0\n[coupling]\nstep = 0.01\n'
    text += f'[instances.plant]\nfmu = "AuvPlant"\n[instances.plant.start]\n{plant}\n'
    if controller is not None:
        text += '[instances.controller]\nfmu = "AuvAutopilot"\n'
        text += f"[instances.controller.start]\n{controller}\n"
    scenario = scenario_from_toml(text, scenario_id, fmu_dir=fmu_dir)
    if columns is None:
        return scenario
    return dataclasses.replace(scenario, record=tuple(columns))


def loop_toml(
    algorithm: str = "gauss-seidel",
    stop_time: float = 1.0,
    controller_multiple: int = 1,
    plant_start: str = "",
    step: float = H,
    fmu_dir: Path | None = None,
) -> str:
    """The loop's scenario text: the FMUs are named relative to the folder the file is in,
    or in ``fmu_dir`` (absolute paths)."""
    fmus = "" if fmu_dir is None else f"{fmu_dir}/"
    return f"""
summary = "integrator under a sampled gain"
stop_time = {stop_time}
[coupling]
step = {step}
algorithm = "{algorithm}"
order = ["controller", "plant"]
step_multiples = {{ controller = {controller_multiple} }}
[instances.plant]
fmu = "{fmus}CosimTestIntegrator.fmu"
[instances.plant.start]
x0 = {X0}
{plant_start}
[instances.controller]
fmu = "{fmus}CosimTestGain.fmu"
[instances.controller.start]
k = {K}
"""


def write_loop_file(folder: Path, fmu_dir: Path, plant_start: str = "", extra: str = "") -> Path:
    """``folder/loop.toml``: the loop (id "loop") with its FMUs in ``fmu_dir`` and the TOML
    lines ``extra`` after it."""
    path = folder / "loop.toml"
    path.write_text('id = "loop"\n' + loop_toml(plant_start=plant_start, fmu_dir=fmu_dir) + extra)
    return path
