"""Our FMUs as another FMI tool runs them: fmpy's ``simulate_fmu`` with the options a tool
user sets (a relative tolerance, ...), each FMU alone. What the FMU ignores or refuses is
said in its log, with what to do instead."""

from __future__ import annotations

import contextlib
import re
from pathlib import Path

import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException

from cosim.fmus.build import FMUS

STATUS_WARNING = 1
# a word of the description beyond the variable's own symbol (``X_u|u|`` has none)
WORD = re.compile(r"[a-z]{3,}")


def _simulate(path: Path, **options) -> list[tuple[int, str]]:
    """Run ``path`` for 0.1 s with fmpy's ``simulate_fmu``: the (status, message) pairs the
    FMU logged, until the end or the call fmpy raised on."""
    messages: list[tuple[int, str]] = []

    def logger(_component, _instance, status, _category, message):
        messages.append((status, message.decode()))

    with contextlib.suppress(FMICallException):
        simulate_fmu(str(path), stop_time=0.1, logger=logger, **options)
    return messages


@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_relative_tolerance_the_fmu_ignores_is_warned_of(name, fmu_paths):
    """fmpy passes ``relative_tolerance`` on to fmi2SetupExperiment; none of our FMUs has an
    error-controlled integrator, so it must say it ignores the tolerance, and how to
    control the accuracy instead, rather than take it silently with fmi2OK."""
    assert _simulate(fmu_paths[name]) == []  # no tolerance given: nothing to say
    warnings = [text for status, text in _simulate(fmu_paths[name], relative_tolerance=1e-8)
                if status == STATUS_WARNING]  # fmt: skip
    assert len(warnings) == 1, warnings
    assert "tolerance = 1e-08 ignored" in warnings[0], warnings[0]


@pytest.mark.parametrize("name", sorted(FMUS))
def test_every_variable_has_a_description_beyond_its_symbol(name, fmu_paths):
    """A tool lists each variable with its description beside the name: a description that
    only spells the symbol again (``Y_uv``: "Y_uv") tells its user nothing."""
    variables = read_model_description(str(fmu_paths[name])).modelVariables
    bare = {v.name: v.description for v in variables if not WORD.search(v.description or "")}
    assert bare == {}


@pytest.mark.parametrize("name", ["AuvAutopilot", "AuvGuidance"])
def test_a_cross_current_the_compensation_cannot_hold_says_what_to_change(name, fmu_paths):
    """With compensate_current on, a cross-current as fast as the design speed stops the FMU
    (at initialisation or at the first step); its message named the condition only, and
    must say which parameters to change."""
    start = {"compensate_current": True, "current_east": 2.0, "heading_mode": 1}
    if name == "AuvGuidance":
        del start["heading_mode"]
    errors = [text for status, text in _simulate(fmu_paths[name], start_values=start)
              if "cross-current 2 m/s" in text]  # fmt: skip
    assert errors, "no message names the cross-current"
    assert "turn compensate_current off or raise design_speed" in errors[0], errors[0]
