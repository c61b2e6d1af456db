"""Each built FMU as an engineer meets it alone in another tool: its variables'
descriptions state the conventions an operator needs (which way an angle, a depth and a
current count), read from modelDescription.xml as any importer reads them."""

from __future__ import annotations

from pathlib import Path

import pytest
from fmpy import read_model_description

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
