"""A tail guard that has not ended GUARD_TIMEOUT_S after the run released its folder (a
guard stopped, or one whose input a forked child still holds open) is ended and reaped
by the release: none is left running, nor a Popen dropped with it still running."""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import sys
import warnings
from pathlib import Path

import pytest

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
