"""The plant FMU with its compiled path on and off (AUV_COSIM_NO_JIT=1): both run, agree
to 1e-12 in every output (a new output computed on one path only is caught here), and the
FMU says when it fell back to the reference."""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

from plant_fmu.auv_plant import AuvPlant
from plant_fmu.model import compiled

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


def _plant_where_numba_raises(raised: str) -> str:
    """A script stepping the plant three times where importing numba raises ``raised``
    (a Python expression) and printing the non-OK messages it logged."""
    return f"""
import importlib.abc, sys

class NumbaRaises(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "numba" or name.startswith("numba."):
            raise {raised}
        return None

sys.meta_path.insert(0, NumbaRaises())
from plant_fmu.auv_plant import AuvPlant

plant = AuvPlant(instance_name="numba-raises")
plant.enter_initialization_mode()
plant.exit_initialization_mode()
for k in range(3):
    assert plant.do_step(0.01 * k, 0.01), plant.log_queue
print(repr([(m.status.name, m.msg) for m in plant.log_queue if m.status.name != "ok"]))
"""


# as Python raises it for a numba not installed
WITHOUT_NUMBA = _plant_where_numba_raises(
    'ModuleNotFoundError("No module named \'numba\'", name="numba")'
)
# as numba's import raises where llvmlite's shared library cannot load
BROKEN_NUMBA = _plant_where_numba_raises('OSError("Could not find/load shared object file")')


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


def test_a_numba_that_fails_to_import_otherwise_than_by_importerror_leaves_numpy(run_python):
    """A broken numba (its llvmlite's shared library missing or built for another glibc
    raises OSError, a numba built for another numpy AttributeError) is no numba: the plant
    steps the numpy reference, and its one warning names the error and how to repair numba
    instead of telling the host to install it."""
    done = run_python(BROKEN_NUMBA)
    assert done.returncode == 0, done.stderr[-3000:]
    logged = ast.literal_eval(done.stdout.strip().splitlines()[-1])
    assert len(logged) == 1, logged
    status, message = logged[0]
    assert status == "warning"
    assert "OSError: Could not find/load shared object file" in message, message
    assert (
        "install numba in this Python" not in message
        and "-m pip install --force-reinstall numba" in message
    )


INITIALISED_TWICE = """
import os
os.environ["AUV_COSIM_NO_JIT"] = "1"
from plant_fmu.auv_plant import AuvPlant

plant = AuvPlant(instance_name="off")
vr = {v.name: v.value_reference for v in plant.vars.values()}
plant.enter_initialization_mode()
plant.set_real([vr["u_0"]], [1.2])
plant.get_real([vr["u"]])  # the outputs to start from: the model built once
plant.set_real([vr["tunnel_force"]], [1.0])  # an input after it: built again at the exit
plant.exit_initialization_mode()
assert plant.do_step(0.0, 0.01), plant.log_queue
print(sum("compiled plant is off" in m.msg for m in plant.log_queue))
"""


def test_a_plant_built_twice_in_initialisation_says_once_that_it_is_not_compiled(run_python):
    """A master reads the outputs to start from and then writes inputs (FMI's exchange in
    initialisation mode), so the plant's model is built twice: the missing compiled path
    is still one warning per instance, not one per build."""
    done = run_python(INITIALISED_TWICE)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.split() == ["1"]


STEPPED = """
import json, os, sys
os.environ["AUV_COSIM_NO_JIT"] = "1"
sys.path.insert(0, sys.argv[1])
from test_plant_jit_off import stepped_outputs
from plant_fmu.auv_plant import AuvPlant

print(json.dumps(stepped_outputs(AuvPlant(instance_name="off"))))
"""


def stepped_outputs(plant: AuvPlant) -> dict[str, float]:
    """Every output ``plant`` declares, after half a second of turning and diving with
    every actuator input set."""
    vrs = {var.name: vr for vr, var in plant.vars.items()}
    outputs = [var.name for var in plant.vars.values() if var.causality.name == "output"]
    plant.enter_initialization_mode()
    plant.set_real([vrs["u_0"], vrs["v_0"], vrs["down_0"]], [1.5, -0.05, 2.0])
    plant.exit_initialization_mode()
    actuators = ("fin_angle", "tunnel_force", "mass_position_cmd", "roll_torque")
    plant.set_real([vrs[n] for n in actuators], [0.1, 5.0, 0.03, 0.5])
    for k in range(50):
        assert plant.do_step(0.01 * k, 0.01), plant.log_queue
    return dict(zip(outputs, plant.get_real([vrs[n] for n in outputs]), strict=True))


@pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)
def test_every_plant_output_steps_alike_with_the_compiled_path_on_and_off(run_python):
    """Every output the plant declares (not a list of them here) has the same value after
    half a second of manoeuvring on the compiled path (this process) as on the numpy
    reference (AUV_COSIM_NO_JIT=1): an output refreshed only by the reference step
    (``AuvPlant._refresh_outputs``, which the compiled step bypasses) keeps its start value
    when numba is on. The fast twin of
    :func:`test_plant_fmu_agrees_with_the_compiled_path_off`."""
    on = stepped_outputs(AuvPlant(instance_name="on"))
    done = run_python(STEPPED, Path(__file__).parent)
    assert done.returncode == 0, done.stderr[-3000:]
    off = json.loads(done.stdout.strip().splitlines()[-1])
    assert on.keys() == off.keys()
    assert {"yaw", "u_rel", "kinetic_energy", "quat_w"} <= on.keys()
    assert on["yaw"] != 0.0  # it did turn
    apart = {
        name: (on[name], off[name])
        for name in on
        if not np.isclose(on[name], off[name], rtol=1e-12, atol=1e-12)
    }
    assert not apart, f"outputs (on, off) the compiled step leaves behind: {apart}"
