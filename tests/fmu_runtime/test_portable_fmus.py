"""Our FMUs away from the environment that built them, as a colleague receives them: copied
with the build's Python recorded nowhere, run from a fresh virtual environment holding
only fmpy and numpy, from a C host in ``env -i`` pointed at such an environment, and from
every other CPython minor a host may run (3.9 to 3.13 but the build's) with numpy alone.
Each gives the build environment's results.

The environments are made once per session with pip (slow); a test skips, saying why,
when pip cannot reach the package index or that CPython is not installed (pyenv).
"""

from __future__ import annotations

import json
import re
import shutil
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from c_hosts import compiled_host, run_clean
from repo_paths import TESTS
from venvs import make_venv

from cosim.fmus.build import FMUS
from cosim.fmus.native import OVERRIDE_VARIABLE
from fmu_runtime.entry import RECORD_FILE
from plant_fmu.model import compiled

pytestmark = pytest.mark.slow
AGREEMENT = 1e-9
RUNS = {  # start values and inputs of a 2 s run of each FMU alone
    "AuvPlant": {"u_0": 1.5, "v_0": -0.1, "mass_position_cmd": 0.02, "tunnel_force": 0.5},
    "AuvAutopilot": {"heading_mode": 3, "yaw": 0.1, "r": 0.01, "v_rel": -0.05, "u_rel": 1.5},
}

RUN = """
import json, sys
from fmu_harness import Harness

fmu = Harness(sys.argv[1], instance="portable", **json.loads(sys.argv[2]))
names = [n for n, v in fmu.variables.items() if v.causality == "output" and v.type == "Real"]
rows = fmu.run(2.0, 0.01, names)
fmu.close()
print(json.dumps(rows.tolist()))
"""


@pytest.fixture(scope="session")
def fresh_venv(tmp_path_factory) -> Path:
    """fmpy and numpy (and what they depend on), nothing of auv-cosim."""
    return make_venv(
        tmp_path_factory.mktemp("fresh") / "venv", sys._base_executable, "fmpy", "numpy"
    )


# the CPythons docs/hosts.md says were measured, but the build's own: an FMU built under 3.13
# runs in a 3.11 host as one built under 3.11 runs in a 3.13 host
HOST_PYTHONS = ("3.9", "3.10", "3.11", "3.12", "3.13")
BUILD_PYTHON = ".".join(map(str, sys.version_info[:2]))
OTHER_PYTHONS = tuple(minor for minor in HOST_PYTHONS if minor != BUILD_PYTHON)


@pytest.fixture(scope="session", params=OTHER_PYTHONS)
def other_python(request, tmp_path_factory) -> Path:
    """pyenv's CPython of that minor version (shared libpython) with numpy alone."""
    minor = request.param
    found = sorted(Path("/root/.pyenv/versions").glob(f"{minor}.*/bin/python{minor}"))
    if not found or not list(found[-1].parents[1].glob(f"lib/libpython{minor}.so*")):
        pytest.skip(f"no CPython {minor} with a shared libpython in /root/.pyenv/versions")
    return make_venv(tmp_path_factory.mktemp(f"py{minor}") / "venv", found[-1], "numpy")


@pytest.fixture(scope="module")
def travelled(fmu_paths, tmp_path_factory) -> dict[str, Path]:
    """Copies of the built FMUs whose record names a build Python that is nowhere, as on a
    colleague's machine."""
    folder = tmp_path_factory.mktemp("travelled")
    copies = {}
    for name in FMUS:
        copy = folder / f"{name}.fmu"
        with zipfile.ZipFile(fmu_paths[name]) as source, zipfile.ZipFile(copy, "w") as target:
            for info in source.infolist():
                data = source.read(info)
                if info.filename == f"resources/{RECORD_FILE}":
                    data = re.sub(rb"build_python=.*", b"build_python=/nonexistent/bin/python",
                                  data)  # fmt: skip
                target.writestr(info, data)
        copies[name] = copy
    return copies


def _harness_only(folder: Path) -> Path:
    """A folder holding tests/fmu_harness.py alone (the tests' folder would bring more)."""
    folder.mkdir(exist_ok=True)
    shutil.copy(TESTS / "fmu_harness.py", folder)
    return folder


def _rows(python: Path, fmu: Path, name: str, home: Path) -> np.ndarray:
    done = run_clean([python, "-c", RUN, fmu, json.dumps(RUNS[name])], home,
                     PYTHONPATH=str(_harness_only(home / "harness")))  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-3000:]
    return np.array(json.loads(done.stdout.strip().splitlines()[-1]))


@pytest.mark.parametrize("name", sorted(RUNS))
def test_a_fresh_venv_with_fmpy_and_numpy_gets_the_build_environments_results(
    name, travelled, fresh_venv, clean_home
):
    ours = _rows(Path(sys.executable), travelled[name], name, clean_home)
    theirs = _rows(fresh_venv / "bin" / "python", travelled[name], name, clean_home)
    assert ours.shape == theirs.shape == (200, ours.shape[1])
    assert np.max(np.abs(ours - theirs)) <= AGREEMENT


def test_a_c_host_in_env_i_runs_the_plant_from_a_venv_folder(
    travelled, fresh_venv, host, tmp_path, clean_home
):
    with zipfile.ZipFile(travelled["AuvPlant"]) as archive:
        archive.extractall(tmp_path / "plant")
    done = run_clean([host, tmp_path / "plant", "AuvPlant", "cycles", 2, 200], clean_home,
                     PATH="/nonexistent", **{OVERRIDE_VARIABLE: str(fresh_venv)})  # fmt: skip
    assert "cycles: 2 x 200 ok" in done.stdout, done.stdout[-3000:] + done.stderr[-3000:]
    assert done.stderr == ""


def test_another_cpython_with_numpy_alone_runs_the_plant(
    travelled, other_python, host, tmp_path, clean_home
):
    """Every other CPython minor from 3.9 to 3.13 (the FMUs built with this Python) in a C
    host."""
    with zipfile.ZipFile(travelled["AuvPlant"]) as archive:
        archive.extractall(tmp_path / "plant")
    done = run_clean([host, tmp_path / "plant", "AuvPlant", "cycles", 2, 200], clean_home,
                     PATH="/nonexistent", **{OVERRIDE_VARIABLE: str(other_python)})  # fmt: skip
    assert "cycles: 2 x 200 ok" in done.stdout, done.stdout[-3000:] + done.stderr[-3000:]
    assert done.stderr == ""


def test_a_c_host_whose_numba_cannot_load_runs_the_plant_on_numpy(
    travelled, host, tmp_path, clean_home
):
    """A numba whose import raises OSError, as it does when llvmlite's shared library is
    missing or needs a newer glibc, is no numba: the plant instantiates and steps its
    numpy path (before, fmi2Instantiate returned NULL: the plant's module failed to import;
    the warning it logs instead is checked in tests/plant_fmu/test_plant_jit_off.py)."""
    broken = tmp_path / "site" / "numba"
    broken.mkdir(parents=True)
    (broken / "__init__.py").write_text('raise OSError("Could not find/load shared object file")\n')
    with zipfile.ZipFile(travelled["AuvPlant"]) as archive:
        archive.extractall(tmp_path / "plant")
    done = run_clean([host, tmp_path / "plant", "AuvPlant", "cycles", 1, 20], clean_home,
                     PATH="/nonexistent", PYTHONPATH=str(broken.parent),
                     **{OVERRIDE_VARIABLE: sys.executable})  # fmt: skip
    assert "cycles: 1 x 20 ok" in done.stdout, done.stdout[-3000:] + done.stderr[-3000:]


@pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)
def test_a_numba_cache_folder_that_cannot_be_written_is_said_to_the_hosts_logger(
    travelled, tmp_path, clean_home
):
    """numba's cache folder named by the host's environment as a file: the FMU still runs,
    compiling without a cache, and says so as a Warning to the host's logger, not as a
    Python warning (a source line under it) on the host's stderr, where a host that is not
    Python never looks."""
    log_host = compiled_host(TESTS / "fmu_runtime" / "hosts" / "log_host.c", tmp_path)
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    with zipfile.ZipFile(travelled["AuvPlant"]) as archive:
        archive.extractall(tmp_path / "plant")
    command = [log_host, tmp_path / "plant", "AuvPlant", "contract", "plant"]
    environment = {"NUMBA_CACHE_DIR": str(blocker), OVERRIDE_VARIABLE: sys.executable}
    done = run_clean(command, clean_home, **environment)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert done.stderr == ""
    assert f"numba's cache folder '{blocker}'" in done.stdout, done.stdout[-3000:]
