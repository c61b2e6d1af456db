"""A tail guard that has not ended GUARD_TIMEOUT_S after the run released its folder (a
guard stopped, say) is ended and reaped by the release: none is left running, nor a Popen
dropped with it still running; a guard told ``done`` ends by itself."""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import warnings
from pathlib import Path

import pytest
from process_group import started_in_group

from cosim.outputs import folder as folder_module
from cosim.outputs.folder import RunFolder

# a guard that never ends by itself: it ignores what it is told and its input's end
STUCK_GUARD = (
    "import signal, time\nsignal.signal(signal.SIGTERM, signal.SIG_IGN)\ntime.sleep(600)\n"
)


def _running(pid: int) -> bool:
    """Whether ``pid`` is a process not yet reaped (a zombie counts: nobody waited for it)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


@pytest.mark.skipif(sys.platform == "win32", reason="signals to a process id")
def test_a_guard_that_outlives_the_timeout_is_ended_and_reaped(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """release() waited GUARD_TIMEOUT_S for the guard, then dropped its Popen: the guard
    ran on, and Python said "ResourceWarning: subprocess <pid> is still running"."""
    script = tmp_path / "stuck_guard.py"
    script.write_text(STUCK_GUARD)
    monkeypatch.setattr(folder_module, "GUARD_SCRIPT", script)
    monkeypatch.setattr(folder_module, "GUARD_TIMEOUT_S", 0.2)
    run = RunFolder.claim(tmp_path / "run")
    run.start_guard(tmp_path / "run" / "results.csv", None)
    assert run._guard is not None
    pid = run._guard.pid
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            run.release()
            gc.collect()
        assert not _running(pid), f"the guard {pid} is still running"
        assert not [w for w in caught if issubclass(w.category, ResourceWarning)], caught
    finally:
        with contextlib.suppress(ProcessLookupError, ChildProcessError):
            os.killpg(pid, signal.SIGKILL)  # its own session: the group is its id
            os.waitpid(pid, 0)


@pytest.mark.skipif(sys.platform == "win32", reason="a socket handed to another process")
def test_a_guard_told_done_ends_while_a_child_holds_its_input(tmp_path: Path) -> None:
    """A child forked by the run (a copy of the guard's socket in it) kept the input open
    after the run closed its end: the guard, told ``done``, read on to the end of its input
    and was killed GUARD_TIMEOUT_S later (exit code -9) instead of ending."""
    run = RunFolder.claim(tmp_path / "run")
    run.start_guard(tmp_path / "run" / "results.csv", None)
    guard, channel = run._guard, run._channel
    assert guard is not None and channel is not None
    holder = [sys.executable, "-c", "import time; time.sleep(600)"]
    try:
        with started_in_group(holder, pass_fds=(channel.fileno(),)):
            run.release()
            assert guard.returncode == 0
    finally:
        with contextlib.suppress(ProcessLookupError, ChildProcessError):
            os.killpg(guard.pid, signal.SIGKILL)
            os.waitpid(guard.pid, 0)
