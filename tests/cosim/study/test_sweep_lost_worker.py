"""A lost worker: one ``dask worker`` (nanny and worker process) killed with SIGKILL while
it runs a run of a study on a real scheduler with two workers. The scheduler retries its
tasks on the other worker, so the study completes every run and gives the uninterrupted
table; only with the scheduler's retries set to none (``allowed-failures = 0``) are the
lost runs recorded as failed, with an error that says so."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from distributed import Client
from sweep_helpers import complete_table, dask_processes, end_group, table, wait_for

pytestmark = pytest.mark.cluster  # every test starts Dask workers

LONG_RUNS = """
scenario = "bs-3"
stop_time = 8.0
[grid]
"plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
"plant.current_east" = [0.0, 0.1]
"""
RUNS = 8


@pytest.fixture(scope="module")
def long_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("lost") / "long.toml"
    path.write_text(LONG_RUNS, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def uninterrupted(
    long_study: Path, fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> list[dict[str, str]]:
    return complete_table(long_study, tmp_path_factory.mktemp("uninterrupted"), fmu_dir, RUNS)


def rows_written(csv_path: Path) -> int:
    return max(0, csv_path.read_bytes().count(b"\n") - 1) if csv_path.is_file() else 0


def kill_a_busy_worker(client: Client, workers: list[subprocess.Popen], out: Path) -> set[str]:
    """Once a run is in the table, SIGKILL the whole ``dask worker`` (nanny and worker)
    that is running a run; returns the run ids the scheduler says it lost."""
    busy: list[str] = []

    def a_worker_is_busy() -> bool:
        if rows_written(out / "runs.csv") < 1:
            return False
        busy[:] = [w for w, keys in client.processing().items() if keys]
        return bool(busy)

    wait_for(a_worker_is_busy, "a worker running a run after the first row")
    pid = client.run(os.getpid, workers=busy[:1])[busy[0]]
    victim = next(proc for proc in workers if proc.pid == os.getpgid(pid))
    os.killpg(victim.pid, signal.SIGKILL)
    victim.wait(timeout=30)

    def removal() -> dict | None:
        events = [msg for _, msg in client.get_events("all")]
        return next((m for m in events if m.get("action") == "remove-worker"), None)

    wait_for(lambda: removal() is not None, "the scheduler to notice the lost worker", 60)
    lost = {str(key) for key in removal()["processing-tasks"]}
    assert lost, "the killed worker was running nothing"
    return {key.split("-")[1] for key in lost}  # run-<run id>-<session>


def sweep_losing_a_worker(
    study: Path, fmu_dir: Path, tmp_path: Path, scheduler_env: dict[str, str]
) -> set[str]:
    """The study on a fresh two-worker cluster, one worker killed mid-study; returns the
    ids of the runs that were on it. The study must still exit 0."""
    with dask_processes(tmp_path / "cluster", "tcp", scheduler_env) as cluster:
        argv = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--quiet"]
        argv += ["--out", str(tmp_path / "out"), "--fmu-dir", str(fmu_dir), *cluster.options]
        proc = subprocess.Popen(argv, start_new_session=True, stderr=subprocess.PIPE)
        try:
            with Client(cluster.address, timeout=60) as client:
                lost = kill_a_busy_worker(client, cluster.workers, tmp_path / "out")
            _, stderr = proc.communicate(timeout=300)
            assert proc.returncode == 0, stderr.decode()
        finally:
            end_group(proc, signal.SIGKILL)
            proc.stderr.close()
    return lost


@pytest.mark.slow
def test_a_lost_worker_s_runs_are_retried(
    long_study: Path, uninterrupted: list[dict[str, str]], fmu_dir: Path, tmp_path: Path
) -> None:
    lost = sweep_losing_a_worker(long_study, fmu_dir, tmp_path, {})
    rows = table(tmp_path / "out")
    assert lost <= {row["run"] for row in rows}
    assert all(row["status"] == "complete" for row in rows), rows
    assert rows == uninterrupted  # in the study's order: the same values to the last digit


@pytest.mark.slow
def test_runs_lost_without_retries_are_failed_with_the_reason(
    long_study: Path, uninterrupted: list[dict[str, str]], fmu_dir: Path, tmp_path: Path
) -> None:
    env = {"DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    lost = sweep_losing_a_worker(long_study, fmu_dir, tmp_path, env)
    rows = {row["run"]: row for row in table(tmp_path / "out")}
    assert len(rows) == RUNS
    failed = {run for run, row in rows.items() if row["status"] == "failed"}
    assert failed == lost
    for run in failed:
        assert rows[run]["error"].startswith("lost: 1 worker process died while running")
        assert "distributed.scheduler.allowed-failures = 0" in rows[run]["error"]
    for reference in uninterrupted:  # every other run as if nothing happened
        if reference["run"] not in failed:
            assert rows[reference["run"]] == reference
