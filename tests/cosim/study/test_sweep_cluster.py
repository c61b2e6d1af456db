"""Studies across processes: the local cluster listens on 127.0.0.1 only, a real
distributed cluster (``dask scheduler`` + two ``dask worker``) gives the same table, and a
study killed with SIGKILL resumes to the same table without running a finished run again.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from sweep_helpers import (
    SMALL_RUNS,
    dask_processes,
    end_group,
    group_alive,
    sweep,
    table,
    wait_for,
)

from cosim.cli import main

pytestmark = pytest.mark.cluster  # every test starts Dask workers

LISTENING = """
import json, os, psutil
from cosim.study.execution import open_client

if __name__ == "__main__":
    with open_client(2) as client:
        workers = client.scheduler_info()["workers"]
        pids = client.run(os.getpid)
        listening = []
        for pid in [os.getpid(), *pids.values()]:
            for conn in psutil.Process(pid).net_connections(kind="inet"):
                if conn.status == psutil.CONN_LISTEN:
                    listening.append([pid, conn.laddr.ip, conn.laddr.port])
        print(json.dumps({"scheduler": client.scheduler.address, "workers": list(workers),
                          "nannies": [w["nanny"] for w in workers.values()],
                          "listening": listening}))
"""


@pytest.mark.slow
def test_the_local_cluster_listens_on_localhost_only(run_python) -> None:
    # a fresh process, so that no other test's listening socket is counted
    proc = run_python(LISTENING, timeout=180)
    assert proc.returncode == 0, proc.stderr
    found = json.loads(proc.stdout.strip().splitlines()[-1])
    addresses = [found["scheduler"], *found["workers"], *found["nannies"]]
    assert len(addresses) == 5
    assert all(re.fullmatch(r"tcp://127\.0\.0\.1:\d+", a) for a in addresses), addresses
    # every socket listening in the scheduler's and the workers' processes (their
    # addresses, the /health servers of each): nothing on 0.0.0.0 or another interface
    assert {ip for _, ip, _ in found["listening"]} == {"127.0.0.1"}, found["listening"]
    ports = {port for _, _, port in found["listening"]}
    assert {int(a.rsplit(":", 1)[1]) for a in addresses} <= ports
    assert 8787 not in ports  # the dashboard is off by default


@pytest.fixture(params=["tcp", "tls"])
def dask_cluster(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[list[str]]:
    """``dask scheduler`` and two ``dask worker`` (plain TCP, or TLS with a test
    certificate) in a folder without FMUs; yields the sweep options that reach it."""
    if request.param == "tls" and shutil.which("openssl") is None:
        pytest.skip("openssl is needed to make the TLS test certificate")
    with dask_processes(tmp_path / "elsewhere", request.param) as cluster:
        yield cluster.options


@pytest.mark.slow
def test_a_distributed_cluster_gives_the_same_table(
    dask_cluster: list[str],
    small_study: Path,
    small_reference: list[dict[str, str]],
    fmu_dir: Path,
    tmp_path: Path,
) -> None:
    sweep(small_study, tmp_path / "out", fmu_dir, *dask_cluster)
    assert table(tmp_path / "out") == small_reference


@pytest.mark.slow
def test_a_tls_scheduler_needs_the_certificates(
    small_study: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    argv = ["sweep", str(small_study), "--out", str(tmp_path / "out")]
    assert main([*argv, "--scheduler", "tls://127.0.0.1:1"]) == 1
    assert "a tls:// address needs --tls-ca-file, --tls-cert and --tls-key" in (
        capsys.readouterr().err
    )
    assert main([*argv, "--scheduler", "tls://127.0.0.1:1", "--tls-cert", "c.pem"]) == 1
    assert "missing: --tls-ca-file, --tls-key" in capsys.readouterr().err


def whole_rows(csv_path: Path) -> int:
    """Rows of runs.csv that are whole lines (the header not counted)."""
    if not csv_path.is_file():
        return 0
    return max(0, csv_path.read_bytes().count(b"\n") - 1)


@pytest.mark.slow
def test_sigkill_then_resume_gives_the_uninterrupted_table(
    small_study: Path,
    small_reference: list[dict[str, str]],
    fmu_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
) -> None:
    out = tmp_path / "out"
    (tmp_path / "tmp").mkdir()
    argv = [
        sys.executable,
        "-m",
        "cosim.cli",
        "sweep",
        str(small_study),
        "--out",
        str(out),
        "--fmu-dir",
        str(fmu_dir),
        "--workers",
        "1",
        "--quiet",
    ]
    env = {**os.environ, "TMPDIR": str(tmp_path / "tmp")}
    proc = subprocess.Popen(
        argv, env=env, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        half = SMALL_RUNS // 2
        wait_for(
            lambda: whole_rows(out / "runs.csv") >= half or proc.poll() is not None,
            "half of the runs",
        )
        if proc.poll() is not None:
            pytest.fail(f"the study ended (exit {proc.returncode}) before it could be killed: "
                        f"{proc.stderr.read().decode(errors='replace')[-3000:]}")  # fmt: skip
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=30)
        # its worker process notices and exits: nothing of the study outlives it
        wait_for(lambda: not group_alive(proc.pid), "the killed study's workers to exit", 30)
    finally:
        end_group(proc, signal.SIGKILL)
        proc.stdout.close()
        proc.stderr.close()
    finished = whole_rows(out / "runs.csv")
    assert half <= finished < SMALL_RUNS

    sweep(small_study, out, fmu_dir, "--workers", "1", "--resume")
    report = capsys.readouterr().out
    # every finished run was skipped; only the others ran (the one in flight among them)
    expected = f"({finished} already in the table, {SMALL_RUNS - finished} run now)"
    assert expected in report
    assert table(out) == small_reference


@pytest.mark.slow
def test_a_study_runs_where_the_fork_servers_socket_path_is_too_long(
    small_study: Path, small_reference: list[dict[str, str]], fmu_dir: Path, tmp_path: Path
) -> None:
    """Under a TMPDIR so long that the fork server's socket path exceeds AF_UNIX's limit
    (~108 bytes) the fork server cannot start: Dask starts the workers its own way and the
    study completes (it failed with "Nanny failed to start" when the workers were asked of
    a fork server that was not running)."""
    long_tmp = tmp_path / ("t" * 60) / ("m" * 60)
    long_tmp.mkdir(parents=True)
    out = tmp_path / "out"
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(small_study), "--out", str(out),
               "--fmu-dir", str(fmu_dir), "--workers", "1", "--quiet"]  # fmt: skip
    proc = subprocess.Popen(
        command,
        env={**os.environ, "TMPDIR": str(long_tmp)},
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    try:
        _, err = proc.communicate(timeout=600)
    finally:
        end_group(proc, signal.SIGKILL)
    assert proc.returncode == 0, err.decode(errors="replace")[-3000:]
    assert table(out) == small_reference
