"""The process limits a run and a study need: the address space a run maps, checked
against the limit on it (``ulimit -v``, ``prlimit --as``) before a run or a study starts
and named in a failure for want of memory; the open files a study or a recorded run needs
(``ulimit -n``); the file-size limit (``ulimit -f``) named where it stops a file.

Under a limit below what a run maps, nothing said so: numba's LLVM library "could not be
found" as the plant FMU loaded, the recording's libraries "failed to map segment", a
thread "could not be started", and OpenBLAS (loaded with the recording's libraries)
retried its start-up allocation for minutes, the run hung. Most of the address space is
reserved, never touched (numba's LLVM, the libraries' thread pools and the threads' malloc
arenas): a run's resident memory peaks near 320 MB ([runs.md](../docs/runs.md#resources),
measured by ``scripts/resource_floor.py``)."""

from __future__ import annotations

import errno
import os
import socket
from collections.abc import Iterator
from contextlib import contextmanager

from cosim.errors import CosimError

MB = 1 << 20  # bytes
# The least address space `auv-cosim run bs-3` completed in on x86-64 Linux with two cores,
# with its recording and without (--no-rrd), and `auv-cosim sweep` with local workers, as
# scripts/resource_floor.py measured them (3546, 1729 and 1085 MB, bisected to 100 MB;
# another measurement saw 3500 fail and 1000 complete), rounded down to 50 MB: a limit
# below is sure to fail, one a little above may still.
RUN_ADDRESS_SPACE = 3500 * MB
RUN_NO_RECORDING_ADDRESS_SPACE = 1700 * MB
STUDY_ADDRESS_SPACE = 1000 * MB
# The least open files (ulimit -n) `auv-cosim sweep` with two local workers completed with
# (it failed at 40, printing Dask's tracebacks), and `auv-cosim run bs-3` with its
# recording (at 16 it failed naming no limit, at 12 rerun-sdk panicked; --no-rrd ran at 10).
STUDY_OPEN_FILES = 48
RUN_OPEN_FILES = 24


def address_space_limit() -> int | None:
    """This process's soft limit on its address space in bytes (``ulimit -v`` times 1024),
    or None: unlimited, or a system that has no such limit (Windows)."""
    try:
        import resource
    except ImportError:
        return None
    soft, _ = resource.getrlimit(resource.RLIMIT_AS)
    return None if soft == resource.RLIM_INFINITY else soft


def check_address_space(what: str, needed: int) -> None:
    """Refuse, in one line, to start ``what`` ("a run with its recording", "a study")
    under an address-space limit below the ``needed`` bytes it maps, where it would fail
    naming anything but the limit, or hang. Raises CosimError."""
    limit = address_space_limit()
    if limit is not None and limit < needed:
        raise CosimError(
            f"the address-space limit of this process, {limit // MB} MB (ulimit -v), is "
            f"below the {needed // MB} MB {what} maps (most of it reserved, not used): "
            f"raise it (ulimit -v {needed // 1024}) or lift it (ulimit -v unlimited)"
        )


def out_of_memory(reason: str) -> str:
    """``reason`` (a failure for want of memory: a MemoryError, a thread not started) with
    the address-space limit named, if one is set: ``out of memory (address-space limit
    800 MB, ulimit -v: raise it)``."""
    limit = address_space_limit()
    if limit is None:
        return f"out of memory ({reason})"
    return f"out of memory ({reason}; address-space limit {limit // MB} MB, ulimit -v: raise it)"


def check_open_files(what: str, needed: int) -> None:
    """Raise this process's soft limit on open files to ``needed`` if its hard limit allows
    (children inherit it), else refuse, in one line, to start ``what`` ("a study"), whose
    libraries would fail with tracebacks of their own. Raises CosimError."""
    try:
        import resource
    except ImportError:
        return
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    if soft == resource.RLIM_INFINITY or soft >= needed:
        return
    if hard == resource.RLIM_INFINITY or hard >= needed:
        resource.setrlimit(resource.RLIMIT_NOFILE, (needed, hard))
        return
    raise CosimError(
        f"the open-files limit of this process, {soft} (ulimit -n), is below the {needed} "
        f"{what} needs: raise it (ulimit -n {needed})"
    )


@contextmanager
def open_files_limit_kept() -> Iterator[None]:
    """Put this process's soft limit on open files back after the block as it was before
    it: what :func:`check_open_files` raised in the block for a study or a run called from
    Python (``cosim.sweep``) would otherwise stay raised in the caller's process, and in
    every process it starts later (the command's process ends instead)."""
    try:
        import resource
    except ImportError:
        yield
        return
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    try:
        yield
    finally:
        now, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
        if now != soft:
            resource.setrlimit(resource.RLIMIT_NOFILE, (soft, hard))


def check_local_study() -> None:
    """Refuse (or, for open files, raise the soft limit for) a study whose local workers,
    sharing this process's limits, could not run: :func:`check_address_space` and
    :func:`check_open_files` with a study's needs. Raises CosimError."""
    check_address_space("a study", STUDY_ADDRESS_SPACE)
    check_open_files("a study", STUDY_OPEN_FILES)
    check_loopback()
    check_semaphores()


def check_semaphores() -> None:
    """Refuse, in one line, a study whose local workers could not be started: each is
    started with a semaphore of multiprocessing's, which POSIX keeps in ``/dev/shm``; where
    that is missing or read-only (a container's), Dask printed tracebacks and said "Nanny
    failed to start". Raises CosimError. The probe is made as "fork" makes its locks,
    unlinked at once: not registered with multiprocessing's resource tracker, which a
    "spawn" lock would start here, before a study starts it immune to SIGHUP
    (:mod:`cosim.study.fork_server`)."""
    import multiprocessing

    try:
        fork = multiprocessing.get_context("fork")
    except ValueError:  # no fork (Windows): no /dev/shm either
        return
    try:
        fork.Lock()
    except OSError as exc:
        raise CosimError(
            "a study's workers need a semaphore of multiprocessing's, which this process "
            f"cannot make ({exc.strerror or exc}; POSIX keeps them in /dev/shm): give it a "
            "writable /dev/shm (docker run --shm-size), or give --scheduler a cluster's address"
        ) from None


def check_loopback() -> None:
    """Refuse, in one line, a study whose local workers could not reach each other: a
    connection to a socket of this process on 127.0.0.1 fails at once where the loopback
    interface is down (``unshare -n``), where Dask waited 30 s for its cluster and said
    only that it timed out. Raises CosimError."""
    try:
        with socket.socket() as server:
            server.bind(("127.0.0.1", 0))
            server.listen(1)
            socket.create_connection(server.getsockname(), timeout=5).close()
    except OSError as exc:
        raise CosimError(
            "a study's local workers talk over 127.0.0.1, which this process cannot reach "
            f"({exc.strerror or exc}): bring the loopback interface up (ip link set lo up) "
            "or give --scheduler a cluster's address"
        ) from None


FILE_SIZE_LIMIT = "(ulimit -f)"  # how :func:`unwritten` names the limit


def unwritten(exc: OSError) -> str:
    """Why a file could not be written (``exc``), in a few words: its ``strerror``, and for
    a file past this process's file-size limit (``ulimit -f``) that limit, which no free
    space on the disk tells: ``File too large: the file-size limit of this process, 65536
    bytes (ulimit -f), stopped it: raise it``; for a name or path too long, the system's
    limit it is over (:func:`_too_long`)."""
    reason = exc.strerror or str(exc)
    if exc.errno == errno.ENAMETOOLONG and exc.filename:
        return f"{reason}{_too_long(os.fsdecode(exc.filename))}"
    if exc.errno != errno.EFBIG:
        return reason
    try:
        import resource
    except ImportError:
        return reason
    soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
    if soft == resource.RLIM_INFINITY:
        return reason
    return (
        f"{reason}: the file-size limit of this process, {soft} bytes {FILE_SIZE_LIMIT}, "
        "stopped it: raise it (ulimit -f unlimited)"
    )


def _too_long(path: str) -> str:
    """What made ``path`` "too long": a name over the system's limit for a name, or a path
    over its limit for a path, which may be the temporary file's written first beside it
    (:func:`cosim.whole_file.write_whole`'s ``.<name>.<pid>.tmp``) where ``path`` itself
    is within it. The limits, in bytes, as the folder's file system gives them
    (``pathconf``; none on Windows, whose message stays the system's)."""
    pathconf = getattr(os, "pathconf", None)
    folder = os.path.dirname(path) or "."
    while not os.path.isdir(folder) and os.path.dirname(folder) != folder:
        folder = os.path.dirname(folder)
    try:
        name_max, path_max = pathconf(folder, "PC_NAME_MAX"), pathconf(folder, "PC_PATH_MAX")  # type: ignore[misc]
    except (OSError, ValueError, TypeError):  # no such query here
        return ""
    longest = max((os.fsencode(name) for name in path.split(os.sep)), key=len)
    size = len(os.fsencode(path))
    if len(longest) > name_max:
        return f": a name of {len(longest)} bytes, over the system's limit of {name_max} bytes"
    if size >= path_max:
        return f": a path of {size} bytes, over the system's limit of {path_max - 1} bytes"
    temporary = size + len(f"..{os.getpid()}.tmp")
    return (
        f": the temporary file written first beside it makes a path of {temporary} bytes, "
        f"over the system's limit of {path_max - 1} bytes: write into a folder of a "
        "shorter path"
    )
