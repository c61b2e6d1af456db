"""The workers' fork server ends without its interpreter's teardown once the command that
started it has ended (it held the command's stderr through that teardown): what the
server registered to run at exit before :mod:`cosim.study.server_exit` does not run."""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

import pytest

from cosim.study import fork_server

# the command: starts a fork server with these preloads, prints its pid, ends (the server
# imports them from its working folder, the command's: Python 3.11's ignores sys.path)
COMMAND = """
import sys
from multiprocessing import forkserver, get_context
get_context("forkserver").set_forkserver_preload(sys.argv[1:])
forkserver.ensure_running()
print(forkserver._forkserver._forkserver_pid, flush=True)
"""
# a module the server imports first: at the interpreter's exit it leaves a file
PROBE = """
import atexit, pathlib
atexit.register(pathlib.Path(__file__).with_name("torn-down").touch)
"""


def _ended(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()[0]
    except OSError:
        return True
    return state in {"Z", "X"}


def server_teardown(tmp_path: Path, preload: list[str]) -> bool:
    """Whether the fork server of a command preloading ``preload`` after the probe ran
    its exit handlers after the command ended."""
    (tmp_path / "exit_probe.py").write_text(PROBE, encoding="utf-8")
    done = subprocess.run([sys.executable, "-c", COMMAND, "exit_probe", *preload], cwd=tmp_path,
                          capture_output=True, text=True, check=True, timeout=120)  # fmt: skip
    pid = int(done.stdout)
    deadline = time.monotonic() + 60
    while not _ended(pid) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _ended(pid), f"the fork server {pid} outlived its command by 60 s"
    return (tmp_path / "torn-down").exists()


@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_the_fork_server_skips_its_teardown(tmp_path: Path) -> None:
    assert fork_server.PRELOAD[-1] == "cosim.study.server_exit"
    assert not server_teardown(tmp_path, ["cosim.study.server_exit"])


@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_without_it_the_server_tears_down(tmp_path: Path) -> None:
    """The probe itself: a server that ends normally runs the probe's exit handler."""
    assert server_teardown(tmp_path, [])
