"""FMUs that break FMI 2.0 in a run (a Reference FMU rebuilt with the misbehaviour,
tests/status_fmu.py): a status out of the standard's enum, an fmi2Terminate that fails, a
doStep that blocks while the user presses Ctrl-C, a variable name FMI forbids. The run
stops with one line naming the instance, the call and the time, keeps its rows so far and
frees what FMI allows to be freed."""

from __future__ import annotations

import os
import signal
import sys
import zipfile
from pathlib import Path

import pytest
from process_group import as_in_a_terminal, started_in_group
from status_fmu import DAHLQUIST, status_fmu

from cosim.engine import master
from cosim.engine.slave import _idle_libraries, unzipped
from cosim.errors import CosimError
from cosim.scenario.spec import scenario_from_toml

RUN = 'stop_time = 1.0\n[coupling]\nstep = 0.1\n[instances.d]\nfmu = "{fmu}"\n'


def run_of(fmu: Path) -> master.RunResult:
    """1 s in steps of 0.1 s of one instance ``d`` of ``fmu``."""
    return master.run(scenario_from_toml(RUN.format(fmu=fmu.name), base_dir=fmu.parent))


def freed(fmu: Path, instance: str) -> bool:
    """Whether ``instance`` of ``fmu`` was freed (fmi2FreeInstance): its library waits,
    idle, for this process's next run."""
    folder = str(unzipped(fmu))
    return any(key[0] == folder and key[3] == instance for key in _idle_libraries)


@pytest.mark.parametrize("status", [-1, 7])
def test_a_step_status_out_of_the_standard_stops_the_run_naming_it(
    tmp_path: Path, status: int
) -> None:
    """A doStep answering a number no fmi2Status has: -1 was taken for a Warning (the run
    went on to its end, "complete", its report saying the step "returned Warning"). Both
    stop the run at that step, naming the number as no status, its rows so far kept, and
    the instance is not called again (as after fmi2Fatal: nothing says it can be)."""
    fmu = status_fmu(tmp_path, status, 0.35)
    result = run_of(fmu)
    assert result.error == (
        f"d: fmi2DoStep returned {status} (not an fmi2Status) at t = 0.4 s "
        "(the FMU logged no reason)"
    )
    assert not result.complete and result.time_reached == pytest.approx(0.4)
    assert result.rows == 5
    assert not freed(fmu, "d")


def test_a_failed_terminate_frees_the_instance_and_is_reported(tmp_path: Path) -> None:
    """fmi2Terminate answering fmi2Error after a whole run: the instance was never freed
    (a leak per run, in a study's worker thousands) and nothing told the user. It is
    freed (FMI 2.0 allows only fmi2FreeInstance after an Error) and the failure is kept
    among the instance's messages; every row was computed, so the run stays complete."""
    fmu = status_fmu(tmp_path, "OK", 0.35, terminate="Error")
    result = run_of(fmu)
    assert result.complete, result.error
    assert result.messages["d"] == ["[Error] fmi2Terminate returned Error"]
    assert result.messages_logged == {"d": 1}
    assert freed(fmu, "d")


def test_a_fatal_terminate_leaves_the_instance_alone(tmp_path: Path) -> None:
    """fmi2Terminate answering fmi2Fatal: reported, and the instance is not freed (FMI
    2.0: after Fatal no function of the instance may be called)."""
    fmu = status_fmu(tmp_path, "OK", 0.35, terminate="Fatal")
    result = run_of(fmu)
    assert result.messages["d"] == ["[Fatal] fmi2Terminate returned Fatal"]
    assert not freed(fmu, "d")


def test_a_terminate_status_out_of_the_standard_is_reported_and_not_freed(
    tmp_path: Path,
) -> None:
    """fmi2Terminate answering a number no fmi2Status has (-1): fmpy's wrapper raises only
    above fmi2Warning, so it passed as OK, unreported, and the instance was freed. It is
    kept among the messages, naming the number, and the instance is not called again (as
    after such a status from a step: nothing says what it may still do)."""
    fmu = status_fmu(tmp_path, "OK", 0.35, terminate=-1)
    result = run_of(fmu)
    assert result.messages["d"] == [
        "[-1 (not an fmi2Status)] fmi2Terminate returned -1 (not an fmi2Status)"
    ]
    assert not freed(fmu, "d")


SET_UP = [
    ("ENTER_STATUS", "fmi2EnterInitializationMode"),
    ("EXIT_STATUS", "fmi2ExitInitializationMode"),
    ("SET_REAL_STATUS", "fmi2SetReal"),
]


@pytest.mark.parametrize("status", [-1, 7])
@pytest.mark.parametrize(("macro", "function"), SET_UP)
def test_a_set_up_status_out_of_the_standard_stops_the_run_naming_it(
    tmp_path: Path, macro: str, function: str, status: int
) -> None:
    """A set-up call (entering or leaving initialisation mode, a start value set) answering
    a number no fmi2Status has: -1 passed as OK through fmpy's wrappers (they raise above
    fmi2Warning only) and the run went on. The run is refused before its first row, naming
    the call and the number, and the instance is not called again (as after fmi2Fatal)."""
    fmu = status_fmu(tmp_path, "OK", 99.0, answers={macro: status})
    with_start = RUN + "[instances.d.start]\nk = -2.0\n"
    scenario = scenario_from_toml(with_start.format(fmu=fmu.name), base_dir=tmp_path)
    with pytest.raises(CosimError) as raised:
        master.run(scenario)
    assert str(raised.value).startswith(f"d: {function} returned {status} (not an fmi2Status)")
    assert not freed(fmu, "d")


@pytest.mark.parametrize("status", [-1, 7])
def test_a_state_restore_status_out_of_the_standard_stops_the_run_naming_it(
    tmp_path: Path, status: int
) -> None:
    """fmi2SetFMUstate answering a number no fmi2Status has while an adaptive step is
    redone from its saved state: -1 passed as OK and the run went on from a state the FMU
    may never have taken. The run stops, naming the call and the number, and the instance
    is not called again."""
    fmu = status_fmu(tmp_path, "OK", 99.0, answers={"SET_STATE_STATUS": status})
    adaptive = RUN.replace(
        "step = 0.1", 'step = 0.1\nalgorithm = "adaptive"\nerror_estimate = "doubling"'
    )
    result = master.run(scenario_from_toml(adaptive.format(fmu=fmu.name), base_dir=tmp_path))
    assert result.error is not None
    assert result.error.startswith(f"d: fmi2SetFMUstate returned {status} (not an fmi2Status)")
    assert not result.complete
    assert not freed(fmu, "d")


def test_a_failed_state_save_frees_the_states_already_taken(tmp_path: Path) -> None:
    """An adaptive step saves every instance's state (fmi2GetFMUstate) before it steps:
    when a later instance's save failed, the states already taken from the earlier ones
    were never freed (fmi2FreeFMUstate; a leak per failed run, in a study's worker
    thousands). They are freed, and the run stops naming the instance that failed."""
    fine = status_fmu(tmp_path / "fine", "OK", 99.0)
    status_fmu(tmp_path / "failing", "OK", 99.0, answers={"GET_STATE_STATUS": "Error"})
    text = (
        'stop_time = 1.0\n[coupling]\nstep = 0.1\nalgorithm = "adaptive"\n'
        'error_estimate = "doubling"\n[instances.a]\nfmu = "fine/Status.fmu"\n'
        '[instances.b]\nfmu = "failing/Status.fmu"\n'
    )
    result = master.run(scenario_from_toml(text, base_dir=tmp_path))
    assert result.error is not None
    assert result.error.startswith("b: fmi2GetFMUstate returned Error"), result.error
    (library,) = [
        fmu
        for key, fmus in _idle_libraries.items()
        if key[0] == str(unzipped(fine)) and key[3] == "a"
        for fmu in fmus
    ]
    assert library.dll.cosim_test_live_states() == 0


_CLI = "import sys; from cosim.cli import main; sys.argv[0] = 'auv-cosim'; sys.exit(main())"


@pytest.mark.slow
def test_ctrl_c_during_a_blocking_step_stops_the_run_when_it_returns(tmp_path: Path) -> None:
    """Ctrl-C while an FMU's doStep computes for long (here 3 s, in C): no Python runs
    until the step returns, then the run stops there, exit 130, one line, its rows up to
    that step in results.csv. (A step that never returns cannot be stopped from inside the
    process: docs/coupling.md.)"""
    fmu = status_fmu(tmp_path, "OK", 0.35, block_s=3)
    scenario = tmp_path / "block.toml"
    scenario.write_text(RUN.format(fmu=fmu.name))
    out = tmp_path / "out"
    command = [sys.executable, "-c", _CLI, "run", str(scenario), "--no-rrd", "--quiet",
               "--out", str(out)]  # fmt: skip
    with started_in_group(command, cwd=tmp_path, preexec_fn=as_in_a_terminal) as proc:
        assert proc.stderr is not None
        line = proc.stderr.readline()  # the FMU says it blocks, in the step from 0.4 s
        assert line == "cosim_test_status: blocking\n", line + proc.stderr.read()
        os.kill(proc.pid, signal.SIGINT)
        code = proc.wait(timeout=120)
        stderr = proc.stderr.read()
    assert code == 130, stderr
    assert stderr.splitlines() == [
        f"auv-cosim run: interrupted (Ctrl-C) at t = 0.5 s (partial results in {out})"
    ]
    times = [line.split(",")[0] for line in (out / "results.csv").read_text().splitlines()[1:]]
    assert [round(float(t), 9) for t in times] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]


def with_line_feed_in_a_name(dest: Path) -> Path:
    """Dahlquist with a second name of its output x (an alias) holding a line feed."""
    declared = (
        '<ScalarVariable name="x&#10;y" valueReference="1" causality="output" '
        'variability="continuous" initial="calculated"><Real/></ScalarVariable>'
    )
    with zipfile.ZipFile(DAHLQUIST) as src, zipfile.ZipFile(dest, "w") as out:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode().replace("</ModelVariables>", declared + "</ModelVariables>")
                text = text.replace('dependencies=""/>', 'dependencies=""/><Unknown index="5"/>')
                data = text.encode()
            out.writestr(item, data)
    return dest


def test_a_variable_name_with_a_line_feed_is_refused_at_load(tmp_path: Path) -> None:
    """FMI 2.0 forbids a line feed, carriage return or tab in a variable name (section
    2.2.9, either naming convention): such a name ran, and its results.csv header then
    spanned two lines, which `auv-cosim report` could not read ("could not convert string
    'y"' to float64"). It is refused as the FMU is read, in one line naming it."""
    fmu = with_line_feed_in_a_name(tmp_path / "Named.fmu")
    with pytest.raises(CosimError) as refused:
        scenario_from_toml(RUN.format(fmu=fmu.name), base_dir=tmp_path)
    message = str(refused.value)
    assert "\n" not in message
    assert message.endswith(
        "Named.fmu: not a valid FMU: the variable name 'x\\ny' holds a line feed "
        "(U+000A), which FMI 2.0 forbids in a variable name"
    ), message
