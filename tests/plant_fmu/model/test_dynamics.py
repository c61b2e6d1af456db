"""Physical invariants of the plant's equations of motion."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp

from plant_fmu.model.dynamics import (
    INPUT_NAMES,
    N_STATES,
    STATE_INDEX,
    PlantModel,
    Variant,
)
from plant_fmu.model.kinematics import euler_rate_matrix, rotation_matrix
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.moving_mass import servo_motion
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import MAX_SUBSTEPS, advance, simulate, substeps

NU = slice(6, 12)


def _balanced(name: str = "remus100"):
    """No net restoring force or moment: W = B, r_g = 0."""
    p = load_vehicle(name)
    return p.replace(W=p.B, z_g=0.0, x_g=0.0)


def _impulses(model: PlantModel, nu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Body-frame linear and angular impulse [p; pi] = (M_RB + M_A) nu (Thm 5.1)."""
    impulse = model.mass_matrix @ nu
    return impulse[:3], impulse[3:]


@pytest.mark.slow
def test_ideal_fluid_conserves_energy_and_both_casimirs():
    """Thm 5.1 / (5.1.12): in an ideal fluid with W = B and r_g = 0 the motion is Kirchhoff's:
    kinetic energy, |p|^2/2 and p.pi are constant, here over 60 s of tumbling. RK4 at
    2.5 ms keeps them to about 1e-11 (relative; 3e-13 at 1 ms, 5e-9 at 10 ms), far below
    the bound 1e-8 a broken invariant would exceed."""
    model = PlantModel(_balanced(), Variant.FULL, ideal_fluid=True)
    x0 = state_vector(dict(u=1.2, v=0.3, w=-0.2, p=0.8, q=0.5, r=-0.6, roll=0.3, pitch=0.2))
    _, states = simulate(model, x0, input_vector(), duration=60.0, h=0.05, max_substep=0.0025)
    energy = [model.kinetic_energy(x, input_vector()) for x in states]
    p_sq = [np.dot(*(2 * [_impulses(model, x[NU])[0]])) / 2 for x in states]
    p_pi = [np.dot(*_impulses(model, x[NU])) for x in states]
    assert np.ptp(states[:, STATE_INDEX["roll"]]) > 1.0  # it really tumbles
    for invariant in (energy, p_sq, p_pi):
        invariant = np.asarray(invariant)
        assert np.max(np.abs(invariant - invariant[0])) <= 1e-8 * abs(invariant[0])


_speeds = st.floats(-0.5, 0.5, allow_nan=False)


@pytest.mark.slow
@settings(max_examples=40, deadline=None)
@given(
    u=st.floats(0.05, 2.0),
    v=_speeds,
    w=_speeds,
    p=st.floats(-1.0, 1.0),
    q=_speeds,
    r=_speeds,
    roll=st.floats(-1.0, 1.0),
    pitch=st.floats(-0.5, 0.5),
)
def test_viscous_fluid_never_adds_kinetic_energy(u, v, w, p, q, r, roll, pitch):
    """Without forcing or restoring terms, viscous forces only dissipate: with our
    M_uq = N_ur the lift terms form negative-definite quadratic forms for u > 0."""
    model = PlantModel(_balanced(), Variant.FULL)
    x = state_vector(dict(u=u, v=v, w=w, p=p, q=q, r=r, roll=roll, pitch=pitch))
    zero = input_vector()
    energy = model.kinetic_energy(x, zero)
    for _ in range(100):
        x = advance(model, x, zero, 0.02)
        new = model.kinetic_energy(x, zero)
        assert new <= energy * (1 + 1e-12)
        energy = new


def test_printed_M_uq_would_let_the_fluid_add_energy():
    """Why remus100 uses M_uq = -6.40: with the printed +6.40 the heave-pitch lift form
    u [Z_uw w^2 + (Z_uq + M_uw) w q + M_uq q^2] is indefinite, so the power of the viscous
    forces in heave and pitch is positive for some states (surge drag aside)."""
    for name, sign in (("remus100", -1), ("remus100-printed", 1)):
        model = PlantModel(_balanced(name), Variant.FULL)
        x = state_vector(dict(u=1.5, q=0.02))  # small q: the quadratic lift term dominates
        nu = x[NU]
        heave_pitch_power = nu[[2, 4]] @ model.viscous(nu)[[2, 4]]
        assert np.sign(heave_pitch_power) == sign


def _fin_acceleration(derivative, model: PlantModel, u_r: float) -> np.ndarray:
    """What a 0.1 rad stern-plane angle adds to [w', q'] at the straight run u_r m/s
    (relative to still water; every other term cancels in the difference)."""
    x = state_vector({"u": u_r})
    with_fin = derivative(x, input_vector({"fin_angle": 0.1}))
    without = derivative(x, input_vector())
    return (with_fin - without)[[STATE_INDEX["w"], STATE_INDEX["q"]]]


@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_stern_planes_push_the_other_way_when_the_flow_comes_from_astern(path):
    """A fin is a thin plate: its lift is the normal force of the flow's component across
    it, -u_r sin(delta_s), so the flow meeting the plate from astern (u_r < 0) pushes it
    the other way, with the same magnitude (u_r |u_r|, not u_r^2). Ahead, a positive angle
    lifts the tail (Z < 0) and pitches the nose down (M_ds < 0); astern the same angle must
    push the tail down and the nose up."""
    from plant_fmu.model import compiled

    model = PlantModel(load_vehicle("remus100"), Variant.FULL)
    if path == "compiled":
        if not compiled.AVAILABLE:
            pytest.skip(compiled.NO_JIT_REASON)
        derivative = compiled.CompiledPlant(model).derivative
    else:
        derivative = model.derivative
    ahead = _fin_acceleration(derivative, model, 1.2)
    astern = _fin_acceleration(derivative, model, -1.2)
    assert ahead[1] < 0.0  # nose down ahead (M_ds < 0)
    np.testing.assert_allclose(astern, -ahead, rtol=1e-12, atol=0.0)


def _relative_form_derivative(model: PlantModel, x_rel: np.ndarray, inputs: np.ndarray):
    """(3.6.10), written independently of PlantModel.derivative from the same force terms:
    (M_RB + M_A) nur_dot + C_RB(nu_r) nu_r + C_A(nu_r) nu_r + D(nu_r) nu_r + g = tau,
    with the state holding nu_r, and eta1_dot = R nu_r + V_c."""
    phi, theta, psi = x_rel[3:6]
    nu_r = x_rel[NU]
    _, mass_accel, f_mm = model.moving_mass(x_rel, inputs)
    force = (
        model.actuators(inputs, nu_r[0])
        + f_mm
        + model.restoring(phi, theta)
        - model.coriolis_rigid_body(nu_r)
        - model.coriolis_added_mass(nu_r)
        + model.viscous(nu_r)
    )
    dx = np.zeros(N_STATES)
    dx[0:3] = rotation_matrix(phi, theta, psi) @ nu_r[:3] + inputs[5:8]
    dx[3:6] = euler_rate_matrix(phi, theta) @ nu_r[3:]
    dx[NU] = np.linalg.solve(model.mass_matrix, force)
    dx[12], dx[13] = x_rel[13], mass_accel
    return dx


@pytest.mark.slow
def test_steady_uniform_current_full_form_equals_relative_form():
    """In a steady, uniform current the full form (3.6.2/4.3.1) reduces exactly to the
    relative-velocity form (3.6.10, 4.3.2): the same trajectory to 1e-9."""
    model = PlantModel(load_vehicle(), Variant.FULL)
    current = np.array([0.15, -0.2, 0.05])
    inputs = input_vector(
        dict(thrust=9.0, roll_torque=-0.3, tunnel_force=2.0, fin_angle=0.05, mass_position_cmd=0.02,
             current_north=current[0], current_east=current[1], current_down=current[2])
    )  # fmt: skip
    x0 = state_vector(dict(u=1.4, v=0.1, w=0.05, p=0.1, q=0.05, r=-0.1, roll=0.1, yaw=0.5))
    R0 = rotation_matrix(*x0[3:6])
    x0_rel = x0.copy()
    x0_rel[6:9] -= R0.T @ current
    opts = dict(method="DOP853", rtol=1e-12, atol=1e-13, t_eval=np.linspace(0, 20, 81))
    full = solve_ivp(lambda t, x: model.derivative(x, inputs), (0, 20), x0, **opts)
    rel = solve_ivp(lambda t, x: _relative_form_derivative(model, x, inputs), (0, 20), x0_rel,
                    **opts)  # fmt: skip
    assert full.success and rel.success
    # map the relative run back to velocity over ground
    rel_over_ground = rel.y.copy()
    for k in range(rel.y.shape[1]):
        rel_over_ground[6:9, k] += rotation_matrix(*rel.y[3:6, k]).T @ current
    assert np.max(np.abs(full.y - rel_over_ground)) < 1e-9
    assert np.ptp(full.y[STATE_INDEX["east"]]) > 1.0  # the current really moved it


def test_sudden_current_carries_a_neutrally_buoyant_balanced_body_along():
    """The impulse of the (Mbar + M_A) nuc_dot term: a body with m = mbar and r_g = 0,
    at rest in still water, moves with the water the instant the current starts."""
    p = load_vehicle()
    neutral = p.replace(m=p.B / p.g, W=p.B, z_g=0.0)
    model = PlantModel(neutral, Variant.FULL)
    x = state_vector(dict(roll=0.2, pitch=-0.1, yaw=1.0))
    jump = np.array([0.3, -0.2, 0.1])
    d_nu = model.current_change_velocity_jump(x, jump)
    np.testing.assert_allclose(d_nu[:3], rotation_matrix(*x[3:6]).T @ jump, atol=1e-12)
    np.testing.assert_allclose(d_nu[3:], 0.0, atol=1e-12)
    # a body heavier than the water it displaces lags the water
    heavy = PlantModel(neutral.replace(m=1.2 * neutral.m))
    assert np.all(np.abs(heavy.current_change_velocity_jump(x, jump)[:3]) < np.abs(d_nu[:3]))


@pytest.fixture(scope="module")
def lateral() -> PlantModel:
    return PlantModel(load_vehicle(), Variant.LATERAL)


@pytest.mark.slow
def test_moving_mass_stays_within_its_stops_and_rests_without_reacting(lateral):
    x0 = state_vector(dict(u=1.5))
    inputs = input_vector(dict(thrust=9.0, mass_position_cmd=5.0))
    _, states = simulate(lateral, x0, inputs, duration=20.0, h=0.01)
    y_v = states[:, STATE_INDEX["mass_position"]]
    assert np.max(np.abs(y_v)) <= 0.06
    assert y_v[-1] == 0.06 and states[-1, STATE_INDEX["mass_velocity"]] == 0.0
    # against the stop the servo exerts nothing on the hull; only the offset weight acts
    y_vel, accel, force = lateral.moving_mass(states[-1], inputs)
    assert (y_vel, accel, force[1]) == (0.0, 0.0, 0.0)
    p = lateral.params
    phi = states[-1, STATE_INDEX["roll"]]
    assert force[3] == pytest.approx(p.m_v * p.g * 0.06 * np.cos(phi))


@pytest.mark.slow
def test_out_of_range_command_is_stopped_not_integrated(lateral):
    """A 5 m command drives the mass into its stop, where it stays: the stroke bounds the
    position, the command is not integrated past it."""
    x0 = state_vector(dict(u=1.5, v=-0.05))
    inputs = input_vector(dict(thrust=9.0, mass_position_cmd=-5.0))
    _, states = simulate(lateral, x0, inputs, 10.0, 0.01)
    y_v = states[:, STATE_INDEX["mass_position"]]
    assert np.min(y_v) == -0.06 and np.max(np.abs(y_v)) <= 0.06
    assert np.all(y_v[20:] == -0.06)  # there after 0.2 s, and resting
    assert np.all(states[20:, STATE_INDEX["mass_velocity"]] == 0.0)


def test_mass_hitting_a_stop_gives_its_momentum_back_to_the_hull():
    """Free hull in an ideal fluid (no restoring, no damping): what the servo pushes into the
    mass it takes from the hull, and the inelastic collision at the stop hands it back, so
    the sway and yaw impulse of hull plus mass, (M nu + m_v y_vel [0,1,0,-z_g,0,x_v]), stays
    zero through a 5 m command slamming the mass into its stop at ~1.5 m/s."""
    params = _balanced()
    model = PlantModel(params, Variant.LATERAL, ideal_fluid=True)
    _, states = simulate(
        model, state_vector(), input_vector(dict(mass_position_cmd=5.0)), 0.3, 0.01
    )
    rail = np.array([0.0, 1.0, 0.0, -params.z_g, 0.0, params.x_v])
    impulse = [model.mass_matrix @ x[NU] + params.m_v * x[13] * rail for x in states]
    impact = params.m_v * np.max(np.abs(states[:, STATE_INDEX["mass_velocity"]]))
    assert impact > 5.0  # N s: a real collision
    assert states[-1, STATE_INDEX["mass_position"]] == 0.06
    for k in (1, 5):  # sway, yaw
        assert np.max(np.abs([i[k] for i in impulse])) < 1e-3 * impact


@pytest.mark.slow
def test_rail_speed_limit_when_set():
    params = load_vehicle().replace(mass_speed_limit=0.03)
    model = PlantModel(params, Variant.LATERAL)
    inputs = input_vector(dict(thrust=9.0, mass_position_cmd=0.06))
    _, states = simulate(model, state_vector(dict(u=1.5)), inputs, 10.0, 0.01)
    speed = states[:, STATE_INDEX["mass_velocity"]]
    assert np.max(np.abs(speed)) <= 0.03
    assert np.max(speed) == pytest.approx(0.03)  # the limit is reached, so it acts


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_at_the_rail_speed_limit_the_servo_pushes_the_mass_no_faster(direction: float) -> None:
    """The fast twin of the speed limit's run: a mass at the limit (either way along the
    rail) is not accelerated outwards however gently the servo pushes (here 0.01 m/s^2,
    from the servo law (6.3.12) solved for the command), and may still be slowed."""
    params = load_vehicle().replace(mass_speed_limit=0.03)
    y_vel = direction * 0.03

    def command_for(accel: float) -> float:
        """y_cmd giving the servo's y'' = accel at y_v = 0 (6.3.12), m."""
        return (params.m_v * accel + params.d_v * y_vel) / params.k_v

    assert servo_motion(params, 0.0, y_vel, command_for(direction * 0.01)) == (y_vel, 0.0)
    vel, accel = servo_motion(params, 0.0, y_vel, command_for(-direction * 0.01))
    assert vel == y_vel and accel == pytest.approx(-direction * 0.01)


@pytest.mark.parametrize("variant", list(Variant))
def test_frozen_degrees_of_freedom_stay_frozen(variant):
    model = PlantModel(load_vehicle(), variant)
    x0 = state_vector(dict(u=1.5, v=0.1, r=0.1))
    inputs = input_vector(dict(thrust=9.0, mass_position_cmd=0.03, fin_angle=0.1))
    _, states = simulate(model, x0, inputs, 5.0, 0.01)
    free = set(variant.states)
    for name, k in STATE_INDEX.items():
        moved = np.ptp(states[:, k]) > 0
        assert moved == (name in free), name


@pytest.mark.slow
def test_same_inputs_give_bit_identical_trajectories():
    model = PlantModel(load_vehicle(), Variant.FULL)
    x0 = state_vector(dict(u=1.5, v=0.05, roll=0.1))
    inputs = input_vector(dict(thrust=9.0, mass_position_cmd=0.03, fin_angle=-0.1,
                               current_east=0.2))  # fmt: skip
    a = simulate(model, x0, inputs, 5.0, 0.01)[1]
    b = simulate(PlantModel(load_vehicle(), Variant.FULL), x0, inputs, 5.0, 0.01)[1]
    assert np.array_equal(a, b)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("name", ["thrust", "current_east", "mass_position_cmd"])
def test_non_finite_inputs_are_refused_by_name(lateral, name, bad):
    inputs = input_vector(dict(thrust=9.0))
    inputs[INPUT_NAMES.index(name)] = bad
    with pytest.raises(ValueError, match=rf"input {name} = .*expected a finite number"):
        advance(lateral, state_vector(dict(u=1.5)), inputs, 0.01)


@pytest.mark.parametrize("h", [0.0, -0.01, np.nan])
def test_bad_step_is_refused(lateral, h):
    with pytest.raises(ValueError, match="step h ="):
        advance(lateral, state_vector(dict(u=1.5)), input_vector(thrust=9.0), h)


@pytest.mark.parametrize(("h", "max_substep", "n"), [(1e12, 0.01, "1e+14"), (0.01, 1e-9, "1e+07")])
def test_a_step_of_more_sub_steps_than_a_host_can_wait_for_is_refused_unstarted(
    lateral, h, max_substep, n
):
    # Guards the hang: ceil(h / max_substep) sub-steps were started whatever their number.
    with pytest.raises(
        ValueError, match=rf"takes {re.escape(n)} sub-steps .* at most {MAX_SUBSTEPS}"
    ):
        advance(lateral, state_vector(dict(u=1.5)), input_vector(thrust=9.0), h, max_substep)


@pytest.mark.parametrize(("h", "max_substep"), [(0.1, 5e-324), (1e300, 1e-10)])
def test_a_step_whose_sub_step_count_overflows_is_refused_saying_why(h, max_substep):
    """A subnormal max_substep (5e-324 s), or a step so long that h / max_substep is inf,
    failed the plant's step with "OverflowError: cannot convert float infinity to integer"
    (found by random FMI call sequences); now the sub-step limit's own reason."""
    with pytest.raises(ValueError, match=rf"takes inf sub-steps .* at most {MAX_SUBSTEPS}"):
        substeps(h, max_substep)


def test_the_sub_step_limit_admits_its_own_number():
    assert substeps(MAX_SUBSTEPS * 0.01, 0.01) == MAX_SUBSTEPS
    with pytest.raises(ValueError, match=f"expected at most {MAX_SUBSTEPS}"):
        substeps((MAX_SUBSTEPS + 1) * 0.01, 0.01)


@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_a_sub_step_too_long_for_a_stiff_vehicle_is_refused_saying_so(path):
    """A moving-mass servo of 1000 rad/s makes RK4 at 10 ms sub-steps unstable: the step is
    refused naming the state that left the model's range and max_substep (before, an
    OverflowError, or outputs of nan a step later), and 1 ms sub-steps take it."""
    from plant_fmu.model import compiled

    if path == "compiled" and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    model = PlantModel(load_vehicle("remus100").replace(mass_natural_frequency=1000.0),
                       Variant.LATERAL)  # fmt: skip
    fast = compiled.CompiledPlant(model) if path == "compiled" else None
    x = state_vector(dict(u=1.5))
    u = input_vector(dict(mass_position_cmd=0.02), thrust=9.0)
    with pytest.raises(ValueError, match=r"left the model.s range .*a smaller max_substep keeps"):
        for _ in range(50):
            x = advance(model, x, u, 0.01, 0.01, fast)
    x = state_vector(dict(u=1.5))
    for _ in range(50):
        x = advance(model, x, u, 0.01, 0.001, fast)
    assert abs(x[STATE_INDEX["r"]]) < 1.0 and abs(x[STATE_INDEX["mass_position"]]) <= 0.06


@pytest.mark.parametrize("path", ["reference", "compiled"])
@pytest.mark.parametrize("moving_mass_model", [0, 1])
def test_a_full_variant_step_gone_non_finite_is_refused_saying_so(path, moving_mass_model):
    """The 6-DOF vehicle at rest over ground in a sudden 99 m/s current sees the water at
    99 m/s: RK4 at 10 ms turns its state to nan within a 0.1 s step. The step is refused
    naming the state (before, the Euler angles' whole turns of a nan quaternion raised
    "cannot convert float NaN to integer", which the FMU logged as the reason)."""
    from plant_fmu.model import compiled

    if path == "compiled" and (moving_mass_model == 1 or not compiled.AVAILABLE):
        pytest.skip("the two-body model, or numba off, has no compiled path")
    model = PlantModel(load_vehicle("remus100"), Variant.FULL, moving_mass_model=moving_mass_model)
    fast = compiled.CompiledPlant(model) if path == "compiled" else None
    x = state_vector(dict(u=1.5))
    u = input_vector(dict(current_east=99.0), thrust=9.0)
    with pytest.raises(ValueError, match=r"left the model.s range in a step of 0\.1 s .*: \w+ = "):
        advance(model, x, u, 0.1, 0.01, fast)  # 10 sub-steps: nan before the step ends


@pytest.mark.parametrize(
    ("variant", "moving_mass_model", "name"),
    [
        (Variant.FULL, 0, "roll_torque"),
        (Variant.LATERAL, 0, "roll_torque"),
        (Variant.FULL, 1, "roll_torque"),
        (Variant.HORIZONTAL, 1, "mass_position_cmd"),
    ],
)
@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_an_input_that_throws_an_angle_to_infinity_is_refused_saying_so(
    path, variant, moving_mass_model, name
):
    """A roll torque of 1e308 N m (a fault's gain gone wild) spins the roll angle to inf
    within a step, and so does a mass command of 1e308 m the horizontal two-body yaw:
    math.cos(inf) raised "math domain error", which the plant FMU logged as the reason, a
    message naming neither the step nor what left the range. The step is refused as any
    step that leaves the model's range is."""
    from plant_fmu.model import compiled

    if path == "compiled" and (moving_mass_model == 1 or not compiled.AVAILABLE):
        pytest.skip("the two-body model, or numba off, has no compiled path")
    model = PlantModel(load_vehicle(), variant, moving_mass_model=moving_mass_model)
    fast = compiled.CompiledPlant(model) if path == "compiled" else None
    inputs = input_vector({name: 1e308}, thrust=9.0)
    with pytest.raises(ValueError, match=r"left the model.s range in a step of 0\.05 s .*math"):
        advance(model, state_vector(dict(u=1.5, v=0.1, r=0.05, roll=0.1)), inputs, 0.05, 0.01, fast)


@pytest.mark.parametrize("name", ["thrust", "tunnel_force"])
@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_an_input_that_overflows_the_attitude_is_refused_saying_so(path, name):
    """A thrust or tunnel force of 1e8 N spins the 6-DOF vehicle so fast within a 0.1 s
    step that the attitude quaternion's norm overflows and normalising it leaves zero:
    both paths raised "division by zero" (ZeroDivisionError, not even a ValueError), which
    the plant FMU logged as the reason. The step is refused as any step that leaves the
    model's range is."""
    from plant_fmu.model import compiled

    if path == "compiled" and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    model = PlantModel(load_vehicle(), Variant.FULL)
    fast = compiled.CompiledPlant(model) if path == "compiled" else None
    inputs = input_vector({name: 1e8}, thrust=9.0)
    with pytest.raises(ValueError, match=r"left the model.s range in a step of 0\.1 s .*division"):
        advance(model, state_vector(dict(u=1.5)), inputs, 0.1, 0.01, fast)


@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_a_current_faster_than_any_velocity_the_model_takes_is_refused_by_name(path):
    """A steady current carries the vehicle at its own speed, so a current beyond MAX_SPEED
    (100 m/s) leaves the model's range whatever the vehicle does. A scenario's
    current_east = 1e10 was refused only after RK4 had thrown the vehicle to u = -2.4e130
    m/s, naming u and blaming the sub-step; the step is now refused naming the current,
    and a vehicle drifting with a current the model takes steps with it."""
    from plant_fmu.model import compiled

    if path == "compiled" and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    model = PlantModel(load_vehicle("remus100"), Variant.FULL)
    fast = compiled.CompiledPlant(model) if path == "compiled" else None
    x = state_vector(dict(u=1.5))
    too_fast = input_vector(dict(current_east=1e10), thrust=9.0)
    with pytest.raises(
        ValueError, match=r"input current_east = 1e\+10 m/s: expected \|current_east\| <= 100 m/s"
    ):
        advance(model, x, too_fast, 0.01, 0.01, fast)
    balanced = PlantModel(_balanced(), Variant.FULL)  # no force on a body at rest in water
    fast = compiled.CompiledPlant(balanced) if path == "compiled" else None
    drifting = state_vector(dict(u=-90.0))
    with_it = input_vector(dict(current_north=-90.0))
    after = advance(balanced, drifting, with_it, 0.01, 0.01, fast)
    assert after[STATE_INDEX["north"]] == pytest.approx(-0.9, rel=1e-12)
    np.testing.assert_allclose(after[NU], drifting[NU], rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_a_sheared_current_faster_than_the_model_takes_is_refused_naming_the_shear(path):
    """The current at the vehicle is current_north + current_shear_dUdy * east: with a
    shear of 0.1 1/s a vehicle 2 km east sits in a 200 m/s current, beyond MAX_SPEED, though
    every current input is 0. Such a step was taken (the vehicle thrown to u = 65 m/s) or
    refused naming u and blaming the sub-step; it is now refused before it starts, naming
    the sheared current, the shear and the east position, in both step paths."""
    from plant_fmu.model import compiled

    if path == "compiled" and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    model = PlantModel(load_vehicle("remus100"), Variant.FULL, current_shear=0.1)
    fast = compiled.CompiledPlant(model) if path == "compiled" else None
    x = state_vector(dict(u=1.5, east=2000.0))
    with pytest.raises(
        ValueError,
        match=r"current at the vehicle, north = 200 m/s \(current_north 0 m/s \+ "
        r"current_shear_dUdy 0\.1 1/s \* east 2000 m\): expected \|.*\| <= 100 m/s",
    ):
        advance(model, x, input_vector({}, thrust=9.0), 0.01, 0.01, fast)
    near = state_vector(dict(u=1.5, east=900.0))  # 90 m/s: within the range, stepped
    assert np.all(np.isfinite(advance(model, near, input_vector({}), 0.01, 0.01, fast)))


@pytest.mark.parametrize("path", ["reference", "compiled"])
def test_idle_stern_planes_exert_nothing_whatever_their_reference_speed(path):
    """The stern planes' force scales with (u_r / fin_reference_speed)^2 delta_s: with
    delta_s = 0 it is 0 for any reference speed the parameter range takes (> 0). With
    fin_reference_speed = 1e-200 the square overflowed to inf and inf * 0 made the state
    nan, and the step was refused naming north = nan and blaming the sub-step; idle fins
    now give the same step as at the dissertation's reference speed."""
    from plant_fmu.model import compiled

    if path == "compiled" and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    remus = load_vehicle("remus100")
    x, inputs = state_vector(dict(u=1.5, w=0.1)), input_vector({}, thrust=9.0)
    steps = []
    for params in (remus, remus.replace(fin_reference_speed=1e-200)):
        model = PlantModel(params, Variant.FULL)
        fast = compiled.CompiledPlant(model) if path == "compiled" else None
        steps.append(advance(model, x, inputs, 0.01, 0.01, fast))
    np.testing.assert_array_equal(steps[1], steps[0])
