"""The plant FMU with its compiled path on and off (AUV_COSIM_NO_JIT=1): both run, agree
to 1e-12, and the FMU says when it fell back to the reference."""

from __future__ import annotations

import ast

import numpy as np
import pytest

RUN = """
import os, sys
if sys.argv[3] == "off":
    os.environ["AUV_COSIM_NO_JIT"] = "1"
from pathlib import Path
import ast

import numpy as np
from cosim.engine import master
from cosim.scenario.spec import load_scenario
scenario = load_scenario(sys.argv[1], fmu_dir=Path(sys.argv[2])).with_overrides(stop_time=10.0)
result = master.run(scenario)
assert result.complete, result.error
np.save(sys.argv[4], result.values)
print("\\n".join(result.messages.get("plant", [])))
"""


@pytest.mark.slow
@pytest.mark.parametrize("scenario", ["bs-3", "vert-2"])
def test_plant_fmu_agrees_with_the_compiled_path_off(scenario, fmu_paths, run_python, tmp_path):
    fmu_dir = fmu_paths["AuvPlant"].parent
    assert fmu_paths["AuvAutopilot"].parent == fmu_dir
    values, logs = {}, {}
    for mode in ("on", "off"):
        out = tmp_path / f"{mode}.npy"
        done = run_python(RUN, scenario, fmu_dir, mode, out)
        assert done.returncode == 0, done.stderr[-3000:]
        values[mode], logs[mode] = np.load(out), done.stdout
    assert "AUV_COSIM_NO_JIT=1 turns the compiled path off" in logs["off"]
    assert "compiled plant is off" not in logs["on"]
    assert np.abs(values["on"]).max() > 0.1
    # relative as well as absolute: the autopilot's compiled backstepping rounds apart from
    # its reference by 1e-17, which the chattering tunnel force of vert-2 amplifies to
    # 1e-12 of its 5-10 N
    np.testing.assert_allclose(values["off"], values["on"], rtol=1e-12, atol=1e-12)


WITHOUT_NUMBA = """
import importlib.abc, sys

class NoNumba(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "numba" or name.startswith("numba."):
            raise ImportError("No module named 'numba'")
        return None

sys.meta_path.insert(0, NoNumba())
from plant_fmu.auv_plant import AuvPlant

plant = AuvPlant(instance_name="no-numba")
plant.enter_initialization_mode()
plant.exit_initialization_mode()
for k in range(3):
    assert plant.do_step(0.01 * k, 0.01), plant.log_queue
print(repr([(m.status.name, m.msg) for m in plant.log_queue if m.status.name != "ok"]))
"""


def test_a_host_without_numba_is_told_once_what_the_reference_path_costs(run_python):
    """numba is optional: without it the plant steps the numpy reference and says so, once
    per instance, with the cost scripts/bench_no_numba.py measured."""
    done = run_python(WITHOUT_NUMBA)
    assert done.returncode == 0, done.stderr[-3000:]
    logged = ast.literal_eval(done.stdout.strip().splitlines()[-1])
    assert len(logged) == 1, logged
    status, message = logged[0]
    assert status == "warning"
    assert (
        "the compiled plant is off (numba cannot be imported (No module named 'numba'))" in message
    )
    assert "each step about 16 times as long" in message and "install numba" in message
