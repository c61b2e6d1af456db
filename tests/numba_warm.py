"""numba's kernels compiled once for the session's pytest-xdist workers, not once by each.

On a first run with an empty numba cache (a clean HOME: a CI runner, a new machine), each
worker of ``pytest -n 2`` compiled the same kernels, the FMUs' and the source tree's
(~17 s of CPU each), at once, into the same cache: twice the work on the two cores the
tests wait for. The first worker to get here compiles them, in a fresh process (pythonfmu
caches modules), under a lock the others wait at; they then load what it wrote. A cache
that holds the built FMUs' kernels already (every later run) costs a look at one folder.
"""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from process_group import run_in_group
from worker_shared import build_once, shared_folder

import cosim
from plant_fmu.model import jit

WARM_UP = """
import sys
from pathlib import Path

import cosim
from controller_fmu.autopilot import Autopilot, AutopilotConfig
from cosim.analysis.closed_loop import simulate_closed_loop
from cosim.engine import master
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import state_vector
from plant_fmu.model.parameters import load_vehicle

fmu_dir = Path(sys.argv[1])
for scenario in ("bs-3", "lqr-1", "vert-1"):  # the FMUs': lateral and 6-DOF, each law
    short = cosim.load_scenario(scenario, fmu_dir=fmu_dir).with_overrides(stop_time=0.02)
    master.run(short, keep_rows=False)
remus = load_vehicle("remus100")
for variant, depth in ((Variant.LATERAL, 0), (Variant.FULL, 1)):  # the source tree's
    model = PlantModel(remus, variant=variant)
    for heading in (1, 3):
        autopilot = Autopilot(AutopilotConfig.build(heading_mode=heading, depth_mode=depth))
        x0 = state_vector({"u": 1.5})
        simulate_closed_loop(autopilot, model, x0, 0.02, 0.01, compiled=CompiledPlant(model))
"""


def compile_once(tmp_path_factory: pytest.TempPathFactory, plant: Path) -> None:
    """Compile the kernels of the session's FMUs (``plant``: its AuvPlant.fmu, beside the
    others) and of the source tree once for all the session's xdist workers, if numba's
    cache holds none of that build's (looked at under the lock: the folder appears as the
    first worker starts to compile); nothing without xdist or with numba off."""
    if "PYTEST_XDIST_WORKER" not in os.environ or jit.load_numba()[0] is None:
        return
    with zipfile.ZipFile(plant) as fmu:
        runtime = fmu.read("resources/fmu_runtime.txt").decode()
    package = dict(line.partition("=")[::2] for line in runtime.splitlines())["package"]
    cache = Path(os.environ.get("NUMBA_CACHE_DIR") or jit.default_cache_dir())

    def compile_kernels(folder: Path) -> None:
        if (cache / "auv_cosim" / package).is_dir():
            return  # compiled by an earlier session
        command = [sys.executable, "-c", WARM_UP, str(plant.parent)]
        packages = str(Path(cosim.__file__).resolve().parents[1])  # not tests/'s folders
        path = os.pathsep.join(filter(None, [packages, os.environ.get("PYTHONPATH")]))
        env = {**os.environ, "PYTHONPATH": path}
        try:
            done = run_in_group(command, timeout=900, cwd=folder, env=env)
        except subprocess.TimeoutExpired:
            return  # the tests compile on their own then
        if done.returncode != 0:  # as they do then, and say why
            print(f"numba warm-up failed: {done.stderr[-2000:]}", file=sys.stderr)

    build_once(shared_folder(tmp_path_factory, "numba_warm"), compile_kernels)
