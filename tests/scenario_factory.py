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
) -> str:
    """The loop's scenario text: the FMUs are named relative to the folder they are in."""
    return f"""
summary = "integrator under a sampled gain"
stop_time = {stop_time}
[coupling]
step = {step}
algorithm = "{algorithm}"
order = ["controller", "plant"]
step_multiples = {{ controller = {controller_multiple} }}
[instances.plant]
fmu = "CosimTestIntegrator.fmu"
[instances.plant.start]
x0 = {X0}
{plant_start}
[instances.controller]
fmu = "CosimTestGain.fmu"
[instances.controller.start]
k = {K}
"""
