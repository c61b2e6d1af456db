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

Our FMUs' native loader (``fmu_runtime/native/runtime.c``) registers the same handler
in C right after it loads pythonfmu's library (renamed ``<model>_pythonfmu.so`` beside
it); this module then finds two libraries and stands aside. It still guards an FMU whose
binary is pythonfmu's alone (built where no C compiler was found) and any other pythonfmu
FMU ``auv-cosim run`` loads.

The fix, done from the FMU side so that every host benefits (fmpy, our master,
libcosimpy, ecospy, the ecos and cosim command-line programs): once per loaded wrapper
library, register ``finalizePythonInterpreter`` itself as a C exit handler with
``__cxa_atexit``. Exit handlers run last-registered first, and ours is registered after
the library's static was constructed (at load time), so ours runs first, while the
static is alive: it releases the guard properly (in a host where pythonfmu started
Python, that is where ``Py_Finalize`` runs, on pythonfmu's own thread, as designed) and
leaves the pointer empty, so the two later resets find nothing to release. With
instances still alive at exit the call only drops the static's reference; they hold
their own. A C exit handler rather than Python's ``atexit``: a non-Python host may never
finalise Python, so a Python handler would never run there.

``ctypes`` is used because nothing else can reach a symbol of the already-loaded wrapper
library; ``dlopen`` of the same path returns the loaded copy, and the library stays
mapped until the process ends (RTLD_NODELETE, above), so the handler's address stays
valid. ``__cxa_atexit`` passes one ``void*`` argument, which the ``void(void)`` function
ignores (x86-64 and AArch64 calling conventions).
"""

from __future__ import annotations

import ctypes
import sys
from pathlib import Path

SYMBOL = "finalizePythonInterpreter"

# Process-wide by nature: one exit hook per loaded wrapper library, whatever the number
# of instances (each instantiate would otherwise add a handler).
_guarded: set[Path] = set()
_guarded_resources: set[str] = set()  # resources folders whose library is in _guarded


def wrapper_library(resources: str | Path) -> Path | None:
    """The pythonfmu wrapper library of the FMU whose ``resources/`` folder is given, or
    None if there is not exactly one Linux binary beside it."""
    candidates = sorted((Path(resources).parent / "binaries" / "linux64").glob("*.so"))
    return candidates[0] if len(candidates) == 1 else None


def install(resources: str | Path | None) -> bool:
    """Register the exit hook for the FMU extracted around ``resources``.

    Returns True if a hook is (now or already) registered; False where it does not apply
    (no resources, as when pythonfmu's builder constructs the class; not Linux: on
    Windows ``DllMain`` runs before the static destructors; no wrapper library; a
    pythonfmu without the symbol).
    Never raises: it is called from an FMU's constructor.
    """
    try:
        if resources is None or not sys.platform.startswith("linux"):
            return False
        if str(resources) in _guarded_resources:  # every instance of every run asks
            return True
        library = wrapper_library(resources)
        if library is None:
            return False
        library = library.resolve()
        if library in _guarded:
            _guarded_resources.add(str(resources))
            return True
        finalize = getattr(ctypes.CDLL(str(library)), SYMBOL, None)
        if finalize is None:
            return False
        libc = ctypes.CDLL(None)
        libc.__cxa_atexit.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        if libc.__cxa_atexit(ctypes.cast(finalize, ctypes.c_void_p), None, None) != 0:
            return False
        _guarded.add(library)
        _guarded_resources.add(str(resources))
        return True
    except Exception:  # an FMU constructor must not raise (see safe_slave.py)
        return False
