"""The built-in FMUs built once per user, served to every working folder that needs them.

A newcomer running ``auv-cosim run bs-3`` in a second working folder waited ~20 s for
the three FMUs to be built again into its ``build/fmus``, from the same sources. Each
FMU built is kept in the user's cache folder too (``$XDG_CACHE_HOME/auv-cosim/builds``
or ``~/.cache/auv-cosim/builds``, a store of :mod:`cosim.user_cache`), one folder an
FMU and version, named by the FMU's name and what its build records (the sources'
digest, ``SOURCE_DATE_EPOCH``, the Python it records: what decides whether a folder's
FMU is up to date, :func:`cosim.fmus.build.build_fmu`), holding ``<Name>.fmu`` and its
``<Name>.fmu.sha256``. A folder whose FMU is missing or out of date gets a copy of the
kept one, checked as a folder's own is (its record, its file's hash) before it is
copied (a damaged one, a byte changed in place too, is built again, saying so in one
line); the builds are reproducible (the same sources give the same bytes), so a copy
is what a build would write. At most :data:`KEPT` are kept, the least recently used
removed first.

``AUV_COSIM_NO_BUILD_CACHE=1`` turns the store off (every folder builds its own, as
before); ``auv-cosim build --force`` builds regardless and keeps what it built.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import warnings
from collections.abc import Callable
from contextlib import suppress
from pathlib import Path

import cosim.user_cache as user_cache
from cosim.user_cache import LOCK_SUFFIX, publish
from cosim.whole_file import write_whole

STORE_DIR = "builds"  # beside numba's cache folder and the studies' "fmus"
KEPT = 12  # FMUs kept (~1.4 MB each): four versions of the three
OFF_VARIABLE = "AUV_COSIM_NO_BUILD_CACHE"


def store_folder() -> Path | None:
    """The folder the built FMUs are kept in; None where it is turned off or there is
    none (:func:`cosim.user_cache.store_folder`)."""
    if os.environ.get(OFF_VARIABLE, "").strip() not in ("", "0"):
        return None
    return user_cache.store_folder(STORE_DIR)


def entry_name(name: str, record: str) -> str:
    """The folder of the FMU ``name`` built with ``record`` (its build's record without
    the file's own hash: sources, date, Python)."""
    return f"{name}-{hashlib.sha256(record.encode()).hexdigest()[:32]}"


def fetch(
    name: str, record: str, target: Path, hash_file: Path, whole: Callable[[Path, Path], bool]
) -> bool:
    """Copy the kept FMU ``name`` built with ``record`` to ``target`` and its record to
    ``hash_file``, each whole or not at all, if one is kept and ``whole`` (the build's
    integrity check: FMU file, hash file) accepts it; whether it did. The caller holds
    ``target``'s build lock."""
    store = store_folder()
    if store is None:
        return False
    key = entry_name(name, record)
    entry = store / key
    kept_fmu, kept_hash = entry / target.name, entry / hash_file.name
    try:
        lock = user_cache.shared_lock(store / f"{key}{LOCK_SUFFIX}") if entry.is_dir() else None
    except OSError:
        return False
    if lock is None:
        return False
    try:
        if not whole(kept_fmu, kept_hash):  # damaged: the build that follows replaces it
            warnings.warn(
                f"the kept FMU {kept_fmu} is damaged (not the file its build recorded): "
                "building it again",
                RuntimeWarning,
                stacklevel=3,
            )
            return False
        write_whole(target, lambda tmp: shutil.copyfile(kept_fmu, tmp))
        write_whole(hash_file, lambda tmp: shutil.copyfile(kept_hash, tmp))
        with suppress(OSError):
            os.utime(store / f"{key}{LOCK_SUFFIX}")  # used now: the last to be removed
    except OSError:
        return False  # the folder's copy not written (a full disk): the caller builds
    finally:
        os.close(lock)
    user_cache.remove_unused(store, keep=key, kept=KEPT)
    return True


def keep(
    name: str, record: str, target: Path, hash_file: Path, whole: Callable[[Path, Path], bool]
) -> None:
    """Keep a copy of the FMU ``target`` just built with ``record`` and its ``hash_file``,
    unless a copy ``whole`` accepts is kept (a damaged one is replaced); nothing where the
    store cannot hold it (the build is done: a full cache costs the next folder a build)."""
    store = store_folder()
    if store is None:
        return
    key = entry_name(name, record)
    entry = store / key

    def fill(fresh: Path) -> None:
        shutil.copyfile(target, fresh / target.name)
        shutil.copyfile(hash_file, fresh / hash_file.name)

    try:
        store.mkdir(mode=0o700, parents=True, exist_ok=True)
        lock = user_cache.shared_lock(store / f"{key}{LOCK_SUFFIX}")
    except OSError:
        return
    try:
        with suppress(OSError):
            if not whole(entry / target.name, entry / hash_file.name):
                if os.path.lexists(entry):
                    user_cache.move_away(entry)  # a damaged copy (fetch refused it)
                publish(entry, fill)
            os.utime(store / f"{key}{LOCK_SUFFIX}")
    finally:
        os.close(lock)
    user_cache.remove_unused(store, keep=key, kept=KEPT)
