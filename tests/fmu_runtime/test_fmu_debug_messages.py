"""Our FMUs' own debug messages, in both runtimes: with debug logging on for one of the
categories they declare, the plant says when its RK4 sub-step count changes and the
autopilot when a command reaches or leaves its limit, each as an fmi2OK message of that
category; with it off, or on for other categories, nothing of theirs reaches the host.
(They logged no debug message at all: a user turning debug logging on saw nothing more.)"""

from __future__ import annotations

import json

import pytest

RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}

DEBUG = """
import json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmpy.fmi2 import fmi2String
from fmu_harness import Harness, status_of

kind, fmu = sys.argv[3], sys.argv[1]
report = {}
for asked in (["CATEGORY"], ["logStatusError"], None):
    h = Harness(fmu, instance=kind, initialize=False)
    s = h.slave
    names = asked or []
    array = (fmi2String * len(names))(*[n.encode() for n in names])
    status = status_of(s.fmi2SetDebugLogging, s.component, asked is not None, len(names), array)
    h.log.clear()
    h.initialize(**START)
    for step in STEPS:
        assert h.step(step) == 0, h.messages()
    own = [(st, text) for st, text in h.log if st == 0 and not text.startswith("the FMU runs")]
    report[str(asked)] = [status, own]
    h.close()
print(json.dumps(report))
"""

CASES = {
    # 1 sub-step of 0.01 s, then 5 of 0.01 s, then 1 again
    "plant": ("AuvPlant", "logPlantSteps", {}, (0.01, 0.05, 0.01), ["5 RK4 sub-steps"]),
    # the LQR with a heading error of 1.5 rad: the moving mass's command at its limit
    "controller": (
        "AuvAutopilot",
        "logAutopilotLimits",
        {"heading_mode": 1, "u_rel": 1.5, "yaw_setpoint": 1.5},
        (0.01, 0.01),
        ["mass_position_cmd reached its limit"],
    ),
}


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
@pytest.mark.parametrize("instance", sorted(CASES))
def test_debug_messages_of_a_category_reach_the_host_only_when_asked_for(
    runtime, instance, fmu_paths, run_python
):
    fmu, category, start, steps, expected = CASES[instance]
    code = DEBUG.replace("CATEGORY", category)
    code = code.replace("START", repr(start)).replace("STEPS", repr(steps))
    done = run_python(code, fmu_paths[fmu], RUNTIMES[runtime], instance)
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    status, own = report[str([category])]
    assert status == 0, own
    texts = [text for _, text in own]
    for wanted in expected:
        assert any(wanted in text for text in texts), texts
    for other in (str(["logStatusError"]), "None"):  # other categories, or off: none
        assert report[other] == [0, []], report[other]
