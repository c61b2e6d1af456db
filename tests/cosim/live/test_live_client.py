"""scripts/live_client.py, started before the run it steers (as docs/live-runs.md shows, with
``&``): it waits for the endpoint to open instead of failing with "connection refused", and
its first request reaches the run."""

from __future__ import annotations

import contextlib
import json
import os
import signal
import socket
import subprocess
import sys
import time

import pytest
from repo_paths import ROOT

TIMEOUT_S = 60.0  # generous: the machine may be busy; nothing here is timed


@pytest.mark.slow
def test_the_live_client_waits_for_the_runs_endpoint() -> None:
    # a port nothing listens on yet, kept bound (not listening: a connection is refused)
    # until the endpoint opens on it, so no other process is given it in between
    reserved = socket.socket()
    reserved.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEPORT, 1)
    reserved.bind(("127.0.0.1", 0))
    port = reserved.getsockname()[1]
    client = subprocess.Popen(
        [sys.executable, str(ROOT / "scripts" / "live_client.py"), str(port)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    try:
        time.sleep(1.0)  # the client starts first and finds no endpoint (not a measurement)
        assert client.poll() is None, client.communicate()
        endpoint = socket.create_server(("127.0.0.1", port), reuse_port=True)  # the run's
        reserved.close()
        with endpoint:
            endpoint.settimeout(TIMEOUT_S)
            connection, _ = endpoint.accept()
            with connection, connection.makefile("rw") as channel:
                request = json.loads(channel.readline())
        assert request == {"set": {"controller.yaw_setpoint": 0.35}}
        _, err = client.communicate(timeout=TIMEOUT_S)
        assert "the run has ended" in err and "Traceback" not in err  # closed without reply
    finally:
        reserved.close()
        with contextlib.suppress(ProcessLookupError):
            os.killpg(client.pid, signal.SIGKILL)
        client.wait()


@pytest.mark.parametrize("argument", ["--help-me", "five", "70000"])
def test_a_bad_port_is_refused_in_one_line_naming_it(argument: str) -> None:
    """``python scripts/live_client.py five`` (or an option it lacks, or a port past 65535)
    says what it expected instead of a Python traceback, and connects nowhere."""
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "live_client.py"), argument],
        capture_output=True, text=True, timeout=TIMEOUT_S, check=False,
    )  # fmt: skip
    assert done.returncode == 2, done
    assert "Traceback" not in done.stderr
    assert argument in done.stderr.splitlines()[-1], done.stderr
