"""A local study's FMUs extracted once for later studies too, kept by content.

The client of a local study extracts its FMUs for its workers (:mod:`cosim.study.unpacked`)
while both cores of a 2-core machine are full (its own imports, and the workers' fork
server's): ~0.06-0.1 s of its CPU, mostly the kernel's, for ~160 files, before its first
run, in every study. The extraction is kept instead in the user's cache folder, beside
numba's (``$XDG_CACHE_HOME/auv-cosim/fmus`` or ``~/.cache/auv-cosim/fmus``: the parent
of :func:`plant_fmu.model.jit.default_cache_dir`), one folder per set of FMU files,
named by their SHA-256 digests; a later study of the same FMUs finds it and extracts
nothing. At most :data:`KEPT` sets are kept, the least recently used removed first.

Studies may run at once: the store is one of :mod:`cosim.user_cache` (a set extracted
into a fresh folder and renamed into place whole; a shared ``flock`` on its lock file as
long as a study's session lasts, a set removed only under the exclusive lock). A set is
renamed into place only whole (every file of its FMUs, and their copies, :func:`_damage`),
and a set found damaged (files cut short by a power cut after the rename or by hand, a
link dangling, a file in its place, a file written to since it was kept: a byte changed
in place) is replaced under the exclusive lock, saying so in one line; where another
study holds it, this one says so in one line and extracts into its own folder.

Where there is no store (:func:`cosim.user_cache.store_folder`: no ``flock``, or no cache
folder of the user's own) or the folder cannot be made or locked, a study extracts its
FMUs into its own scratch folder, as before (:func:`kept_unpacked` returns None).
"""

from __future__ import annotations

import hashlib
import os
import stat
import warnings
import zipfile
from collections.abc import Mapping
from contextlib import ExitStack, suppress
from pathlib import Path

import cosim.user_cache as user_cache
from cosim.errors import CosimError
from cosim.study.unpacked import unpack
from cosim.user_cache import LOCK_SUFFIX, publish

STORE_DIR = "fmus"  # beside numba's cache folder
KEPT = 4  # sets of FMUs kept (~5 MB each for bs-3's three)
LAYOUT = "unpacked-2"  # what a set's folder holds (cosim.study.unpacked, CHANGE_TIMES): in its name
CHANGE_TIMES = "change-times.txt"  # in a set's folder: each file's st_ctime_ns as it was kept


def store_folder() -> Path:
    """The folder the sets are kept in."""
    return user_cache.cache_root() / STORE_DIR


def kept_unpacked(fmu_paths: Mapping[str, Path], stack: ExitStack) -> dict[str, str] | None:
    """:func:`cosim.study.unpacked.unpack` of ``fmu_paths`` into the store (extracting
    only a set not kept yet), the set locked for as long as ``stack`` lasts; None where the
    store cannot be used, or cannot hold the set (then the caller extracts into a folder
    of its own, which refuses an FMU as :func:`~cosim.study.unpacked.unpack` does)."""
    store = user_cache.store_folder(STORE_DIR)
    if store is None:
        return None
    try:
        store.mkdir(mode=0o700, parents=True, exist_ok=True)
        fmus = {hashlib.sha256(p.read_bytes()).hexdigest(): p for p in fmu_paths.values()}
        digests = sorted(fmus)
        key = hashlib.sha256(" ".join([LAYOUT, *digests]).encode()).hexdigest()  # names aside
        lock = user_cache.shared_lock(store / f"{key}{LOCK_SUFFIX}")
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
    user_cache.remove_unused(store, keep=key, kept=KEPT)
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
        user_cache.fcntl.flock(lock, user_cache.fcntl.LOCK_EX | user_cache.fcntl.LOCK_NB)
    except OSError as exc:
        raise _InUseError(
            f"the kept FMUs {entry} are damaged ({damage}) and another study uses them: "
            "extracting into this study's own folder; the next study replaces them"
        ) from exc
    user_cache.move_away(entry)
    _extract_set(fmu_paths, fmus, entry)
    user_cache.fcntl.flock(lock, user_cache.fcntl.LOCK_SH)  # others may use the set again
    warnings.warn(
        f"the kept FMUs {entry} were damaged ({damage}): extracted again",
        RuntimeWarning,
        stacklevel=3,
    )


def _damage(entry: Path, fmus: Mapping[str, Path], kept: bool = True) -> str:
    """ "" if ``entry`` holds each FMU of ``fmus`` (SHA-256 -> FMU file) whole, else what is
    wrong: each member of its archive a regular file of the size the archive declares
    (through the resource folders' links, :func:`cosim.study.unpacked._extract`) and its
    file's copy beside it of the file's size, readable by its owner, and (``kept``: the set
    in place, not one being extracted) not changed since it was kept. Sizes and change
    times, not contents: a stat for each of the ~390 files of bs-3's three (~4 ms of CPU),
    where hashing them would cost about what keeping the set saves. A file's change time
    (st_ctime_ns) is the system's, moved by every write or chmod and set by no call of a
    user's (``touch`` sets the modification time): a byte changed in place, the size and
    modification time kept, shows there (:data:`CHANGE_TIMES`). Names joined as text,
    which costs half of what pathlib does."""
    recorded: dict[str, int] = {}
    if kept:
        try:
            with open(os.path.join(entry, CHANGE_TIMES), encoding="utf-8") as listed:
                recorded = {name: int(ns) for ns, _, name in
                            (line.rstrip("\n").partition(" ") for line in listed)}  # fmt: skip
        except (OSError, ValueError) as exc:
            return f"{CHANGE_TIMES}: {getattr(exc, 'strerror', None) or exc}"
    for name, size in _members(fmus):
        try:
            found = os.stat(os.path.join(entry, name))
        except OSError as exc:
            return f"{name}: {exc.strerror}"
        if not stat.S_ISREG(found.st_mode) or found.st_size != size:
            return f"{name} is {found.st_size} bytes, not {size}"
        if not found.st_mode & stat.S_IRUSR:  # by its mode: root reads it, a worker not
            return f"{name} cannot be read (mode {stat.S_IMODE(found.st_mode):03o})"
        if kept and recorded.get(name) != found.st_ctime_ns:
            return f"{name} was written to since it was kept"
    return ""


def _members(fmus: Mapping[str, Path]) -> list[tuple[str, int]]:
    """(name in a set's folder, size in bytes) of every file of ``fmus`` (SHA-256 -> FMU
    file): each FMU's copy and the members of its archive."""
    wanted = []
    for digest, path in fmus.items():
        wanted.append((f"{digest}.fmu", path.stat().st_size))
        with zipfile.ZipFile(path) as archive:
            wanted += [(f"{digest}/{info.filename}", info.file_size)
                       for info in archive.infolist() if not info.is_dir()]  # fmt: skip
    return wanted


def _extract_set(fmu_paths: Mapping[str, Path], fmus: Mapping[str, Path], entry: Path) -> None:
    """Extract the set and rename it to ``entry`` once it is whole (else OSError:
    :func:`~cosim.study.unpacked.unpack` leaves out an FMU's copy it could not write)."""

    def fill(fresh: Path) -> None:
        unpack(fmu_paths, fresh)
        damage = _damage(fresh, fmus, kept=False)
        if damage:
            raise OSError(f"not extracted whole: {damage}")
        times = (f"{os.stat(os.path.join(fresh, name)).st_ctime_ns} {name}\n"
                 for name, _ in _members(fmus))  # fmt: skip
        (fresh / CHANGE_TIMES).write_text("".join(times), encoding="utf-8")

    publish(entry, fill)
