"""Values cross the FMU boundary in C: the runtime answers fmi2Get*/fmi2Set* from the
slave's value buffers without Python (not even the GIL), a step is the one call into
Python, and what the C side holds (Strings, non-finite values, FMU states, tunable
parameters written between steps) reaches the slave or the host exactly, in both runtimes
where both apply."""

from __future__ import annotations

import json

import pytest
from c_hosts import run_clean

from cosim.fmus.build import FMUS

RUNTIMES = {"runtime": {}, "pythonfmu": {"AUV_FMU_RUNTIME": "pythonfmu"}}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_gets_and_sets_need_no_gil_while_the_host_holds_it(name, host, extracted, clean_home):
    """A C host takes Python's GIL in one thread; another thread gets and sets every Real,
    Integer and String meanwhile. A call that needed the GIL would wait for ever (the host
    then prints "blocked" after 60 s)."""
    done = run_clean([host, extracted[name], name, "gil"], clean_home, timeout=600)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "values without the GIL: 500 calls, worst status 0" in done.stdout, done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_serialised_fmu_state_restores_bit_identically_in_a_c_host(
    name, runtime, host, extracted, clean_home
):
    """Step, save and serialise; step on. A fresh instance deserialises the bytes, is set
    to the state and steps the same: every Real output equal to the last bit."""
    done = run_clean([host, extracted[name], name, "state"], clean_home, **RUNTIMES[runtime])
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "state: identical over" in done.stdout, done.stdout


CALLS_INTO_PYTHON = """
import json, os, sys
import fmpy
from fmu_harness import Harness

FMPY = os.path.dirname(fmpy.__file__) + os.sep  # fmpy's own files: not any path naming fmpy
fmu = Harness(sys.argv[1], instance="x", initialize=False, **json.loads(sys.argv[2]))
vr = {n: v.valueReference for n, v in fmu.variables.items()}
kinds = {t: [v.valueReference for v in fmu.variables.values() if v.type == t]
         for t in ("Real", "Integer", "Boolean", "String")}
inputs = [v.valueReference for v in fmu.variables.values()
          if v.causality == "input" and v.type == "Real"]
entered = []


def profile(frame, event, arg):  # the FMU's Python entered from an FMI call (fmpy's)
    caller = frame.f_back  # (not the harness's own logger: with logging on, every debug
    # category is, and the plant's first step says how it steps)
    if (event == "call" and caller is not None and caller.f_code.co_filename.startswith(FMPY)
            and not frame.f_code.co_filename.startswith(FMPY)
            and "fmu_harness" not in frame.f_code.co_filename):
        entered.append(frame.f_code.co_name)


def calls(label, action):
    entered.clear()
    sys.setprofile(profile)
    try:
        action()
    finally:
        sys.setprofile(None)
    return {label: sorted(set(entered)) if entered else [], label + " calls": len(entered)}


s = fmu.slave
report = {}
s.setupExperiment(startTime=0.0)
s.enterInitializationMode()
report.update(calls("init first read", lambda: s.getReal(kinds["Real"])))
values = s.getReal(inputs)
report.update(calls("init write, read", lambda: (s.setReal(inputs, values),
                                                 s.getReal(kinds["Real"]))))
report.update(calls("init read again", lambda: s.getReal(kinds["Real"])))
s.exitInitializationMode()


def exchange(k):
    s.getReal(kinds["Real"])
    s.getInteger(kinds["Integer"])
    s.getBoolean(kinds["Boolean"])
    s.getString(kinds["String"])
    s.setReal(inputs, s.getReal(inputs))
    s.doStep(k * 0.01, 0.01)


report.update(calls("100 steps", lambda: [exchange(k) for k in range(100)]))
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_step_is_the_one_call_into_python(name, fmu_paths, run_python):
    """Through fmpy with a profiler on: 100 steps of getting every variable, setting the
    inputs and stepping enter the FMU's Python 100 times, in do_step; a read in
    initialisation mode after a write (entering it is one) enters it once, to compute the
    outputs to start from, and a second read not at all. fmpy's frames are told by fmpy's
    folder: a TMPDIR whose path named "fmpy" hid every frame of the extracted FMU."""
    done = run_python(CALLS_INTO_PYTHON, fmu_paths[name], "{}")
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["100 steps"] == ["do_step"] and report["100 steps calls"] == 100, report
    for first_read_after_a_write in ("init first read", "init write, read"):
        assert report[first_read_after_a_write] == ["_initial_outputs"], report
        assert report[first_read_after_a_write + " calls"] == 1, report
    assert report["init read again"] == [], report


NOT_FINITE = """
import json, os, shutil, sys
from fmpy import extract
from fmu_harness import Harness

os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
folder = extract(sys.argv[1])
for path in __import__("glob").glob(f"{folder}/resources/*/plant_fmu/model/vehicles/*.toml"):
    os.remove(path)  # no parameter set: the physical parameters read NaN
fmu = Harness(sys.argv[1], unzip_dir=folder, initialize=False)
try:
    fmu.get("m")
    status = 0
except Exception as exc:
    status = getattr(exc, "status", -1)
print(json.dumps({"status": status, "errors": fmu.messages(3)}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_real_that_is_not_finite_is_refused_when_read(runtime, fmu_paths, run_python):
    """A plant whose vehicle data is gone holds NaN for its physical parameters: reading
    one is fmi2Error with a line naming it, never a NaN handed on."""
    runtime_value = RUNTIMES[runtime].get("AUV_FMU_RUNTIME", "")
    done = run_python(NOT_FINITE, fmu_paths["AuvPlant"], runtime_value)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["status"] == 3, report
    assert "m = nan is not finite" in report["errors"], report


STRINGS_AND_TUNING = """
import ctypes, json, os, sys
from fmpy.fmi2 import fmi2String, fmi2ValueReference
from fmu_harness import Harness, status_of

os.environ["AUV_FMU_RUNTIME"] = sys.argv[3]
plant = Harness(sys.argv[1], initialize=False)
s = plant.slave
vehicle = plant.variables["vehicle"].valueReference
s.setupExperiment(startTime=0.0)
report = {"start": s.getString([vehicle])[0].decode()}
plant.set(vehicle="no_such_vehicle")  # before initialisation mode: read back as written
report["read back"] = s.getString([vehicle])[0].decode()
bad = (fmi2String * 1)(b"remus\\xff100")
refs = (fmi2ValueReference * 1)(vehicle)
report["not UTF-8"] = status_of(s.fmi2SetString, s.component, refs, 1, bad)
report["after"] = s.getString([vehicle])[0].decode()
s.enterInitializationMode()
report["exit"] = status_of(s.exitInitializationMode)
report["plant errors"] = plant.messages(3)

autopilot = Harness(sys.argv[2], instance="autopilot", heading_mode=0, yaw_setpoint=0.5)
forces = []
for k in range(4):
    if k == 2:  # tunable: takes effect at the next step
        autopilot.set(heading_mode=3)
    autopilot.step(0.01)
    forces.append(autopilot.get("mass_position_cmd")[0])
report["mass commands"] = forces
report["autopilot errors"] = autopilot.messages(3)
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_strings_and_tunable_parameters_written_in_c_reach_the_slave(
    runtime, fmu_paths, run_python
):
    """A String written in initialisation mode reads back at once and reaches the slave
    (initialisation fails naming it); one that is not UTF-8 is refused at the call,
    changing nothing. A tunable parameter written between steps takes effect at the next."""
    runtime_value = RUNTIMES[runtime].get("AUV_FMU_RUNTIME", "")
    done = run_python(
        STRINGS_AND_TUNING, fmu_paths["AuvPlant"], fmu_paths["AuvAutopilot"], runtime_value
    )
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["start"] == "remus100"
    assert report["read back"] == report["after"] == "no_such_vehicle"
    assert report["not UTF-8"] == 3
    assert report["exit"] == 3 and "no_such_vehicle" in report["plant errors"]
    commands = report["mass commands"]
    assert commands[:2] == [0.0, 0.0] and commands[2] != 0.0, report  # backstepping from 3rd
    assert report["autopilot errors"] == ""
