"""Imported last by the workers' fork server (:mod:`cosim.study.fork_server`): the Python
code of the FMUs the command names, imported once for every worker it forks.

Each FMU of one build ships one package (``auvfmu_<hash>``: :mod:`fmu_runtime.entry`), which
the FMU's runtime imports from the FMU's own ``resources/`` at its first instance in a
process unless that package is imported already (``fmu_runtime/native/python.c``). Each
worker imported it in its warm-up. Here the server imports it, once, from its own
extraction of each ``*.fmu`` in the folder named by ``AUV_COSIM_FORK_FMU_DIR`` (the
command's ``--fmu-dir``, set for the server only by
:func:`cosim.study.fork_server.start`); each worker then finds it imported and only loads
the FMUs' libraries, their compiled kernels and their instances. The folder is kept while
the server lives (numba's cache of the kernels is keyed by the files beside them:
:mod:`plant_fmu.model.jit`) and removed when it exits. An FMU whose package is not among
these (another build, a study of other FMUs) is loaded by the worker as before. Never
raises: the server would end, and the workers would start their own way.
"""

from __future__ import annotations

import atexit
import gc
import importlib.machinery
import importlib.util
import os
import shutil
import sys
import tempfile
import zipfile
from pathlib import Path

from cosim.study.fork_server import FMU_DIR_VARIABLE

RECORD = "resources/fmu_runtime.txt"  # package=<name>, among others (by the build)


def package_of(fmu: Path) -> str | None:
    """The build package an FMU's runtime imports (None: not one of ours)."""
    with zipfile.ZipFile(fmu) as archive:
        if RECORD not in archive.namelist():
            return None
        lines = archive.read(RECORD).decode("utf-8").splitlines()
    fields = dict(line.split("=", 1) for line in lines if "=" in line)
    return fields.get("package") or None


def import_package(fmu: Path, package: str, folder: Path) -> None:
    """Extract ``resources/<package>/`` of ``fmu`` into ``folder`` and import the package
    from there, as the FMU's runtime does (its ``__init__`` imports every module)."""
    with zipfile.ZipFile(fmu) as archive:
        members = [n for n in archive.namelist() if n.startswith(f"resources/{package}/")]
        archive.extractall(folder, members)
    spec = importlib.machinery.PathFinder.find_spec(package, [str(folder / "resources")])
    if spec is None or spec.loader is None:
        raise ImportError(f"no package {package} in {fmu}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[package] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        for name in [n for n in sys.modules if n == package or n.startswith(f"{package}.")]:
            del sys.modules[name]
        raise


def preload(fmu_dir: Path) -> list[str]:
    """Import the package of every FMU in ``fmu_dir`` (once each) into a folder removed at
    this process's exit; the packages imported."""
    done: list[str] = []
    folder: Path | None = None
    for fmu in sorted(fmu_dir.glob("*.fmu")):
        try:
            package = package_of(fmu)
            if package is None or package in sys.modules:
                continue
            if folder is None:
                folder = Path(tempfile.mkdtemp(prefix="auv-cosim-fork-fmus-"))
                _remove_at_exit(folder)
            import_package(fmu, package, folder / package)
            done.append(package)
        except Exception:  # an optimisation: the worker imports it itself
            continue
    return done


def _remove_at_exit(folder: Path) -> None:
    """Remove ``folder`` when this process exits (not a process forked from it: they end
    with ``os._exit``, and its owner check stays)."""
    owner = os.getpid()

    def remove() -> None:
        if os.getpid() == owner:
            shutil.rmtree(folder, ignore_errors=True)

    atexit.register(remove)


_named = os.environ.get(FMU_DIR_VARIABLE)
if _named and os.path.isdir(_named):
    preload(Path(_named))
    gc.freeze()  # as cosim.study.preload does: out of the collector's reach in each worker
