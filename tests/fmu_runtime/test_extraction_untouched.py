"""An FMU leaves the folder a host extracted it into as it found it, and runs from it when
the folder is read-only (a host that unpacks FMUs into a shared read-only place, another
user running them):

* each FMU on its runtime, run by fmpy from an extraction without the shipped
  ``__pycache__`` folders (what a host whose Python is another minor version than the
  build's sees: the shipped ``.pyc`` files are for the build's cache tag only, so that
  Python compiles the modules itself), writes no file into it (pythonfmu's binary, the
  fallback, still lets that Python write its ``.pyc`` files: docs/hosts.md);
* the plant runs from an extraction that cannot be written, even by root
  (``tests/read_only.py``).

Each run is a fresh process, since an FMU's modules stay imported for its life.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from process_group import run_in_group
from read_only import read_only_prefix, writable_again

SIMULATE = """
import sys
from fmpy import simulate_fmu
result = simulate_fmu(sys.argv[1], stop_time=0.2, step_size=0.01, output_interval=0.01)
print(len(result), "rows")
"""


def _extract(fmu: Path, folder: Path) -> Path:
    with zipfile.ZipFile(fmu) as archive:
        archive.extractall(folder)
    return folder


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob("*")}


def _simulate(prefix: list[str], folder: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    command = [*prefix, sys.executable, "-c", SIMULATE, str(folder)]
    return run_in_group(command, timeout=300, env=env)


def _env(runtime: str) -> dict[str, str]:
    # PYTHONDONTWRITEBYTECODE (set where this suite runs, perhaps) is no host's default
    unset = ("AUV_FMU_RUNTIME", "PYTHONDONTWRITEBYTECODE")
    env = {k: v for k, v in os.environ.items() if k not in unset}
    if runtime:
        env["AUV_FMU_RUNTIME"] = runtime
    return env


@pytest.mark.slow
@pytest.mark.parametrize("name", ["AuvPlant", "AuvAutopilot"])
def test_a_python_without_shipped_bytecode_writes_nothing_into_the_extraction(
    name, fmu_paths, tmp_path
):
    """A host's Python of another minor version used to compile the FMU's modules and
    write their ``.pyc`` files into ``resources/.../__pycache__`` of the extraction."""
    folder = _extract(fmu_paths[name], tmp_path / name)
    for cache in sorted(folder.rglob("__pycache__"), reverse=True):
        shutil.rmtree(cache)
    before = _tree(folder)
    done = _simulate([], folder, _env(""))
    assert done.returncode == 0, done.stderr[-3000:]
    assert "21 rows" in done.stdout
    assert sorted(_tree(folder) - before) == []


@pytest.mark.slow
@pytest.mark.parametrize("runtime", ["", "pythonfmu"])
def test_the_plant_runs_from_an_extraction_it_cannot_write(runtime, fmu_paths, tmp_path):
    """The plant from a read-only extraction (its shipped ``.pyc`` files removed too, so
    the host's Python would write them if it could): it runs, with no error logged."""
    folder = _extract(fmu_paths["AuvPlant"], tmp_path / "AuvPlant")
    for cache in sorted(folder.rglob("__pycache__"), reverse=True):
        shutil.rmtree(cache)
    before = _tree(folder)
    try:
        done = _simulate(read_only_prefix(folder), folder, _env(runtime))
    finally:
        writable_again(folder)
    assert done.returncode == 0, done.stderr[-3000:]
    assert "21 rows" in done.stdout
    assert "Error" not in done.stderr, done.stderr[-3000:]
    assert sorted(_tree(folder) - before) == []
