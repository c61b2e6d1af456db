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
  (:func:`_shared_lock` checks that the file it locked is still the one of that name);
* a set is renamed into place only whole (every file of its FMUs, and their copies,
  :func:`_damage`), and a set found damaged (files cut short by a power cut after the
  rename or by hand, a link dangling, a file in its place) is replaced under the
  exclusive lock; where another study holds it, this one says so in one line and
  extracts into its own folder.

Where there is no ``flock`` (Windows), no cache folder of the user's own (the cache's
fallback in the temporary folder, which other users share) or the folder cannot be made
or locked, a study extracts its FMUs into its own scratch folder, as before
(:func:`kept_unpacked` returns None).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import stat
import tempfile
import warnings
import zipfile
from collections.abc import Mapping
from contextlib import ExitStack, suppress
from pathlib import Path

from cosim.errors import CosimError
from cosim.scratch import claim
from cosim.study.unpacked import unpack
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
        fmus = {hashlib.sha256(p.read_bytes()).hexdigest(): p for p in fmu_paths.values()}
        digests = sorted(fmus)
        key = hashlib.sha256(" ".join([LAYOUT, *digests]).encode()).hexdigest()  # names aside
        lock = _shared_lock(store / f"{key}{LOCK_SUFFIX}")
    except OSError:
        return None
    stack.callback(os.close, lock)
    entry = store / key
    try:
        _make_whole(fmu_paths, fmus, entry, lock)
    except _InUseError as exc:
        warnings.warn(str(exc), RuntimeWarning, stacklevel=2)
        return None
    except (OSError, CosimError):  # the cache's disk full, say: the study's may not be
        return None
    with suppress(OSError):
        os.utime(store / f"{key}{LOCK_SUFFIX}")  # used now: the last to be removed
    _remove_unused(store, keep=key)
    return {digest: str((entry / digest).resolve()) for digest in digests}  # as unpack's


class _InUseError(OSError):
    """A kept set is damaged and another study uses it: it cannot be replaced now."""


def _make_whole(
    fmu_paths: Mapping[str, Path], fmus: Mapping[str, Path], entry: Path, lock: int
) -> None:
    """Make ``entry`` the whole set of ``fmus`` (SHA-256 -> FMU file), the caller holding
    the shared ``lock`` on it: extracted if missing; if damaged (its files cut short or
    gone by a crash, a full disk or a hand: :func:`_damage`), replaced under the exclusive
    lock, which no other study holding the set allows (:class:`_InUseError`). Raises OSError
    or CosimError where the set cannot be extracted whole."""
    if not os.path.lexists(entry):
        _extract_set(fmu_paths, fmus, entry)
        return
    damage = _damage(entry, fmus)
    if not damage:
        return
    try:  # Linux drops the shared lock on a failed upgrade: the caller then leaves the set
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as exc:
        raise _InUseError(
            f"the kept FMUs {entry} are damaged ({damage}) and another study uses them: "
            "extracting into this study's own folder; the next study replaces them"
        ) from exc
    _move_away(entry.parent, entry)
    _extract_set(fmu_paths, fmus, entry)
    fcntl.flock(lock, fcntl.LOCK_SH)  # others may use the set again


def _damage(entry: Path, fmus: Mapping[str, Path]) -> str:
    """ "" if ``entry`` holds each FMU of ``fmus`` (SHA-256 -> FMU file) whole, else what is
    wrong: each member of its archive a regular file of the size the archive declares
    (through the resource folders' links, :func:`cosim.study.unpacked._extract`) and its
    file's copy beside it of the file's size. Sizes, not contents: a stat for each of the
    ~390 files of bs-3's three (~4 ms of CPU), where hashing them would cost about what
    keeping the set saves; names joined as text, which costs half of what pathlib does."""
    for digest, path in fmus.items():
        wanted = [(f"{digest}.fmu", path.stat().st_size)]
        with zipfile.ZipFile(path) as archive:
            wanted += [(f"{digest}/{info.filename}", info.file_size)
                       for info in archive.infolist() if not info.is_dir()]  # fmt: skip
        for name, size in wanted:
            try:
                found = os.stat(os.path.join(entry, name))
            except OSError as exc:
                return f"{name}: {exc.strerror}"
            if not stat.S_ISREG(found.st_mode) or found.st_size != size:
                return f"{name} is {found.st_size} bytes, not {size}"
    return ""


def _extract_set(fmu_paths: Mapping[str, Path], fmus: Mapping[str, Path], entry: Path) -> None:
    """Extract the set into a fresh folder and rename it to ``entry`` once it is whole
    (else OSError: :func:`~cosim.study.unpacked.unpack` leaves out an FMU's copy it could
    not write); if another process renamed its own there first, this one's is removed."""
    fresh = Path(tempfile.mkdtemp(prefix=NEW_PREFIX, dir=entry.parent))
    claim(fresh)  # removed by the next process if this one is killed before the rename
    try:
        unpack(fmu_paths, fresh)
        damage = _damage(fresh, fmus)
        if damage:
            raise OSError(f"not extracted whole: {damage}")
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
        if os.path.lexists(entry):
            _move_away(store, entry)
        lock_path.unlink()
    finally:
        os.close(fd)


def _move_away(store: Path, entry: Path) -> None:
    """Remove the set ``entry`` (or whatever has its name), renamed first into a folder
    claimed for removal, so that no process finds a set half removed."""
    old = Path(tempfile.mkdtemp(prefix=OLD_PREFIX, dir=store))
    claim(old)
    os.rename(entry, old / entry.name)
    shutil.rmtree(old, ignore_errors=True)
