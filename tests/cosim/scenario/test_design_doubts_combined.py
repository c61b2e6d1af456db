"""Gain and delay faults on one command are judged together while they overlap (gains
multiply, delays add), on the autopilot's own loop (controller_fmu.lqr.delayed_poles),
and a fault that stops before the run does is said to."""

from __future__ import annotations

from pathlib import Path

import pytest

import cosim
from cosim.scenario.design_doubts import design_doubts


def _lqr_1_with(fmu_paths: dict[str, Path], tmp_path: Path, faults: str) -> cosim.Scenario:
    """lqr-1 at a communication step of 1 ms with ``faults`` (TOML) on its command to
    plant.mass_position_cmd."""
    text = (Path(cosim.__file__).parent / "scenarios" / "lqr-1.toml").read_text() + faults
    path = tmp_path / "faults.toml"
    path.write_text(text)
    scenario = cosim.load_scenario(path, fmu_dir=fmu_paths["AuvPlant"].parent)
    return scenario.with_overrides(step=0.001)


def _fault(name: str, kind: str, start: float, stop: float | None = None) -> str:
    until = "" if stop is None else f"stop = {stop!r}\n"
    return (
        f'\n[[faults]]\nname = "{name}"\ntarget = "plant.mass_position_cmd"\n{kind}\n'
        f"start = {start!r}\n{until}"
    )


def _upper_gain_margin() -> float:
    from cosim.analysis.margins import loop_margins, lqr_loop
    from plant_fmu.model.parameters import load_vehicle

    upper = loop_margins(lqr_loop(load_vehicle("remus100"), 1.525, 0.01)).upper_gain_margin
    assert upper is not None
    return upper.value


@pytest.mark.slow
def test_a_gain_and_a_delay_fault_past_the_margins_together_are_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A gain of 0.9 times the upper gain margin and a delay of 6 ms (the delay margin is
    9.9 ms) on lqr-1's mass command are each inside the margins, and ran without a word
    while both were on, though together they put the loop past them; overlapping only
    from t = 2 s, they are named together from there, until the first stops."""
    gain = f'kind = "gain"\nvalue = {0.9 * _upper_gain_margin()!r}'
    faults = _fault("servo", gain, 1.0, 5.0) + _fault("late", 'kind = "delay"\nsteps = 6', 2.0)
    alone = [
        _lqr_1_with(fmu_paths, tmp_path, _fault("servo", gain, 1.0)),
        _lqr_1_with(fmu_paths, tmp_path, _fault("late", 'kind = "delay"\nsteps = 6', 2.0)),
    ]
    assert [design_doubts(scenario) for scenario in alone] == [[], []]
    (line,) = design_doubts(_lqr_1_with(fmu_paths, tmp_path, faults))
    assert line.startswith(
        "faults.servo and faults.late together (on plant.mass_position_cmd, the command of "
        "controller's heading_mode lqr: a gain of "
    ), line
    assert "and a delay of 6 steps (0.006 s)) are past that loop's margins" in line, line
    assert "so from t = 2 s until t = 5 s (a fault's stop) it is unstable" in line, line


def test_a_fault_that_stops_early_is_said_to(fmu_paths: dict[str, Path], tmp_path: Path) -> None:
    """A gain fault past the margins from t = 1 s that stops at t = 3 s was warned of as
    if it never stopped ("from t = 1 s it is unstable"): the loop is unstable only while
    it is on, which the warning now says; one that stops after the run's end is not."""
    gain = f'kind = "gain"\nvalue = {1.1 * _upper_gain_margin()!r}'
    (line,) = design_doubts(_lqr_1_with(fmu_paths, tmp_path, _fault("servo", gain, 1.0, 3.0)))
    assert "so from t = 1 s until t = 3 s (its stop) it is unstable" in line, line
    late = _fault("servo", gain, 1.0, 1000.0)
    (line,) = design_doubts(_lqr_1_with(fmu_paths, tmp_path, late))
    assert "so from t = 1 s it is unstable" in line, line
