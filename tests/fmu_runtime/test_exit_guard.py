"""pythonfmu 0.7's use-after-free at process exit, and our guards against it: the native
loader's (``fmu_runtime/native/runtime.c``) in front of the wrapper, and
``fmu_runtime/exit_guard.py`` for an FMU whose binary is pythonfmu's alone (built without
a C compiler; :func:`pythonfmu_binary_only` makes one from a built FMU).

The bug aborted one CI run ("corrupted double-linked list") but shows as a crash only
when glibc's heap happens to be in the wrong state, so the regression test asks valgrind
instead: it reports the invalid access inside the FMU's wrapper library deterministically.
A control run with the guard switched off shows that the test detects the bug.
"""

from __future__ import annotations

import re
import shutil
import zipfile
from pathlib import Path

import pytest

from fmu_runtime import exit_guard

LOAD_AND_FREE = """
import importlib, sys
from pathlib import Path
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave


def guard_of(folder):
    \"\"\"The exit_guard module of the FMU's own build package (imported if need be).\"\"\"
    resources = Path(folder) / "resources"
    lines = (resources / "fmu_runtime.txt").read_text().split()
    record = dict(line.split("=", 1) for line in lines)
    sys.path.insert(0, str(resources))
    try:
        return importlib.import_module(record["package"] + ".fmu_runtime.exit_guard")
    finally:
        sys.path.remove(str(resources))


guards = []
for path in sys.argv[2:]:
    md = read_model_description(path)
    folder = extract(path)
    guards.append(guard_of(folder))
    if sys.argv[1] == "unguarded":
        guards[-1].install = lambda resources: False
    slave = FMU2Slave(guid=md.guid, unzipDirectory=folder,
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="x")
    slave.instantiate(loggingOn=True)
    slave.freeInstance()
print(sorted({p.name for guard in guards for p in guard._guarded}))
"""


def pythonfmu_binary_only(fmu: Path, folder: Path) -> Path:
    """A copy of ``fmu`` in ``folder`` whose linux64 binary is pythonfmu's library alone,
    as a build without a C compiler makes it."""
    copy = folder / fmu.name
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(copy, "w") as target:
        for info in source.infolist():
            name = info.filename
            if name == f"binaries/linux64/{fmu.stem}.so":
                continue  # the native loader
            data = source.read(info)
            info.filename = name.replace("_pythonfmu.so", ".so")
            target.writestr(info, data)
    return copy


@pytest.fixture(scope="module")
def binary_only(fmu_paths, tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("pythonfmu_binary")
    return {name: pythonfmu_binary_only(fmu_paths[name], folder) for name in FMU_NAMES}


FMU_NAMES = ("AuvPlant", "AuvAutopilot")


@pytest.mark.slow
def test_every_fmu_installs_the_guard_without_the_loader(binary_only, run_python):
    done = run_python(LOAD_AND_FREE, "guarded", *binary_only.values())
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "['AuvAutopilot.so', 'AuvPlant.so']"


def test_behind_the_loader_the_python_guard_stands_aside(fmu_paths, run_python):
    """Two libraries beside each other: the Python guard finds no single wrapper, as the
    loader has registered the same exit handler itself."""
    done = run_python(LOAD_AND_FREE, "guarded", *(fmu_paths[n] for n in FMU_NAMES))
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip().splitlines()[-1] == "[]"


def test_install_does_not_apply_without_a_wrapper_library(tmp_path: Path):
    assert exit_guard.install(None) is False  # pythonfmu's builder constructs the class so
    assert exit_guard.install(tmp_path / "resources") is False
    (tmp_path / "binaries" / "linux64").mkdir(parents=True)
    assert exit_guard.wrapper_library(tmp_path / "resources") is None
    library = tmp_path / "binaries" / "linux64" / "Model.so"
    library.write_bytes(b"not a library")
    assert exit_guard.wrapper_library(tmp_path / "resources") == library
    assert exit_guard.install(tmp_path / "resources") is False  # dlopen fails: no raise


def _invalid_accesses_in_fmu_binary(log: str) -> list[str]:
    """valgrind error records (Invalid read/write/free) whose stack is in an FMU binary."""
    records = re.split(r"==\d+== \n", log)
    return [
        r
        for r in records
        if re.search(r"Invalid (read|write|free)", r) and "binaries/linux64/" in r
    ]


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
@pytest.mark.parametrize("mode", ["loader", "guarded", "unguarded"])
def test_no_use_after_free_at_exit(mode, fmu_paths, binary_only, run_python, tmp_path: Path):
    """valgrind memcheck over a process that instantiates and frees the plant FMU: behind
    the native loader, and with pythonfmu's binary alone with the Python guard (the guard
    sits in the base class both FMUs share, and the test above shows both install it), no
    invalid access in an FMU binary; without any guard, the read of freed memory in
    ``finalizePythonInterpreter`` that once crashed CI."""
    log = tmp_path / "valgrind.log"
    code = (
        "import os, subprocess, sys\n"
        # the plant's numpy path (no numba to import under memcheck): the exit is the same
        "env = {**os.environ, 'PYTHONMALLOC': 'malloc', 'AUV_COSIM_NO_JIT': '1'}\n"
        f"sys.exit(subprocess.call(['valgrind', '--log-file={log}', sys.executable, '-c',"
        " sys.argv[1], *sys.argv[2:]], env=env))\n"
    )
    fmu = fmu_paths["AuvPlant"] if mode == "loader" else binary_only["AuvPlant"]
    done = run_python(code, LOAD_AND_FREE, mode, fmu, timeout=600)
    assert done.returncode == 0, done.stderr
    invalid = _invalid_accesses_in_fmu_binary(log.read_text())
    if mode == "unguarded":
        assert invalid and all("finalizePythonInterpreter" in r for r in invalid), invalid
    else:
        assert invalid == []
