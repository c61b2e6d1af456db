"""A run streamed to a Rerun viewer (``--connect``) whose viewer goes away mid-run: the
run goes on to its end with its results and recording, and says so in one warning line
(docs/live-runs.md). The viewer is the rerun CLI's own gRPC server, in a process group of
its own, killed by the test while the run steps."""

from __future__ import annotations

import json
import os
import signal
import socket
import sys
import time
from pathlib import Path

import pytest
from process_group import as_in_a_terminal, started_in_group

from cosim.viz.recording import rerun_executable

STOP_TIME = 12.0  # s, paced at twice real time: ~6 s of stepping to kill the viewer in


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


@pytest.mark.slow
@pytest.mark.viewer
@pytest.mark.skipif(rerun_executable() is None, reason="the rerun CLI is not installed")
def test_a_viewer_gone_mid_run_costs_one_line_not_the_run(tmp_path: Path, fmu_dir: Path) -> None:
    """The run failed as it closed its outputs: "auv-cosim run: RuntimeError: gRPC
    connection severed: ..." after the warning, exit 1, summary.json saying incomplete."""
    port = _free_port()
    server = [rerun_executable(), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port)]
    out = tmp_path / "run"
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--stop-time", str(STOP_TIME),
               "--real-time", "2", "--connect", f"rerun+http://127.0.0.1:{port}/proxy",
               "--fmu-dir", str(fmu_dir), "--out", str(out), "--quiet"]  # fmt: skip
    with started_in_group(server, stdout=None, stderr=None) as viewer:
        deadline = time.monotonic() + 60
        while not _listening(port):
            assert viewer.poll() is None and time.monotonic() < deadline, "no viewer"
            time.sleep(0.1)
        with started_in_group(command, preexec_fn=as_in_a_terminal, cwd=tmp_path) as run:
            results = out / "results.csv"
            while not (results.is_file() and results.stat().st_size > 20_000):  # mid-run
                assert run.poll() is None, run.communicate()
                time.sleep(0.1)
            os.killpg(viewer.pid, signal.SIGKILL)  # the viewer goes away
            _, stderr = run.communicate(timeout=300)
    lines = stderr.splitlines()
    assert run.returncode == 0, stderr
    assert len(lines) == 1 and lines[0].startswith("auv-cosim run: warning: Rerun viewer: "), lines
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] and summary["time_reached"] == STOP_TIME, summary
    assert (out / "recording.rrd").stat().st_size > 0
