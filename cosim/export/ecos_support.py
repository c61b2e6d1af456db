"""ecos (``ecospy``) from a pip install alone: Intel TBB from the ``tbb`` package.

ecospy's native library and its ``ecos`` program link ``libtbb.so.12``. Debian ships it as
``libtbb12``; the ``tbb`` package on the package index (in our ``test`` extra) installs the
same library into the environment's ``lib/`` folder, where the dynamic loader does not
look. Loading it first, by path, satisfies the dependency: the loader matches an already
loaded library by its SONAME. ``ctypes`` because no library loads a shared object by path
into the process's global scope otherwise.

* :func:`preload_tbb` before ``import ecospy`` in Python;
* :func:`tbb_library` for a command line (``LD_PRELOAD`` it, or put its folder on
  ``LD_LIBRARY_PATH``, before running ``ecos``).
"""

from __future__ import annotations

import ctypes
from importlib import metadata
from pathlib import Path

LIBRARY = "libtbb.so.12"


def tbb_library() -> Path | None:
    """The ``libtbb.so.12`` the ``tbb`` package installed, or None (not installed, or a
    platform whose wheel has no such file)."""
    try:
        files = metadata.files("tbb") or []
    except metadata.PackageNotFoundError:
        return None
    for file in files:
        if file.name == LIBRARY:
            path = Path(file.locate()).resolve()
            return path if path.is_file() else None
    return None


def preload_tbb() -> Path | None:
    """Load :func:`tbb_library` into this process (global scope) so that ecospy finds it;
    returns its path, or None where there is none (ecos then needs the system's TBB).

    Raises:
        OSError: the library exists but cannot be loaded (the message says why).
    """
    path = tbb_library()
    if path is not None:
        ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)
    return path
