"""A command a test runs in a process group of its own (tests/process_group.py) leaves no
process behind when it times out, not even one that ignores SIGTERM and SIGINT, as a
study's fork server and the workers forked from it do (a hung run of a fork server test,
ended by hand with SIGTERM, left such a worker waiting for a lock for good)."""

from __future__ import annotations

import signal
import subprocess
import time
from pathlib import Path

import psutil
import pytest
from process_group import run_in_group

# a shell whose background child ignores SIGTERM and SIGINT (``trap ""`` is inherited),
# writes the child's id, and waits for it
STUBBORN = 'trap "" TERM INT; sleep 600 & echo $! > "$1"; wait'


def gone(pid: int, within: float = 10.0) -> bool:
    """Whether the process has ended (a zombie waiting for init to reap it has) within
    ``within`` s: a SIGKILL sent to a group takes effect when each process is next
    scheduled, which under load comes after the group's leader has been reaped."""
    try:
        process = psutil.Process(pid)
        deadline = time.monotonic() + within
        while process.status() != psutil.STATUS_ZOMBIE:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.05)
    except psutil.NoSuchProcess:
        pass
    return True


@pytest.mark.slow
@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="POSIX process groups")
def test_a_command_that_times_out_leaves_no_process_behind(tmp_path: Path) -> None:
    child = tmp_path / "child.pid"
    with pytest.raises(subprocess.TimeoutExpired):
        run_in_group(["sh", "-c", STUBBORN, "sh", str(child)], timeout=3)
    pid = int(child.read_text())
    assert gone(pid), psutil.Process(pid).cmdline()
