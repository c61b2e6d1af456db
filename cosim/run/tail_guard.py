"""Cut a torn last row off a results.csv once the run writing it is gone, however it ended.

Run as ``python -I -S tail_guard.py FILE`` by the run folder (:mod:`cosim.run.folder`),
in a session of its own (so a signal for the run's process group does not reach it), with
a pipe from the run on its standard input: it waits until the pipe closes -- the run
closed it at its end, or the kernel did when the run was killed (SIGKILL included) -- and
then truncates FILE after its last newline. The run's writer leaves only whole rows, but
the kernel may stop a write at a page boundary when the process is killed, which Python
cannot prevent: this is the one place that can finish the job.

Standard library only, and nothing imported from the package: it starts in a few
milliseconds, isolated (``-I -S``) from the environment.
"""

from __future__ import annotations

import os
import signal
import sys

TAIL_BYTES = 1 << 20  # a row is far shorter than this


def cut_torn_tail(path: str) -> int:
    """Truncate ``path`` after its last newline; return the bytes cut (0 if none)."""
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return 0  # removed meanwhile (a new run with --overwrite): nothing to repair
    try:
        size = os.fstat(fd).st_size
        start = max(0, size - TAIL_BYTES)
        os.lseek(fd, start, os.SEEK_SET)
        tail = os.read(fd, size - start)
        if tail.endswith(b"\n") or not tail:
            return 0
        keep = start + tail.rfind(b"\n") + 1  # rfind -1: no newline at all -> start
        os.ftruncate(fd, keep)
        return size - keep
    finally:
        os.close(fd)


def main(argv: list[str]) -> int:
    for name in ("SIGINT", "SIGHUP"):  # a terminal's signals are the run's to handle
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    while os.read(0, 65536):  # until the run closes the pipe or dies
        pass
    for path in argv:
        cut_torn_tail(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
