"""The attitude through any orientation: beyond 70 deg of pitch the stepping integrates a
unit quaternion, so a vehicle that tumbles, loops or dives vertically passes pitch +-90 deg
with its physics intact, and the Euler-angle outputs are a rule of the attitude (the triple
with |pitch| <= 90 deg, roll and yaw continued by whole turns), the same at every step;
below, it integrates the Euler angles as it always did."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.spatial.transform import Rotation

from plant_fmu.model import compiled
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.kinematics import euler_from_quaternion, rotation_matrix
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.state_layout import QUATERNION_CHART_PITCH
from plant_fmu.model.stepping import simulate

NU = slice(6, 12)
PITCH = 4
YAW = 5


def _balanced():
    """Neutrally buoyant, centre of gravity at the centre of buoyancy: no restoring."""
    p = load_vehicle()
    return p.replace(W=p.B, z_g=0.0, x_g=0.0)


def _earth_impulse(model: PlantModel, states: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Earth-frame linear impulse R p and angular impulse R pi + x cross R p about the
    earth origin of each state, [p; pi] = (M_RB + M_A) nu (Thm 5.1); in an ideal fluid
    with no restoring both are constant (Kirchhoff)."""
    linear, angular = [], []
    for x in states:
        R = rotation_matrix(*x[3:6])
        impulse = model.mass_matrix @ x[NU]
        linear.append(R @ impulse[:3])
        angular.append(R @ impulse[3:] + np.cross(x[:3], linear[-1]))
    return np.array(linear), np.array(angular)


def _drift(values: np.ndarray, scale: float) -> np.ndarray:
    """|values(t) - values(0)| / scale for each sample."""
    return np.linalg.norm(values - values[0], axis=1) / scale


def _tumble(duration: float, fast: bool):
    """A neutrally buoyant vehicle in an ideal fluid, started slow and pitching up at
    1 rad/s from 69 deg with some roll and yaw rate: its nose passes within 0.4 deg of the
    vertical at 0.35 s, and it keeps tumbling."""
    model = PlantModel(_balanced(), Variant.FULL, ideal_fluid=True)
    x0 = state_vector(dict(u=0.3, v=0.1, w=0.05, p=0.3, q=1.0, r=-0.2, roll=0.2, pitch=1.2))
    path = compiled.CompiledPlant(model) if fast and compiled.AVAILABLE else None
    _, states = simulate(model, x0, input_vector(), duration, 0.01, compiled=path)
    return model, states


def _check_tumble(model: PlantModel, states: np.ndarray, floor: float) -> None:
    """Impulse drifts no more after the first passage through the vertical than before it
    (up to the RK4 error's growth: 3x, or ``floor`` relative over a long run); energy and
    the Casimirs |p|^2/2 and p.pi hold as they do without a passage (test_dynamics)."""
    R_zx = np.array([rotation_matrix(*x[3:6])[2, 0] for x in states])  # -sin(pitch)
    crossing = int(np.argmax(np.abs(R_zx) > 0.9999))  # within 0.8 deg of the vertical
    assert crossing > 5, "the run must start away from the vertical"
    assert np.sum(np.abs(R_zx) > 0.9999) < len(states) // 2
    linear, angular = _earth_impulse(model, states)
    for values in (linear, angular):
        drift = _drift(values, np.linalg.norm(values[0]))
        before, after = drift[:crossing].max(), drift[crossing:].max()
        assert after <= max(3.0 * before, floor), (before, after)
    still = input_vector()
    energy = np.array([model.kinetic_energy(x, still) for x in states])
    impulses = np.array([model.mass_matrix @ x[NU] for x in states])
    p_sq = 0.5 * np.sum(impulses[:, :3] ** 2, axis=1)
    p_pi = np.sum(impulses[:, :3] * impulses[:, 3:], axis=1)
    for invariant in (energy, p_sq, p_pi):
        assert np.max(np.abs(invariant - invariant[0])) <= 1e-8 * abs(invariant[0])


def test_tumbling_through_the_vertical_keeps_the_impulse_short():
    """0.7 s, through pitch 90 deg at 0.35 s (the reference path)."""
    model, states = _tumble(0.7, fast=False)
    _check_tumble(model, states, floor=1e-9)
    assert np.max(np.abs(states[:, PITCH])) <= np.pi / 2  # the triple with |pitch| <= 90 deg
    assert np.ptp(states[:, YAW]) > 2.5  # yaw swings round the vertical by nearly 180 deg


@pytest.mark.slow
def test_tumbling_through_the_vertical_keeps_the_impulse():
    """Half a minute of free tumbling after passing the vertical, looping over and over
    (the compiled path, which the plant FMU steps)."""
    model, states = _tumble(30.0, fast=True)
    _check_tumble(model, states, floor=1e-7)
    assert np.ptp(states[:, PITCH]) > 2.8  # nose from near straight up to below -70 deg
    assert np.ptp(states[:, YAW]) > 10 * np.pi  # over and over: more than five turns


def _loop(duration: float, fast: bool):
    """A loop: a vehicle without restoring moment at 3 m/s, 40 N of thrust and the stern
    planes hard over, started pitching up at 2 rad/s with a trace of roll and yaw rate:
    its nose passes within 0.05 deg of straight up at 1.05 s and it carries on over. The
    attitude, and the body rates it came from, every 2 ms (fine enough for a spline
    through the rates to hold them to 1e-8)."""
    model = PlantModel(_balanced(), Variant.FULL)
    inputs = input_vector(dict(fin_angle=-0.5), thrust=40.0)
    x0 = state_vector(dict(u=3.0, q=2.0, p=0.005, r=0.002, pitch=0.8))
    path = compiled.CompiledPlant(model) if fast and compiled.AVAILABLE else None
    return simulate(model, x0, inputs, duration, 0.002, compiled=path)


def _independent_attitude(times: np.ndarray, states: np.ndarray) -> Rotation:
    """The rotation integrated from the body rates alone: R_dot = R S(omega), with omega(t)
    a cubic spline through the sampled rates, by scipy (DOP853 on the quaternion)."""
    omega = CubicSpline(times, states[:, 9:12])

    def rate(t, q):  # scipy's quaternions are [x, y, z, w]
        w = omega(t)
        x, y, z, s = q
        return 0.5 * np.array(
            [s * w[0] + y * w[2] - z * w[1], s * w[1] + z * w[0] - x * w[2],
             s * w[2] + x * w[1] - y * w[0], -x * w[0] - y * w[1] - z * w[2]]
        )  # fmt: skip

    start = Rotation.from_euler("ZYX", states[0, [5, 4, 3]]).as_quat()
    run = solve_ivp(rate, times[[0, -1]], start, "DOP853", times, rtol=1e-12, atol=1e-13)
    return Rotation.from_quat(run.y.T)


@pytest.mark.parametrize(
    ("duration", "fast"), [(1.5, True), pytest.param(6.0, False, marks=pytest.mark.slow)]
)
def test_a_loop_turns_the_vehicle_as_its_body_rates_say(duration, fast):
    """Short: the compiled path; long, over the top and on: the reference."""
    times, states = _loop(duration, fast)
    stepped = Rotation.from_matrix([rotation_matrix(*x[3:6]) for x in states])
    independent = _independent_attitude(times, states)
    error = (stepped.inv() * independent).magnitude()
    assert np.max(error) < 1e-6
    # it really goes over the top: the nose points (nearly) straight up on the way
    assert np.max(-stepped.as_matrix()[:, 2, 0]) > 0.99999


def test_past_the_vertical_the_triple_with_pitch_within_90_deg_is_output():
    """Of the two triples (phi, theta, psi) and (phi + pi, pi - theta, psi + pi), the one
    with |theta| <= 90 deg, even where the other is nearer the previous output; roll and
    yaw keep their whole turns (yaw runs on past 180 deg)."""
    beyond = Rotation.from_euler("ZYX", [0.3, 1.60, 0.1])  # pitch just past 90 deg
    q = np.roll(beyond.as_quat(), 1)  # [w, x, y, z]
    phi, theta, psi = euler_from_quaternion(q, (0.5, 1.55, 0.6))
    assert (phi, theta, psi) == pytest.approx((0.1 + np.pi, np.pi - 1.60, 0.3 + np.pi), abs=1e-9)
    q = np.roll(Rotation.from_euler("ZYX", [-3.0, 0.0, 0.0]).as_quat(), 1)
    assert euler_from_quaternion(q, (0.0, 0.0, 3.2))[2] == pytest.approx(2 * np.pi - 3.0)


_ANGLE = st.floats(-10.0, 10.0, allow_nan=False)


@settings(max_examples=300, deadline=None)
@given(st.tuples(_ANGLE, _ANGLE, _ANGLE), st.tuples(_ANGLE, _ANGLE, _ANGLE))
def test_the_triple_is_a_rule_of_the_attitude_alone(euler, previous):
    """For any attitude and any previous output, the triple describes the attitude, has
    |pitch| <= 90 deg, and differs from the principal triple (scipy's) by whole turns of
    roll and yaw only: the previous output never picks the other triple."""
    attitude = Rotation.from_euler("ZYX", euler[::-1])
    if abs(np.cos(attitude.as_euler("ZYX")[1])) < 1e-6:
        return  # at the vertical itself roll and yaw separately are not defined
    q = np.roll(attitude.as_quat(), 1)
    phi, theta, psi = euler_from_quaternion(q, previous)
    np.testing.assert_allclose(rotation_matrix(phi, theta, psi), attitude.as_matrix(), atol=1e-9)
    yaw, pitch, roll = attitude.as_euler("ZYX")
    assert theta == pytest.approx(pitch, abs=1e-9)
    for ours, principal in ((phi, roll), (psi, yaw)):
        turns = (ours - principal) / (2 * np.pi)
        assert turns == pytest.approx(round(turns), abs=1e-9)


@pytest.mark.parametrize("fast", [False, True])
def test_after_a_pass_near_the_vertical_the_attitude_output_does_not_depend_on_the_step(fast):
    """The tumble passes within 0.4 deg of straight up at 0.35 s, where roll and yaw swing
    by nearly 180 deg: stepped at 10, 5 and 2.5 ms it ends with the same roll, pitch and yaw
    at 1 s (to RK4's error), not one triple at one step and the other at another."""
    model = PlantModel(_balanced(), Variant.FULL, ideal_fluid=True)
    x0 = state_vector(dict(u=0.3, v=0.1, w=0.05, p=0.3, q=1.0, r=-0.2, roll=0.2, pitch=1.2))
    ends = []
    for step in (0.01, 0.005, 0.0025):
        path = compiled.CompiledPlant(model) if fast and compiled.AVAILABLE else None
        _, states = simulate(model, x0, input_vector(), 1.0, step, compiled=path)
        ends.append(states[-1, 3:6])
    np.testing.assert_allclose(ends[0], ends[2], atol=1e-5)
    np.testing.assert_allclose(ends[1], ends[2], atol=1e-6)


def _euler_rk4(model: PlantModel, x: np.ndarray, inputs: np.ndarray, dt: float) -> np.ndarray:
    """One RK4 step of PlantModel.derivative on the Euler angles, each stage projected:
    the stepping as it was before the quaternion chart existed."""
    f, stage = model.derivative, model.project
    k1 = f(x, inputs)
    k2 = f(stage(x + 0.5 * dt * k1), inputs)
    k3 = f(stage(x + 0.5 * dt * k2), inputs)
    k4 = f(stage(x + dt * k3), inputs)
    return model.project(x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4), collide=True)


@pytest.mark.parametrize("fast", [False, True])
def test_below_the_chart_pitch_a_step_is_the_euler_angle_step_bit_for_bit(fast):
    """Up to 70 deg of pitch the full variant integrates its Euler angles, so every run that
    stays there (the built-in scenarios reach 58 deg) gives what it gave before the
    quaternion; beyond, the quaternion takes over and the Euler angles follow it."""
    model = PlantModel(load_vehicle(), Variant.FULL)
    path = compiled.CompiledPlant(model) if fast and compiled.AVAILABLE else None
    inputs = input_vector(dict(fin_angle=0.2, tunnel_force=3.0, mass_position_cmd=0.02), thrust=9)
    x0 = state_vector(dict(u=1.5, v=0.1, w=0.05, p=0.2, q=2.0, r=-0.1, roll=0.3, pitch=1.2))
    _, states = simulate(model, x0, inputs, 0.2, 0.01, compiled=path)
    expected = model.project(x0.copy())
    for x in states[1:]:
        euler = abs(expected[PITCH]) <= QUATERNION_CHART_PITCH  # the chart at the step's start
        expected = _euler_rk4(model, expected, inputs, 0.01)
        if not euler:
            break
        assert np.array_equal(x, expected)
    else:
        raise AssertionError("the run must pitch past the chart pitch")
    assert not np.array_equal(x, expected)  # the quaternion's step: the same to RK4's error
    np.testing.assert_allclose(x, expected, atol=1e-6)


@pytest.mark.parametrize("fast", [False, True], ids=["reference", "compiled"])
@pytest.mark.parametrize(
    ("variant", "pitch"),
    [(Variant.FULL, 0.1), (Variant.FULL, 1.3), (Variant.LATERAL, 0.0), (Variant.HORIZONTAL, 0.0)],
)
def test_yaw_runs_on_past_180_deg_without_a_jump(variant, pitch, fast):
    """Turning to starboard from 179 deg, in either attitude chart (pitch 0.1 rad: the Euler
    angles; 1.3 rad, beyond 70 deg: the quaternion) and every variant: the yaw output
    passes 180 deg and goes on, continuous, as docs/model.md#kinematics says, never
    jumping to -180 deg (the autopilot wraps its heading error itself)."""
    model = PlantModel(load_vehicle(), variant)
    if fast and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    path = compiled.CompiledPlant(model) if fast else None
    x0 = state_vector(dict(u=1.5, yaw=np.radians(179.0), pitch=pitch, r=0.3))
    _, states = simulate(model, x0, input_vector(thrust=9.0), 0.5, 0.01, compiled=path)
    yaw = states[:, YAW]
    assert yaw[-1] > np.pi  # past 180 deg
    assert np.max(np.abs(np.diff(yaw))) < 0.1  # rad per 10 ms: no turn of 2 pi


@pytest.mark.parametrize("fast", [False, True], ids=["reference", "compiled"])
@pytest.mark.parametrize("pitch", [np.pi / 2, -np.pi / 2])
def test_a_start_pointing_straight_up_or_down_steps_to_finite_outputs(pitch, fast):
    """At pitch +-90 deg exactly the Euler-rate matrix T (2.2.15) is singular and roll and
    yaw alone are undefined (only roll - yaw, or roll + yaw, is): a start there steps on
    the quaternion to finite outputs describing the same attitude, not to nan."""
    model = PlantModel(load_vehicle(), Variant.FULL)
    if fast and not compiled.AVAILABLE:
        pytest.skip(compiled.NO_JIT_REASON)
    path = compiled.CompiledPlant(model) if fast else None
    x0 = state_vector(dict(u=1.0, roll=0.3, pitch=pitch, yaw=0.2))
    _, states = simulate(model, x0, input_vector(thrust=9.0), 0.01, 0.01, compiled=path)
    assert np.all(np.isfinite(states))
    after, before = rotation_matrix(*states[-1, 3:6]), rotation_matrix(*x0[3:6])
    np.testing.assert_allclose(after, before, atol=1e-4)  # 10 ms from rest: hardly turned
