"""``fork_server.stop()`` waits for the workers' fork server a bounded time: a server still
warming up (importing the run's modules, or waiting for the study it is to warm up on)
is killed past STOP_WAIT_S, not waited for through its whole warm-up (which held the
command's end: the server waits up to 600 s for a study no client hands over)."""

from __future__ import annotations

import sys

import pytest
from process_group import run_in_group

from cosim.study import fork_server

pytestmark = pytest.mark.skipif(not fork_server.available(), reason="no fork server here")

# starts a server that waits for its study (never handed over), stops it at once, and
# says whether it is reaped and forgotten (a later start starts another)
COMMAND = """
import os
from multiprocessing import forkserver
from cosim.study import fork_server
fork_server.STOP_WAIT_S = 0.2
assert fork_server.start(warm=True)
server = forkserver._forkserver
pid, address = server._forkserver_pid, server._forkserver_address
fork_server.stop()
try:
    os.waitpid(pid, os.WNOHANG)
    print("not reaped")
except ChildProcessError:
    print("reaped")
print("forgotten" if server._forkserver_pid is None else "still known")
print("socket left" if os.path.exists(address) else "socket removed")
"""


def test_a_server_still_warming_up_is_ended_past_the_wait() -> None:
    done = run_in_group([sys.executable, "-c", COMMAND], timeout=60)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:3] == ["reaped", "forgotten", "socket removed"], done.stdout
