"""Numba for the compiled fast paths: whether it may be used, and where its cache lives.

The compiled paths (:mod:`plant_fmu.model.compiled`) use ``numba.njit(cache=True)`` without
fastmath, so a compiled function does the same IEEE operations on every run. This module
decides once per process whether numba is usable:

* ``AUV_COSIM_NO_JIT=1`` in the environment turns it off (the reference numpy path runs);
* a numba that cannot be imported turns it off too, whatever it raises (a broken install:
  llvmlite's ``OSError``, numba's ``ImportError`` for a numpy it does not support);
  callers log that as a warning with :func:`numba_fix` (which names the user's ``NUMBA_*``
  variables when numba refused one of them as it was imported: ``NUMBA_NUM_THREADS=0``);
* a ``NUMBA_CPU_FEATURES`` item without its + or - sign turns it off as well: LLVM would
  abort the whole process (an FMU's host) at the first compilation.

Cache folder: numba's default is ``__pycache__`` next to the source, which for an FMU is
the fresh temporary folder the importer unzips it into, so every run would compile again
(several seconds). We therefore set ``NUMBA_CACHE_DIR`` to a per-user folder,
``$XDG_CACHE_HOME/auv-cosim/numba`` (``~/.cache/auv-cosim/numba``; with no home folder at
all, a uid without a passwd entry and HOME unset, ``$TMPDIR/auv-cosim-cache-<uid>/numba``,
private to the user), unless the user has set it, before numba is imported; and we key the
cache of our own modules by their package and content, not by the folder they were loaded
from (numba keys it by folder: see :class:`_ContentCacheLocator`), so every unzipped copy
of the same FMU shares one cache. The content is that of every kernel file
(:data:`KERNEL_FILES`: a compiled function holds the code of the jitted functions it calls
and the constants it reads), so a change to any of them recompiles all
(:func:`kernel_stamp`). The package is the top-level one (an FMU build's
``auvfmu_<hash>``, or ``plant_fmu``/``controller_fmu`` in the source tree), one folder
each: numba's cached code imports its module by name when it is loaded, so a cache written
by one build cannot serve another (whose modules have other names), and folders of their
own keep two builds, or a build and the source tree, from evicting each other's. Under
the package, each version of the kernel files (their stamp) has a folder of its own:
numba names a function's data files by their order in its index (``.1.nbc``) and checks
only the index against the stamp, so a process compiling the kernels as they were before
an edit and one compiling the edited kernels, at once in one folder, could leave one's
index naming the other's code. Concurrent processes of one version (sweeps start many at
once) share the folder: numba writes each cache file to a unique temporary name and moves
it into place with ``os.replace``, which is atomic, so a reader sees an old complete file
or a new complete one, never a torn one; they compile the same code under the same names.

A home folder that cannot be written (a service account's ``HOME=/nonexistent``, the
``HOME=/`` Docker gives a uid without a passwd entry) moves the default to the temporary
folder as well. A cache folder the user named that cannot be written (``NUMBA_CACHE_DIR``,
``XDG_CACHE_HOME``), or a temporary one that is not the user's, turns the cache off, with
a warning naming the folder (:func:`njit`): numba would otherwise fall back to
``__pycache__`` beside the source and, in a read-only ``site-packages``, refuse to compile.
"""

from __future__ import annotations

import functools
import hashlib
import os
import stat
import sys
import tempfile
import warnings
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any, TypeVar

NO_JIT_VARIABLE = "AUV_COSIM_NO_JIT"
# The files the compiled functions' code comes from (paths under the folder that holds
# plant_fmu and controller_fmu): a compiled function holds the code of every jitted
# function it calls and the value of every constant it reads, so its cache is stale once
# any of them changes, not only its own file.
KERNEL_FILES = (
    "plant_fmu/model/compiled.py",
    "plant_fmu/model/state_layout.py",
    "controller_fmu/compiled_backstepping.py",
    "controller_fmu/compiled_autopilot.py",
    "controller_fmu/setpoint_shaping.py",
)
# file names whose functions use the content-keyed cache
_CACHED_MODULES = tuple(os.path.basename(path) for path in KERNEL_FILES)
_F = TypeVar("_F", bound=Callable[..., Any])
WARNED_VARIABLE = "AUV_COSIM_NUMBA_CACHE_WARNED"  # the cache folder already warned of
# in the temporary folder, with the uid: numba's cache where there is no home folder
TEMPORARY_CACHE_PREFIX = "auv-cosim-cache-"
_BROKEN = "numba is installed but cannot be imported"  # how load_numba's reason says so
FEATURES_VARIABLE = "NUMBA_CPU_FEATURES"
# numba variables auv-cosim sets itself (not the user's doing, so never named as a cause)
_OURS = ("NUMBA_CACHE_DIR",)


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/auv-cosim/numba`` (if absolute: the XDG base directory
    specification has a relative one ignored), or ``~/.cache/auv-cosim/numba``; where there
    is no home folder (HOME unset and a uid /etc/passwd does not list, as ``docker run -u
    12345`` gives), HOME is relative (ignored as a relative XDG_CACHE_HOME is) or the
    latter cannot be made and written (HOME=/, a service account's HOME=/nonexistent),
    ``$TMPDIR/auv-cosim-cache-<uid>/numba`` (:func:`_foreign_folder`)."""
    base = os.environ.get("XDG_CACHE_HOME", "")
    if os.path.isabs(base):  # relative: the specification says to ignore it (not the cwd's)
        return Path(base) / "auv-cosim" / "numba"
    # "~" itself where there is none (Path.home() raises); HOME as it is, relative too:
    # a relative one is ignored as a relative XDG_CACHE_HOME is (not a cache per cwd)
    home = os.path.expanduser("~")
    if os.path.isabs(home):
        folder = Path(home) / ".cache" / "auv-cosim" / "numba"
        try:
            folder.mkdir(parents=True, exist_ok=True)
        except OSError:
            pass
        else:
            if os.access(folder, os.W_OK | os.X_OK):
                return folder
    uid = os.getuid() if hasattr(os, "getuid") else ""
    return Path(tempfile.gettempdir()) / f"{TEMPORARY_CACHE_PREFIX}{uid}" / "numba"


def load_numba() -> tuple[ModuleType | None, str]:
    """(the numba module, "") when the compiled paths may be used, else (None, why not)."""
    if os.environ.get(NO_JIT_VARIABLE, "").strip() not in ("", "0"):
        return None, f"{NO_JIT_VARIABLE}={os.environ[NO_JIT_VARIABLE]} turns the compiled path off"
    unsigned = _unsigned_cpu_features(os.environ.get(FEATURES_VARIABLE, ""))
    if unsigned:
        return None, (
            f"{FEATURES_VARIABLE}={os.environ[FEATURES_VARIABLE]!r} holds {unsigned!r}, "
            "which LLVM aborts the process on (expected features each starting with + or "
            "-, comma-separated: '+avx2,-fma')"
        )
    os.environ.setdefault("NUMBA_CACHE_DIR", str(default_cache_dir()))
    try:
        import numba
        import numba.core.caching  # what _install_locator extends
    except ImportError as exc:
        if isinstance(exc, ModuleNotFoundError) and exc.name == "numba":
            return None, f"numba cannot be imported ({exc})"
        return None, f"{_BROKEN} ({type(exc).__name__}: {exc})"
    except Exception as exc:  # a broken install is no numba (numba is optional): llvmlite
        # raises OSError when its shared library is missing or needs a newer glibc, a numba
        # built for another numpy can raise AttributeError; the FMU then steps numpy's path.
        # A setting numba refuses as it is imported raises ValueError (NUMBA_NUM_THREADS=0).
        settings = _numba_settings() if isinstance(exc, ValueError) else ""
        return None, f"{_BROKEN} ({type(exc).__name__}: {exc}){settings}"
    _install_locator()
    return numba, ""


def _unsigned_cpu_features(features: str) -> str:
    """The first item of a ``NUMBA_CPU_FEATURES`` value that does not start with + or -
    ("" if none): LLVM asserts on such an item and aborts the process at the first
    compilation (numba passes the text on unchecked), where an FMU's host would die."""
    return next((item for item in features.split(",") if item and item[0] not in "+-"), "")


def _numba_settings() -> str:
    """ ", with NUMBA_X='value' set" naming the user's numba variables (numba reads them as
    it is imported, and refuses some values by raising), or "" where none is set."""
    settings = [
        f"{name}={value!r}"
        for name, value in sorted(os.environ.items())
        if name.startswith("NUMBA_") and name not in _OURS
    ]
    return f", with {', '.join(settings)} set" if settings else ""


def numba_fix(reason: str) -> str:
    """What gives this Python the compiled paths, when :func:`load_numba` said ``reason``."""
    if reason.startswith(NO_JIT_VARIABLE):
        return f"unset {NO_JIT_VARIABLE} for the compiled plant"
    if reason.startswith(FEATURES_VARIABLE):
        return f"correct or unset {FEATURES_VARIABLE} for the compiled plant"
    if not reason.startswith(_BROKEN):
        return "install numba in this Python for the compiled plant"
    import numpy

    python = sys.executable or "python"
    repair = (
        f"repair numba for the compiled plant ({python} -m pip install --force-reinstall "
        f"numba, a release that supports numpy {numpy.__version__})"
    )
    settings = reason.rpartition(", with ")[2]
    if reason.endswith(" set") and settings.startswith("NUMBA_"):
        names = ", ".join(item.partition("=")[0] for item in settings[:-4].split(", "))
        return (
            f"correct or unset {names} (numba reads its variables as it is imported) for the "
            f"compiled plant, else {repair}"
        )
    return repair


def njit(numba: ModuleType, function: _F) -> _F:
    """``numba.njit(cache=True)(function)``; ``numba.njit(function)`` when numba's cache
    folder cannot be written (:func:`cache_problem`): compiled again in every process
    (seconds for the plant and the autopilot), where numba would otherwise raise."""
    compiled: _F = numba.njit(cache=cache_problem() == "")(function)
    return compiled


def cache_problem() -> str:
    """ "" when numba's cache folder (``NUMBA_CACHE_DIR``, which :func:`load_numba` sets)
    can be made and written, else why not; the first time in a process, also a warning."""
    return _folder_problem(os.environ.get("NUMBA_CACHE_DIR", ""))


@functools.cache
def _folder_problem(folder: str) -> str:
    """:func:`cache_problem` of ``folder`` (asked once per folder and process)."""
    try:
        why = _foreign_folder(Path(folder).parent)
        if not why:
            os.makedirs(folder, exist_ok=True)
            tempfile.TemporaryFile(dir=folder).close()
    except OSError as exc:
        why = f"cannot be written ({exc.strerror})"
    if why:
        problem = (
            f"numba's cache folder {folder!r} (NUMBA_CACHE_DIR) {why}: compiling without "
            "a cache, again in every process; set XDG_CACHE_HOME or NUMBA_CACHE_DIR to a "
            "writable folder"
        )
        # Once a process, not once a copy of this module: the master and every FMU import
        # their own copy (an FMU's under its own package name), each with its own cache
        # of this function, and a run printed the warning once per copy. The environment
        # is what the copies share (a process started from this one is not told again).
        if os.environ.get(WARNED_VARIABLE) != folder:
            os.environ[WARNED_VARIABLE] = folder
            warnings.warn(problem, RuntimeWarning, stacklevel=2)
        return problem
    return ""


def _foreign_folder(parent: Path) -> str:
    """ "" unless ``parent`` is the temporary fallback of :func:`default_cache_dir` and not
    this user's: made now (mode 0700) if missing, it must be no symbolic link and belong to
    this uid, since in a shared temporary folder (/tmp) another user could have made it
    and put compiled code there for this user's processes to load (pytest checks its
    pytest-of-<user> folder the same way); else what it is instead."""
    if not parent.name.startswith(TEMPORARY_CACHE_PREFIX) or not hasattr(os, "getuid"):
        return ""
    if parent.parent != Path(tempfile.gettempdir()):
        return ""
    parent.mkdir(mode=0o700, exist_ok=True)
    info = os.lstat(parent)
    if stat.S_ISLNK(info.st_mode) or info.st_uid != os.getuid():
        owner = "a symbolic link" if stat.S_ISLNK(info.st_mode) else f"user {info.st_uid}'s"
        return f"is in {parent}, which is {owner}, not this user's (uid {os.getuid()})"
    if stat.S_IMODE(info.st_mode) & 0o077:
        os.chmod(parent, 0o700)
    return ""


def compiled_entry(function: Callable[..., Any], args: tuple[Any, ...]) -> Callable[..., Any]:
    """The compiled code of the numba function ``function`` for the types of ``args``
    (compiled, or loaded from numba's cache, now), called without numba's dispatch, which
    types every argument at every call (~0.15 us an array); ``function`` itself when
    numba is off (a plain Python function). Only for calls with arguments of exactly
    these types: the caller binds the arrays once (``functools.partial``) and passes
    scalars of the same kinds (a Python int, a float) at each call."""
    compile_for = getattr(function, "compile", None)
    if compile_for is None:
        return function
    typeof = function.typeof_pyval  # type: ignore[attr-defined]
    entry: Callable[..., Any] = compile_for(tuple(typeof(a) for a in args))
    return entry


def _install_locator() -> None:
    """Put :class:`_ContentCacheLocator` first in numba's list of cache locators (once).

    numba has no public hook for this (``NUMBA_CACHE_LOCATOR_CLASSES`` would replace the
    locators of every numba user in the process); the class answers only for our files.
    """
    from numba.core import caching  # imported by load_numba, after NUMBA_CACHE_DIR is set

    # public from numba 0.62; numba 0.60 and 0.61 (pyproject's floor, an FMU host's) have the
    # same class under a private name
    user_folder: Any = getattr(caching, "UserProvidedCacheLocator", None)
    if user_folder is None:
        user_folder = caching._UserProvidedCacheLocator

    class _ContentCacheLocator(user_folder):
        """numba's user-folder locator with the folder named after the function's
        top-level package and the kernels' stamp (``<package>/<stamp[:16]>``): numba's
        own names it after the file's folder, which differs for every unzipped copy of an
        FMU. The stamp is :func:`kernel_stamp` (numba's is a SHA-256 of the function's
        own file), so a change to any kernel file recompiles, into a folder of its own."""

        def __init__(self, py_func: Callable[..., Any], py_file: str) -> None:
            super().__init__(py_func, py_file)
            package = str(py_func.__module__).partition(".")[0]
            # one folder per version of the kernels: numba names data files by their
            # order in the index and checks only the index against the stamp, so two
            # versions compiled at once into one folder could pair one's index with the
            # other's code
            version = kernel_stamp(py_file)[:16]
            self._cache_path = os.path.join(caching.config.CACHE_DIR, "auv_cosim", package, version)

        def get_source_stamp(self) -> str:
            return kernel_stamp(self._py_file)

        @classmethod
        def from_function(
            cls, py_func: Callable[..., Any], py_file: str
        ) -> _ContentCacheLocator | None:
            if os.path.basename(py_file) not in _CACHED_MODULES:
                return None
            located: _ContentCacheLocator | None = super().from_function(py_func, py_file)
            return located

    locators = caching.CacheImpl._locator_classes
    if not any(getattr(c, "__name__", "") == "_ContentCacheLocator" for c in locators):
        locators.insert(0, _ContentCacheLocator)
    _install_unreadable_as_miss(caching)


OUR_FOLDER = os.sep + "auv_cosim" + os.sep  # in the path of each folder our locator names


def _install_unreadable_as_miss(caching: ModuleType) -> None:
    """Make a cache file of ours that cannot be read a miss, compiled and written again
    (once a process: every copy of this module shares numba's class).

    numba writes each file whole (``os.replace``), but a power cut after the rename, a
    full disk or a hand can leave one cut short, and numba reads an index or data file it
    cannot unpickle by raising (``EOFError: Ran out of input``): every later run of the
    plant failed so until the user found the file. numba treats a data file that cannot
    be opened as a miss already (OSError); this extends that to one that cannot be
    unpickled, and an index that cannot be, to an empty one (numba then rewrites it).
    Only for files under our folders (:data:`OUR_FOLDER`): other numba users keep theirs."""
    files: Any = caching.IndexDataCacheFile
    if getattr(files, "_auv_cosim_unreadable_as_miss", False):
        return
    load_index, load_data = files._load_index, files._load_data

    def _load_index(self: Any) -> dict[Any, Any]:
        try:
            index: dict[Any, Any] = load_index(self)
        except OSError:
            raise
        except Exception:  # any unpickling error of a file cut short or overwritten
            if OUR_FOLDER not in self._cache_path:
                raise
            return {}
        return index

    def _load_data(self: Any, name: str) -> Any:
        try:
            return load_data(self, name)
        except OSError:
            raise
        except Exception as exc:  # numba's load() takes OSError for a miss
            if OUR_FOLDER not in self._cache_path:
                raise
            raise OSError(f"numba's cache file {name} cannot be read ({exc!r})") from exc

    files._load_index, files._load_data = _load_index, _load_data
    files._auv_cosim_unreadable_as_miss = True


def kernel_root(py_file: str) -> Path | None:
    """The folder holding ``plant_fmu`` and ``controller_fmu`` above a kernel file (in an
    FMU, the build's package folder), or None."""
    for folder in Path(py_file).resolve().parents:
        if (folder / KERNEL_FILES[0]).is_file():
            return folder
    return None


def kernel_stamp(py_file: str) -> str:
    """numba's cache stamp of a kernel file's functions: a SHA-256 of every file of
    :data:`KERNEL_FILES` beside it."""
    root = kernel_root(py_file)
    files = [root / name for name in KERNEL_FILES] if root is not None else [Path(py_file)]
    return _stamp(tuple((str(f), *_file_key(f)) for f in files))


def _file_key(path: Path) -> tuple[int, int]:
    try:
        stat = path.stat()
    except OSError:
        return (-1, -1)
    return (stat.st_mtime_ns, stat.st_size)


@functools.lru_cache(maxsize=64)
def _stamp(files: tuple[tuple[str, int, int], ...]) -> str:
    """(cached per files' modification times and sizes, as numba caches its own)."""
    digest = hashlib.sha256()
    for name, _, size in files:
        data = Path(name).read_bytes() if size >= 0 else b"(missing)"
        digest.update(f"{os.path.basename(name)}\n".encode())
        digest.update(data)
    return digest.hexdigest()
