"""Temporary folders that a process killed outright does not leave behind.

A process's temporary files (its FMUs extracted, a study's run folders) go into one
folder of its own, ``$TMPDIR/auv-cosim-scratch-<uid>/<pid>-XXXXXXXX`` (the user's own,
mode 0700), made at the first
:func:`process_folder` and removed as the process ends, however Python ends it. A
process ended by SIGKILL (``kill -9``, the OOM killer), a reboot or a power cut runs
nothing at its end; so each folder has a lock file beside it (``<folder>.dirlock``) that
its process holds while it lives, and the first :func:`process_folder` of every process
removes each folder whose lock no live process holds. This is Dask's own scheme for its
``dask-scratch-space`` (``distributed.diskutils.WorkSpace``), with the library Dask locks
with (``locket``: ``flock`` on POSIX, ``msvcrt.locking`` on Windows, released by the
system when the process dies); a global lock orders a new folder's lock against a purge
listing the lock files, so a purge never takes a live folder whose lock is not yet held.

A folder can name other paths its process made outside it (:func:`claim`: the
``pymp-*`` folder multiprocessing makes for a local study's fork server), removed with it
by whoever purges it. Purging costs a directory listing once per process.
"""

from __future__ import annotations

import multiprocessing.util
import os
import shutil
import stat
import tempfile
import threading
from pathlib import Path
from typing import Any

import locket

# in the temporary folder (TMPDIR): one a user, where the system has users (not Windows,
# whose temporary folder is the user's own)
SCRATCH_DIR = "auv-cosim-scratch" + (f"-{os.getuid()}" if hasattr(os, "getuid") else "")
LOCK_SUFFIX = ".dirlock"  # beside each process's folder: held while its process lives
LISTING_WAIT_S = 10.0  # s a purge waits for the global lock before it gives up
CLAIMS_FILE = "claimed-paths"  # in a process's folder: other paths it made, one a line

_making = threading.Lock()  # held while a thread makes this process's folder
_own: dict[int, Path] = {}  # process id -> its folder (a forked child makes its own)
_locks: dict[Path, Any] = {}  # this process's folder -> the lock it holds on it
_claimed: dict[Path, set[Path]] = {}  # this process's folder -> the paths it claimed


def base_folder() -> Path:
    """The folder holding every process's scratch folder, in the temporary folder."""
    return Path(tempfile.gettempdir()) / SCRATCH_DIR


def _own_base(base: Path) -> None:
    """Make ``base`` private to this user (mode 0700), or refuse it: where the temporary
    folder is shared (/tmp), a folder of this name that another user made, or a symbolic
    link, would let them see this user's runs, or name paths in it for this user's next
    purge to remove (pytest checks its pytest-of-<user> folder the same way). Raises
    PermissionError naming the folder and what to do."""
    base.mkdir(mode=0o700, parents=True, exist_ok=True)
    if not hasattr(os, "getuid"):
        return
    info = os.lstat(base)
    if stat.S_ISLNK(info.st_mode) or info.st_uid != os.getuid():
        owner = "a symbolic link" if stat.S_ISLNK(info.st_mode) else f"user {info.st_uid}'s"
        raise PermissionError(
            f"temporary folder {base} is {owner}, not this user's (uid {os.getuid()}): "
            "remove it, or set TMPDIR to a folder of your own"
        )
    if stat.S_IMODE(info.st_mode) & 0o077:
        os.chmod(base, 0o700)


def process_folder() -> Path:
    """This process's scratch folder, made (after purging what dead processes left) at the
    first call and removed as the process ends; later calls cost a dictionary look-up."""
    folder = _own.get(os.getpid())
    if folder is not None and folder.is_dir():
        return folder
    with _making:  # one folder for all threads (a study's cluster starts on its own)
        folder = _own.get(os.getpid())
        if folder is None or not folder.is_dir():
            base = base_folder()
            _own_base(base)
            purge(base)
            folder = _own[os.getpid()] = _locked_folder(base)
            # multiprocessing's finalizers run at exit (atexit) and also where a
            # multiprocessing child (a Dask worker) ends by os._exit, past atexit
            multiprocessing.util.Finalize(None, remove, args=(folder,), exitpriority=0)
    return folder


def _locked_folder(base: Path) -> Path:
    """A new folder in ``base`` whose lock this process holds; a file system refusing
    locks gives a folder without a lock file, which no purge takes (as before)."""
    guard = locket.lock_file(str(base / "global.lock"))
    try:
        guard.acquire()
    except OSError:
        guard = None
    try:
        folder = Path(tempfile.mkdtemp(prefix=f"{os.getpid()}-", dir=base))
        lock_path = str(folder) + LOCK_SUFFIX
        try:
            lock = locket.lock_file(lock_path)
            lock.acquire()
        except OSError:
            Path(lock_path).unlink(missing_ok=True)
        else:
            _locks[folder] = lock
    finally:
        if guard is not None:
            guard.release()
    return folder


def claim(path: Path) -> None:
    """Have ``path`` (a folder this process made outside its scratch folder) removed with
    the scratch folder by a later process if this one is killed; ending normally, the
    process removes it itself. A path claimed again is not written again."""
    folder = process_folder()
    if path in _claimed.setdefault(folder, set()):
        return
    with open(folder / CLAIMS_FILE, "a", encoding="utf-8") as claims:
        claims.write(f"{path}\n")
    _claimed[folder].add(path)


def remove(folder: Path) -> None:
    """Remove ``folder`` (one process's scratch folder) and its lock file, releasing the
    lock if this process holds it. The paths it claimed are their makers' to remove."""
    shutil.rmtree(folder, ignore_errors=True)
    lock = _locks.pop(folder, None)
    if lock is not None:
        lock.release()
    Path(str(folder) + LOCK_SUFFIX).unlink(missing_ok=True)


def remove_own() -> None:
    """Remove this process's scratch folder now, if it has made one: a process about to
    fork children that outlive its use of it (the workers' fork server after its warm-up,
    :mod:`cosim.study.server_warm`; each child makes a folder of its own)."""
    folder = _own.pop(os.getpid(), None)
    if folder is not None:
        remove(folder)


def purge(base: Path) -> list[Path]:
    """Remove every folder in ``base`` whose process is gone (its lock free), with the
    paths it claimed; the folders removed. The listing waits for the global lock (held
    for a folder's creation or a listing, milliseconds; a process that gave up instead
    while a study's workers made their folders left the dead one's folders, as every
    process purges once); a folder another process is purging is left to it."""
    listing = locket.lock_file(str(base / "global.lock"), timeout=LISTING_WAIT_S)
    try:
        with listing:
            candidates = [p for p in base.glob(f"*{LOCK_SUFFIX}") if p.is_file()]
    except (locket.LockError, OSError):
        return []
    purged = []
    for lock_path in candidates:
        folder = Path(str(lock_path)[: -len(LOCK_SUFFIX)])
        if folder in _locks:
            continue
        if _purge_stale(folder, lock_path):
            purged.append(folder)
    return purged


def _purge_stale(folder: Path, lock_path: Path) -> bool:
    """Remove ``folder``, its claimed paths and ``lock_path`` if no process holds the lock;
    whether it did."""
    lock = locket.lock_file(str(lock_path), timeout=0)
    try:
        lock.acquire()
    except (locket.LockError, OSError):
        return False
    try:
        claims = folder / CLAIMS_FILE
        if claims.is_file():
            for line in claims.read_text("utf-8").splitlines():
                shutil.rmtree(line, ignore_errors=True)
        shutil.rmtree(folder, ignore_errors=True)
    finally:
        lock.release()
    lock_path.unlink(missing_ok=True)
    return True
