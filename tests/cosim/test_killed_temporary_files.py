"""A run or study killed outright (SIGKILL: ``kill -9``, the OOM killer; a reboot) runs
nothing at its end: what it had in the temporary folder (its FMUs extracted, a study's
run folders, multiprocessing's folder) is removed by the next run or study, never what a
live one uses, and a killed study's workers end with it. Each test runs the command line
in a subprocess, in a process group the test kills, with its own ``tmp_path`` as TMPDIR."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from process_group import group_ended, run_in_group, started_in_group

from cosim.scratch import SCRATCH_DIR

LONG = "6000"  # s of bs-3: still stepping when the test kills it (~30 s of wall clock)


def environ(tmpdir: Path) -> dict[str, str]:
    tmpdir.mkdir(exist_ok=True)
    return {**os.environ, "TMPDIR": str(tmpdir)}


def run_command(fmu_dir: Path, out: Path, stop_time: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir),
            "--out", str(out), "--quiet", "--no-rrd", "--stop-time", stop_time]  # fmt: skip


def left_in(tmpdir: Path) -> list[str]:
    """What is in ``tmpdir`` beside the scratch folders' own lock files (relative paths):
    every folder a process made, and a scratch folder's lock file with no folder."""
    found = []
    for path in sorted(tmpdir.rglob("*")):
        relative = path.relative_to(tmpdir)
        if relative == Path(SCRATCH_DIR) or relative == Path(SCRATCH_DIR, "global.lock"):
            continue
        if len(relative.parts) <= 2:
            found.append(str(relative))
    return found


def wait_for(proc: subprocess.Popen, ready: Path, timeout: float = 120.0) -> None:
    """Until ``ready`` (a results.csv) holds rows: ``proc`` has loaded its FMUs."""
    deadline = time.monotonic() + timeout
    while not (ready.exists() and ready.stat().st_size > 2000):
        assert proc.poll() is None, f"ended early: {proc.communicate()}"
        assert time.monotonic() < deadline, f"no {ready} within {timeout} s"
        time.sleep(0.05)


def kill_when(proc: subprocess.Popen, ready: Path) -> None:
    """SIGKILL ``proc`` (not its group) once ``ready`` holds rows."""
    wait_for(proc, ready)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)


@pytest.mark.slow
def test_the_next_run_removes_what_a_killed_run_left_in_tmpdir(fmu_dir: Path, tmp_path: Path):
    """`auv-cosim run` killed by SIGKILL while stepping left its FMUs extracted in TMPDIR
    (a ``tmpXXXXXXXX`` folder per FMU), forever; the next run removes them."""
    env = environ(tmp_path / "tmp")
    with started_in_group(run_command(fmu_dir, tmp_path / "killed", LONG), env=env) as proc:
        kill_when(proc, tmp_path / "killed" / "results.csv")
    assert left_in(tmp_path / "tmp"), "the killed run had nothing in TMPDIR: no test"
    done = run_in_group(run_command(fmu_dir, tmp_path / "next", "1"), timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    assert left_in(tmp_path / "tmp") == []


@pytest.mark.slow
def test_a_run_keeps_its_files_while_another_starts_and_ends(fmu_dir: Path, tmp_path: Path):
    """A run starting beside a live one (whose files it must not take for a dead one's)
    leaves the live one's FMUs in place: the live one steps on, and removes them itself
    when it ends (SIGTERM)."""
    env = environ(tmp_path / "tmp")
    results = tmp_path / "live" / "results.csv"
    with started_in_group(run_command(fmu_dir, tmp_path / "live", LONG), env=env) as live:
        wait_for(live, results)
        before = left_in(tmp_path / "tmp")
        done = run_in_group(run_command(fmu_dir, tmp_path / "next", "1"), timeout=120, env=env)
        assert done.returncode == 0, done.stderr
        assert before and left_in(tmp_path / "tmp") == before
        size = results.stat().st_size
        while results.stat().st_size == size:  # still stepping, on the FMUs kept
            assert live.poll() is None, live.communicate()
            time.sleep(0.05)
        live.send_signal(signal.SIGTERM)
        live.communicate(timeout=120)
    assert left_in(tmp_path / "tmp") == []


STUDY = """scenario = "bs-3"
stop_time = 300.0
[grid]
"plant.v_0" = [-0.05, 0.05]
"controller.k0" = [0.2, 0.5, 0.7]
"""


def run_folders(tmpdir: Path) -> list[Path]:
    """The run folders of a study's workers, wherever in ``tmpdir``."""
    return [p for p in tmpdir.rglob("auv-cosim-run-*") if p.is_dir()]


def sweep_command(fmu_dir: Path, study: Path, *options: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--workers", "2",
            "--oversubscribe", "--fmu-dir", str(fmu_dir), "--quiet", *options]  # fmt: skip


@pytest.mark.slow
@pytest.mark.cluster
def test_a_resumed_study_removes_what_a_killed_one_left(fmu_dir: Path, tmp_path: Path):
    """`auv-cosim sweep` killed by SIGKILL (its process only) with runs on its workers left
    its FMUs, each worker's run folder and multiprocessing's folder in TMPDIR forever; its
    workers end with it, and ``--resume`` keeps every finished row, runs the rest, and
    removes what the killed study left."""
    tmpdir = tmp_path / "tmp"
    env = environ(tmpdir)
    (tmp_path / "study.toml").write_text(STUDY)
    table = tmp_path / "out" / "runs.csv"
    command = sweep_command(fmu_dir, tmp_path / "study.toml", "--out", str(tmp_path / "out"))
    with started_in_group(command, env=env) as proc:
        deadline = time.monotonic() + 240
        while not (table.is_file() and table.read_text().count("\n") > 1 and run_folders(tmpdir)):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no finished run and no run on a worker"
            time.sleep(0.05)
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=30)  # reaped: no zombie left in the group
        assert group_ended(proc.pid, within=30.0), "the killed study's workers ran on"
    finished = table.read_text().splitlines()[1:]
    assert run_folders(tmpdir), "the killed study had no run folder in TMPDIR: no test"
    done = run_in_group([*command, "--resume"], timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    lines = table.read_text().splitlines()
    assert set(finished) <= set(lines) and len(lines) == 7
    parquet = pd.read_parquet(tmp_path / "out" / "runs.parquet")
    assert sorted(parquet["run"]) == sorted(line.split(",")[0] for line in lines[1:])
    assert [p for p in left_in(tmpdir) if not p.startswith("dask-scratch-space")] == []


KILLED_IN_MEMORY = """
import os, signal, sys, threading, time
from pathlib import Path
import cosim

def kill_when_stepping():
    while not any(Path(os.environ["TMPDIR"]).rglob("results.csv")):
        time.sleep(0.05)
    time.sleep(1)
    os.kill(os.getpid(), signal.SIGKILL)

threading.Thread(target=kill_when_stepping, daemon=True).start()
cosim.run("bs-3", stop_time=6000, recording=False, fmu_dir=sys.argv[1])
"""


@pytest.mark.slow
def test_the_next_run_removes_what_a_killed_kernel_s_run_left(fmu_dir: Path, tmp_path: Path):
    """``cosim.run`` without ``out`` runs in a temporary folder: a notebook kernel killed
    during it (the OOM killer) left that folder, its results.csv growing to the kill, in
    TMPDIR forever; the next run removes it."""
    env = environ(tmp_path / "tmp")
    killed = [sys.executable, "-c", KILLED_IN_MEMORY, str(fmu_dir)]
    done = run_in_group(killed, timeout=180, env=env)
    assert done.returncode == -signal.SIGKILL, done.stderr
    assert list((tmp_path / "tmp").rglob("results.csv")), "nothing left: no test"
    done = run_in_group(run_command(fmu_dir, tmp_path / "next", "1"), timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    assert left_in(tmp_path / "tmp") == []
