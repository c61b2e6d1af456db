"""Scenarios for tests that need a :class:`~cosim.run.scenario.Scenario` object (the Rerun
sink takes one): the two built FMUs with chosen start values and recorded columns."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from cosim.run.scenario import Scenario, scenario_from_toml


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
