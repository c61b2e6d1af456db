"""Every built-in scenario gives byte-identical results.csv with the FMUs' runtime (values
in C, one call into Python a step) and with pythonfmu's own binary
(``AUV_FMU_RUNTIME=pythonfmu``, every value through Python): the whole set once each way,
each way in a process of its own, as ``auv-cosim run <id> --no-rrd`` writes them."""

from __future__ import annotations

import hashlib
import json

import pytest

from cosim.scenario.spec import builtin_scenarios

RUN_ALL = """
import hashlib, json, os, sys
from pathlib import Path

os.environ["AUV_FMU_RUNTIME"] = sys.argv[2]
import cosim

digests = {}
for scenario in json.loads(sys.argv[3]):
    out = Path(sys.argv[4]) / scenario
    cosim.run(scenario, out=out, recording=False, fmu_dir=sys.argv[1])
    digests[scenario] = hashlib.sha256((out / "results.csv").read_bytes()).hexdigest()
print(json.dumps(digests))
"""


@pytest.mark.slow
def test_every_scenario_gives_the_same_bytes_in_both_runtimes(fmu_paths, run_python, tmp_path):
    scenarios = sorted(builtin_scenarios())
    assert len(scenarios) >= 18
    fmu_dir = fmu_paths["AuvPlant"].parent
    digests = {}
    for runtime in ("", "pythonfmu"):
        done = run_python(
            RUN_ALL, fmu_dir, runtime, json.dumps(scenarios), tmp_path / (runtime or "runtime"),
            timeout=1800,
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-3000:]
        digests[runtime] = json.loads(done.stdout.strip().splitlines()[-1])
    different = [s for s in scenarios if digests[""][s] != digests["pythonfmu"][s]]
    assert different == [], different
    empty = hashlib.sha256(b"").hexdigest()
    assert empty not in digests[""].values()
