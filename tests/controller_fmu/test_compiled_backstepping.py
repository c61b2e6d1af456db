"""The compiled backstepping law (controller_fmu.compiled_backstepping) against the Python
reference (BacksteppingHeading.command on the numpy plant): the same measurement sequence,
taken from closed-loop runs, gives the same commands, error coordinates and filter state
to 1e-12 (they differ only in the rounding of the plant derivative's matrix products)."""

from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from controller_fmu.backstepping import BacksteppingGains, BacksteppingHeading
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.setpoint_shaping import wrap_angle
from cosim.analysis.closed_loop import simulate_closed_loop
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import state_vector
from plant_fmu.model.parameters import load_vehicle

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)

H = 0.01
MEASURED = ("v", "r", "p", "roll", "yaw", "mass_position")
# bs-3 (Sec. 6.3.3 gains, U0 = 1.525 m/s) and slow-1 (k0 = 0.3, k1 = 0.8, U0 = 1.017 m/s)
CASES = {
    "bs-3": ({"u": 1.5, "v": -0.1}, {}, 1.525),
    "slow-1": ({"u": 1.0, "v": 0.1}, {"k0": 0.3, "k1": 0.8, "thrust_command": 4.0}, 1.017),
}


def _controller(speed: float, gains: BacksteppingGains, use_compiled: bool) -> BacksteppingHeading:
    design = LateralDesignModel(load_vehicle("remus100"), speed, use_compiled=use_compiled)
    return BacksteppingHeading(design, gains)


@pytest.mark.parametrize("case", sorted(CASES))
def test_compiled_law_agrees_with_the_reference_over_a_closed_loop_run(case):
    x0, config, speed = CASES[case]
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3, design_speed=speed, **config))
    model = PlantModel(load_vehicle("remus100"), variant=Variant.LATERAL)
    run = simulate_closed_loop(autopilot, model, state_vector(x0), 30.0, H)
    gains = autopilot.backstepping.gains
    reference, fast = _controller(speed, gains, False), _controller(speed, gains, True)
    assert reference.design.compiled_plant is None and fast.design.compiled_plant is not None
    worst = 0.0
    for k, x in enumerate(run.states[:-1]):
        v, r, p, phi, yaw, y_v = (float(x[STATE_INDEX[n]]) for n in MEASURED)
        ref = reference.command(k * H, v, r, p, phi, wrap_angle(yaw), y_v)
        out = fast._compiled(k * H, v, r, p, phi, wrap_angle(yaw), y_v)
        assert out[0] == 0.0  # no transition pending after the call
        expected = (ref.mass_position, ref.tunnel_force, *ref.errors[1:])
        np.testing.assert_allclose(out[1:], expected, rtol=1e-12, atol=1e-12)
        worst = max(worst, float(np.max(np.abs(np.subtract(out[1:], expected)))))
    np.testing.assert_allclose(fast._state, reference._state, rtol=1e-12, atol=1e-12)
    assert 0.0 <= worst < 1e-12
    # the run moved the mass and fired the thruster: the comparison covered a real transient
    assert np.ptp(run.commands[:, 0]) > 0.01 and np.ptp(run.commands[:, 1]) > 0.1


def test_compiled_law_snapshot_restore_and_reset_share_the_reference_state():
    gains = BacksteppingGains()
    fast = _controller(1.525, gains, True)
    for k in range(5):
        fast.command_values(k * H, 0.1, 0.05, 0.01, 0.02, 0.3, 0.01)
    saved = fast.snapshot()
    assert saved.last_time == pytest.approx(4 * H)
    after = [fast.command_values((5 + k) * H, 0.1, 0.05, 0.01, 0.02, 0.3, 0.01) for k in range(3)]
    fast.restore(saved)
    assert [fast.command_values((5 + k) * H, 0.1, 0.05, 0.01, 0.02, 0.3, 0.01)
            for k in range(3)] == after  # fmt: skip
    fast.reset()
    assert fast.snapshot().last_time is None and not fast._state.any()
