"""FMUs of other groups' making beside ours (tests/fmus/cosim_test_foreign.py): a reason an
FMU logs over several lines, an output that turns infinite, an FMU that logs more
warnings than a run keeps; and doStep statuses pythonfmu cannot answer (Warning, a partial
step's Discard, Pending) from a Reference FMU rebuilt (tests/status_fmu.py)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import pytest
from status_fmu import DAHLQUIST, status_fmu

from cosim.engine import master
from cosim.engine.slave import LOG_LINES_KEPT, _idle_libraries, unzipped
from cosim.errors import CosimError
from cosim.scenario.spec import scenario_from_toml


def foreign_toml(start: str, algorithm: str = "gauss-seidel") -> str:
    """A run of one CosimTestForeign instance ``f`` for 1 s in steps of 0.1 s, with the
    start values ``start`` (TOML lines)."""
    return f"""
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


def foreign(test_fmu_dir: Path, start: str, algorithm: str = "gauss-seidel") -> master.RunResult:
    """:func:`foreign_toml` run."""
    return master.run(scenario_from_toml(foreign_toml(start, algorithm), base_dir=test_fmu_dir))


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


def test_an_fmu_that_cannot_save_its_state_is_told_why_adaptive_needs_it(
    test_fmu_dir: Path,
) -> None:
    """An FMU that declares canGetAndSetFMUstate but fails fmi2GetFMUstate stops an
    adaptive run at its first step; the error says why the algorithm asked and what runs
    it instead (a declared "false" is refused at load, test_fmi_semantics)."""
    result = foreign(test_fmu_dir, "state_fails = true", "adaptive")
    assert result.time_reached == 0.0
    assert (
        "f: fmi2GetFMUstate returned Fatal at t = 0 s: algorithm 'adaptive' saves every "
        "instance's state to roll rejected steps back; use 'gauss-seidel' or 'jacobi' "
        "with a fixed step"
    ) in (result.error or "")


def test_an_infinite_output_stops_the_run_naming_it_without_a_numpy_warning(
    test_fmu_dir: Path, tmp_path: Path, run_python
) -> None:
    """An output that turns infinite stops the run with the variable and the time, and
    the check itself warns of nothing: numpy's "invalid value encountered in dot" (of the
    inf . 0 the check computes) reached the user as a warning before the error. In a fresh
    process, as a user runs it: pytest resets the warning filters a module sets on import."""
    scenario = tmp_path / "inf.toml"
    scenario.write_text(foreign_toml("bad_at = 0.35\nbad_inf = true"))
    code = """
        import sys
        from pathlib import Path
        from cosim.engine import master
        from cosim.scenario.spec import scenario_from_toml

        text = Path(sys.argv[1]).read_text()
        print(master.run(scenario_from_toml(text, base_dir=Path(sys.argv[2]))).error)
    """
    done = run_python(code, scenario, test_fmu_dir)
    assert done.stdout.strip() == "non-finite value at t = 0.4 s: f.y = inf", done.stderr
    assert "invalid value" not in done.stderr, done.stderr


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


def test_a_percent_sign_in_a_message_of_pythonfmus_binary_is_shown_as_written(
    test_fmu_dir: Path,
) -> None:
    """pythonfmu's own binary passes a Python message to the host as its printf format,
    its % signs as they are, with no argument: fmpy's logger proxy formatted it, and
    "50% done" (`% d`, a conversion) read an argument never passed, showing garbage (a
    `%s` or `%n` there may crash the process). Such an FMU's message is taken as text,
    its `%%` as one % (ours double every %, as the standard's formats want)."""
    result = foreign(test_fmu_dir, 'shout = "progress 50% done, 100%% sure"')
    assert result.complete, result.error
    assert result.messages["f"][-1] == "[Warning] progress 50% done, 100% sure"


def status_run(folder: Path, status: str, terminated: bool = False) -> master.RunResult:
    """1 s in steps of 0.1 s of one instance ``d`` of Dahlquist whose doStep answers
    fmi2``status`` from t = 0.4 s on (tests/fmus/cosim_test_status.c)."""
    fmu = status_fmu(folder, status, 0.35, terminated)
    text = 'stop_time = 1.0\n[coupling]\nstep = 0.1\n[instances.d]\nfmu = "Status.fmu"\n'
    return master.run(scenario_from_toml(text, base_dir=fmu.parent))


def test_a_step_that_returns_warning_is_noted_with_its_time(tmp_path: Path) -> None:
    """A doStep's fmi2Warning with no message logged left no trace of the run: it is kept
    among the instance's messages (the report and summary.json show them), and the run
    goes on."""
    result = status_run(tmp_path, "Warning")
    assert result.complete, result.error
    assert result.messages["d"] == ["[Warning] fmi2DoStep returned Warning at t = 0.4 s"]


def test_a_partial_step_is_reported_with_the_time_the_fmu_reached(tmp_path: Path) -> None:
    """A doStep's Discard without fmi2Terminated is a step the FMU did only part of
    (FMI 2.0, 4.2.3): the error says how far it got (fmi2LastSuccessfulTime), not only
    that the FMU logged no reason (a fixed-step run retries no step)."""
    result = status_run(tmp_path, "Discard")
    assert not result.complete
    assert result.error == (
        "d: fmi2DoStep returned Discard at t = 0.4 s: a partial step, to t = 0.45 s "
        "(the FMU logged no reason)"
    )


def test_a_pending_step_is_cancelled_and_its_instance_freed(tmp_path: Path) -> None:
    """fmi2Pending (a step run asynchronously, which this master never waits for) was
    taken for a Fatal: the instance was left instantiated. The error names what Pending
    means, the step is cancelled (fmi2CancelStep) and the instance freed."""
    result = status_run(tmp_path, "Pending")
    assert result.error == (
        "d: fmi2DoStep returned Pending at t = 0.4 s: the FMU runs its step "
        "asynchronously, which this master does not wait for; the step was cancelled "
        "(the FMU logged no reason)"
    )
    folder = str(unzipped(tmp_path / "Status.fmu"))
    assert any(key[0] == folder and key[3] == "d" for key in _idle_libraries)


def test_an_fmu_needing_a_tool_that_fails_to_instantiate_says_it_needs_one(
    tmp_path: Path,
) -> None:
    """needsExecutionTool="true" (an FMU that couples to a tool it does not ship) runs
    like any other (pythonfmu's FMUs declare it too); when such an FMU fails to
    instantiate, the error says it needs its tool beside the FMU's own reason (here a
    Reference FMU whose GUID no longer matches its binary's)."""
    path = tmp_path / "Tool.fmu"
    with zipfile.ZipFile(DAHLQUIST) as src, zipfile.ZipFile(path, "w") as out:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode().replace('guid="{221063D2', 'guid="{00000000')
                data = text.replace("<CoSimulation", '<CoSimulation needsExecutionTool="true"')
                data = data.encode()
            out.writestr(item, data)
    text = 'stop_time = 0.2\n[coupling]\nstep = 0.1\n[instances.t]\nfmu = "Tool.fmu"\n'
    with pytest.raises(CosimError) as refused:
        master.run(scenario_from_toml(text, base_dir=tmp_path))
    assert str(refused.value) == (
        "t: cannot set up Tool.fmu: Failed to instantiate model: [Error] Wrong GUID. "
        '(Tool.fmu declares needsExecutionTool="true": is the tool it needs installed and '
        "running?)"
    )


def test_a_step_refused_before_it_started_is_not_called_partial() -> None:
    """The plant refuses a step it cannot take (a current beyond its range) before it
    starts, with Discard and fmi2LastSuccessfulTime at the step's start: that read "a
    partial step, to t = 0 s", a step the FMU never took part of."""
    from types import SimpleNamespace

    from cosim.engine.slave import DISCARD, describe

    refused = SimpleNamespace(name="plant", state="stepping", partial_step=lambda: 2.5,
                              messages=["[Error] the current at the vehicle ..."])  # fmt: skip
    assert describe(refused, "fmi2DoStep", DISCARD, 2.5) == (  # type: ignore[arg-type]
        "plant: fmi2DoStep returned Discard at t = 2.5 s: the step was refused, the FMU "
        "still at t = 2.5 s: [Error] the current at the vehicle ..."
    )
