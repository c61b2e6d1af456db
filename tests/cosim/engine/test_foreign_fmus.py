"""FMUs of other groups' making beside ours (tests/fmus/cosim_test_foreign.py): a reason an
FMU logs over several lines, an output that turns infinite, and an FMU that logs more
warnings than a run keeps."""

from __future__ import annotations

import warnings
from pathlib import Path

from cosim.engine import master
from cosim.engine.slave import LOG_LINES_KEPT
from cosim.scenario.spec import scenario_from_toml


def foreign(test_fmu_dir: Path, start: str, algorithm: str = "gauss-seidel") -> master.RunResult:
    """A run of one CosimTestForeign instance ``f`` for 1 s in steps of 0.1 s, with the
    start values ``start`` (TOML lines)."""
    text = f"""
stop_time = 1.0
[coupling]
step = 0.1
algorithm = "{algorithm}"
[instances.f]
fmu = "CosimTestForeign.fmu"
[instances.f.start]
{start}
[output]
record = ["f.y"]
"""
    return master.run(scenario_from_toml(text, base_dir=test_fmu_dir))


def test_a_reason_logged_over_several_lines_is_one_line_of_the_error(
    test_fmu_dir: Path,
) -> None:
    """pythonfmu logs an exception in the FMU as two lines (the call, then the exception):
    the run's error stays one line and keeps both."""
    result = foreign(test_fmu_dir, "state_fails = true", "adaptive")
    assert not result.complete
    error = result.error or ""
    assert "\n" not in error, error
    assert "f: fmi2GetFMUstate returned" in error
    assert "RuntimeError('this FMU cannot save its state')" in error
    assert all("\n" not in line for line in result.messages["f"])


def test_an_infinite_output_stops_the_run_naming_it_without_a_numpy_warning(
    test_fmu_dir: Path,
) -> None:
    """An output that turns infinite stops the run with the variable and the time, and
    the check itself warns of nothing (numpy's "invalid value encountered in dot" reached
    the user as a warning of the run)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = foreign(test_fmu_dir, "bad_at = 0.35\nbad_inf = true")
    assert result.error == "non-finite value at t = 0.4 s: f.y = inf"
    assert [str(w.message) for w in caught] == []


def test_warnings_beyond_those_kept_are_counted_and_the_report_says_so(
    test_fmu_dir: Path,
) -> None:
    """An FMU logging 30 warnings a step for 10 steps: the run keeps the last
    LOG_LINES_KEPT and counts all 300, and the report says how many it left out."""
    from cosim.runner import logged_lines

    result = foreign(test_fmu_dir, "chatter = 30\nchatter_warns = true")
    assert result.complete
    assert len(result.messages["f"]) == LOG_LINES_KEPT
    assert result.messages["f"][-1] == "[Warning] step at 0.900: line 29"
    assert result.messages_logged == {"f": 300}
    lines = logged_lines(result)
    assert lines[-1] == (
        f"  f logged {300 - 3} more (summary.json keeps the last {LOG_LINES_KEPT} of 300)"
    )
