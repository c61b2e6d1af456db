"""Numba for the compiled fast paths: whether it may be used, and where its cache lives.

The compiled paths (:mod:`plant_fmu.model.compiled`) use ``numba.njit(cache=True)`` without
fastmath, so a compiled function does the same IEEE operations on every run. This module
decides once per process whether numba is usable:

* ``AUV_COSIM_NO_JIT=1`` in the environment turns it off (the reference numpy path runs);
* an ``ImportError`` of numba turns it off too; callers log that as a warning.

Cache folder: numba's default is ``__pycache__`` next to the source, which for an FMU is
the fresh temporary folder the importer unzips it into, so every run would compile again
(several seconds). We therefore set ``NUMBA_CACHE_DIR`` to a per-user folder,
``$XDG_CACHE_HOME/auv-cosim/numba`` (``~/.cache/auv-cosim/numba``), unless the user has set
it, before numba is imported; and we key the cache of our own modules by file name and
content, not by the folder they were loaded from (numba keys it by folder: see
:class:`_ContentCacheLocator`), so every unzipped copy of the same FMU shares one cache.
Concurrent processes (sweeps start many at once) can share the folder: numba writes each
cache file to a unique temporary name and moves it into place with ``os.replace``, which
is atomic, so a reader sees an old complete file or a new complete one, never a torn one.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

NO_JIT_VARIABLE = "AUV_COSIM_NO_JIT"
# file names whose functions use the content-keyed cache (plant_fmu/model/compiled.py,
# controller_fmu/compiled_backstepping.py)
_CACHED_MODULES = ("compiled.py", "compiled_backstepping.py")


def default_cache_dir() -> Path:
    """``$XDG_CACHE_HOME/auv-cosim/numba``, or ``~/.cache/auv-cosim/numba``."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "auv-cosim" / "numba"


def load_numba() -> tuple[ModuleType | None, str]:
    """(the numba module, "") when the compiled paths may be used, else (None, why not)."""
    if os.environ.get(NO_JIT_VARIABLE, "").strip() not in ("", "0"):
        return None, f"{NO_JIT_VARIABLE}={os.environ[NO_JIT_VARIABLE]} turns the compiled path off"
    os.environ.setdefault("NUMBA_CACHE_DIR", str(default_cache_dir()))
    try:
        import numba
        import numba.core.caching  # what _install_locator extends
    except ImportError as exc:
        return None, f"numba cannot be imported ({exc})"
    _install_locator()
    return numba, ""


def _install_locator() -> None:
    """Put :class:`_ContentCacheLocator` first in numba's list of cache locators (once).

    numba has no public hook for this (``NUMBA_CACHE_LOCATOR_CLASSES`` would replace the
    locators of every numba user in the process); the class answers only for our files.
    """
    from numba.core import caching  # imported by load_numba, after NUMBA_CACHE_DIR is set

    class _ContentCacheLocator(caching.UserProvidedCacheLocator):
        """numba's user-folder locator with the folder named after the source file only:
        numba's own names it after the file's folder, which differs for every unzipped
        copy of an FMU. The stamp stays numba's (a SHA-256 of the file's content), so a
        changed file recompiles."""

        def __init__(self, py_func: Callable[..., Any], py_file: str) -> None:
            super().__init__(py_func, py_file)
            self._cache_path = os.path.join(caching.config.CACHE_DIR, "auv_cosim")

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
