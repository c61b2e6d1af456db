"""Leave a killed run's files whole: cut a torn last row off results.csv and a recording
back to its last flush, once the run writing them is gone, however it ended; and, if it
had not stepped yet, remove what it created and put back an earlier run it was replacing.

Run as ``python -I -S tail_guard.py MANIFEST CSV [RRD]`` by the run folder
(:mod:`cosim.outputs.folder`), in a session of its own (so a signal for the run's process
group does not reach it), with a socket from the run on its standard input (a pipe where
there are no Unix sockets); the locks the run hands over on it (the recording's) are held
until the guard ends. The run writes lines on it:

* ``rrd SIZE`` each time the recording is flushed (SIZE: the file's size then, a message
  boundary);
* ``aside ["ORIGINAL", "ASIDE"]`` (JSON) for each file of an earlier run it set aside
  (renamed) before opening its own outputs, and ``new "PATH"`` for each file it created;
* ``commit`` once it has taken its first step (the set-aside files are then removed);
* ``done`` when its files are complete: the guard then ends at once, without reading on
  to its input's end (a child the run forked may hold a copy of it open).

When the pipe closes -- the run closed it at its end, or the kernel did when the run was
killed (SIGKILL included) -- without ``done``: a run that never committed is undone (the
files it created removed, any set-aside ones renamed back, so the folder is as it was and
the same command runs again without ``--overwrite``: before its first step it computed
nothing, and files it left while opening its outputs, before its summary.json, would
hold no run ``--overwrite`` could recognise); otherwise CSV is truncated after its last
newline and RRD to the last SIZE, and the run's MANIFEST records what the files now hold
(:func:`file_identity`), so a later ``--overwrite`` knows them as the run's. The writers
leave whole rows and messages, but the kernel may stop a write at a page boundary when
the process is killed, and rerun writes its stream in pieces: this is the one place that
can finish the job.

Standard library only, and nothing imported from the package: it starts in a few
milliseconds, isolated (``-I -S``) from the environment. :func:`file_identity` (and
:func:`head_sha256`, of a file's first bytes) is also the run folder's one definition of
what identifies a file a run wrote.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import signal
import socket
import stat
import sys
from collections.abc import Callable
from pathlib import Path

TAIL_BYTES = 1 << 20  # a row is far shorter than this
IDENTITY_KEYS = ("dev", "ino", "size", "mtime_ns", "sha256")
# reading a file without following a link or blocking on a FIFO (POSIX), in binary (Windows)
READ_FLAGS = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
READ_FLAGS |= getattr(os, "O_BINARY", 0)


def file_identity(path: str | os.PathLike[str]) -> dict[str, int | str] | None:
    """What identifies the regular file at ``path`` (a link is not followed): device,
    inode, size (bytes), modification time (ns) and the SHA-256 of its content. None if
    it is missing or not a regular file. A file rewritten in place, or deleted and
    written again (the inode is often the same), differs in at least one of them."""
    try:
        fd = os.open(path, READ_FLAGS)
    except OSError:
        return None
    try:
        before = os.fstat(fd)
        if not stat.S_ISREG(before.st_mode):
            return None
        digest = hashlib.sha256()
        while chunk := os.read(fd, 1 << 20):
            digest.update(chunk)
        after = os.fstat(fd)
    except OSError:
        return None
    finally:
        os.close(fd)
    if (after.st_size, after.st_mtime_ns) != (before.st_size, before.st_mtime_ns):
        return None  # changing while read: no identity to trust
    return {
        "dev": before.st_dev,
        "ino": before.st_ino,
        "size": before.st_size,
        "mtime_ns": before.st_mtime_ns,
        "sha256": digest.hexdigest(),
    }


def head_sha256(path: str | os.PathLike[str], size: int) -> str | None:
    """The SHA-256 (hex) of the first ``size`` bytes of the regular file ``path`` (a link
    is not followed); None if it holds fewer or cannot be read."""
    try:
        fd = os.open(path, READ_FLAGS)
    except OSError:
        return None
    digest, left = hashlib.sha256(), size
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        while left and (chunk := os.read(fd, min(left, 1 << 20))):
            digest.update(chunk)
            left -= len(chunk)
    except OSError:
        return None
    finally:
        os.close(fd)
    return None if left else digest.hexdigest()


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


def record_identities(manifest: str, paths: list[str]) -> None:
    """Update the manifest's entries for ``paths`` with what the files hold now (the run
    was killed after its last update). Entries are matched by the file they name."""
    folder = Path(manifest).parent
    try:
        data = json.loads(Path(manifest).read_text(encoding="utf-8"))
        entries = data["files"]
    except (OSError, ValueError, KeyError, TypeError):
        return  # no manifest of ours: nothing to update
    wanted = {os.path.realpath(p) for p in paths}
    for entry in entries:
        target = os.path.realpath(folder / str(entry.get("path", "")))
        if target in wanted:
            identity = file_identity(target)
            if identity is not None:
                entry.update(identity)
    tmp = f"{manifest}.guard.tmp"
    try:
        with contextlib.suppress(FileNotFoundError):  # a link planted at the name goes:
            os.unlink(tmp)  # never written through (cosim.whole_file, not imported here)
        with open(tmp, "x", encoding="utf-8") as file:
            file.write(json.dumps(data))
        os.replace(tmp, manifest)
    except OSError:  # nothing better to do: the run is gone
        Path(tmp).unlink(missing_ok=True)


def undo(created: list[str], aside: list[tuple[str, str]]) -> None:
    """Remove what the run created and rename the set-aside files back."""
    for path in created:
        with contextlib.suppress(OSError):
            os.unlink(path)
    for original, moved in aside:
        if not os.path.lexists(original):
            with contextlib.suppress(OSError):
                os.rename(moved, original)


def reader() -> Callable[[], bytes]:
    """What reads the run's next bytes from standard input: a socket's, keeping every
    descriptor handed over with them (the locks, held until this process ends), else a
    pipe's."""
    try:
        channel = socket.socket(fileno=0)
    except OSError:  # a pipe
        return lambda: os.read(0, 65536)
    held: list[int] = []

    def read() -> bytes:
        data, fds, _, _ = socket.recv_fds(channel, 65536, 4)
        held.extend(fds)
        return data

    return read


def main(argv: list[str]) -> int:
    for name in ("SIGINT", "SIGHUP"):  # a terminal's signals are the run's to handle
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_IGN)
    manifest, files = argv[0], argv[1:]
    committed, rrd_size, pending = False, None, b""
    created: list[str] = []
    aside: list[tuple[str, str]] = []
    read = reader()
    while chunk := read():  # until the run says done, closes its end or dies
        lines = (pending + chunk).split(b"\n")
        pending = lines.pop()  # an incomplete line waits for the rest
        for line in lines:
            word, _, rest = line.decode("utf-8", "surrogateescape").partition(" ")
            if word == "done":  # not read on to the end: a child the run forked may
                return 0  # hold a copy of the input open long after the run
            elif word == "commit":
                committed, aside = True, []
            elif word == "rrd":
                rrd_size = int(rest)
            elif word == "new":
                created.append(json.loads(rest))
            elif word == "aside":
                original, moved = json.loads(rest)
                aside.append((original, moved))
    if not committed:  # it never stepped: nothing computed, the folder as it was
        undo([*created, manifest], aside)
        return 0
    cut_torn_tail(files[0])
    if len(files) > 1 and rrd_size is not None:
        cut_to(files[1], rrd_size)
    record_identities(manifest, [*files, str(Path(manifest).with_name("summary.json"))])
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
