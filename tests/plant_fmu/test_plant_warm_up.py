"""The plant and the backstepping law compile (or load) their numba code during
initialisation, so a first run's stepping loop is not charged with the compilation."""

from __future__ import annotations

import pytest

CHECK = """
import sys
from fmu_harness import Harness
h = Harness(sys.argv[1], "plant")
compiled = [m for n, m in sys.modules.items() if n.endswith("plant_fmu.model.compiled")]
print("plant", [bool(m.advance_into.signatures) for m in compiled])
h.close()
"""


@pytest.mark.slow
def test_plant_initialisation_compiles_the_step(fmu_paths, run_python) -> None:
    done = run_python(CHECK, fmu_paths["AuvPlant"])
    assert done.returncode == 0, done.stderr[-2000:]
    assert "plant [True]" in done.stdout, done.stdout


def test_backstepping_law_is_compiled_when_made() -> None:
    from controller_fmu import compiled_backstepping as fast
    from controller_fmu.autopilot import Autopilot, AutopilotConfig
    from plant_fmu.model import compiled

    if not compiled.AVAILABLE:
        pytest.skip(f"numba is off: {compiled.NO_JIT_REASON}")
    Autopilot(AutopilotConfig(heading_mode=3))
    assert fast.command.signatures  # compiled before any sample was asked for
