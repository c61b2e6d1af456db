"""``auv-cosim sweep``'s process ends without its interpreter's teardown.

Once a study's command has returned its exit code, its files are written and closed, its
cluster is closed and its workers have ended. The interpreter then runs its exit handlers
(:mod:`atexit`: logging's flush, multiprocessing's finalizers and its temporary folder,
Dask's, ``weakref.finalize``'s) and flushes its standard streams, and only then tears its
modules down: with Dask, pyarrow and matplotlib imported, ~0.025 s of CPU that writes
nothing and that the user waits for after the study has ended, with one worker as with
two (a 2-worker sweep's CPU from its page written to its end: 0.044-0.049 s with the
teardown, 0.021-0.022 s without; the rest is the kernel ending the process). So
:func:`arm` registers, before any other exit handler is registered, a handler of its
own; exit handlers run in the reverse order of their registration, so it runs last, after
every other. Once :func:`end_with` has been given
the command's exit code, that handler flushes the standard streams and ends the process
with :func:`os._exit` and that code, as the workers' fork server ends
(:mod:`cosim.study.server_exit`): by hand, as Python has no setting for an end without
its teardown.

Where the handler cannot be the last one (another exit handler was registered before it:
a coverage tool's, say, which the teardown would otherwise skip), where a stream cannot be
flushed (Python's own end then says so, and exits 120, as before), or where the command
ended without an exit code (an exception: its traceback), the process ends as Python ends
it.
"""

from __future__ import annotations

import atexit
import os
import stat
import sys
from contextlib import suppress

_code: int | None = None  # the command's exit code, once it has returned one


def arm() -> bool:
    """Register the end (once), if no exit handler is registered yet; whether it was."""
    count = getattr(atexit, "_ncallbacks", None)  # CPython's; elsewhere: not armed
    if count is None or count() != 0:
        return False
    atexit.register(_end)
    return True


def end_with(code: int) -> None:
    """End the process with ``code`` after the other exit handlers (if :func:`arm` did)."""
    global _code
    _code = code


def _end() -> None:
    if _code is None:
        return
    streams = {id(s): s for s in (sys.stdout, sys.stderr, sys.__stdout__, sys.__stderr__)}
    for stream in streams.values():
        if stream is None:
            continue
        try:
            stream.flush()
        except Exception:  # Python's own end says what went wrong, as before
            return
    _tracker_told()
    os._exit(_code)


def _tracker_told() -> None:
    """Tell multiprocessing's resource tracker, if this process started one, that this
    process has ended: its pipe from this process closed now, after every exit handler
    (multiprocessing's own, which release the semaphores the tracker watches, included),
    not as the kernel ends the process, after it has freed the process's memory. The
    tracker holds the command's stderr until it has ended (it says there what it cleans
    up): a pipe reading the command waited for it. By hand: multiprocessing has no call
    for it outside its own tests.

    The pipe is not closed but replaced by /dev/null under the same fd at once
    (``os.dup2``): a thread registering a resource before the process ends (a daemon
    thread's) writes there, not into a closed fd or the next file opened in its place,
    and its probe of the tracker finds it alive (a closed fd made it start another)."""
    tracker = sys.modules.get("multiprocessing.resource_tracker")
    fd = getattr(getattr(tracker, "_resource_tracker", None), "_fd", None)
    if not isinstance(fd, int):
        return
    with suppress(OSError):  # closed already, or no /dev/null: nothing to tell
        if not stat.S_ISFIFO(os.fstat(fd).st_mode):
            return  # closed, and the fd reused: not the tracker's pipe any more
        null = os.open(os.devnull, os.O_WRONLY)
        try:
            os.dup2(null, fd, inheritable=False)
        finally:
            os.close(null)
