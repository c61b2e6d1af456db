"""Leave a killed run's files whole: cut a torn last row off results.csv and a recording
back to its last flush, once the run writing them is gone, however it ended.

Run as ``python -I -S tail_guard.py CSV [RRD]`` by the run folder (:mod:`cosim.outputs.folder`),
in a session of its own (so a signal for the run's process group does not reach it), with
a pipe from the run on its standard input. The run writes ``rrd SIZE`` lines on it each
time the recording is flushed (SIZE: the file's size then, a message boundary) and
``done`` when its files are complete. When the pipe closes -- the run closed it at its
end, or the kernel did when the run was killed (SIGKILL included) -- without ``done``,
CSV is truncated after its last newline and RRD to the last SIZE. The writers leave whole
rows and messages, but the kernel may stop a write at a page boundary when the process
is killed, and rerun writes its stream in pieces: this is the one place that can finish
the job.

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
        return 0  # removed meanwhile: nothing to repair
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


def cut_to(path: str, size: int) -> int:
    """Truncate ``path`` to ``size`` bytes if it is longer; return the bytes cut."""
    try:
        fd = os.open(path, os.O_RDWR)
    except FileNotFoundError:
        return 0
    try:
        extra = os.fstat(fd).st_size - size
        if extra > 0:
            os.ftruncate(fd, size)
        return max(extra, 0)
    finally:
        os.close(fd)


def main(argv: list[str]) -> int:
    for name in ("SIGINT", "SIGHUP"):  # a terminal's signals are the run's to handle
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    done, rrd_size, pending = False, None, b""
    while chunk := os.read(0, 65536):  # until the run closes the pipe or dies
        lines = (pending + chunk).split(b"\n")
        pending = lines.pop()  # an incomplete line waits for the rest
        for line in lines:
            if line == b"done":
                done = True
            elif line.startswith(b"rrd "):
                rrd_size = int(line[4:])
    if not done:
        cut_torn_tail(argv[0])
        if len(argv) > 1 and rrd_size is not None:
            cut_to(argv[1], rrd_size)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
