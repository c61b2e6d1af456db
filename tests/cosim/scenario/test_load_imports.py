"""Loading a scenario checks its values without the controllers' code: the autopilot's
start values are checked with its parameters' own module, not with the autopilot, whose
import brings numba and the compiled controllers (~0.3 s of CPU) to every run's and
every study client's start."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

PROBE = """
import json, sys
from pathlib import Path
from cosim.scenario.spec import load_scenario
load_scenario("bs-3", fmu_dir=Path(sys.argv[1]))
heavy = ("numba", "scipy", "controller_fmu.autopilot", "plant_fmu.model.compiled")
print(json.dumps([name for name in heavy if name in sys.modules]))
"""


@pytest.mark.fmu
def test_loading_a_scenario_imports_no_controller_and_no_compiled_code(
    fmu_paths: dict[str, Path],
) -> None:
    fmu_dir = fmu_paths["AuvPlant"].parent
    done = subprocess.run(
        [sys.executable, "-c", PROBE, str(fmu_dir)], capture_output=True, text=True, timeout=120
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout) == []
