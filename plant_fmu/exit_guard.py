"""Work around pythonfmu 0.7's use-after-free at process exit (Linux only).

The bug, in pythonfmu's C++ wrapper ``libpythonfmu-export.so`` (shipped in every FMU as
``binaries/linux64/<model>.so``): the guard object that owns the embedded interpreter
lives in a static ``std::shared_ptr``, and an ``__attribute__((destructor))`` function,
``finalizePythonInterpreter``, resets that pointer. The library can never be unloaded
(its ``std::regex`` code carries STB_GNU_UNIQUE symbols, which make it RTLD_NODELETE, so
fmpy's ``dlclose`` after ``fmi2FreeInstance`` is a no-op), so both run at process exit, in
the wrong order: ``exit()`` first runs the static's destructor, which frees the guard
once no instance holds it, then ``_dl_fini`` calls ``finalizePythonInterpreter``, which
decrements a reference count inside the freed block. Valgrind reports the invalid read
in every process that instantiated and freed one of our FMUs; when the freed chunk sits
in one of glibc's doubly linked bins, the decrement corrupts the list and the host aborts
with "corrupted double-linked list" (it happened once in CI, in the validation smoke run).

The fix, done from the FMU side so that every Python host benefits (fmpy, our master,
libcosimpy, ecospy): a Python ``atexit`` handler, which runs inside ``Py_FinalizeEx`` and
so before any C exit handler, calls ``finalizePythonInterpreter`` itself while the static
is still alive. That releases the guard properly and leaves the pointer empty, so the two
later resets find nothing to release. Calling it again, or with instances still alive,
is harmless: they hold their own references to the guard.

It is installed only where the host started Python itself (``sys.orig_argv`` is not
empty). Where pythonfmu started the interpreter (a C or C++ host with libpython
preloaded), ``Py_Finalize`` runs from inside the guard's destructor and the handler must
not re-enter it. ``ctypes`` is used because nothing else can reach a symbol of the
already-loaded wrapper library; ``dlopen`` of the same path returns the loaded copy.
"""

from __future__ import annotations

import atexit
import ctypes
import sys
from pathlib import Path

SYMBOL = "finalizePythonInterpreter"

# Process-wide by nature: one exit hook per loaded wrapper library, whatever the number
# of instances (each instantiate would otherwise add a handler).
_guarded: set[Path] = set()


def wrapper_library(resources: str | Path) -> Path | None:
    """The pythonfmu wrapper library of the FMU whose ``resources/`` folder is given, or
    None if there is not exactly one Linux binary beside it."""
    candidates = sorted((Path(resources).parent / "binaries" / "linux64").glob("*.so"))
    return candidates[0] if len(candidates) == 1 else None


def install(resources: str | Path | None) -> bool:
    """Register the exit hook for the FMU extracted around ``resources``.

    Returns True if a hook is (now or already) registered; False where it does not apply
    (no resources, as when pythonfmu's builder constructs the class; not Linux; an
    interpreter started by pythonfmu; no wrapper library; a pythonfmu without the symbol).
    Never raises: it is called from an FMU's constructor.
    """
    try:
        if resources is None or not sys.platform.startswith("linux") or not sys.orig_argv:
            return False
        library = wrapper_library(resources)
        if library is None:
            return False
        library = library.resolve()
        if library in _guarded:
            return True
        finalize = getattr(ctypes.CDLL(str(library)), SYMBOL, None)
        if finalize is None:
            return False
        finalize.restype = None
        finalize.argtypes = []
        atexit.register(finalize)
        _guarded.add(library)
        return True
    except Exception:  # an FMU constructor must not raise (see safe_slave.py)
        return False
