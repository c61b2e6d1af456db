"""The run report's first line gives its times as the grid has them (the shortest text
that reads back as the same float, in s) and counts its steps in good English."""

from __future__ import annotations

from pathlib import Path

from scenario_factory import loop_toml

from cosim.runner import report, run_scenario
from cosim.scenario.spec import scenario_from_toml

STEP = 0.1234567  # s: seven significant digits, one more than a "%g" shows


def test_one_step_of_a_seven_digit_step_is_reported_as_given(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """A stop time of 20000.05 s was reported as "t = 20000 of 20000 s", and one step
    as "1 steps"."""
    text = loop_toml(stop_time=STEP, step=STEP)
    outcome = run_scenario(scenario_from_toml(text, base_dir=test_fmu_dir), tmp_path / "run",
                           no_rrd=True)  # fmt: skip
    first = report(outcome).splitlines()[0]
    assert f"t = {STEP!r} of {STEP!r} s, 1 step of {STEP!r} s (gauss-seidel)" in first, first


def test_whole_seconds_have_no_trailing_point_zero(test_fmu_dir: Path, tmp_path: Path) -> None:
    """A whole time reads as before ("t = 1 of 1 s"), steps counted in the plural."""
    text = loop_toml(stop_time=1.0, step=0.5)
    outcome = run_scenario(scenario_from_toml(text, base_dir=test_fmu_dir), tmp_path / "run",
                           no_rrd=True)  # fmt: skip
    first = report(outcome).splitlines()[0]
    assert "t = 1 of 1 s, 2 steps of 0.5 s (gauss-seidel)" in first, first


def test_a_sweep_stopped_after_one_run_keeps_one_finished_run(tmp_path: Path) -> None:
    """A sweep interrupted after its first run said "1 finished runs kept"."""
    import signal

    from cosim.api import _stopped

    (tmp_path / "runs.csv").write_text("run,error\n0a1b,\n", encoding="utf-8")
    message = str(_stopped(signal.SIGINT, tmp_path))
    assert message.startswith("interrupted (Ctrl-C): 1 finished run kept in"), message


def test_a_point_computed_as_n_h_is_named_without_its_rounding_noise() -> None:
    """A run stopped at point 57 of 0.01 s steps is at 57 * 0.01 = 0.5700000000000001 s in
    floating point: its messages name 0.57 s, as the user's step reads, to the nanosecond
    (the recording's ``sim_time``); a time with more digits than that keeps them."""
    from cosim.errors import seconds

    assert [seconds(57 * 0.01), seconds(3 * 0.1), seconds(20000.05)] == ["0.57", "0.3", "20000.05"]
    assert [seconds(1.0), seconds(2.5e-9), seconds(1e12 + 0.5)] == [
        "1",
        "2.5e-09",
        "1000000000000.5",
    ]
