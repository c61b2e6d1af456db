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
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from distributed import Client
from sweep_helpers import SMALL_RUNS, sweep, table

from cosim.cli import main
from cosim.study.execution import tls_security

DASK = str(Path(sys.executable).parent / "dask")
START_TIMEOUT_S = 120.0


def wait_for(condition, what: str, timeout: float = START_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def end_group(proc: subprocess.Popen, sig: int = signal.SIGTERM) -> None:
    """Stop the process group this test started (its leader is ``proc``) and reap it."""
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


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


def certificates(folder: Path) -> list[str]:
    """A self-signed certificate for 127.0.0.1 (its own CA), as dask's TLS options."""
    cert, key = folder / "cert.pem", folder / "key.pem"
    command = "openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=auv-cosim-test"
    command += " -addext subjectAltName=IP:127.0.0.1"
    argv = [*command.split(), "-keyout", str(key), "-out", str(cert)]
    subprocess.run(argv, check=True, capture_output=True, timeout=60)
    return ["--tls-ca-file", str(cert), "--tls-cert", str(cert), "--tls-key", str(key)]


@pytest.fixture(params=["tcp", "tls"])
def dask_cluster(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[list[str]]:
    """``dask scheduler`` and two ``dask worker --nthreads 1`` on 127.0.0.1 (plain TCP,
    or TLS with a test certificate), in a folder without FMUs (they must travel); yields
    the sweep options that reach it. Every process is ended afterwards."""
    if request.param == "tls" and shutil.which("openssl") is None:
        pytest.skip("openssl is needed to make the TLS test certificate")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    tls = certificates(elsewhere) if request.param == "tls" else []
    env = {**os.environ, "TMPDIR": str(elsewhere)}
    address_file = elsewhere / "scheduler.json"
    started: list[subprocess.Popen] = []
    options = {
        "cwd": elsewhere,
        "env": env,
        "start_new_session": True,
        "stdout": subprocess.DEVNULL,
        "stderr": subprocess.DEVNULL,
    }
    try:
        started.append(
            subprocess.Popen(
                [
                    DASK,
                    "scheduler",
                    "--protocol",
                    request.param,
                    "--host",
                    "127.0.0.1",
                    "--port",
                    "0",
                    "--no-dashboard",
                    "--scheduler-file",
                    str(address_file),
                    *tls,
                ],
                **options,
            )
        )
        wait_for(address_file.is_file, "the scheduler")
        for i in range(2):
            started.append(
                subprocess.Popen(
                    [
                        DASK,
                        "worker",
                        "--scheduler-file",
                        str(address_file),
                        "--nthreads",
                        "1",
                        "--nworkers",
                        "1",
                        "--host",
                        "127.0.0.1",
                        "--no-dashboard",
                        "--local-directory",
                        str(elsewhere / f"w{i}"),
                        *tls,
                    ],
                    **options,
                )
            )
        address = json.loads(address_file.read_text())["address"]
        assert address.startswith(f"{request.param}://127.0.0.1:")
        security = tls_security(*(Path(p) for p in tls[1::2])) if tls else None
        with Client(address, security=security, timeout=START_TIMEOUT_S) as client:
            client.wait_for_workers(2, timeout=START_TIMEOUT_S)
        yield ["--scheduler", address, *tls]
    finally:
        for proc in reversed(started):
            end_group(proc)
    for i in range(2):  # the FMU plugin was removed at the end of the study, its files too
        assert not list((elsewhere / f"w{i}").rglob("*.fmu"))


def test_a_distributed_cluster_gives_the_same_table(
    dask_cluster: list[str],
    small_study: Path,
    small_reference: list[dict[str, str]],
    fmu_dir: Path,
    tmp_path: Path,
) -> None:
    sweep(small_study, tmp_path / "out", fmu_dir, *dask_cluster)
    assert table(tmp_path / "out") == small_reference


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
        assert proc.poll() is None, "the study finished before it could be killed"
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
