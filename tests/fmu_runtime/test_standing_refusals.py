"""A refused input value stands (each doStep is discarded naming it) until a valid value
is written, a reset or a state set: the same in both runtimes, as docs/hosts.md says, and
on the instance it was written to only."""

from __future__ import annotations

import json

import pytest
from fmpy import read_model_description

RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}

STANDING = """
import json, math, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmu_harness import Harness, status_of

report = {}
refused = Harness(sys.argv[1], instance="refused")
other = Harness(sys.argv[1], instance="other")
thrust = refused.variables["thrust"].valueReference
refused.step(0.01)
report["bad write"] = status_of(refused.slave.setReal, [thrust], [math.nan])
report["other steps"] = other.step(0.01)
report["standing"] = refused.step(0.01)
during, at = refused.slave.getFMUState(), refused.time  # while the refusal stands
report["good write"] = status_of(refused.slave.setReal, [thrust], [9.0])
report["after the good write"] = refused.step(0.01)
report["bad again"] = status_of(refused.slave.setReal, [thrust], [math.nan])
refused.slave.setFMUState(during)
report["after the state set"] = refused.step(0.01, at=at)
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_state_set_ends_a_standing_refusal_in_both_runtimes(runtime, fmu_paths, run_python):
    """Guards pythonfmu's runtime restoring, with a state taken while a refusal stood, the
    refusal itself (every later doStep discarded), where our runtime's state set ends it
    (the state's values are the valid ones the refused write left in place)."""
    done = run_python(STANDING, fmu_paths["AuvPlant"], RUNTIMES[runtime])
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report == {
        "bad write": 3, "other steps": 0, "standing": 2, "good write": 0,
        "after the good write": 0, "bad again": 3, "after the state set": 0,
    }, report  # fmt: skip


FIXED_BEFORE_INITIALISATION = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmu_harness import Harness, status_of

fmu = Harness(sys.argv[1], instance="guidance", initialize=False)
lookahead = fmu.variables["lookahead"].valueReference
report = {"bad write": status_of(fmu.slave.setReal, [lookahead], [-1.0])}
fmu.slave.setupExperiment(startTime=0.0)
report["enter"] = status_of(fmu.slave.enterInitializationMode)
report["exit"] = status_of(fmu.slave.exitInitializationMode)
report["lookahead"] = fmu.slave.getReal([lookahead])[0]
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_a_refused_fixed_parameter_leaves_its_start_in_both_runtimes(
    runtime, fmu_paths, run_python
):
    """Guards the two runtimes agreeing on a fixed parameter's refused write before
    initialisation (FMI 2.0: a refused fmi2Set changes nothing): the variable keeps its
    start value, and initialisation goes on from it, in each."""
    done = run_python(FIXED_BEFORE_INITIALISATION, fmu_paths["AuvGuidance"], RUNTIMES[runtime])
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    declared = read_model_description(str(fmu_paths["AuvGuidance"])).modelVariables
    start = float(next(v.start for v in declared if v.name == "lookahead"))
    assert report == {"bad write": 3, "enter": 0, "exit": 0, "lookahead": start}, report
