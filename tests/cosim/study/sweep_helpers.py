"""Helpers of the study tests: the small reference study, running sweep, reading runs.csv,
a real Dask cluster of processes (``dask scheduler`` + ``dask worker``) and ending them."""

from __future__ import annotations

import contextlib
import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from distributed import Client
from process_group import close_pipes

from cosim.cli import main
from cosim.study.execution import tls_security

DASK = str(Path(sys.executable).parent / "dask")
# a grid study of 8 runs of bs-3 over v_0 and k0, its other tables at their defaults
GRID_STUDY = """
scenario = "bs-3"
stop_time = 20.0
[grid]
"plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
"controller.k0" = [0.2, 0.5]
[random]
n = 0
seed = 1
[metrics]
"""
# a scenario of the plant alone whose vehicle set is a file beside it (myveh.toml)
PLANT_WITH_VEHICLE_FILE = """\
id = "plant-alone"
stop_time = 0.2
[coupling]
step = 0.1
[instances.plant]
fmu = "{fmu}"
[instances.plant.start]
vehicle = "myveh.toml"
"""
VEHICLE_FILE = 'base = "remus100"\nm = 31.0\n'  # myveh.toml: REMUS 100 with m = 31 kg
START_TIMEOUT_S = 120.0

SMALL_STUDY = """
scenario = "bs-3"
stop_time = 1.0
[grid]
"plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
[random]
n = 3
seed = 11
sampling = "latin-hypercube"
"plant.current_east" = { uniform = [0.0, 0.2] }
"""
SMALL_RUNS = 12


def sweep(study: Path, out: Path, fmu_dir: Path, *args: str) -> None:
    """``auv-cosim sweep`` in this process; fails the test unless it exits 0."""
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet"]
    assert main([*argv, *args]) == 0


def complete_table(study: Path, out: Path, fmu_dir: Path, runs: int) -> list[dict[str, str]]:
    """The study's :func:`table` run with 2 local workers; fails the test unless all
    ``runs`` runs complete."""
    sweep(study, out, fmu_dir, "--workers", "2")
    rows = table(out)
    assert len(rows) == runs and all(r["status"] == "complete" for r in rows)
    return rows


def table(out: Path) -> list[dict[str, str]]:
    """runs.csv's rows without the wall clock (the one column identical runs differ in)."""
    with (out / "runs.csv").open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        del row["wall_clock_s"]
    return rows


def wait_for(condition: Callable[[], bool], what: str, timeout: float = START_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        time.sleep(0.05)


def end_group(proc: subprocess.Popen, sig: int = signal.SIGTERM) -> None:
    """Stop the process group this test started (its leader is ``proc``) and reap it; what
    is left of the group once the leader is gone (a study's workers ignore SIGTERM: the
    client ends them) is killed."""
    if proc.poll() is None:
        os.killpg(proc.pid, sig)
    try:
        proc.wait(timeout=30)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        close_pipes(proc)


def group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    return True


def certificates(folder: Path) -> list[str]:
    """A self-signed certificate for 127.0.0.1 (its own CA), as dask's TLS options."""
    cert, key = folder / "cert.pem", folder / "key.pem"
    command = "openssl req -x509 -newkey rsa:2048 -nodes -days 1 -subj /CN=auv-cosim-test"
    command += " -addext subjectAltName=IP:127.0.0.1"
    argv = [*command.split(), "-keyout", str(key), "-out", str(cert)]
    subprocess.run(argv, check=True, capture_output=True, timeout=60)
    return ["--tls-ca-file", str(cert), "--tls-cert", str(cert), "--tls-key", str(key)]


@dataclass
class DaskProcesses:
    """A running cluster: its address, the sweep options that reach it, the security a
    client needs, and the two ``dask worker`` process groups (each its own session)."""

    address: str
    options: list[str]
    security: object
    workers: list[subprocess.Popen]


def _scheduler_address(path: Path) -> str | None:
    """The address in a scheduler file, None while it is not written whole (the scheduler
    creates the file, then writes its JSON)."""
    try:
        return str(json.loads(path.read_text())["address"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


@contextmanager
def dask_processes(
    folder: Path,
    protocol: str = "tcp",
    scheduler_env: Mapping[str, str] | None = None,
    worker_envs: Sequence[Mapping[str, str]] = ({}, {}),
) -> Iterator[DaskProcesses]:
    """``dask scheduler`` and a ``dask worker --nthreads 1`` for each of ``worker_envs``
    (two by default, each its extra environment: a PYTHONPATH that hides or replaces
    auv-cosim) on 127.0.0.1 (``protocol`` tcp, or tls with a test certificate), working in
    ``folder`` (created; no FMUs there, they must travel). ``scheduler_env``: extra
    environment of the scheduler (Dask config). Every process is ended afterwards; the
    surviving workers must have removed the study's FMU files (the plugin's tear-down)."""
    folder.mkdir(parents=True)
    tls = certificates(folder) if protocol == "tls" else []
    env = {**os.environ, "TMPDIR": str(folder)}
    address_file = folder / "scheduler.json"
    started: list[subprocess.Popen] = []
    options = {"cwd": folder, "start_new_session": True, "stdout": subprocess.DEVNULL}
    options["stderr"] = subprocess.DEVNULL
    scheduler = [DASK, "scheduler", "--protocol", protocol, "--host", "127.0.0.1"]
    scheduler += ["--port", "0", "--no-dashboard", "--scheduler-file", str(address_file)]
    worker = [DASK, "worker", "--scheduler-file", str(address_file), "--nthreads", "1"]
    worker += ["--nworkers", "1", "--host", "127.0.0.1", "--no-dashboard"]
    try:
        started.append(
            subprocess.Popen([*scheduler, *tls], env={**env, **(scheduler_env or {})}, **options)
        )
        # the file is there before its JSON is whole: wait for the address it holds
        wait_for(lambda: _scheduler_address(address_file) is not None, "the scheduler")
        for i, extra in enumerate(worker_envs):
            local = ["--local-directory", str(folder / f"w{i}")]
            command = [*worker, *local, *tls]
            started.append(subprocess.Popen(command, env={**env, **extra}, **options))
        address = str(_scheduler_address(address_file))
        assert address.startswith(f"{protocol}://127.0.0.1:")
        security = tls_security(*(Path(p) for p in tls[1::2])) if tls else None
        if worker_envs:
            with Client(address, security=security, timeout=START_TIMEOUT_S) as client:
                client.wait_for_workers(len(worker_envs), timeout=START_TIMEOUT_S)
        yield DaskProcesses(address, ["--scheduler", address, *tls], security, started[1:])
    finally:
        alive = [proc.poll() is None for proc in started[1:]]
        for proc in reversed(started):
            end_group(proc)
    for i, was_alive in enumerate(alive):  # the plugin was removed at the end, its files too
        assert not was_alive or not list((folder / f"w{i}").rglob("*.fmu"))
