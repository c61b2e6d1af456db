"""How an FMU's Python code is laid out and entered: its build package and pythonfmu's entry.

The build (:mod:`cosim.fmus.build`) puts the FMU's packages (``plant_fmu``,
``controller_fmu``, ``fmu_runtime`` and pythonfmu's own) under one top-level package named
after their content, ``auvfmu_<hash>``, with their imports renamed to it. The FMU's runtime
imports that package from the FMU's own ``resources/`` and constructs the slave class
itself (``fmu_runtime/native/slave.c``): two builds in one process never share a module,
and two extractions of one build share the same code. The package's ``__init__``
(:func:`package_init_source`) imports every module of the shipped packages at once
(:func:`import_packages`), while the folder they come from exists: modules outlive the
extraction they were imported from, which a host may delete after freeing the instance,
and a later instance of the same build then finds every module it needs already imported.

pythonfmu's own binary, kept in the FMU as the fallback (``AUV_FMU_RUNTIME=pythonfmu``),
needs a top-level entry module named in ``resources/slavemodule.txt``; the build writes
one, named after the build package too (:func:`entry_source`). What pythonfmu 0.7's
``fmi2Instantiate`` does with it, every time:

1. it inserts the instance's ``resources`` folder at ``sys.path[0]`` (a new entry per
   instance, never removed: :func:`release_search_path` removes it once the instance
   exists);
2. it imports the entry module (after the first time in a process, the one in
   ``sys.modules``);
3. it compiles that module's file again and executes it with the cached module's namespace
   as globals and a fresh dict as locals, takes the name of the ``Fmi2Slave`` subclass
   found in the fresh dict, and constructs the class of that *name* from the cached module;
4. it leaks the MRO list and class reprs of every class in the fresh dict (about 1 KiB),
   and releases a reference to the module namespace it never took (``PyModule_GetDict``
   returns a borrowed reference).

So the entry defines nothing (step 3 re-executes an import of a cached module, which
creates no class) and gives its namespace back the reference step 4 takes away
(:func:`hold_namespace`); without that, a few instances in, the namespace is freed under
its module (a segmentation fault).
"""

from __future__ import annotations

import ctypes
import importlib
import pkgutil
import sys
import threading
import warnings
from collections.abc import Iterable
from contextlib import AbstractContextManager
from pathlib import Path
from types import ModuleType
from typing import Any, cast

from .log_text import without_traceback

_PACKAGE_INIT = '''"""The Python code of {fmu}.fmu and its siblings of one build (by the build).

{packages}, with their imports renamed under this package, whose name is taken from their
content: another build never shares a module with this one in a process.
"""

from .fmu_runtime.entry import import_packages

import_packages(__name__, {names!r})
'''

_ENTRY = '''"""pythonfmu entry module of {fmu}.fmu, written by the build.

pythonfmu's own binary (AUV_FMU_RUNTIME=pythonfmu) imports it; it defines nothing, it binds
the slave class by import (see fmu_runtime/entry.py). The FMU's runtime does not use it.
"""

from {package}.fmu_runtime.entry import hold_namespace

hold_namespace(globals())

from {module} import {cls}  # noqa: E402
'''

# resources/<this>, written by the build for the FMU's runtime (fmu_runtime/native/loader.h)
RECORD_FILE = "fmu_runtime.txt"

# Process-wide by nature, like sys.modules: package name -> the package object whose
# modules import_packages has imported.
_imported: dict[str, ModuleType] = {}
_import_warnings: list[str] = []  # what the imports warned of, until an instance logs it


def package_init_source(fmu: str, names: Iterable[str], shipped: Iterable[str]) -> str:
    """The ``__init__.py`` of a build package shipping the packages ``shipped``, whose
    ``names`` are imported whole at once."""
    packages = ", ".join(f"``{name}``" for name in shipped)
    return _PACKAGE_INIT.format(fmu=fmu, packages=packages, names=tuple(names))


def entry_source(fmu: str, package: str, module: str, cls: str) -> str:
    """The text of pythonfmu's entry module of FMU ``fmu`` whose slave class is
    ``module.cls`` (``module`` inside the build package ``package``)."""
    return _ENTRY.format(fmu=fmu, package=package, module=module, cls=cls)


def hold_namespace(namespace: dict[str, Any]) -> None:
    """Take one more reference to an entry module's namespace (run by every execution of
    the entry module, so it balances the reference pythonfmu releases after each one).

    ``ctypes.pythonapi`` because no Python-level operation adds a reference without
    storing one; every host that runs our FMUs has the Python C API in its global symbol
    namespace (compiled extensions such as numpy's need it too).
    """
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


def import_packages(package: str, names: Iterable[str]) -> None:
    """Import every module of the subpackages ``names`` of ``package`` (once per package
    object), while the folder they are imported from exists. A warning the imports raise
    (numba's cache folder that cannot be written) is kept for the next instance to log
    (:func:`take_import_warnings`): raised as a Python warning, it reached the host's
    stderr, with a source line under it, where a host that is not Python never looks.
    A host's filter that makes warnings errors (``-W error``) is for its own code: here
    it keeps the warning too, where it failed the import and so fmi2Instantiate. Builds
    imported from several threads take turns (:func:`_warnings_lock`); a warning another
    thread of the host raises meanwhile is kept with them (the warnings module's state is
    process-wide in Python before 3.14). Each is kept as one line, a traceback it holds
    cut to its exception (:func:`~fmu_runtime.log_text.without_traceback`)."""
    with _warnings_lock(), warnings.catch_warnings(record=True) as said:
        rules = cast("list[Any]", warnings.filters)  # a list (typeshed: a Sequence)
        rules[:] = [("default", *rule[1:]) if rule[0] == "error" else rule for rule in rules]
        for name in names:
            full = f"{package}.{name}"
            module = importlib.import_module(full)
            if _imported.get(full) is module:
                continue
            for info in pkgutil.walk_packages(module.__path__, prefix=f"{full}."):
                importlib.import_module(info.name)
            _imported[full] = module
    _import_warnings.extend(without_traceback(str(warning.message)) for warning in said)


def _warnings_lock() -> AbstractContextManager[Any]:
    """The lock every build package's imports hold while they keep warnings: one per
    process, not one per copy of this module (each build package has its own).
    catch_warnings swaps process-wide functions and puts back what it found at its start:
    two builds imported from two threads at once, the later to end put the earlier's
    recorder back, and warnings went to a list no one read or to the host's stderr.
    (No deadlock: a build's imports never wait for another build's package.)"""
    # setdefault on a module's dict is one step under the GIL: one lock, whoever is first
    lock = vars(warnings).setdefault("_auv_cosim_import_lock", threading.RLock())
    return cast("AbstractContextManager[Any]", lock)


def take_import_warnings() -> list[str]:
    """The warnings :func:`import_packages` kept, once (the next instance logs them)."""
    taken = list(dict.fromkeys(_import_warnings))
    _import_warnings.clear()
    return taken


def release_search_path(resources: str | Path) -> bool:
    """Remove the ``sys.path[0]`` entry pythonfmu inserted for an instance whose
    ``resources`` folder is given; True if it was there.

    Safe once the instance exists: its packages are imported, and their submodules are
    found through each package's ``__path__``, not ``sys.path``. Only for an FMU's
    extraction (it holds :data:`RECORD_FILE`): pythonfmu's builder removes its own entry
    itself.
    """
    if sys.path and sys.path[0] == str(resources) and Path(resources, RECORD_FILE).is_file():
        del sys.path[0]
        return True
    return False
