"""The pythonfmu entry module of our FMUs, shaped around how pythonfmu 0.7 instantiates.

What ``fmi2Instantiate`` of pythonfmu 0.7's wrapper library does, every time:

1. it inserts the instance's ``resources`` folder at ``sys.path[0]`` (a new entry per
   instance, never removed);
2. it imports the module named in ``resources/slavemodule.txt``: after the first time in a
   process that is the module in ``sys.modules``, from whichever extraction it came;
3. it compiles that module's file again and executes it with the cached module's namespace
   as globals and a fresh dict as locals, takes the name of the ``Fmi2Slave`` subclass
   found in the fresh dict, and constructs the class of that *name* from the cached module;
4. it leaks the MRO list and class reprs of every class in the fresh dict (about 1 KiB),
   and releases a reference to the module namespace it never took (``PyModule_GetDict``
   returns a borrowed reference).

So a slave class defined in the entry module is created anew at each instantiation and
kept alive by the leaked list (47 KiB per instance, before this was fixed), and a namespace whose
functions do not hold extra references is freed after a few instances (a segmentation
fault). The build (:mod:`cosim.fmus.build`) therefore writes a generated entry module,
:func:`entry_source`, that defines nothing: it binds the slave class by import (step 3
re-executes an import of a cached module, which creates nothing) and gives its namespace
back the reference step 4 takes away (:func:`hold_namespace`). :func:`release_search_path`
removes step 1's entry once the instance exists.

Because the modules outlive the extraction they were imported from, which a host may
delete after freeing the instance, the entry also imports every module of the packages
the FMU ships at once (:func:`import_packages`): a second FMU sharing a package (the
autopilot ships ``plant_fmu`` too) then finds every module it needs already imported,
instead of looking for one in a deleted folder.
"""

from __future__ import annotations

import ctypes
import importlib
import pkgutil
import sys
from collections.abc import Iterable
from pathlib import Path
from types import ModuleType
from typing import Any

_ENTRY = '''"""pythonfmu entry module of {fmu}.fmu, written by the build.

It defines nothing: it imports the shipped packages whole and binds the slave class by
import (see fmu_runtime/entry.py).
"""

from fmu_runtime.entry import hold_namespace, import_packages

hold_namespace(globals())
import_packages({packages!r})

from {module} import {cls}  # noqa: E402
'''

# Process-wide by nature, like sys.modules: package name -> the package object whose
# modules import_packages has imported.
_imported: dict[str, ModuleType] = {}


def entry_source(fmu: str, module: str, cls: str, packages: Iterable[str]) -> str:
    """The text of the entry module of FMU ``fmu`` whose slave class is ``module.cls`` and
    which ships ``packages``."""
    return _ENTRY.format(fmu=fmu, module=module, cls=cls, packages=tuple(packages))


def hold_namespace(namespace: dict[str, Any]) -> None:
    """Take one more reference to an entry module's namespace (run by every execution of
    the entry module, so it balances the reference pythonfmu releases after each one).

    ``ctypes.pythonapi`` because no Python-level operation adds a reference without
    storing one; every host that runs our FMUs has the Python C API in its global symbol
    namespace (compiled extensions such as numpy's need it too).
    """
    ctypes.pythonapi.Py_IncRef(ctypes.py_object(namespace))


def import_packages(names: Iterable[str]) -> None:
    """Import every module of the packages ``names`` (once per package object), while the
    folder they are imported from exists."""
    for name in names:
        package = importlib.import_module(name)
        if _imported.get(name) is package:
            continue
        for info in pkgutil.walk_packages(package.__path__, prefix=f"{name}."):
            importlib.import_module(info.name)
        _imported[name] = package


def release_search_path(resources: str | Path) -> bool:
    """Remove the ``sys.path[0]`` entry pythonfmu inserted for an instance whose
    ``resources`` folder is given; True if it was there.

    Safe once the instance exists: its packages are imported, and their submodules are
    found through each package's ``__path__``, not ``sys.path``. Only for an FMU's
    extraction: pythonfmu's builder removes its own entry itself.
    """
    if sys.path and sys.path[0] == str(resources):
        del sys.path[0]
        return True
    return False
