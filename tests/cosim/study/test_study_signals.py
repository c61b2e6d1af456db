"""A study ends on a stop signal as a run does (exit 128 + signal, one line, the finished
rows kept, no worker tracebacks), and a study in which no run completed exits 1."""

from __future__ import annotations

import contextlib
import csv
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from process_group import as_in_a_terminal

from cosim.cli import main
from cosim.scratch import LOCK_SUFFIX, SCRATCH_DIR, purge

pytestmark = pytest.mark.cluster  # every test starts Dask workers

LONG_STUDY = 'scenario = "bs-3"\nstop_time = {stop_time}\n[grid]\n"plant.v_0" = {values}\n'


def rows(table: Path) -> list[dict[str, str]]:
    if not table.is_file():
        return []
    with table.open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def assert_no_scratch_folder_left(own: Path) -> None:
    """No process's scratch folder is left in ``own``: only the global lock, and lock
    files no process holds, which the next process's purge removes. (A process ended while
    it removed its folder, between the folder and its lock file, or while it purged
    another's, leaves such a lone lock file; under load a worker the study's end kills
    can: seen once in a loaded suite. The order is on purpose: the lock file goes last,
    so a folder is never left without one.)"""
    left = [p.name for p in own.iterdir() if p.name != "global.lock"]
    assert [name for name in left if not name.endswith(LOCK_SUFFIX)] == [], left
    purge(own)
    assert [p.name for p in own.iterdir()] == ["global.lock"]


def start_study(
    tmp_path: Path, fmu_dir: Path, stop_time: float, workers: int, values: list[float]
) -> tuple[Path, Path, subprocess.Popen]:
    """``auv-cosim sweep`` of bs-3 over ``values`` of plant.v_0 started in a process group of
    its own, as from a terminal: its TMPDIR, its output folder and its process."""
    scratch = tmp_path / "tmp"  # the study's TMPDIR
    scratch.mkdir()
    study = tmp_path / "long.toml"
    study.write_text(LONG_STUDY.format(stop_time=stop_time, values=values), encoding="utf-8")
    out = tmp_path / "out"
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--out", str(out)]
    command += ["--fmu-dir", str(fmu_dir), "--workers", str(workers), "--quiet"]
    process = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path), "TMPDIR": str(scratch)},
        preexec_fn=as_in_a_terminal,
    )
    return scratch, out, process


@pytest.mark.slow
@pytest.mark.parametrize(
    ("signum", "group", "workers", "stop_time"),
    [
        (signal.SIGINT, True, 1, 2.0),
        (signal.SIGTERM, False, 1, 2.0),
        (signal.SIGTERM, True, 2, 300.0),  # runs of ~1 s: the signal comes in the middle of one
        (signal.SIGHUP, True, 2, 300.0),  # a terminal closed: its hangup reaches every process
    ],
)
def test_a_stop_signal_ends_a_study_with_one_line_and_its_rows(
    signum: int, group: bool, workers: int, stop_time: float, tmp_path: Path, fmu_dir: Path
) -> None:
    """Ctrl-C flooded stderr with worker tracebacks; SIGTERM killed the study without a
    reason and with leaked-semaphore warnings. Ctrl-C goes to the whole process group,
    as a terminal sends it; so does SIGTERM from a CI job cancelled or `kill -- -PGID`,
    which ended the workers before the study could, and the scheduler's broadcasts to
    them printed 36 lines of CommClosedError tracebacks; and the workers' fork server,
    ended by it too, left each run in flight's temporary folder behind. A hangup to the group
    killed multiprocessing's resource tracker, whose successor printed a KeyError traceback
    for each semaphore the workers gave back."""
    values = [round(-0.2 + 0.01 * i, 2) for i in range(40)]
    scratch, out, process = start_study(tmp_path, fmu_dir, stop_time, workers, values)
    try:
        deadline = time.monotonic() + 240
        while not rows(out / "runs.csv") and time.monotonic() < deadline:
            assert process.poll() is None, process.communicate()
            time.sleep(0.2)
        if group:
            os.killpg(process.pid, signum)
        else:
            process.send_signal(signum)
        _, err = process.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError):  # the study and any worker left
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    assert process.returncode == 128 + signum, err
    assert "Traceback" not in err and "leaked semaphore" not in err, err
    assert "died unexpectedly" not in err, err
    assert "CommClosedError" not in err and " - ERROR - " not in err, err
    own = scratch / SCRATCH_DIR  # every process's scratch folder gone, their base kept
    assert [p.name for p in scratch.iterdir() if p.name != "dask-scratch-space"] == [own.name]
    assert_no_scratch_folder_left(own)
    name = {signal.SIGINT: "interrupted (Ctrl-C)", signal.SIGTERM: "terminated (SIGTERM)"}.get(
        signal.Signals(signum), "hung up (SIGHUP)"
    )
    (line,) = [line for line in err.splitlines() if line.startswith("auv-cosim sweep:")]
    assert line.startswith(f"auv-cosim sweep: {name}; ") and re.search(
        r" \d+ finished runs? kept in ", line
    ), line
    kept = rows(out / "runs.csv")
    assert 1 <= len(kept) < len(values)
    assert all(row["status"] == "complete" for row in kept)


@pytest.mark.slow
def test_a_stop_signal_stops_the_runs_in_flight_on_the_workers(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """A stop signal ended the study, but each run in flight on a worker went on until
    Dask's nanny, 4 s into closing its worker, killed the worker (SIGKILL): the worker's
    scratch folder was left, with the run's folder in it. Under load the study's ~1 s runs
    outlived that (two workers' folders left, seen in a loaded suite); these runs of
    ~10 s do unloaded. The study's end stops its runs in flight at their next step, and
    each worker ends in order, its folder removed."""
    scratch, _, process = start_study(tmp_path, fmu_dir, 3000.0, 2, [-0.1, 0.1])
    own = scratch / SCRATCH_DIR
    try:
        deadline = time.monotonic() + 240
        while len(list(own.glob("*/auv-cosim-run-*"))) < 2 and time.monotonic() < deadline:
            assert process.poll() is None, process.communicate()
            time.sleep(0.1)
        os.killpg(process.pid, signal.SIGTERM)
        _, err = process.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError):  # the study and any worker left
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    assert process.returncode == 128 + signal.SIGTERM, err
    assert err.startswith("auv-cosim sweep: terminated (SIGTERM)") and err.count("\n") == 1, err
    assert_no_scratch_folder_left(own)


@pytest.mark.slow
def test_a_study_in_which_no_run_completed_exits_1(
    tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """A study in which every run failed exited 0."""
    study = tmp_path / "failing.toml"
    # the plant refuses a mass beyond its stroke (no declared range says so)
    grid = '[grid]\n"plant.mass_position_0" = [0.5]\n'
    study.write_text('scenario = "bs-3"\nstop_time = 1.0\n' + grid)
    out = tmp_path / "out"
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet"]
    assert main([*argv, "--workers", "1"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no run completed (1 failed: see the error column" in err
    assert [row["status"] for row in rows(out / "runs.csv")] == ["failed"]


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="no SIGHUP on this system")
def test_a_study_under_nohup_leaves_the_hangup_ignored(run_python) -> None:
    """``nohup auv-cosim sweep ...``: the study caught SIGHUP anyway (nohup ignores it for
    the command), so its terminal hanging up ended it, exit 129. SIGHUP stays ignored
    while the study runs; SIGINT and SIGTERM are still caught. In a fresh process that
    starts as nohup starts it."""
    code = """
        import signal
        signal.signal(signal.SIGHUP, signal.SIG_IGN)  # as nohup does, before anything
        from cosim.study.signals import stop_study_on_signals
        with stop_study_on_signals():
            caught = [signal.getsignal(s) not in (signal.SIG_IGN, signal.SIG_DFL)
                      for s in (signal.SIGHUP, signal.SIGINT, signal.SIGTERM)]
        print(caught)
    """
    done = run_python(code)
    assert done.returncode == 0, done.stderr
    assert done.stdout == "[False, True, True]\n"


# the command in a process of its own (argv None, as the auv-cosim script calls it), a
# Ctrl-C arriving once the study is over, while its report is written
CTRL_C_AS_IT_ENDS = """
import os, signal, sys
import cosim.study.runner as runner
from cosim.cli import main

report = runner.report


def report_under_fire(outcome):
    os.kill(os.getpid(), signal.SIGINT)
    return report(outcome)


runner.report = report_under_fire
sys.argv = ["auv-cosim", "sweep", *sys.argv[1:]]
sys.exit(main())
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_a_ctrl_c_once_the_study_is_over_changes_nothing(
    run_python, fmu_dir: Path, tmp_path: Path
) -> None:
    """``auv-cosim sweep`` ended by "auv-cosim sweep: interrupted", exit 130 (or died by
    SIGINT, -2, as the interpreter shut down) when a Ctrl-C came after its study had
    finished, its table written: as ``auv-cosim run`` does, the stop signals are ignored
    once the study is over, and the finished study exits 0."""
    study = tmp_path / "study.toml"
    study.write_text(LONG_STUDY.format(stop_time=0.2, values=[0.0, 0.1]), encoding="utf-8")
    out = tmp_path / "out"
    args = [study, "--out", out, "--fmu-dir", fmu_dir, "--workers", "1", "--quiet"]
    done = run_python(CTRL_C_AS_IT_ENDS, *args)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "interrupted" not in done.stderr
    assert [row["status"] for row in rows(out / "runs.csv")] == ["complete", "complete"]
