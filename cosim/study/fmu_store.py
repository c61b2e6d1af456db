"""A local study's FMUs extracted once for later studies too, kept by content.

The client of a local study extracts its FMUs for its workers (:mod:`cosim.study.unpacked`)
while both cores of a 2-core machine are full (its own imports, and the workers' fork
server's): ~0.06-0.1 s of its CPU, mostly the kernel's, for ~160 files, before its first
run, in every study. The extraction is kept instead in the user's cache folder, beside
numba's (``$XDG_CACHE_HOME/auv-cosim/fmus`` or ``~/.cache/auv-cosim/fmus``: the parent
of :func:`plant_fmu.model.jit.default_cache_dir`), one folder per set of FMU files,
named by their SHA-256 digests; a later study of the same FMUs finds it and extracts
nothing. At most :data:`KEPT` sets are kept, the least recently used removed first.

Studies may run at once, so every step is safe against another process doing the same:

* a set is extracted into a fresh folder of the store and renamed into place whole
  (``os.rename``, atomic); whoever renames second removes its own copy and uses the
  first, and a process killed midway leaves nothing that a study would use (the folder
  is claimed by :func:`cosim.scratch.claim`, removed by the next process);
* a study holds a shared lock (``flock``) on its set's lock file as long as its session
  lasts; a set is removed only under the exclusive lock, which it cannot get while any
  study uses the set, and a lock file removed with its set is opened again
  (:func:`_shared_lock` checks that the file it locked is still the one of that name).

Where there is no ``flock`` (Windows), no cache folder of the user's own (the cache's
fallback in the temporary folder, which other users share) or the folder cannot be made
or locked, a study extracts its FMUs into its own scratch folder, as before
(:func:`kept_unpacked` returns None).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Mapping
from contextlib import ExitStack, suppress
from pathlib import Path

from cosim.errors import CosimError
from cosim.scratch import claim
from cosim.study.unpacked import MODEL_DESCRIPTION, unpack
from plant_fmu.model.jit import TEMPORARY_CACHE_PREFIX, default_cache_dir

try:
    import fcntl
except ImportError:  # Windows: no flock; studies extract into their own folders
    fcntl = None  # type: ignore[assignment]

STORE_DIR = "fmus"  # beside numba's cache folder
KEPT = 4  # sets of FMUs kept (~5 MB each for bs-3's three)
LOCK_SUFFIX = ".lock"
NEW_PREFIX = ".new-"  # a set being extracted, renamed into place when whole
OLD_PREFIX = ".old-"  # a set being removed
LAYOUT = "unpacked-1"  # what a set's folder holds (cosim.study.unpacked): part of its name


def store_folder() -> Path:
    """The folder the sets are kept in."""
    return default_cache_dir().parent / STORE_DIR


def kept_unpacked(fmu_paths: Mapping[str, Path], stack: ExitStack) -> dict[str, str] | None:
    """:func:`cosim.study.unpacked.unpack` of ``fmu_paths`` into the store (extracting
    only a set not kept yet), the set locked for as long as ``stack`` lasts; None where the
    store cannot be used, or cannot hold the set (then the caller extracts into a folder
    of its own, which refuses an FMU as :func:`~cosim.study.unpacked.unpack` does)."""
    if fcntl is None:
        return None
    store = store_folder()
    if store.parent.name.startswith(TEMPORARY_CACHE_PREFIX):
        return None  # no cache folder of the user's own: a shared /tmp is no place to keep code
    try:
        store.mkdir(mode=0o700, parents=True, exist_ok=True)
        digests = sorted({hashlib.sha256(p.read_bytes()).hexdigest() for p in fmu_paths.values()})
        key = hashlib.sha256(" ".join([LAYOUT, *digests]).encode()).hexdigest()  # names aside
        lock = _shared_lock(store / f"{key}{LOCK_SUFFIX}")
    except OSError:
        return None
    stack.callback(os.close, lock)
    entry = store / key
    if not entry.is_dir():
        try:
            _extract_set(fmu_paths, store, entry)
        except (OSError, CosimError):  # the cache's disk full, say: the study's may not be
            return None
    found = {digest: (entry / digest).resolve() for digest in digests}
    if not all((folder / MODEL_DESCRIPTION).is_file() for folder in found.values()):
        return None  # a kept set someone took files from: not ours to mend (others read it)
    with suppress(OSError):
        os.utime(store / f"{key}{LOCK_SUFFIX}")  # used now: the last to be removed
    _remove_unused(store, keep=key)
    return {digest: str(folder) for digest, folder in found.items()}  # as unpack's


def _extract_set(fmu_paths: Mapping[str, Path], store: Path, entry: Path) -> None:
    """Extract the set into a fresh folder and rename it to ``entry``; if another
    process renamed its own there first, this one's copy is removed."""
    fresh = Path(tempfile.mkdtemp(prefix=NEW_PREFIX, dir=store))
    claim(fresh)  # removed by the next process if this one is killed before the rename
    try:
        unpack(fmu_paths, fresh)
        with suppress(OSError):  # taken: another study renamed the same set first
            os.rename(fresh, entry)
    finally:
        shutil.rmtree(fresh, ignore_errors=True)


def _shared_lock(path: Path) -> int:
    """A descriptor holding a shared lock on the lock file ``path`` (made if missing),
    which is still the file of that name: a set's remover unlinks it under the exclusive
    lock, and a descriptor opened before that locks a file nobody else will see."""
    if fcntl is None:
        raise OSError("no flock on this system")
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
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


def _remove_unused(store: Path, keep: str) -> None:
    """Remove the sets beyond the :data:`KEPT` most recently used (``keep`` among them)
    that no study uses now (their exclusive lock free), and their lock files."""
    locks = []
    for path in store.glob(f"*{LOCK_SUFFIX}"):
        with suppress(OSError):
            locks.append((path.stat().st_mtime, path))
    others = [path for _, path in sorted(locks, reverse=True) if path.stem != keep]
    for lock_path in others[KEPT - 1 :]:
        with suppress(OSError):
            _remove_set(store, lock_path)


def _remove_set(store: Path, lock_path: Path) -> None:
    """Remove the set of ``lock_path`` and the lock file, if no study holds its lock."""
    if fcntl is None:
        raise OSError("no flock on this system")
    fd = os.open(lock_path, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)  # OSError: a study uses it
        entry = store / lock_path.stem
        if entry.is_dir():
            old = Path(tempfile.mkdtemp(prefix=OLD_PREFIX, dir=store))
            claim(old)
            os.rename(entry, old / entry.name)
            shutil.rmtree(old, ignore_errors=True)
        lock_path.unlink()
    finally:
        os.close(fd)
