"""Galilean invariance: in a steady, uniform current every variant, with either model of
the moving mass, moves relative to the water exactly as it moves in still water, and is
carried along by V_c t."""

import numpy as np
import pytest

from plant_fmu.model.dynamics import STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.moving_mass import MovingMassModel
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance, simulate

NU = slice(6, 12)
ATTITUDE_AND_MASS = [3, 4, 5, 12, 13]
CURRENT = np.array([0.1, 0.2, 0.0])  # m/s, earth frame
DURATION, STEP = 30.0, 0.01
SUBSTEP = 0.005  # s: RK4 error of the over-ground integration (the full form's) < 1e-10


def _still_and_current_runs(
    variant: Variant, moving_mass_model: MovingMassModel
) -> tuple[PlantModel, np.ndarray, np.ndarray]:
    """The same relative start (rolled, yawed, sway-disturbed) in still water and in
    CURRENT, with thrust, tunnel force and a mass command acting."""
    model = PlantModel(load_vehicle(), variant, moving_mass_model=moving_mass_model)
    actuators = dict(thrust=9.0, tunnel_force=1.5, mass_position_cmd=0.02, fin_angle=0.05)
    still = input_vector(actuators)
    moving = input_vector({**actuators, "current_north": CURRENT[0], "current_east": CURRENT[1]})
    x0 = model.project(
        state_vector(
            dict(u=1.4, v=0.15, w=0.03, p=0.2, q=0.02, r=-0.1, roll=0.3, pitch=0.05, yaw=0.8)
        )
    )
    x0_current = x0.copy()  # over ground: the still-water velocity plus the current
    x0_current[NU] += x0[NU] - model.relative_velocity(x0, moving)
    _, in_still_water = simulate(model, x0, still, DURATION, STEP, SUBSTEP)
    _, in_current = simulate(model, x0_current, moving, DURATION, STEP, SUBSTEP)
    return model, in_still_water, in_current


@pytest.mark.slow
@pytest.mark.parametrize("moving_mass_model", list(MovingMassModel))
@pytest.mark.parametrize("variant", list(Variant))
def test_steady_uniform_current_only_carries_the_vehicle_along(variant, moving_mass_model):
    model, still, current = _still_and_current_runs(variant, moving_mass_model)
    moving = input_vector(dict(current_north=CURRENT[0], current_east=CURRENT[1]))
    relative = np.array([model.relative_velocity(x, moving) for x in current])
    np.testing.assert_allclose(relative, still[:, NU], rtol=0, atol=1e-9)
    np.testing.assert_allclose(
        current[:, ATTITUDE_AND_MASS], still[:, ATTITUDE_AND_MASS], rtol=0, atol=1e-9
    )
    times = np.arange(len(still))[:, None] * STEP
    np.testing.assert_allclose(current[:, :3] - still[:, :3], times * CURRENT, rtol=0, atol=1e-9)
    # the start really is rolled and the motion really couples the degrees of freedom
    assert np.ptp(still[:, STATE_INDEX["yaw"]]) > 0.1
    if variant is not Variant.HORIZONTAL:
        assert np.max(np.abs(still[:, STATE_INDEX["roll"]])) > 0.1


@pytest.mark.parametrize("moving_mass_model", list(MovingMassModel))
@pytest.mark.parametrize("variant", [Variant.LATERAL, Variant.HORIZONTAL])
def test_planar_relative_form_is_the_full_form_in_level_motion(variant, moving_mass_model):
    """Level, unrolled motion in a sheared current: the planar variants' relative form with
    the shear terms of (5.3.1) gives the full form's (3.4.20) rates, so the two ways of
    writing the current agree wherever both apply."""
    p = load_vehicle()
    level = p.replace(W=p.B, z_g=0.0)  # no roll-sway coupling in M_RB: the planes decouple
    options = dict(current_shear=0.05, moving_mass_model=moving_mass_model)
    full = PlantModel(level, Variant.FULL, **options)
    planar = PlantModel(level, variant, **options)
    x = state_vector(dict(east=3.0, yaw=0.7, u=1.3, v=0.12, r=-0.15, mass_velocity=0.1))
    inputs = input_vector(
        dict(
            thrust=9.0,
            tunnel_force=2.0,
            mass_position_cmd=0.03,
            current_north=0.1,
            current_east=-0.2,
        )
    )
    compared = [0, 1, 5, 6, 7, 11, 12, 13]  # north, east, yaw, u, v, r and the mass
    np.testing.assert_allclose(
        planar.derivative(x, inputs)[compared],
        full.derivative(x, inputs)[compared],
        rtol=1e-12,
        atol=1e-12,
    )
    assert abs(full.derivative(x, inputs)[7]) > 0.1  # sway really accelerates


def _stop_hitting_runs(moving_mass_model: MovingMassModel, duration: float):
    """Still water and CURRENT from the same relative start, with the mass command
    switching between +-10 cm every 1.5 s: the servo drives the mass into its 6 cm stops
    at up to 0.3 m/s, again and again. Returns (model, still, current) states."""
    model = PlantModel(load_vehicle(), Variant.FULL, moving_mass_model=moving_mass_model)
    moving = input_vector(dict(current_north=CURRENT[0], current_east=CURRENT[1]))
    x0 = model.project(
        state_vector(dict(u=1.4, v=0.15, w=0.03, p=0.2, q=0.02, r=-0.1, roll=0.3, yaw=0.8))
    )
    x0_current = x0.copy()
    x0_current[NU] += x0[NU] - model.relative_velocity(x0, moving)
    runs = []
    for x, current in ((x0, (0.0, 0.0)), (x0_current, CURRENT[:2])):
        states = [x]
        for k in range(round(duration / STEP)):
            command = 0.1 if int(k * STEP / 1.5) % 2 == 0 else -0.1
            inputs = input_vector(
                dict(
                    thrust=9.0,
                    mass_position_cmd=command,
                    current_north=current[0],
                    current_east=current[1],
                )
            )
            states.append(advance(model, states[-1], inputs, STEP, SUBSTEP))
        runs.append(np.array(states))
    return model, runs[0], runs[1]


def _invariance_error(moving_mass_model: MovingMassModel, duration: float) -> float:
    """The largest difference between the motion relative to the water in CURRENT and the
    motion in still water (velocities, attitude, mass, position minus V_c t)."""
    model, still, current = _stop_hitting_runs(moving_mass_model, duration)
    at_stop = np.abs(still[:, STATE_INDEX["mass_position"]]) == model.params.mass_stroke
    hits = np.count_nonzero(np.diff(at_stop.astype(int)) == 1)
    assert hits >= max(1, round(duration / 1.5))
    moving = input_vector(dict(current_north=CURRENT[0], current_east=CURRENT[1]))
    relative = np.array([model.relative_velocity(x, moving) for x in current])
    times = np.arange(len(still))[:, None] * STEP
    return max(
        np.max(np.abs(relative - still[:, NU])),
        np.max(np.abs(current[:, ATTITUDE_AND_MASS] - still[:, ATTITUDE_AND_MASS])),
        np.max(np.abs(current[:, :3] - still[:, :3] - times * CURRENT)),
    )


def test_a_two_body_stop_impact_is_galilean_invariant():
    """The stops' impacts are resolved at the stop, on the velocity change alone, so a
    current only carries the vehicle along through them (rounding: 1e-10)."""
    assert _invariance_error(MovingMassModel.TWO_BODY, 1.0) <= 1e-9


@pytest.mark.slow
def test_two_body_stop_impacts_are_as_galilean_invariant_as_the_static_mass():
    """Four impacts in 6 s: as invariant as the static mass (whose mass matrix does not
    depend on where the mass is, so its impacts never depended on the frame)."""
    static = _invariance_error(MovingMassModel.DISSERTATION, 6.0)
    two_body = _invariance_error(MovingMassModel.TWO_BODY, 6.0)
    assert two_body <= max(3.0 * static, 1e-9), (two_body, static)
