"""The compiled plant (plant_fmu.model.compiled) against the numpy reference.

Both do the same arithmetic; only the rounding of the matrix products differs (numpy hands
them to BLAS), so whole closed-loop runs agree to 1e-12. The FMU-level agreement, with the
compiled path on and off (AUV_COSIM_NO_JIT=1), is in tests/plant_fmu/test_plant_jit_off.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from cosim.analysis.closed_loop import simulate_closed_loop
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import N_STATES, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance, stepping_state

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)

# The built-in scenarios bs-3, vert-2 and cur-2, in process (their TOML's values).
SCENARIOS = {
    "bs-3": (Variant.LATERAL, {"u": 1.5, "v": -0.1}, {}, {"heading_mode": 3, "depth_mode": 0}),
    "vert-2": (
        Variant.FULL,
        {"u": 1.5, "v": 0.1},
        {},
        {"heading_mode": 3, "depth_mode": 1, "mass_lock_time": 15.0},
    ),
    "cur-2": (
        Variant.LATERAL,
        {"u": 1.5},
        {"current_east": 0.2},
        {"heading_mode": 3, "depth_mode": 0, "k0": 0.3, "k1": 0.8, "compensate_current": False},
    ),
}
SETPOINTS = {"bs-3": (0.0, 0.0), "vert-2": (0.0, 1.0), "cur-2": (-0.13177042745465108, 0.0)}


def _state(values: dict[str, float]) -> np.ndarray:
    x = np.zeros(N_STATES)
    for name, value in values.items():
        x[STATE_INDEX[name]] = value
    return x


@pytest.mark.slow
@pytest.mark.parametrize("scenario", sorted(SCENARIOS))
def test_closed_loop_runs_agree_with_the_reference(scenario):
    variant, x0, current, gains = SCENARIOS[scenario]
    yaw, depth = SETPOINTS[scenario]
    model = PlantModel(load_vehicle("remus100"), variant=variant)
    runs = [
        simulate_closed_loop(
            Autopilot(AutopilotConfig.build(**gains)),
            model,
            _state(x0),
            60.0,
            0.01,
            current=current,
            yaw_setpoint=yaw,
            depth_setpoint=depth,
            compiled=fast,
        )
        for fast in (None, compiled.CompiledPlant(model))
    ]
    assert np.abs(runs[0].states).max() > 0.1  # the vehicle moved
    np.testing.assert_allclose(runs[1].states, runs[0].states, rtol=0.0, atol=1e-12)
    np.testing.assert_allclose(runs[1].commands, runs[0].commands, rtol=0.0, atol=1e-12)


@pytest.mark.slow
@pytest.mark.parametrize(
    "options",
    [
        {"variant": Variant.FULL},
        {"variant": Variant.LATERAL},
        {"variant": Variant.HORIZONTAL},
        {"variant": Variant.FULL, "current_shear": 0.05},
        {"variant": Variant.LATERAL, "current_shear": 0.05},
        {"variant": Variant.HORIZONTAL, "current_shear": -0.05},
        {"variant": Variant.FULL, "ideal_fluid": True},
        {"variant": Variant.FULL, "servo_reaction": False},
        {"variant": Variant.LATERAL, "servo_reaction": False},
    ],
)
def test_every_option_agrees_from_random_states(options):
    model = PlantModel(load_vehicle("remus100"), **options)
    fast = compiled.CompiledPlant(model)
    rng = np.random.default_rng(15)
    for _ in range(20):
        x = model.project(rng.normal(scale=0.3, size=N_STATES))
        inputs = np.array([9.0, 0.1, 1.0, 0.05, 0.02, *rng.normal(scale=0.3, size=3)])
        np.testing.assert_allclose(
            fast.derivative(x, inputs), model.derivative(x, inputs), rtol=1e-13, atol=1e-13
        )
        z = stepping_state(x)
        for quaternion in (False, True) if model.variant is Variant.FULL else (False,):
            np.testing.assert_allclose(
                fast.step_derivative(z, inputs, quaternion),
                model.step_derivative(z, inputs, quaternion),
                rtol=1e-13,
                atol=1e-13,
            )
        nu_r = model.relative_velocity(z, inputs)
        expected = [*nu_r[:3], model.kinetic_energy(z, inputs)]
        np.testing.assert_allclose(fast.outputs(z, inputs), expected, rtol=1e-14, atol=1e-14)
        # stepping into the stops with the mass fast: the impact path of project
        x[STATE_INDEX["mass_position"]], x[STATE_INDEX["mass_velocity"]] = 0.0199, 0.5
        inputs[4] = 0.05
        reference, stepped = x, x
        for _ in range(50):
            reference = advance(model, reference, inputs, 0.01)
            stepped = advance(model, stepped, inputs, 0.01, compiled=fast)
        np.testing.assert_allclose(stepped, reference, rtol=0.0, atol=1e-12)


def test_two_body_model_has_no_compiled_path():
    model = PlantModel(load_vehicle("remus100"), moving_mass_model=1)
    assert "moving_mass_model = 1" in compiled.supports(model)
    with pytest.raises(ValueError, match="moving_mass_model = 1"):
        compiled.CompiledPlant(model)


def test_non_finite_input_and_state_are_named():
    model = PlantModel(load_vehicle("remus100"))
    fast = compiled.CompiledPlant(model)
    inputs = np.array([9.0, 0, 0, 0, 0, 0, 0, np.nan])
    with pytest.raises(ValueError, match=r"input current_down = .*nan"):
        advance(model, np.zeros(N_STATES), inputs, 0.01, compiled=fast)
    x = np.zeros(N_STATES)
    x[STATE_INDEX["q"]] = np.inf
    with pytest.raises(ValueError, match=r"state q = .*inf"):
        advance(model, x, np.zeros(8), 0.01, compiled=fast)
