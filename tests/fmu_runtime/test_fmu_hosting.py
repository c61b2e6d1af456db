"""Our built FMUs as a Python host (fmpy) sees them, each case in fresh processes, since an
FMU's modules stay imported for the life of a process and a broken FMU may crash it:

* a parameter loop (a fresh extraction per run, deleted after it) gives bit-identically
  the results of fresh processes, through ``simulate_fmu`` and through ``FMU2Slave``;
* a second build of AuvPlant.fmu with other sources, loaded after the first in the same
  process, runs its own code;
* instantiate/free cycles keep (almost) no memory (``scripts/bench_instances.py``);
* fmi2FreeInstance frees the FMU states a host took and never freed;
* calls against the FMI 2.0 rules return fmi2Error with the reason logged, the host
  survives, and the valid call afterwards works;
* every output read in initialisation mode is the value the FMU starts from;
* a host whose exit handlers terminate and free instances after Python has shut down
  exits cleanly; the FMU's runtime and pythonfmu's binary give the same results.
"""

from __future__ import annotations

import json
import re
import shutil
from pathlib import Path

import pytest
from repo_paths import ROOT

from cosim.fmus.build import FMUS

# One run of each FMU alone, its start values with one of them varied (the reported loop
# for the plant; for the autopilot an LQR design, which reads the vehicle data too).
CASES = {
    "AuvPlant": {
        "start": {"u_0": 1.5},
        "vary": "v_0",
        "values": [0.02, 0.04, 0.06],
        "output": "v",
        "stop": 5.0,
        "h": 0.05,
    },
    "AuvAutopilot": {
        "start": {"heading_mode": 1, "design_step": 0.05},
        "vary": "yaw_setpoint",
        "values": [0.1, 0.2, 0.3],
        "output": "mass_position_cmd",
        "stop": 1.0,
        "h": 0.05,
    },
}

RUNS = """
import json, shutil, sys
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave

fmu, case, drivers = sys.argv[1], json.loads(sys.argv[2]), sys.argv[3].split(",")
n = round(case["stop"] / case["h"])
times = [k * case["h"] for k in range(n + 1)]  # t_n = n h, steps t_n+1 - t_n, as fmpy does


def by_simulate_fmu(value):
    result = simulate_fmu(fmu, stop_time=case["stop"], output_interval=case["h"],
                          start_values={**case["start"], case["vary"]: value},
                          output=[case["output"]])
    return [float(x) for x in result[case["output"]]]


def by_fmu2slave(value):
    md = read_model_description(fmu)
    variables = {v.name: v for v in md.modelVariables}
    folder = extract(fmu)
    try:
        slave = FMU2Slave(guid=md.guid, unzipDirectory=folder, instanceName="x",
                          modelIdentifier=md.coSimulation.modelIdentifier)
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        for name, start in {**case["start"], case["vary"]: value}.items():
            var = variables[name]
            getattr(slave, "set" + var.type)([var.valueReference], [start])
        slave.exitInitializationMode()
        out = [variables[case["output"]].valueReference]
        values = [slave.getReal(out)[0]]
        for t, t_next in zip(times, times[1:]):
            slave.doStep(t, t_next - t)
            values.append(slave.getReal(out)[0])
        slave.terminate()
        slave.freeInstance()
        return values
    finally:
        shutil.rmtree(folder)


run = {"simulate_fmu": by_simulate_fmu, "FMU2Slave": by_fmu2slave}
print(json.dumps({d: [run[d](v) for v in case["values"]] for d in drivers}))
"""


def _json_result(done) -> dict:
    assert done.returncode == 0, done.stderr[-3000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_a_parameter_loop_in_one_process_matches_fresh_processes(name, fmu_paths, run_python):
    case = CASES[name]
    fresh = [
        _json_result(
            run_python(RUNS, fmu_paths[name], json.dumps({**case, "values": [v]}), "simulate_fmu")
        )["simulate_fmu"][0]
        for v in case["values"]
    ]
    assert len({json.dumps(run) for run in fresh}) == 3  # three different results
    assert all(len(run) == round(case["stop"] / case["h"]) + 1 for run in fresh)
    loop = _json_result(
        run_python(RUNS, fmu_paths[name], json.dumps(case), "simulate_fmu,FMU2Slave")
    )
    assert loop["simulate_fmu"] == fresh  # bit-identical (JSON keeps every float exactly)
    assert loop["FMU2Slave"] == fresh


TWO_BUILDS = """
import json, sys
from fmu_harness import Harness

report = {}
for key, path in (("first", sys.argv[1]), ("second", sys.argv[2])):
    fmu = Harness(path, u_0=1.5)
    report[key] = {"thrust": float(fmu.get("thrust")[0]), "step": fmu.step(0.01),
                   "errors": fmu.messages(3)}
    fmu.close()
report["packages"] = sorted({m.split(".")[0] for m in sys.modules if m.startswith("auvfmu_")})
print(json.dumps(report))
"""

BUILD_ELSEWHERE = """
import sys
sys.path.insert(0, sys.argv[1])  # the changed sources shadow the installed packages
from pathlib import Path
from cosim.fmus.build import build_fmu
import plant_fmu
assert plant_fmu.__file__.startswith(sys.argv[1]), plant_fmu.__file__
print(build_fmu("AuvPlant", Path(sys.argv[2])))
"""


@pytest.mark.slow
def test_a_second_build_in_the_same_process_runs_its_own_code(fmu_paths, run_python, tmp_path):
    """Its thrust input starts at 8 N where the first build's starts at 9 N: each
    instance runs the code of the build it came from."""
    src = tmp_path / "src"
    for package in ("plant_fmu", "controller_fmu", "fmu_runtime"):
        shutil.copytree(ROOT / package, src / package, ignore=shutil.ignore_patterns("__pycache__"))
    plant = src / "plant_fmu" / "auv_plant.py"
    text = plant.read_text()
    assert 'INPUT_STARTS: dict[str, float] = {"thrust": 9.0}' in text
    plant.write_text(text.replace('{"thrust": 9.0}', '{"thrust": 8.0}'))
    built = run_python(BUILD_ELSEWHERE, src, tmp_path / "other")
    assert built.returncode == 0, built.stderr[-3000:]
    other = Path(built.stdout.strip().splitlines()[-1])

    report = _json_result(run_python(TWO_BUILDS, fmu_paths["AuvPlant"], other))
    assert report["first"] == {"thrust": 9.0, "step": 0, "errors": ""}
    assert report["second"] == {"thrust": 8.0, "step": 0, "errors": ""}
    assert len(report["packages"]) == 2  # one package per build, side by side


@pytest.mark.slow
def test_instantiate_free_cycles_keep_under_2_mb_per_1000(fmu_paths, run_python):
    """300 cycles of each of our FMUs after a warm-up; 2 MB per 1,000 cycles, scaled."""
    script = (
        "import runpy, sys; sys.argv = sys.argv[1:]; "
        "runpy.run_path(sys.argv[0], run_name='__main__')"
    )
    done = run_python(
        script,
        ROOT / "scripts" / "bench_instances.py",
        "--fmu-dir", fmu_paths["AuvPlant"].parent, "--cycles", "300", "--warmup", "50",
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-3000:]
    growth = dict(re.findall(r"^(\w+): 300 cycles grow RSS by (-?[\d.]+) MB", done.stdout, re.M))
    assert set(growth) == set(FMUS), done.stdout
    assert all(float(mb) < 0.6 for mb in growth.values()), done.stdout


RULES = """
import json, sys
from fmpy import read_model_description
from fmpy.fmi1 import FMICallException
from fmu_harness import Harness

plant, autopilot = sys.argv[1], sys.argv[2]
report = {}


def status(call, *args, **kwargs):
    try:
        call(*args, **kwargs)
    except FMICallException as exc:
        return exc.status
    return 0


fmu = Harness(plant, u_0=1.5)  # wrong communication point, then the right one
report["first step"] = fmu.step(0.01)
report["wrong point"] = fmu.step(0.01, at=0.5)
report["right point"] = fmu.step(0.01)
report["wrong point errors"] = fmu.messages(3)
fmu.close()

fmu = Harness(plant, initialize=False)  # initialisation mode entered twice
fmu.slave.setupExperiment(startTime=0.0)
fmu.slave.enterInitializationMode()
report["double enter"] = status(fmu.slave.enterInitializationMode)
fmu.slave.exitInitializationMode()
report["double enter step"] = fmu.step(0.01)
report["double enter errors"] = fmu.messages(3)
fmu.close()

fmu = Harness(plant, initialize=False)  # left without being entered
fmu.slave.setupExperiment(startTime=0.0)
report["exit without enter"] = status(fmu.slave.exitInitializationMode)
report["exit without enter step"] = fmu.step(0.01)
fmu.slave.enterInitializationMode()
fmu.slave.exitInitializationMode()
report["after enter step"] = fmu.step(0.01)
report["exit without enter errors"] = fmu.messages(3)
fmu.close()

fmu = Harness(plant, initialize=False)  # out-of-range Integer, then a valid one
fmu.slave.setupExperiment(startTime=0.0)
fmu.slave.enterInitializationMode()
report["variant 7"] = status(fmu.set, variant=7)
report["variant after 7"] = fmu.slave.getInteger([fmu.variables["variant"].valueReference])[0]
fmu.set(variant=1)
fmu.slave.exitInitializationMode()
report["variant 1 step"] = fmu.step(0.01)
report["variant errors"] = fmu.messages(3)
fmu.close()

fmu = Harness(autopilot, instance="controller", initialize=False)  # after the plant was
fmu.slave.setupExperiment(startTime=0.0)                           # freed and its
fmu.slave.enterInitializationMode()                                # extraction deleted
report["depth_mode 5"] = status(fmu.set, depth_mode=5)
fmu.slave.exitInitializationMode()
report["depth_mode 5 step"] = fmu.step(0.01)
report["depth_mode errors"] = fmu.messages(3)
fmu.close()

declared = {}
for path in (plant, autopilot):
    for v in read_model_description(path).modelVariables:
        if v.type == "Integer":
            declared[v.name] = [v.min, v.max]
report["declared"] = declared
print(json.dumps(report))
"""


@pytest.mark.slow
def test_calls_against_the_fmi_rules_are_refused_and_the_host_survives(fmu_paths, run_python):
    """Each refused call returns fmi2Error (3), names the reason in the log and changes
    nothing: the valid call afterwards works."""
    report = _json_result(run_python(RULES, fmu_paths["AuvPlant"], fmu_paths["AuvAutopilot"]))
    assert (report["first step"], report["wrong point"], report["right point"]) == (0, 3, 0)
    assert (
        "doStep at t = 0.5 s refused: currentCommunicationPoint = 0.5 s is not the FMU's "
        "current time 0.01 s"
    ) in report["wrong point errors"]
    assert (report["double enter"], report["double enter step"]) == (3, 0)
    assert (
        "enterInitializationMode refused: the FMU is in initialisation mode"
        in report["double enter errors"]
    )
    assert (report["exit without enter"], report["exit without enter step"]) == (3, 3)
    assert report["after enter step"] == 0
    assert (
        "exitInitializationMode refused: the FMU is instantiated"
        in report["exit without enter errors"]
    )
    assert report["variant 7"] == 3
    assert report["variant after 7"] == 0  # the write was refused: the old value stays
    assert "variant = 7 refused: expected 0 <= variant <= 2" in report["variant errors"]
    assert report["variant 1 step"] == 0
    assert (report["depth_mode 5"], report["depth_mode 5 step"]) == (3, 0)
    assert "depth_mode = 5 refused: expected 0 <= depth_mode <= 1" in report["depth_mode errors"]
    assert report["declared"] == {
        "variant": ["0", "2"],
        "moving_mass_model": ["0", "1"],
        "heading_mode": ["0", "3"],
        "depth_mode": ["0", "1"],
    }


# Non-default parameters and inputs for each FMU: the outputs then differ from the
# defaults' (the plant moves, the autopilot's thrust is 4 N, the guidance has a mission).
STARTS = {
    "AuvPlant": {
        "variant": 0, "u_0": 1.5, "v_0": -0.1, "w_0": 0.05, "roll_0": 0.1, "pitch_0": 0.05,
        "yaw_0": 0.3, "r_0": 0.01, "down_0": 2.0, "mass_position_0": 0.01, "current_north": 0.2,
    },
    "AuvAutopilot": {"heading_mode": 3, "thrust_command": 4.0, "yaw_setpoint": 0.2},
    "AuvGuidance": {"waypoints": "10, 0, 2; 10, 10, 2", "north": 1.0, "east": 0.5, "yaw": 0.1},
}  # fmt: skip

OUTPUTS_IN_INITIALISATION = """
import json, sys
from fmpy import read_model_description
from fmu_harness import Harness

path, starts = sys.argv[1], json.loads(sys.argv[2])
outputs = [v for v in read_model_description(path).modelVariables
           if v.causality == "output" and v.type == "Real"]
names = [v.name for v in outputs]
fmu = Harness(path, initialize=False)
fmu.slave.setupExperiment(startTime=0.0)
fmu.slave.enterInitializationMode()
fmu.set(**starts)
during = fmu.get_all(names).tolist()
fmu.slave.exitInitializationMode()
after = fmu.get_all(names).tolist()
fmu.close()
print(json.dumps({"names": names, "during": during, "after": after, "errors": fmu.messages(3),
                  "declared": {v.name: [v.initial, v.start] for v in outputs}}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_every_output_read_in_initialisation_mode_is_the_value_the_fmu_starts_from(
    name, fmu_paths, run_python
):
    """With non-default parameters and inputs written in initialisation mode: each Real
    output read there equals the value after exitInitializationMode, and an output
    declared initial="exact" starts from its declared start value."""
    report = _json_result(
        run_python(OUTPUTS_IN_INITIALISATION, fmu_paths[name], json.dumps(STARTS[name]))
    )
    assert report["errors"] == ""
    assert dict(zip(report["names"], report["during"], strict=True)) == dict(
        zip(report["names"], report["after"], strict=True)
    )
    after = dict(zip(report["names"], report["after"], strict=True))
    exact = {n: float(start) for n, (initial, start) in report["declared"].items()
             if initial == "exact"}  # fmt: skip
    assert {n: after[n] for n in exact} == exact
    calculated = [n for n, (initial, _) in report["declared"].items() if initial == "calculated"]
    assert calculated and any(after[n] != 0.0 for n in calculated)  # the values moved


INITIAL_DEPENDENCIES = """
import json, sys
from xml.etree import ElementTree as ET
from zipfile import ZipFile
from fmpy import read_model_description
from fmu_harness import Harness

path, starts = sys.argv[1], json.loads(sys.argv[2])
root = ET.fromstring(ZipFile(path).read("modelDescription.xml"))
variables = root.findall("ModelVariables/ScalarVariable")
declared = {variables[int(u.get("index")) - 1].get("name"):
            [variables[int(i) - 1].get("name") for i in (u.get("dependencies") or "").split()]
            for u in root.findall("ModelStructure/InitialUnknowns/Unknown")
            if u.get("dependencies") is not None}
model = read_model_description(path)
inputs = [v for v in model.modelVariables if v.causality == "input" and v.type == "Real"]
outputs = sorted(declared)


def outputs_in_initialisation(nudged=None):
    fmu = Harness(path, initialize=False)
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    fmu.set(**starts)
    if nudged is not None:
        fmu.set(**{nudged.name: float(fmu.get_all([nudged.name])[0]) + 0.125})
    values = dict(zip(outputs, fmu.get_all(outputs).tolist()))
    fmu.close()
    return values


base = outputs_in_initialisation()
moved = {v.name: sorted(n for n, x in outputs_in_initialisation(v).items() if x != base[n])
         for v in inputs}
print(json.dumps({"declared": declared, "inputs": [v.name for v in inputs], "moved": moved,
                  "causality": {v.name: v.causality for v in model.modelVariables}}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_outputs_computed_in_initialisation_depend_on_what_the_fmu_declares(
    name, fmu_paths, run_python
):
    """ModelStructure/InitialUnknowns lists what each calculated output depends on: the
    parameters and the inputs it may depend on: every input that moves it in
    initialisation mode (each nudged in turn) is declared, and an FMU declares inputs only
    if some output moves with one. Without the list an importer must assume every input:
    OMSimulator then reports an algebraic loop between the plant and the autopilot, whose
    outputs depend on none of their inputs there."""
    report = _json_result(
        run_python(INITIAL_DEPENDENCIES, fmu_paths[name], json.dumps(STARTS[name]))
    )
    declared, causality = report["declared"], report["causality"]
    assert declared and report["inputs"]
    for output, depends_on in declared.items():
        assert {causality[n] for n in depends_on} <= {"parameter", "input"}
        declared_inputs = {n for n in depends_on if causality[n] == "input"}
        moved_by = {i for i, outputs in report["moved"].items() if output in outputs}
        assert moved_by <= declared_inputs, output
    declares_inputs = any(causality[n] == "input" for d in declared.values() for n in d)
    assert declares_inputs == any(report["moved"].values())
    driven = {"AuvPlant": {"thrust", "roll_torque", "tunnel_force", "fin_angle",
                           "mass_position_cmd"}, "AuvAutopilot": set(report["inputs"])}  # fmt: skip
    assert not driven.get(name, set()) & {n for d in declared.values() for n in d}


LATE_EXIT = """
import ctypes, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

md = read_model_description(sys.argv[1])
slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(sys.argv[1]), instanceName="late",
                  modelIdentifier=md.coSimulation.modelIdentifier)
slave.instantiate(loggingOn=True)
slave.setupExperiment(startTime=0.0)
slave.enterInitializationMode()
slave.exitInitializationMode()
slave.doStep(0.0, 0.01)
# as a host's C++ destructors do: terminate and free after the interpreter has finalised
libc = ctypes.CDLL(None)
libc.__cxa_atexit.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
for name in ("fmi2FreeInstance", "fmi2Terminate"):  # exit handlers run last-registered first
    function = ctypes.cast(getattr(slave.dll, name), ctypes.c_void_p)
    libc.__cxa_atexit(function, ctypes.c_void_p(slave.component), None)
print("exiting")
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", ["", "pythonfmu"])
def test_calls_after_python_has_shut_down_do_not_crash_the_host(
    runtime, fmu_paths, run_python, monkeypatch
):
    """A Python host whose exit handlers call fmi2Terminate and fmi2FreeInstance after
    the interpreter has finalised (libcosimpy's and ecospy's C++ destructors do): the calls
    return without entering Python or its logger, and the process exits 0."""
    monkeypatch.setenv("AUV_FMU_RUNTIME", runtime)
    done = run_python(LATE_EXIT, fmu_paths["AuvPlant"])
    # nothing logged after the interpreter finalised (before it, a debug message may be)
    lines = done.stdout.strip().splitlines()
    assert (done.returncode, lines[-1:]) == (0, ["exiting"]), done.stderr[-3000:]


BOTH_RUNTIMES = """
import json, os, sys
from fmu_harness import Harness

os.environ["AUV_FMU_RUNTIME"] = sys.argv[3]
fmu = Harness(sys.argv[1], **json.loads(sys.argv[2]))
names = [n for n, v in fmu.variables.items() if v.causality == "output" and v.type == "Real"]
rows = [fmu.get_all(names).tolist()]
for _ in range(50):
    assert fmu.step(0.01) == 0, fmu.messages(3)
    rows.append(fmu.get_all(names).tolist())
state = fmu.slave.serializeFMUstate(fmu.slave.getFMUstate())
fmu.close()
print(json.dumps({"rows": rows, "state": len(state)}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_the_runtime_and_pythonfmus_binary_give_the_same_results(name, fmu_paths, run_python):
    starts = json.dumps(STARTS[name])
    ours, theirs = (
        _json_result(run_python(BOTH_RUNTIMES, fmu_paths[name], starts, runtime))
        for runtime in ("", "pythonfmu")
    )
    assert ours["rows"] == theirs["rows"]  # bit-identical outputs
    # each serialises its state its own way (the runtime: the value buffers' bytes and
    # the slave's part; pythonfmu's binary: the slave's JSON alone, the buffers in hex);
    # test_values_in_c.py restores each bit-identically
    assert ours["state"] > 0 and theirs["state"] > 0


DERIVATIVES = """
import json, os, sys
from fmpy.fmi1 import FMICallException
from fmu_harness import Harness


def status(call, *args):
    try:
        call(*args)
    except FMICallException as exc:
        return exc.status
    return 0


def takes(path, runtime):
    fmu = Harness(path, initialize=False)
    vr = {n: v.valueReference for n, v in fmu.variables.items()}
    set_derivatives = fmu.slave.setRealInputDerivatives
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    statuses = {"initialisation mode": status(set_derivatives, [vr["thrust"]], [1], [0.5])}
    fmu.slave.exitInitializationMode()
    statuses["first step"] = fmu.step(0.01)
    statuses["second step"] = fmu.step(0.01)
    statuses["both orders"] = status(set_derivatives, [vr["thrust"]] * 2, [1, 2], [0.25, -1.0])
    statuses["third step"] = fmu.step(0.01)
    for case, args in {"order 3": ([vr["thrust"]], [3], [1.0]),
                       "not finite": ([vr["thrust"]], [1], [float("inf")]),
                       "an output": ([vr["u"]], [1], [1.0]),
                       "a parameter": ([vr["u_0"]], [1], [1.0])}.items():
        statuses[case] = status(set_derivatives, *args)
    fmu.slave.terminate()
    statuses["terminated"] = status(set_derivatives, [vr["thrust"]], [1], [0.5])
    seen = [text for level, text in fmu.log if text.startswith("thrust derivatives")]
    return fmu, {"statuses": statuses, "seen": seen}


def takes_none(path, runtime):
    fmu = Harness(path, initialize=False)
    vr = fmu.variables["north"].valueReference
    set_derivatives = fmu.slave.setRealInputDerivatives
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    statuses = {"initialisation mode": status(set_derivatives, [vr], [1], [0.5])}
    fmu.slave.exitInitializationMode()
    statuses["initialised"] = status(set_derivatives, [vr], [1], [0.5])
    statuses["step"] = fmu.step(0.01)
    return fmu, {"statuses": statuses}


report = {}
for runtime in ("", "pythonfmu"):
    os.environ["AUV_FMU_RUNTIME"] = runtime
    for name, check, path in (("interpolating", takes, sys.argv[1]),
                              ("guidance", takes_none, sys.argv[2])):
        fmu, report[f"{runtime or 'runtime'} {name}"] = check(path, runtime)
        report[f"{runtime or 'runtime'} {name}"]["errors"] = fmu.messages(3)
        fmu.slave.freeInstance()
print(json.dumps(report))
"""


@pytest.mark.slow
def test_input_derivatives_reach_a_slave_that_takes_them_and_no_other(
    fmu_paths, run_python, tmp_path
):
    """A plant (it takes input derivatives) built with a line logging what it sees:
    derivatives of Real inputs, orders 1 and 2, in initialisation mode and when
    initialised, reach the next step only, with the FMU's runtime and with pythonfmu's
    binary behind it alike; anything else is refused; and an FMU that takes none (the
    guidance: canInterpolateInputs="false") refuses every call in both."""
    src = tmp_path / "src"
    for package in ("plant_fmu", "controller_fmu", "fmu_runtime"):
        shutil.copytree(ROOT / package, src / package, ignore=shutil.ignore_patterns("__pycache__"))
    plant = src / "plant_fmu" / "auv_plant.py"
    text = plant.read_text()
    step = "    def _step(self, current_time: float, step_size: float) -> None:\n"
    seen = (
        "        self.log(f\"thrust derivatives {self.input_derivative('thrust', 1)!r} \"\n"
        "                 f\"{self.input_derivative('thrust', 2)!r}\")\n"
    )
    assert step in text
    plant.write_text(text.replace(step, step + seen))
    built = run_python(BUILD_ELSEWHERE, src, tmp_path / "interpolating")
    assert built.returncode == 0, built.stderr[-3000:]
    interpolating = Path(built.stdout.strip().splitlines()[-1])
    report = _json_result(run_python(DERIVATIVES, interpolating, fmu_paths["AuvGuidance"]))
    for runtime in ("runtime", "pythonfmu"):
        taken = report[f"{runtime} interpolating"]
        assert taken["statuses"] == {
            "initialisation mode": 0, "first step": 0, "second step": 0, "both orders": 0,
            "third step": 0, "order 3": 3, "not finite": 3, "an output": 3, "a parameter": 3,
            "terminated": 3,
        }, runtime  # fmt: skip
        assert taken["seen"] == [
            "thrust derivatives 0.5 0.0", "thrust derivatives 0.0 0.0",
            "thrust derivatives 0.25 -1.0",
        ], runtime  # fmt: skip
        assert "order 3, expected 1 or 2" in taken["errors"]
        none = report[f"{runtime} guidance"]
        assert none["statuses"] == {"initialisation mode": 3, "initialised": 3, "step": 0}
        assert "this FMU takes no input derivatives" in none["errors"]


DISCARDED_AGAIN = """
import sys
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException

messages = []
try:
    simulate_fmu(sys.argv[1], stop_time=0.1, output_interval=0.05,
                 start_values={"heading_mode": 3, "r": 1e300},
                 logger=lambda *args: messages.append(args[-1].decode()))
    print("returned")
except FMICallException as exc:
    print(exc.function, exc.status)
print(len(messages))
print("\\n".join(messages))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", ["", "pythonfmu"])
def test_a_step_discarded_and_retried_unchanged_ends_fmpy_instead_of_looping(
    runtime, fmu_paths, run_python, monkeypatch
):
    """fmpy's simulate_fmu retries a discarded step for ever while fmi2Terminated is false
    (millions of identical Error lines until killed): the same step again with nothing set
    since is refused with fmi2Error, and fmpy stops with it after two tries."""
    monkeypatch.setenv("AUV_FMU_RUNTIME", runtime)
    done = run_python(DISCARDED_AGAIN, fmu_paths["AuvAutopilot"], timeout=60)
    lines = done.stdout.splitlines()
    assert lines[:2] == ["fmi2DoStep 3", "2"], done.stdout[-3000:] + done.stderr[-3000:]
    assert "the autopilot computed a non-finite command" in lines[2]
    assert "this step was discarded just before and nothing was set since" in lines[3]


DISCARDED_AGAIN_WITH_INPUTS = """
import os, sys
import numpy as np
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException

messages = []
table = np.array([(0.0, 0.0), (1.0, 0.0)], dtype=[("time", float), ("yaw", float)])
try:
    simulate_fmu(sys.argv[1], stop_time=0.1, output_interval=0.05, input=table,
                 start_values={"heading_mode": 3, "r": 1e300},
                 logger=lambda *args: messages.append(args[-1].decode()) if len(messages) < 9
                 else os._exit(3))  # retried for ever
    print("returned")
except FMICallException as exc:
    print(exc.function, exc.status)
print("\\n".join(messages))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", ["", "pythonfmu"])
def test_a_discarded_step_retried_with_the_same_inputs_written_again_ends_fmpy(
    runtime, fmu_paths, run_python, monkeypatch
):
    """With an input table, fmpy's simulate_fmu writes the inputs again before each try
    of a step: the same values, which counted as something set since the discarded step,
    so the retry went on for ever (1.5 GB of log in seconds). A write that changes no value
    is no change: fmpy stops after two tries, as without inputs."""
    monkeypatch.setenv("AUV_FMU_RUNTIME", runtime)
    done = run_python(DISCARDED_AGAIN_WITH_INPUTS, fmu_paths["AuvAutopilot"], timeout=120)
    lines = [line for line in done.stdout.splitlines() if not line.startswith("Warning: missing")]
    assert done.returncode == 0, done.stderr[-3000:]
    assert lines[0] == "fmi2DoStep 3", done.stdout[-3000:]
    assert "this step was discarded just before and nothing was set since" in lines[2]


UNFREED_STATES = """
import gc, shutil, sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

fmu, warmup, cycles = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
md = read_model_description(fmu)
unzipped = extract(fmu)
slave = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                  modelIdentifier=md.coSimulation.modelIdentifier, instanceName="unfreed")


def cycle():
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    for _ in range(5):
        slave.getFMUstate()  # never given to fmi2FreeFMUstate
    slave.terminate()
    slave.fmi2FreeInstance(slave.component)


counts = []
for total in (warmup, warmup + cycles):
    while len(counts) < total:
        cycle()
        counts.append(None)
    gc.collect()
    counts[-1] = len(gc.get_objects())
print("objects", counts[warmup - 1], counts[-1])
shutil.rmtree(unzipped, ignore_errors=True)
"""


def _objects_kept_over_unfreed_state_cycles(fmu: Path, run_python, cycles: int) -> int:
    """Python objects (``gc.get_objects``) gained over ``cycles`` cycles of instantiate,
    initialise, five fmi2GetFMUstate never freed, terminate and fmi2FreeInstance, after a
    warm-up of 10, in a fresh fmpy process."""
    done = run_python(UNFREED_STATES, fmu, 10, cycles)
    assert done.returncode == 0, done.stderr[-3000:]
    before, after = map(int, re.findall(r"^objects (\d+) (\d+)$", done.stdout, re.M)[0])
    return after - before


def test_fmi2_free_instance_frees_the_states_the_host_never_freed(fmu_paths, run_python):
    """fmi2FreeInstance frees all an instance allocated (FMI 2.0, 2.1.5), its FMU states
    too: a host that saves states and never frees them (it frees the instance instead)
    keeps nothing per cycle. Each state kept held its slave's part (4 Python objects, about
    3.4 KiB): 50 cycles of 5 states kept 1,000 objects; 25 allows the interpreter's own
    caches, which do not grow with the cycles."""
    assert _objects_kept_over_unfreed_state_cycles(fmu_paths["AuvPlant"], run_python, 50) <= 25


@pytest.mark.slow
def test_fmi2_free_instance_frees_unfreed_states_over_1000_cycles(fmu_paths, run_python):
    """The twin above over 1,000 cycles (5,000 states, 20,000 objects kept before)."""
    assert _objects_kept_over_unfreed_state_cycles(fmu_paths["AuvPlant"], run_python, 1000) <= 25
