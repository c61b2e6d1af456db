"""A study's size is counted before any run is built: one over the cap (--max-runs) is
refused at once, in little memory, with one line, and so is an absurd cap; --workers is
capped at the cores; a --scheduler address that is no Dask scheduler is refused in
seconds."""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
from collections.abc import Iterator
from contextlib import nullcontext
from pathlib import Path

import pytest
from deadline import deadline

from cosim.cli import main
from cosim.study import execution, runner

HUGE_GRID = "\n".join(f'"plant.f{i}" = {list(range(100))}' for i in range(5))  # 10^10 runs
# CPU seconds, not wall clock: the hang this guards burned CPU, and a loaded machine
# stretches the wall clock of a quick refusal. The process's peak RSS is its VmHWM:
# getrusage's ru_maxrss keeps the parent's peak across fork and exec, so it would report
# the test process's own size.
MEASURE = """
import re, sys, time
from cosim.cli import main
started = time.process_time()
code = main(sys.argv[1:])
cpu_s = time.process_time() - started
status = open("/proc/self/status").read()
rss_mb = int(re.search(r"VmHWM:\\s+(\\d+) kB", status).group(1)) / 1024
print(code, cpu_s, rss_mb)
"""


def write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "study.toml"
    path.write_text('scenario = "bs-3"\n' + text, encoding="utf-8")
    return path


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs /proc (Linux)")
def test_a_ten_billion_run_grid_is_refused_fast_in_little_memory(tmp_path: Path) -> None:
    """A [grid] of 100^5 points hung before any output, RSS growing ~130 MB/s."""
    study = write(tmp_path, "[grid]\n" + HUGE_GRID + "\n")
    argv = ["sweep", str(study), "--out", str(tmp_path / "out")]
    process = subprocess.Popen(
        [sys.executable, "-c", MEASURE, *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        env={**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)},
    )
    try:
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    code, cpu_s, rss_mb = out.split()
    assert code == "1" and err.count("\n") == 1, err
    assert "1e+10 runs (100 x 100 x 100 x 100 x 100 grid points x 1 samples)" in err
    assert "--max-runs N raises the cap" in err
    assert float(cpu_s) < 2.0 and float(rss_mb) < 200.0, (cpu_s, rss_mb)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(
    ("n", "expected"),
    [
        ("1000000000000", "1e+12 runs (1 grid points x 1000000000000 samples)"),
        ("1e12", "key 'random.n' = 1000000000000.0: expected an integer"),
    ],
)
def test_a_huge_random_n_is_one_line(
    n: str, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """`[random] n = 1e12` ended in a numpy MemoryError traceback."""
    study = write(tmp_path, f'[random]\nn = {n}\n"plant.v_0" = {{ uniform = [0.0, 0.1] }}\n')
    assert main(["sweep", str(study), "--out", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err, err


def test_the_cap_is_raised_by_max_runs(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    study = write(tmp_path, '[grid]\n"plant.v_0" = [0.0, 0.1, 0.2]\n')
    assert main(["sweep", str(study), "--out", str(tmp_path / "o"), "--max-runs", "2"]) == 1
    assert "3 runs (3 grid points x 1 samples); at most 2" in capsys.readouterr().err


@pytest.fixture
def clusters(monkeypatch: pytest.MonkeyPatch) -> list[runner.Cluster]:
    """The clusters `sweep` would start (no study runs, no local cluster started early)."""
    seen: list[runner.Cluster] = []
    monkeypatch.setattr(execution, "early_client", lambda *args, **kw: nullcontext(None))

    def record(study: Path, out: Path | None, *, cluster: runner.Cluster, **kw: object) -> None:
        seen.append(cluster)
        raise runner.StudyError("stopped by the test")

    monkeypatch.setattr(runner, "run_study", record)
    return seen


def test_workers_are_capped_at_the_cores_unless_told(
    tmp_path: Path, capsys: pytest.CaptureFixture, clusters: list[runner.Cluster]
) -> None:
    """`--workers 100` on 2 cores started ~100 processes and no run finished in 300 s.
    (A study of as many runs: a local cluster has no more workers than runs.)"""
    cores = execution.usable_cores()
    values = ", ".join(str(0.001 * k) for k in range(cores + 98))
    study = write(tmp_path, f'[grid]\n"plant.v_0" = [{values}]\n')
    main(["sweep", str(study), "--workers", str(cores + 98)])
    assert f"--workers {cores + 98} capped at the {cores} cores" in capsys.readouterr().err
    most = execution.MAX_WORKERS_PER_CORE * cores
    main(["sweep", str(study), "--workers", str(min(cores + 98, most)), "--oversubscribe"])
    assert [c.workers for c in clusters] == [cores, min(cores + 98, most)]


def test_oversubscribed_workers_beyond_16_per_core_are_refused_whatever_the_runs(
    tmp_path: Path, capsys: pytest.CaptureFixture, clusters: list[runner.Cluster]
) -> None:
    """`--workers 40 --oversubscribe` on 2 cores (over its 16 per core) ran a study of 2
    runs: the count was cut to the runs first, and never met the cap, which
    cosim.sweep(workers=40, oversubscribe=True) meets at once."""
    cores = execution.usable_cores()
    most = execution.MAX_WORKERS_PER_CORE * cores
    study = write(tmp_path, '[grid]\n"plant.v_0" = [0.01, 0.02]\n')
    assert main(["sweep", str(study), "--workers", str(most + 1), "--oversubscribe"]) == 1
    err = capsys.readouterr().err
    assert err == (
        f"auv-cosim sweep: --workers {most + 1}: expected at most {most} worker processes "
        f"({execution.MAX_WORKERS_PER_CORE} per core), even with --oversubscribe\n"
    ), err
    assert clusters == []


@pytest.fixture
def one_core() -> Iterator[int]:
    """This process (its calling thread, as `taskset -c` sets it) on one of its cores for the
    test, the cores it had put back after; the core kept."""
    if not hasattr(os, "sched_setaffinity"):
        pytest.skip("no CPU affinity on this system")
    cores = os.sched_getaffinity(0)
    if len(cores) < 2:
        pytest.skip("this process may use one core already")
    core = min(cores)
    os.sched_setaffinity(0, {core})
    try:
        yield core
    finally:
        os.sched_setaffinity(0, cores)


def test_workers_follow_the_cores_this_process_may_use(
    tmp_path: Path, capsys: pytest.CaptureFixture, clusters: list[runner.Cluster], one_core: int
) -> None:
    """Under `taskset -c 0` on a machine of 2 cores a study started 2 workers on the one
    core it may use (the machine's count), and `--workers 2` was not capped."""
    study = write(tmp_path, '[grid]\n"plant.v_0" = [0.01, 0.02, 0.03]\n')
    main(["sweep", str(study)])
    main(["sweep", str(study), "--workers", "2"])
    assert "--workers 2 capped at the 1 core" in capsys.readouterr().err
    assert [c.workers for c in clusters] == [1, 1]


@pytest.mark.parametrize("value", ["99999999999999999999", "0", "-5", "10000001"])
def test_an_absurd_max_runs_is_refused_in_one_line(
    value: str, tmp_path: Path, capsys: pytest.CaptureFixture, no_early_cluster: None
) -> None:
    """`--max-runs 99999999999999999999` was accepted (no cap at all)."""
    study = write(tmp_path, '[grid]\n"plant.v_0" = [0.0]\n')
    assert main(["sweep", str(study), "--out", str(tmp_path / "o"), "--max-runs", value]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--max-runs {value[:20]}" in err, err
    assert "expected 1 to 10000000" in err
    assert not (tmp_path / "o").exists()


def _serve(reply: bytes | None) -> socket.socket:
    """A TCP server on 127.0.0.1 that accepts connections and says nothing (``reply``
    None) or answers each with ``reply`` (an HTTP server's), until its socket closes."""
    server = socket.create_server(("127.0.0.1", 0))
    held: list[socket.socket] = []

    def serve() -> None:
        with contextlib.suppress(OSError):
            while True:
                connection, _ = server.accept()
                held.append(connection)  # kept open: a silent server never closes it
                if reply is not None:
                    connection.recv(65536)
                    connection.sendall(reply)

    threading.Thread(target=serve, daemon=True).start()
    return server


@pytest.mark.parametrize(
    ("reply", "message"),
    [
        (None, "sends no Dask handshake within 1 s"),  # the probe's 5 s cut to 1 s here
        (b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n", "not a Dask scheduler"),
    ],
    ids=["a silent server", "an HTTP server"],
)
def test_a_scheduler_address_that_is_no_scheduler_is_refused_in_seconds(
    reply: bytes | None,
    message: str,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
    monkeypatch: pytest.MonkeyPatch,
    no_early_cluster: None,
) -> None:
    """--scheduler at a silent TCP server hung for minutes; at an HTTP server it failed
    with numpy's "Unable to allocate 3.07 EiB" traceback. The silent server is waited for
    PROBE_TIMEOUT_S: 1 s here, so that the fast tier does not wait the shipped 5 s."""
    if reply is None:
        monkeypatch.setattr(execution, "PROBE_TIMEOUT_S", 1.0)
    study = write(tmp_path, '[grid]\n"plant.v_0" = [0.0]\n')
    server = _serve(reply)
    address = f"tcp://127.0.0.1:{server.getsockname()[1]}"
    try:
        with deadline(60):  # was: minutes
            code = main(["sweep", str(study), "--scheduler", address, "--out", str(tmp_path / "o")])
    finally:
        server.close()
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1 and message in err, err
    assert f"--scheduler {address}" in err and "EiB" not in err
    assert not (tmp_path / "o").exists()


@pytest.mark.cluster
def test_a_real_scheduler_is_accepted_from_inside_a_running_event_loop() -> None:
    """A Jupyter kernel and an asyncio application call ``cosim.sweep(scheduler=...)`` with
    an event loop running in their thread, where ``asyncio.run`` refuses: the handshake
    probe failed there, and a real Dask scheduler was refused as "not a Dask scheduler"."""
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=0, processes=False, protocol="tcp", host="127.0.0.1", dashboard_address=None
    ) as cluster:

        async def from_a_running_loop() -> None:
            execution.check_scheduler(cluster.scheduler_address)  # refuses by raising

        with deadline(60):
            asyncio.run(from_a_running_loop())
        execution.check_scheduler(cluster.scheduler_address)  # and with no loop running
