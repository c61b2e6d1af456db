"""Mechanical invariants of the equations of motion that hold for any state: the inertia
and Coriolis terms (no work, a positive definite mass matrix wherever the moving mass
sits), energy without damping and actuation (kinetic plus potential, to RK4's order),
energy with damping, hydrostatics, and the port-starboard mirror symmetry of the hull,
its actuators and the moving mass. test_dynamics.py holds the ideal-fluid (W = B, r_g = 0)
invariants, test_current_invariance.py the Galilean ones, test_two_body.py model 1's
momentum and energy with the mass moving.
"""

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from plant_fmu.model import compiled
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import N_INPUTS, N_STATES, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.kinematics import gravity_direction
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.moving_mass import rail_direction, two_body_force
from plant_fmu.model.parameters import builtin_vehicles, load_vehicle
from plant_fmu.model.stepping import advance, simulate

NU = slice(6, 12)
REMUS = load_vehicle("remus100")

_rate = st.floats(-2.0, 2.0)
_nu = st.tuples(_rate, _rate, _rate, _rate, _rate, _rate).map(np.array)
_rail = st.floats(-REMUS.mass_stroke, REMUS.mass_stroke)


@settings(max_examples=60)
@given(nu=_nu, mass_position=_rail)
def test_the_coriolis_and_centripetal_terms_do_no_work(nu: np.ndarray, mass_position: float):
    """nu^T C(nu) nu = 0 for C_RB (2.3.13), C_A (A.62) and, with the mass resting anywhere
    on its rail, model 1's terms of the point mass: they turn the momentum, never change
    the kinetic energy. Relative to the size of the terms, W."""
    model = PlantModel(REMUS, Variant.FULL)
    rigid, added = model.coriolis_rigid_body(nu), model.coriolis_added_mass(nu)
    point_mass = two_body_force(REMUS, nu, mass_position, 0.0)
    scale = float(np.abs(nu) @ (np.abs(rigid) + np.abs(added) + np.abs(point_mass))) + 1e-300
    for force in (rigid, added, point_mass):
        assert abs(float(nu @ force)) <= 1e-14 * scale


@pytest.mark.parametrize("name", builtin_vehicles())
def test_the_mass_matrix_is_symmetric_positive_definite_over_the_whole_rail(name: str):
    """M_RB + M_A + dM(y_v) (model 1) is symmetric positive definite wherever the mass is
    on its rail, and so is the inertia of hull, fluid and mass with the rail's own degree
    of freedom, [[M(y_v), m_v J], [m_v J^T, m_v]] (the form of model 1's kinetic energy):
    no position of the mass makes the kinetic energy indefinite."""
    params = load_vehicle(name)
    model = PlantModel(params, Variant.FULL, moving_mass_model=1)
    rail = params.m_v * rail_direction(params)
    for y_v in np.linspace(-params.mass_stroke, params.mass_stroke, 13):
        M = model.mass_matrix_at(float(y_v))
        assert np.array_equal(M, M.T), y_v
        system = np.block([[M, rail[:, None]], [rail[None, :], np.array([[params.m_v]])]])
        assert np.linalg.eigvalsh(system).min() > 0.0, y_v  # Cholesky's condition
        np.linalg.cholesky(M)


def _potential_energy(params, x: np.ndarray) -> float:
    """Potential of weight and buoyancy, J, zero at the surface and level: (B - W) z for
    the hull's net weight at depth z, -W r_g . Gamma for the weight at r_g about the CB,
    and -m_v g y_v Gamma_y for the moving mass off the middle of its rail."""
    gamma = gravity_direction(x[3], x[4])
    r_g = np.array([params.x_g, 0.0, params.z_g])
    offset = params.m_v * params.g * x[12] * gamma[1]
    return float((params.B - params.W) * x[2] - params.W * r_g @ gamma - offset)


def _energy_drift(model: PlantModel, x0: np.ndarray, inputs: np.ndarray, max_substep: float):
    """Largest change of kinetic plus potential energy over 4 s, J."""
    _, states = simulate(model, x0, inputs, 4.0, 0.04, max_substep)
    energy = [model.kinetic_energy(x, inputs) + _potential_energy(model.params, x) for x in states]
    return float(np.max(np.abs(np.asarray(energy) - energy[0])))


_TUMBLE = dict(u=0.4, v=0.1, w=-0.1, p=0.8, q=0.3, r=-0.3, roll=0.4, pitch=0.3)


@pytest.mark.parametrize(
    ("variant", "moving_mass_model"),
    [
        (Variant.FULL, 0),
        pytest.param(Variant.FULL, 1, marks=pytest.mark.slow),
        pytest.param(Variant.LATERAL, 1, marks=pytest.mark.slow),
        pytest.param(Variant.HORIZONTAL, 0, marks=pytest.mark.slow),
    ],
)
def test_without_damping_or_actuators_energy_is_conserved_to_rk4s_order(
    variant: Variant, moving_mass_model: int
):
    """remus100 as shipped (7 N buoyant, centre of gravity 2 cm below the CB) with the mass
    held 3 cm off centre, without damping, thrust or current: kinetic plus potential energy
    is a constant of the motion, so what drifts is RK4's error, falling as h^4 (16 times
    for half the sub-step; above 10 here), not a term that does work of its own. The
    planar variants hold the depth, so there W = B: their net buoyancy's sway component
    (W - B) sin(phi), which (6.3.13) keeps, would do work on a depth they never change."""
    params = REMUS if variant is Variant.FULL else REMUS.replace(W=REMUS.B)
    model = PlantModel(params, variant, ideal_fluid=True, moving_mass_model=moving_mass_model)
    x0 = model.project(state_vector(dict(_TUMBLE, mass_position=0.03)))
    held = input_vector(dict(mass_position_cmd=0.03))  # the servo at rest: it does no work
    coarse, fine = (_energy_drift(model, x0, held, h) for h in (0.01, 0.005))
    moved = "yaw" if variant is Variant.HORIZONTAL else "roll"
    path = simulate(model, x0, held, 4.0, 0.04)[1][:, STATE_INDEX[moved]]
    assert np.ptp(path) > 0.3  # it really turns
    assert coarse < 1e-6 * model.kinetic_energy(x0, held)
    assert coarse > 10.0 * fine


@pytest.mark.parametrize("start", [dict(_TUMBLE), dict(_TUMBLE, u=-0.8)], ids=["ahead", "astern"])
def test_with_damping_and_no_actuation_energy_never_increases(start: dict[str, float]):
    """The same vehicle with its viscous forces, ahead and astern: kinetic plus potential
    energy never grows from one 40 ms step to the next (to RK4's error, 1e-9 J)."""
    model = PlantModel(REMUS, Variant.FULL)
    x0 = state_vector(dict(start, mass_position=0.03))
    held = input_vector(dict(mass_position_cmd=0.03))
    _, states = simulate(model, x0, held, 4.0, 0.04)
    energy = [model.kinetic_energy(x, held) + _potential_energy(REMUS, x) for x in states]
    assert np.max(np.diff(energy)) <= 1e-9
    assert energy[-1] < 0.5 * energy[0] + 0.5 * min(energy)  # and it really dissipates


@settings(max_examples=60)
@given(nu=_nu, ahead=st.booleans())
@example(nu=np.array([-1.32, -0.48, -0.16, 0.0, -0.08, 0.5]), ahead=False)
def test_remus100s_viscous_forces_never_do_positive_work(nu: np.ndarray, ahead: bool):
    """The power of the cross-flow and lift forces (4.2.6)-(4.2.9), nu_r . D-force, is never
    positive, ahead or astern: the fluid only takes energy (with M_uq = -6.40; the
    printed +6.40 of remus100-printed is positive in heave and pitch: test_dynamics.py).
    Astern the lift terms u_r v_r, u_r r, ... push with the cross flow and only the drag
    outweighs them; the example is where remus100-long-fins' larger lift wins (+5.2 W:
    its kinetic energy grows astern without actuation, a known limit of the lift terms'
    form outside the forward motion they were fitted for)."""
    nu[0] = abs(nu[0]) if ahead else -abs(nu[0])
    assert float(nu @ PlantModel(REMUS, Variant.FULL).viscous(nu)) <= 0.0


def test_hydrostatics_vanish_level_and_right_a_small_tilt():
    """Neutrally buoyant (W = B) with the centre of gravity below the CB: no force and no
    moment level; a small roll or pitch tilt meets a moment against it, -W z_g sin(tilt),
    and no force (3.5.3)."""
    neutral = REMUS.replace(W=REMUS.B)  # a what-if: W = B departs from m g
    model = PlantModel(neutral, Variant.FULL)
    assert neutral.z_g > 0.0 and neutral.x_g == 0.0
    righting = -neutral.W * neutral.z_g
    np.testing.assert_array_equal(model.restoring(0.0, 0.0), np.zeros(6))
    for tilt in (0.05, -0.05):
        roll, pitch = model.restoring(tilt, 0.0), model.restoring(0.0, tilt)
        assert roll[3] == pytest.approx(righting * np.sin(tilt), rel=1e-14)
        assert pitch[4] == pytest.approx(righting * np.sin(tilt), rel=1e-14)
        np.testing.assert_allclose(np.delete(roll, 3), 0.0, atol=1e-14)
        np.testing.assert_allclose(np.delete(pitch, 4), 0.0, atol=1e-14)


@pytest.mark.parametrize("variant", list(Variant))
def test_at_rest_only_the_hydrostatics_act_and_nothing_divides_by_speed(variant: Variant):
    """No propulsion, no speed: with nu = 0 and the stern planes and tunnel thruster idle
    or not, the fins and lift terms vanish with u_r (nothing divides by a speed), so the
    acceleration is the hydrostatic force alone through the mass matrix,
    (M_RB + M_A) nu_dot = g(eta) on the free degrees of freedom (3.5.3): a buoyant
    remus100 (B > W) accelerates upwards."""
    model = PlantModel(REMUS, variant)
    x = state_vector({})
    rest = model.derivative(x, input_vector(dict(thrust=0.0, fin_angle=0.3)))
    free = np.array(variant.velocities)
    expected = np.zeros(6)
    expected[free] = np.linalg.solve(
        model.mass_matrix[np.ix_(free, free)], model.restoring(0.0, 0.0)[free]
    )
    np.testing.assert_allclose(rest[NU], expected, rtol=1e-12, atol=1e-15)
    assert np.all(np.isfinite(rest))
    if variant is Variant.FULL:
        assert rest[STATE_INDEX["w"]] < 0.0  # up: B - W = 7.1 N


@pytest.mark.parametrize("roll_deg", [30.0, 90.0, 120.0, 179.0, -150.0])
def test_a_capsized_hull_is_righted_from_any_roll_but_180_deg(roll_deg: float):
    """Past 90 deg of roll the hydrostatic moment r_g x W Gamma (3.5.3), -W z_g sin(phi)
    with the centre of gravity below the CB, still turns the hull back towards upright;
    upside down (180 deg) it is an equilibrium, and with z_g = 0 nothing rights it."""
    roll = np.radians(roll_deg)
    moment = PlantModel(REMUS, Variant.FULL).restoring(roll, 0.0)[3]
    assert moment == pytest.approx(-REMUS.W * REMUS.z_g * np.sin(roll), rel=1e-12)
    assert moment * roll < 0.0
    assert abs(PlantModel(REMUS, Variant.FULL).restoring(np.pi, 0.0)[3]) < 1e-12
    assert PlantModel(REMUS.replace(z_g=0.0), Variant.FULL).restoring(roll, 0.0)[3] == 0.0


def _random_state_and_inputs(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A state about the straight run (mass within its stops) and inputs with thrust."""
    x = 0.3 * rng.standard_normal(N_STATES)
    x[6] += 1.4
    x[12] = rng.uniform(-0.05, 0.05)
    inputs = 0.3 * rng.standard_normal(N_INPUTS)
    inputs[0], inputs[4] = 9.0, 0.1 * inputs[4]
    return x, inputs


@pytest.mark.parametrize("variant", list(Variant))
def test_the_motion_does_not_depend_on_depth(variant: Variant):
    """The model has no free surface and no depth-dependent term: the derivative is the
    same at any depth, bit for bit."""
    model = PlantModel(REMUS, variant)
    rng = np.random.default_rng(1)
    for _ in range(20):
        x, inputs = _random_state_and_inputs(rng)
        deeper = x.copy()
        deeper[2] += 37.0
        np.testing.assert_array_equal(model.derivative(deeper, inputs), model.derivative(x, inputs))


# Port-starboard mirror: y -> -y turns east, roll, yaw, v, p, r and the mass's position and
# speed, and the roll torque, tunnel force, mass command and eastward current.
_STATE_MIRROR = np.array([1, -1, 1, -1, 1, -1, 1, -1, 1, -1, 1, -1, -1, -1], dtype=float)
_INPUT_MIRROR = np.array([1, -1, -1, 1, -1, 1, -1, 1], dtype=float)


@pytest.mark.parametrize("moving_mass_model", [0, 1])
@pytest.mark.parametrize("variant", list(Variant))
def test_mirrored_starts_give_mirrored_motion(variant: Variant, moving_mass_model: int):
    """The hull is symmetric about its x-z plane: a start and inputs mirrored port to
    starboard (the moving mass and tunnel thruster mirrored too) give the mirrored
    derivative and the mirrored state after a step of 0.1 s, on the compiled path too."""
    model = PlantModel(REMUS, variant, moving_mass_model=moving_mass_model)
    rng = np.random.default_rng(2)
    for _ in range(10):
        x, inputs = _random_state_and_inputs(rng)
        x = model.project(x)
        mirrored_x, mirrored_u = _STATE_MIRROR * x, _INPUT_MIRROR * inputs
        np.testing.assert_allclose(
            model.derivative(mirrored_x, mirrored_u),
            _STATE_MIRROR * model.derivative(x, inputs),
            rtol=1e-13, atol=1e-13,
        )  # fmt: skip
        for path in _paths(model):
            np.testing.assert_allclose(
                advance(model, mirrored_x, mirrored_u, 0.1, compiled=path),
                _STATE_MIRROR * advance(model, x, inputs, 0.1, compiled=path),
                rtol=1e-13, atol=1e-13,
            )  # fmt: skip


def _paths(model: PlantModel) -> list[CompiledPlant | None]:
    """The reference step (None) and, where it applies, the compiled one the FMU takes."""
    if compiled.supports(model) == "":
        return [None, compiled.CompiledPlant(model)]
    return [None]


@settings(max_examples=40)
@given(
    command=st.floats(-10.0, 10.0),
    start=_rail,
    speed=st.floats(-2.0, 2.0),
    variant=st.sampled_from(list(Variant)),
    moving_mass_model=st.sampled_from([0, 1]),
)
def test_the_mass_stays_on_its_rail_for_any_command(
    command: float, start: float, speed: float, variant: Variant, moving_mass_model: int
):
    """Whatever the servo is told (up to 10 m, 170 times the 6 cm stroke) and however fast
    the mass already slides, it ends every step within its stops, and resting against a
    stop it does not move outwards. (The servo follows its command unsaturated, so a
    command of a kilometre accelerates the mass at 5000 m/s^2 and its recoil throws the
    hull out of the model's range: that step is refused, naming the velocity.)"""
    model = PlantModel(REMUS, variant, moving_mass_model=moving_mass_model)
    x = state_vector(dict(u=1.5, mass_position=start, mass_velocity=speed))
    after = advance(model, x, input_vector(dict(mass_position_cmd=command), thrust=9.0), 0.05)
    y_v, y_vel = after[STATE_INDEX["mass_position"]], after[STATE_INDEX["mass_velocity"]]
    assert abs(y_v) <= REMUS.mass_stroke
    if abs(y_v) == REMUS.mass_stroke:
        assert y_vel * y_v <= 0.0


_current = st.floats(-1.0, 1.0)


@settings(max_examples=15)
@given(
    current=st.tuples(_current, _current, _current).map(np.array),
    attitude=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-3.2, 3.2)),
    variant=st.sampled_from(list(Variant)),
)
def test_a_body_drifting_with_the_current_moves_at_its_speed(
    current: np.ndarray, attitude: tuple[float, float, float], variant: Variant
):
    """Neutrally buoyant and balanced (W = B, r_g = 0; a what-if), at rest in the water
    (nu = [U; 0], U the current in body axes) and unactuated: no force acts, so over a
    step of 1 s it keeps its velocity and its position moves by V_c t (the planar
    variants hold the depth, so only the horizontal current carries them)."""
    params = REMUS.replace(W=REMUS.B, z_g=0.0)
    model = PlantModel(params, variant)
    inputs = input_vector(
        dict(zip(("current_north", "current_east", "current_down"), current, strict=True))
    )
    x = model.project(state_vector(dict(zip(("roll", "pitch", "yaw"), attitude, strict=True))))
    x[NU][:3] = model.current_in_body(x, inputs)
    after = advance(model, x, inputs, 1.0)
    np.testing.assert_allclose(after[NU], x[NU], rtol=0.0, atol=1e-13)
    carried = current if variant is Variant.FULL else np.array([*current[:2], 0.0])
    np.testing.assert_allclose(after[:3], carried, rtol=0.0, atol=1e-12)
