"""fmi2SetDebugLogging as FMI 2.0 (section 2.1.5) has it, in both runtimes: the categories
a host names are checked against the FMU's LogCategories (an unknown or NULL one refused
with fmi2Error, as the Reference FMUs do; it returned fmi2OK and did nothing), and the
FMU's Errors reach the host whatever debug logging is set to."""

from __future__ import annotations

import json

import pytest

RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}

CATEGORIES = """
import ctypes, json, os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
from fmpy.fmi2 import fmi2String
from fmu_harness import Harness, status_of

plant = Harness(sys.argv[1], instance="plant", initialize=False)
s = plant.slave


def debug(on, names):
    array = (fmi2String * len(names))(*[n if n is None else n.encode() for n in names])
    return status_of(s.fmi2SetDebugLogging, s.component, on, len(names), array)


report = {
    "declared": debug(1, ["logStatusError", "logAll"]),
    "none": debug(1, []),
    "unknown": debug(1, ["logEvents"]),
    "null": debug(1, [None]),
    "off": debug(0, []),
}
s.setupExperiment(startTime=0.0)
s.enterInitializationMode()
status_of(plant.set, variant=7)  # refused: outside its declared range, an Error logged
report["errors"] = plant.messages(3)
print(json.dumps(report))
"""


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_log_categories_are_checked_and_errors_always_reach_the_host(
    runtime, fmu_paths, run_python
):
    done = run_python(CATEGORIES, fmu_paths["AuvPlant"], RUNTIMES[runtime])
    assert done.returncode == 0, done.stderr[-3000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert (report["declared"], report["none"], report["off"]) == (0, 0, 0), report
    assert (report["unknown"], report["null"]) == (3, 3), report
    assert (
        "logEvents is not a log category of this FMU (expected one of logStatus"
        in (report["errors"])
    )
    assert "category 0 is NULL" in report["errors"]
    assert "variant = 7 refused" in report["errors"], report["errors"]
