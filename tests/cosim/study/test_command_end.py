"""The study command's end without its interpreter's teardown (cosim.study.command_end):
every exit handler runs, every stream is flushed and the exit code is the command's, and
only the teardown after them (a module's objects finalized) is left out; where it cannot
be the last handler, or a stream cannot be flushed, the process ends as Python ends it."""

from __future__ import annotations

import os
import sys
import textwrap
from pathlib import Path

from tests.process_group import run_in_group

ROOT = Path(__file__).resolve().parents[3]

# a process that ends like the command: armed first, exit handlers registered after it,
# text left in stdout's buffer, an object finalized only by the interpreter's teardown
SCRIPT = """
import atexit, sys
from cosim.study import command_end
{before}
armed = command_end.arm()
{after}


class TornDown:
    def __del__(self):
        sys.__stderr__.write("torn down\\n")


kept = TornDown()
atexit.register(lambda: open({mark!r}, "w").write("handler ran"))
sys.stdout.write(f"armed {{armed}}, no newline")  # still in the buffer at the end
sys.stderr.write("a message\\n")
command_end.end_with({code})
sys.exit({code})
"""


FAILING_STDOUT = """
class Full:
    def write(self, text):
        return len(text)

    def flush(self):
        raise OSError(28, "No space left on device")


sys.stdout = Full()
"""


def _ended(tmp_path: Path, code: int = 3, before: str = "", after: str = ""):
    mark = tmp_path / "handler.txt"
    script = textwrap.dedent(SCRIPT.format(before=before, after=after, mark=str(mark), code=code))
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    result = run_in_group([sys.executable, "-c", script], timeout=60, env=env)
    return result, mark


def test_the_process_ends_with_the_code_after_every_handler_and_flush(tmp_path: Path) -> None:
    result, mark = _ended(tmp_path, code=3)
    assert result.returncode == 3, result.stderr
    assert result.stdout == "armed True, no newline"  # flushed
    assert result.stderr == "a message\n"  # no "torn down": the teardown was left out
    assert mark.read_text(encoding="utf-8") == "handler ran"


def test_a_handler_registered_before_it_keeps_the_interpreters_own_end(tmp_path: Path) -> None:
    """It would run after the end's handler: the end is not armed, and Python ends."""
    before = "atexit.register(lambda: sys.__stderr__.write('earlier handler\\n'))"
    result, mark = _ended(tmp_path, code=4, before=before)
    assert result.returncode == 4, result.stderr
    assert result.stdout == "armed False, no newline"
    assert result.stderr == "a message\nearlier handler\ntorn down\n"
    assert mark.read_text(encoding="utf-8") == "handler ran"


def test_a_stream_that_cannot_be_flushed_ends_as_python_ends_it(tmp_path: Path) -> None:
    """stdout refusing its flush (a full disk): Python's own end reports it and exits
    120, as it did before."""
    result, mark = _ended(tmp_path, code=0, after=FAILING_STDOUT)
    assert result.returncode == 120, result.stderr
    assert "No space left on device" in result.stderr
    assert "torn down" in result.stderr
    assert mark.read_text(encoding="utf-8") == "handler ran"


TRACKER_WATCHED = """
import os, time
from multiprocessing import resource_tracker

resource_tracker.ensure_running()
tracker = resource_tracker._resource_tracker._pid
exit_now = os._exit


def exit_once_told(code):
    # the process's last step: has its resource tracker ended (its pipe from here closed)?
    deadline = time.monotonic() + 20
    while os.waitpid(tracker, os.WNOHANG)[0] == 0 and time.monotonic() < deadline:
        time.sleep(0.01)
    ended = time.monotonic() < deadline
    os.write(2, b"tracker ended\\n" if ended else b"tracker still running\\n")
    exit_now(code)


os._exit = exit_once_told
"""


def test_the_resource_tracker_is_told_before_the_process_ends(tmp_path: Path) -> None:
    """The tracker holds the command's stderr until it has ended: told only as the kernel
    ended the process, it kept a pipe reading the command open after the command."""
    result, mark = _ended(tmp_path, code=5, after=TRACKER_WATCHED)
    assert result.returncode == 5, result.stderr
    assert result.stderr == "a message\ntracker ended\n"
    assert mark.read_text(encoding="utf-8") == "handler ran"


# a registration with the tracker after it was told, as a daemon thread's may come before
# the process's last step: here, the last step itself, with a file opened just before
TRACKER_WRITTEN_TO = """
import os
from multiprocessing import resource_tracker

resource_tracker.ensure_running()
pipe = resource_tracker._resource_tracker._fd
exit_now = os._exit


def register_then_exit(code):
    opened = [os.open(FILE, os.O_WRONLY | os.O_CREAT, 0o600)]  # the lowest fd free each
    while opened[-1] < pipe:  # up to the tracker pipe's number, if it is free
        opened.append(os.open(FILE, os.O_WRONLY))
    resource_tracker.register("/auv-cosim-test", "semaphore")
    exit_now(code)


os._exit = register_then_exit
"""


def test_a_registration_after_the_tracker_was_told_writes_into_no_file(tmp_path: Path) -> None:
    """The tracker's pipe closed, its fd was left to the next file opened, into which a
    late registration wrote (the tracker's probe and the registration's line)."""
    opened = tmp_path / "opened.txt"
    after = TRACKER_WRITTEN_TO.replace("FILE", repr(str(opened)))
    result, _ = _ended(tmp_path, code=4, after=after)
    assert result.returncode == 4, result.stderr
    assert opened.read_text(encoding="utf-8") == ""
