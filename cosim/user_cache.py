"""Stores of folders in the user's cache that processes running at once share safely.

What auv-cosim keeps between runs lives beside numba's cache
(``$XDG_CACHE_HOME/auv-cosim`` or ``~/.cache/auv-cosim``: the parent of
:func:`plant_fmu.model.jit.default_cache_dir`), one store a kind (a study's extracted
FMUs, :mod:`cosim.study.fmu_store`; the FMUs built, :mod:`cosim.fmus.kept_builds`), one
folder an entry, named by a digest of what it holds, and a lock file beside it:

* an entry is filled in a fresh folder of the store and renamed into place whole
  (``os.rename``, atomic; :func:`publish`); whoever renames second removes its own copy
  and uses the first, and a process killed midway leaves nothing anyone would use (the
  folder is claimed by :func:`cosim.scratch.claim`, removed by the next process);
* a process holds a shared lock (``flock``) on an entry's lock file while it uses the
  entry (:func:`shared_lock`); an entry is removed only under the exclusive lock, which it
  cannot get while anyone uses it (:func:`remove_unused`), and a lock file removed with
  its entry is opened again (:func:`shared_lock` checks that the file it locked is still
  the one of that name).

Where there is no ``flock`` (Windows) or no cache folder of the user's own (numba's
cache fallen back to the temporary folder, which other users share: no place to keep
code), there is no store (:func:`store_folder` returns None).
"""

from __future__ import annotations

import errno
import os
import shutil
import tempfile
from collections.abc import Callable
from contextlib import suppress
from pathlib import Path

from cosim.scratch import claim
from plant_fmu.model.jit import TEMPORARY_CACHE_PREFIX, default_cache_dir

try:
    import fcntl
except ImportError:  # Windows: no flock, no store
    fcntl = None  # type: ignore[assignment]

LOCK_SUFFIX = ".lock"
NEW_PREFIX = ".new-"  # an entry being filled, renamed into place when whole
OLD_PREFIX = ".old-"  # an entry being removed


def cache_root() -> Path:
    """The user's cache folder of auv-cosim (maybe the temporary fallback)."""
    return default_cache_dir().parent


def matplotlib_cache() -> Path:
    """Where matplotlib's folder goes when its own would be relative (a relative HOME,
    :func:`cosim.errors.matplotlib_folder_absolute`): beside auv-cosim's caches."""
    return cache_root() / "matplotlib"


def store_folder(name: str) -> Path | None:
    """The store ``name`` in the user's cache folder, or None where there can be none."""
    root = cache_root()
    if fcntl is None or root.name.startswith(TEMPORARY_CACHE_PREFIX):
        return None
    return root / name


def publish(entry: Path, fill: Callable[[Path], None]) -> None:
    """Fill a fresh folder of ``entry``'s store with ``fill`` and rename it to ``entry``;
    if another process renamed its own there first, this one's copy is removed. Raises
    what ``fill`` raises, the fresh folder removed."""
    fresh = Path(tempfile.mkdtemp(prefix=NEW_PREFIX, dir=entry.parent))
    claim(fresh)  # removed by the next process if this one is killed before the rename
    try:
        fill(fresh)
        with suppress(OSError):  # taken: another process renamed the same entry first
            os.rename(fresh, entry)
    finally:
        shutil.rmtree(fresh, ignore_errors=True)


def shared_lock(path: Path) -> int:
    """A descriptor holding a shared lock on the lock file ``path`` (made if missing),
    which is still the file of that name: an entry's remover unlinks it under the
    exclusive lock, and a descriptor opened before that locks a file nobody else will see.
    In a cache the user cannot write (a read-only mount, another's folder) the lock file
    is opened for reading: ``flock`` locks a file however it was opened, and an entry
    kept there is used as it is."""
    if fcntl is None:
        raise OSError("no flock on this system")
    while True:
        fd = _open_lock_file(path)
        try:
            fcntl.flock(fd, fcntl.LOCK_SH)
            if os.path.samestat(os.fstat(fd), os.stat(path)):
                return fd
        except FileNotFoundError:
            pass
        except BaseException:
            os.close(fd)
            raise
        os.close(fd)


def _open_lock_file(path: Path) -> int:
    """A descriptor of the lock file ``path``: opened for writing (made if missing) where
    the cache can be written, else for reading (FileNotFoundError if missing)."""
    try:
        return os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
    except OSError as exc:
        if exc.errno not in _READ_ONLY:
            raise
    return os.open(path, os.O_RDONLY)


_READ_ONLY = (errno.EACCES, errno.EPERM, errno.EROFS)  # the cache cannot be written


def remove_unused(store: Path, keep: str, kept: int) -> None:
    """Remove the entries beyond the ``kept`` most recently used (``keep`` among them;
    used: their lock file's time) that nobody uses now, and their lock files."""
    locks = []
    for path in store.glob(f"*{LOCK_SUFFIX}"):
        with suppress(OSError):
            locks.append((path.stat().st_mtime, path))
    others = [path for _, path in sorted(locks, reverse=True) if path.stem != keep]
    for lock_path in others[kept - 1 :]:
        with suppress(OSError):
            _remove_entry(store, lock_path)


def _remove_entry(store: Path, lock_path: Path) -> None:
    """Remove the entry of ``lock_path`` and the lock file, if nobody holds its lock."""
    if fcntl is None:
        raise OSError("no flock on this system")
    fd = os.open(lock_path, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # OSError: someone uses it
        entry = store / lock_path.stem
        if os.path.lexists(entry):
            move_away(entry)
        lock_path.unlink()
    finally:
        os.close(fd)


def move_away(entry: Path) -> None:
    """Remove the entry ``entry`` (or whatever has its name), renamed first into a folder
    claimed for removal, so that no process finds an entry half removed."""
    old = Path(tempfile.mkdtemp(prefix=OLD_PREFIX, dir=entry.parent))
    claim(old)
    os.rename(entry, old / entry.name)
    shutil.rmtree(old, ignore_errors=True)
