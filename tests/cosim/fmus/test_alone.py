"""Each built FMU as an engineer meets it alone in another tool: its variables'
descriptions state the conventions an operator needs (which way an angle, a depth and a
current count), read from modelDescription.xml as any importer reads them; run on its own
start values and DefaultExperiment, it does what docs/hosts.md "Each FMU alone" says."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

from plant_fmu.model.parameters import load_vehicle

# (FMU, variable, what its description must say): the sign conventions docs/interfaces.md
# shows an operator, generated from these descriptions
CONVENTIONS = [
    ("AuvPlant", "yaw", "clockwise from north"),
    ("AuvPlant", "yaw", "whole turns"),
    ("AuvPlant", "yaw_0", "clockwise from north"),
    ("AuvPlant", "r", "clockwise"),
    ("AuvPlant", "roll", "starboard down"),
    ("AuvPlant", "pitch", "bow up"),
    ("AuvPlant", "down", "down positive"),
    ("AuvPlant", "down_0", "down positive"),
    ("AuvPlant", "current_north", "moves towards north"),
    ("AuvPlant", "current_east", "moves towards east"),
    ("AuvAutopilot", "yaw", "clockwise from north"),
    ("AuvAutopilot", "yaw_setpoint", "clockwise from north"),
    ("AuvAutopilot", "depth_setpoint", "down positive"),
    ("AuvGuidance", "yaw", "clockwise from north"),
    ("AuvGuidance", "yaw_setpoint", "clockwise from north"),
    ("AuvGuidance", "depth_setpoint", "down positive"),
    ("AuvGuidance", "waypoint_down", "down positive"),
]


@pytest.mark.parametrize(("fmu", "variable", "phrase"), CONVENTIONS)
def test_a_variables_description_states_its_convention(
    fmu_paths: dict[str, Path], fmu: str, variable: str, phrase: str
) -> None:
    """docs/interfaces.md's yaw row said only "yaw angle psi": not which way it counts,
    nor that it runs on past a turn."""
    described = {
        v.name: v.description or "" for v in read_model_description(fmu_paths[fmu]).modelVariables
    }
    assert phrase in described[variable], f"{fmu}.{variable}: {described[variable]!r}"


# (FMU, start values an importer gives, the Warnings it may log): docs/hosts.md "Each FMU
# alone". The full plant at rest rises (7.1 N buoyant) and says so, truthfully; the
# lateral one runs up to speed straight north without a word.
ALONE = [
    ("AuvPlant", {}, ["the hull is out of the water"]),
    ("AuvPlant", {"variant": 1}, []),
    ("AuvAutopilot", {}, []),
    ("AuvGuidance", {}, []),
]


@pytest.mark.slow  # 60 s of each at 10 ms, the autopilot's laws compiled first
@pytest.mark.parametrize(("fmu", "start", "warned"), ALONE)
def test_an_fmu_run_alone_on_its_defaults_does_what_the_hosts_page_says(
    fmu_paths: dict[str, Path], fmu: str, start: dict[str, int], warned: list[str]
) -> None:
    """Each FMU on its own start values and DefaultExperiment (fmpy's ``simulate_fmu``,
    as another tool runs it): nothing above OK but the Warnings docs/hosts.md names, every
    output finite to the experiment's stop time; the lateral plant stays in the water."""
    logged: list[tuple[int, str]] = []

    def logger(env: object, instance: object, status: int, category: bytes, text: bytes) -> None:
        logged.append((status, text.decode(errors="replace")))

    result = simulate_fmu(fmu_paths[fmu], start_values=start, logger=logger)
    above_ok = [text for status, text in logged if status > 0]  # fmi2OK is 0
    assert len(above_ok) == len(warned), above_ok
    assert all(phrase in text for phrase, text in zip(warned, above_ok, strict=True)), above_ok
    assert all(status == 1 for status, _ in logged if status > 0), logged  # fmi2Warning
    experiment = read_model_description(fmu_paths[fmu]).defaultExperiment
    assert result["time"][-1] == pytest.approx(experiment.stopTime)
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name])), name
    if start.get("variant") == 1:
        assert np.all(result["down"] >= -0.5 * load_vehicle("remus100").diameter)
        assert result["u"][-1] > 1.0  # m/s: up to speed, straight on
