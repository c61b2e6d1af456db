"""A study worker's warm-up (the study plugin's set-up) leaves the FMUs' libraries loaded
and idle for the first task, and their plant code compiled; it never raises."""

from __future__ import annotations

import pytest

WARM = """
import sys
from pathlib import Path
from cosim.engine import slave
from cosim.study.task import prepare, warm_up

base, _ = prepare("bs-3", 20.0, Path(sys.argv[1]))
warm_up(base, base.fmu_paths)
idle = sorted(key[1] for key, objects in slave._idle_libraries.items() if objects)
compiled = [m for n, m in sys.modules.items() if n.endswith("plant_fmu.model.compiled")]
print(idle, [bool(m.advance_into.signatures) for m in compiled])
broken = base.__class__(base.scenario_id, {**base.data, "stop_time": -1.0}, base.fmu_paths)
warm_up(broken, base.fmu_paths)  # a scenario that cannot run: no exception
print("survived")
"""


@pytest.mark.slow
def test_warm_up_loads_the_libraries_and_compiles_the_plant(fmu_paths, run_python) -> None:
    done = run_python(WARM, fmu_paths["AuvPlant"].parent)
    assert done.returncode == 0, done.stderr[-2000:]
    first, last = done.stdout.strip().splitlines()[-2:]
    assert first == "['AuvAutopilot', 'AuvPlant'] [True]", done.stdout
    assert last == "survived"
