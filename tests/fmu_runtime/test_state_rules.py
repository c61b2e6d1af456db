"""FMU states and the variables' rules, from a host's side, in both runtimes: a state set
gives the fixed parameters their values in it (a write of that value is taken, another
refused, as FMI 2.0 has for a fixed parameter after initialisation); a state another FMU
took is refused with nothing changed; a String parameter written again with the value it
has is taken as the other types are; a call's status stays its own when the host's
logger calls the FMU back meanwhile; a state the other runtime took or serialised, and
bytes whose slave part is unreadable, are refused with fmi2Error."""

from __future__ import annotations

import json

import pytest

RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}

STATES = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[3]
from fmu_harness import Harness, status_of

report = {}
heavy = Harness(sys.argv[1], instance="heavy", m=40.0)  # a fixed parameter, then a state
state = heavy.slave.getFMUState()
serialised = heavy.slave.serializeFMUState(state)
m = heavy.variables["m"].valueReference
for how in ("set", "deserialised"):
    plant = Harness(sys.argv[1], instance=how)  # m = its start value, 30.5 kg
    given = state if how == "set" else plant.slave.deserializeFMUState(serialised)
    plant.slave.setFMUState(given)
    report[how] = {
        "m": plant.slave.getReal([m])[0],
        "write of the state's m": status_of(plant.slave.setReal, [m], [40.0]),
        "write of the start value": status_of(plant.slave.setReal, [m], [30.5]),
        "m after": plant.slave.getReal([m])[0],
    }

autopilot = Harness(sys.argv[2], instance="autopilot")
plant = Harness(sys.argv[1], instance="plant")  # last: fmpy's logger proxy is one per process
reals = [v.valueReference for v in plant.variables.values() if v.type == "Real"]
plant.step(0.01)
before = plant.slave.getReal(reals)
foreign = autopilot.slave.getFMUState()
report["foreign state"] = status_of(plant.slave.setFMUState, foreign)
report["unchanged"] = plant.slave.getReal(reals) == before
report["step after"] = plant.step(0.01)
report["errors"] = plant.messages(3)

vehicle = plant.variables["vehicle"].valueReference
report["vehicle again"] = status_of(plant.slave.setString, [vehicle], ["remus100"])
report["another vehicle"] = status_of(plant.slave.setString, [vehicle], ["other"])
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_states_set_fixed_parameters_and_a_foreign_state_changes_nothing(
    runtime, fmu_paths, run_python
):
    """After a state with m = 40 kg was set on a plant started with 30.5 kg, writing 30.5
    was taken (and read back, while the dynamics used 40) and writing 40 refused; a
    state of the autopilot set on the plant changed its values before being refused."""
    done = run_python(STATES, fmu_paths["AuvPlant"], fmu_paths["AuvAutopilot"], RUNTIMES[runtime])
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    for how in ("set", "deserialised"):
        assert report[how] == {
            "m": 40.0, "write of the state's m": 0, "write of the start value": 3, "m after": 40.0
        }, how  # fmt: skip
    assert report["foreign state"] == 3 and report["unchanged"], report
    assert report["step after"] == 0
    assert "not an FMU state of this FMU" in report["errors"], report["errors"]
    assert report["vehicle again"] == 0 and report["another vehicle"] == 3


REENTRANT = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmpy.fmi2 import fmi2LastSuccessfulTime
from fmu_harness import Harness, status_of


class CallingBack(Harness):
    def _on_log(self, component, instance, status, category, message):
        super()._on_log(component, instance, status, category, message)
        self.slave.getRealStatus(fmi2LastSuccessfulTime)  # a host asking meanwhile


guidance = CallingBack(sys.argv[1], instance="guidance", initialize=False)
guidance.slave.setupExperiment(startTime=0.0)
guidance.slave.enterInitializationMode()
guidance.set(waypoints="garbage")
exit_status = status_of(guidance.slave.exitInitializationMode)
print(json.dumps({"exit": exit_status, "errors": guidance.messages(3)}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_failed_call_returns_error_when_the_hosts_logger_calls_the_fmu_back(
    runtime, fmu_paths, run_python
):
    """A logger calling fmi2GetRealStatus while the FMU logged its Error made the failed
    fmi2ExitInitializationMode return fmi2OK."""
    done = run_python(REENTRANT, fmu_paths["AuvGuidance"], RUNTIMES[runtime])
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["exit"] == 3, report
    assert "waypoint" in report["errors"], report


FOREIGN_BYTES = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[3]
from fmu_harness import Harness, status_of

autopilot = Harness(sys.argv[2], instance="autopilot")
serialised = autopilot.slave.serializeFMUState(autopilot.slave.getFMUState())
plant = Harness(sys.argv[1], instance="plant")  # last: fmpy's logger proxy is one per process
status = status_of(plant.slave.deserializeFMUState, serialised)
own = plant.slave.serializeFMUState(plant.slave.getFMUState())
report = {"foreign": status, "own": status_of(plant.slave.deserializeFMUState, own),
          "errors": plant.messages(3)}
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_another_fmus_serialised_state_is_refused_at_deserialisation(
    runtime, fmu_paths, run_python
):
    """The autopilot's serialised state, intact, deserialised by the plant with pythonfmu's
    binary answered fmi2OK (only its layout, checked by the runtime's own slave, told the
    FMUs apart): refused now in both runtimes, naming why, while the plant's own bytes
    still deserialise."""
    done = run_python(
        FOREIGN_BYTES, fmu_paths["AuvPlant"], fmu_paths["AuvAutopilot"], RUNTIMES[runtime]
    )
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert (report["foreign"], report["own"]) == (3, 0), report
    assert "fmi2DeSerializeFMUstate refused" in report["errors"], report["errors"]


OTHER_RUNTIME = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmu_harness import Harness, status_of

taker = Harness(sys.argv[1], instance="taker")
taker.step(0.01)
state = taker.slave.getFMUState()
serialised = taker.slave.serializeFMUState(state)
os.environ["AUV_FMU_RUNTIME"] = sys.argv[3]  # read as each instance is instantiated
plant = Harness(sys.argv[1], instance="plant")  # last: fmpy's logger proxy is one per process
reals = [v.valueReference for v in plant.variables.values() if v.type == "Real"]
before = plant.slave.getReal(reals)
report = {
    "set": status_of(plant.slave.setFMUState, state),
    "free": status_of(plant.slave.freeFMUState, state),
    "deserialise": status_of(plant.slave.deserializeFMUState, serialised),
    "unchanged": plant.slave.getReal(reals) == before,
    "step after": plant.step(0.01),
    "errors": plant.messages(3),
    "own": status_of(taker.slave.deserializeFMUState, serialised),
}
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("taken_in", sorted(RUNTIMES))
def test_a_state_of_the_other_runtime_is_refused_in_memory_and_serialised(
    taken_in, fmu_paths, run_python
):
    """Two instances of one FMU in one process, one on each runtime (AUV_FMU_RUNTIME changed
    between their instantiations): a state the FMU's runtime took, set into the instance on
    pythonfmu's, crashed the host (SIGSEGV), and the other way round its memory was read as
    the other runtime's; serialised, the bytes were taken by pythonfmu's runtime (fmi2OK,
    then refused at fmi2SetFMUstate as "changed, cut or extended") and refused by the
    FMU's as "an FMU with other variables". Each is now refused with fmi2Error naming the
    runtimes, the instance unchanged and stepping on, while the bytes still deserialise in
    the runtime that wrote them."""
    other = next(name for name in RUNTIMES if name != taken_in)
    done = run_python(
        OTHER_RUNTIME, fmu_paths["AuvPlant"], RUNTIMES[taken_in], RUNTIMES[other], timeout=180
    )
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    statuses = [report[k] for k in ("set", "free", "deserialise", "step after", "own")]
    assert statuses == [3, 3, 3, 0, 0], report
    assert report["unchanged"], report
    assert report["errors"].count(RUNTIME_NAMES[taken_in]) == 3, report["errors"]


RUNTIME_NAMES = {"runtime": "the FMU's runtime", "pythonfmu": "pythonfmu's runtime"}


UNREADABLE_PART = """
import json, struct, sys, zlib
from fmu_harness import Harness, status_of

plant = Harness(sys.argv[1], instance="plant")
good = bytes(plant.slave.serializeFMUState(plant.slave.getFMUState()))
mark = good.rfind(b"\\ncrc32=")  # the slave's part: its JSON, then the JSON's CRC-32
forged = bytearray(good[: mark - 8] + b"not json" + good[mark:])
header = 4 + 4 + 8 + 4 + 4  # the runtime's: magic, phase, time, FMU, then its CRC-32
crc = zlib.crc32(bytes(forged[: header - 4] + forged[header:]))
forged[header - 4 : header] = struct.pack("=I", crc)  # as if the runtime had written it
report = {
    "forged": status_of(plant.slave.deserializeFMUState, bytes(forged)),
    "errors": plant.messages(3),
    "own": status_of(plant.slave.deserializeFMUState, good),
}
print(json.dumps(report))
"""


@pytest.mark.slow
def test_bytes_whose_slave_part_is_unreadable_are_refused_at_deserialisation(fmu_paths, run_python):
    """Bytes the runtime's own check passes (its CRC-32 right) whose slave part the slave
    cannot read were deserialised with fmi2OK, the state refused only when set; the
    runtime now refuses them at fmi2DeSerializeFMUstate with the slave's reason."""
    done = run_python(UNREADABLE_PART, fmu_paths["AuvPlant"], timeout=180)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert (report["forged"], report["own"]) == (3, 0), report
    assert "fmi2DeSerializeFMUstate refused: cannot deserialise" in report["errors"], report


REUSED = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmu_harness import Harness, status_of

plant = Harness(sys.argv[1], instance="plant")
u = plant.variables["u"].valueReference
serialised = plant.slave.serializeFMUState(plant.slave.getFMUState())
expected = plant.slave.getReal([u])[0]
state = plant.slave.deSerializeFMUstate(serialised)
first = state.value
for _ in range(3):  # fmpy's "previous FMU state for re-use"
    state = plant.slave.deSerializeFMUstate(serialised, state)
plant.step(0.1)
report = {
    "same state": state.value == first,
    "set": status_of(plant.slave.setFMUState, state),
    "u": plant.slave.getReal([u])[0] == expected,
    "free": status_of(plant.slave.freeFMUState, state),
}
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_state_deserialised_into_a_state_alive_reuses_it(runtime, fmu_paths, run_python):
    """fmpy's ``deSerializeFMUstate(bytes, state)`` hands the FMU a state of its own to
    re-use, as the Reference FMUs do. Each call made a new state and left the one handed
    in alive, unreachable, until fmi2FreeInstance: 20,000 such calls on the guidance grew
    the process by 51 MB. Now the state handed in holds the bytes' state, set with fmi2OK
    and freed once."""
    done = run_python(REUSED, fmu_paths["AuvPlant"], RUNTIMES[runtime])
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report == {"same state": True, "set": 0, "u": True, "free": 0}, report
