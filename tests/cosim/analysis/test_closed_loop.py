"""The LQR design's linear closed loop against the nonlinear one the simulation runs (the
in-process closed loop: the plant's RK4 steps and the autopilot, as a master couples the
FMUs under lqr-1's Gauss-Seidel order): the same poles from the simulation's own Jacobian,
and the same step response for a small heading step, fading as the step grows; and the
depth PD's poles, as its design check and ``analyze margins --loop depth`` compute them,
against the same Jacobian of the 6-DOF loop."""

from __future__ import annotations

import math

import control
import numpy as np
import pytest

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from controller_fmu.depth_pd import DEPTH_PLANE_STATES, DepthPd, sampled_loop_poles
from controller_fmu.matrix_exponential import zero_order_hold
from cosim.analysis.closed_loop import simulate_closed_loop
from cosim.analysis.margins import depth_loop, loop_margins
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

STEP_INFO = ("RiseTime", "SettlingTime", "Overshoot")  # s, s, % of the step
STOP_TIME = 40.0  # s: the linear step response settles within 2 % after 27.6 s


def _trim_thrust(model: PlantModel, speed: float) -> float:
    """The thrust (N) that holds ``speed`` (m/s) on a straight run: u' is affine in it."""
    x = state_vector({"u": speed})
    idle, unit = (model.derivative(x, input_vector(thrust=t))[STATE_INDEX["u"]] for t in (0, 1))
    return float(-idle / (unit - idle))


def _lqr(remus: VehicleParameters, speed: float, step: float) -> tuple[Autopilot, PlantModel]:
    """The LQR autopilot designed at ``speed`` (m/s) for ``step`` (s), its thrust holding
    that speed, its command unsaturated as lqr-1 runs it; and the lateral plant."""
    model = PlantModel(remus, variant=Variant.LATERAL)
    config = AutopilotConfig.build(
        heading_mode=1, design_speed=speed, design_step=step,
        thrust_command=_trim_thrust(model, speed), mass_position_cmd_limit=100.0,
    )  # fmt: skip
    return Autopilot(config), model


@pytest.mark.parametrize(("speed", "step"), [(1.525, 0.01), (1.017, 0.05), (2.0, 0.001)])
def test_the_designed_poles_are_the_simulated_loops_own(
    remus: VehicleParameters, speed: float, step: float
) -> None:
    """The eigenvalues of the Jacobian of one sample of the simulated loop (autopilot, then
    the plant's RK4 step with the command held), by central differences about the
    straight run, are the LQR's designed poles (Ad - Bd K on the design model's zero-order
    hold), and besides them only the surge pole and the free north and east (z = 1)."""
    autopilot, model = _lqr(remus, speed, step)
    assert autopilot.lqr is not None
    assert model.variant is Variant.LATERAL
    x0 = state_vector({"u": speed})
    simulated = list(np.linalg.eigvals(_sample_jacobian(autopilot, model, x0, step)))
    for pole in autopilot.lqr.poles:  # each designed pole matched once
        nearest = int(np.argmin(np.abs(np.array(simulated) - pole)))
        assert abs(simulated.pop(nearest) - pole) < 1e-6, (pole, simulated)
    surge = math.exp(float(_surge_rate(model, speed)) * step)
    np.testing.assert_allclose(np.sort(np.real(simulated)), [surge, 1.0, 1.0], atol=1e-6)


@pytest.mark.parametrize(("speed", "step"), [(1.525, 0.01), (1.017, 0.05), (2.0, 0.001)])
def test_the_depth_loops_poles_are_the_simulated_loops_own(
    remus: VehicleParameters, speed: float, step: float
) -> None:
    """The depth PD's closed-loop poles as ``auv-cosim analyze margins --loop depth``
    prints them (python-control's zero-order hold of the depth plane) and as the autopilot
    checks its gains (:func:`controller_fmu.depth_pd.sampled_loop_poles`) against the
    eigenvalues of the Jacobian of one sample of the simulated 6-DOF loop (the depth PD on,
    no heading law; the plant's RK4 step with the fin command held), by central
    differences about the straight run.

    The simulated loop is the depth plane with the surge speed u, closed by the law's gain
    (to 1e-6); the design's plane leaves u out (z_g couples surge and pitch in the mass
    matrix), which moves its poles by under 2e-3 1/s (a sign slip in the analysis's loop,
    or a lost tau_d, moves them by whole 1/s). The vehicle is made neutrally buoyant
    (B = W), so that the straight run the design linearises at is the loop's equilibrium:
    REMUS 100's 7 N of net buoyancy moves the simulated sample off it (w' = -0.11 m/s^2)."""
    remus = remus.replace(B=remus.W)
    model = PlantModel(remus, variant=Variant.FULL)
    config = AutopilotConfig.build(
        heading_mode=0, depth_mode=1, design_speed=speed, design_step=step,
        thrust_command=_trim_thrust(model, speed),
    )  # fmt: skip
    autopilot = Autopilot(config)
    x0 = state_vector({"u": speed})
    simulated = np.linalg.eigvals(_sample_jacobian(autopilot, model, x0, step))
    analysed = loop_margins(depth_loop(remus, step, speed)).poles
    designed = sampled_loop_poles(DepthPd(), remus, speed, step)
    np.testing.assert_allclose(np.sort_complex(analysed), np.sort_complex(designed))
    with_surge = _depth_loop_with_surge(model, x0, config.thrust_command, step)
    for pole in with_surge:
        assert np.abs(simulated - pole).min() < 1e-6, (pole, simulated)
    for pole in designed:  # 1/s: the continuous-time shift
        nearest = with_surge[np.argmin(np.abs(with_surge - pole))]
        assert abs(np.log(nearest) - np.log(pole)) / step < 2e-3, (pole, with_surge)


def _sample_jacobian(
    autopilot: Autopilot, model: PlantModel, x0: np.ndarray, step: float
) -> np.ndarray:
    """The Jacobian of one sample of the simulated loop over the variant's free states,
    by central differences of 1e-6 about ``x0``."""
    free = [STATE_INDEX[name] for name in model.variant.states]

    def sample(x: np.ndarray) -> np.ndarray:
        return simulate_closed_loop(autopilot, model, x, step, step).states[1, free]

    jacobian = np.empty((len(free), len(free)))
    for j, k in enumerate(free):
        delta = np.zeros_like(x0)
        delta[k] = 1e-6
        jacobian[:, j] = (sample(x0 + delta) - sample(x0 - delta)) / 2e-6
    return jacobian


def _depth_loop_with_surge(
    model: PlantModel, x0: np.ndarray, thrust: float, step: float
) -> np.ndarray:
    """The poles z of Table 6.2's depth PD closed on the plant's (u, w, q, z, theta),
    linearised at ``x0`` with ``thrust`` (N), its fins held over each ``step`` s."""
    states = ("u", *DEPTH_PLANE_STATES)
    A, B = linearize(model, x0, input_vector(thrust=thrust), states, ["fin_angle"])
    law = DepthPd()
    gain = law.k_p * np.array([0.0, 0.0, law.tau_d, law.gamma, 1.0])  # closed_plane's, u too
    Ad, Bd = zero_order_hold(A, B, step)
    poles: np.ndarray = np.linalg.eigvals(Ad + Bd @ gain[None, :])
    return poles


def _surge_rate(model: PlantModel, speed: float) -> float:
    """d u' / d u (1/s) on the straight run at ``speed`` with the trim thrust."""
    inputs = input_vector(thrust=_trim_thrust(model, speed))
    rates = [
        model.derivative(state_vector({"u": speed + d}), inputs)[STATE_INDEX["u"]]
        for d in (1e-6, -1e-6)
    ]
    return float((rates[0] - rates[1]) / 2e-6)


def _linear_step(autopilot: Autopilot, times: np.ndarray) -> np.ndarray:
    """The heading's response (1 per unit of set-point step) of the LQR's linear closed
    loop, python-control's step response of the design model's zero-order hold with
    y_d = -K [v, r, p, phi, psi - psi_d, y_v, y_vel]."""
    assert autopilot.lqr is not None
    lqr, step = autopilot.lqr, autopilot.lqr.sample_time
    Ad, Bd = zero_order_hold(lqr.A, lqr.B, step)
    heading = np.eye(7)[4:5]
    loop = control.ss(Ad - Bd @ lqr.gain[None, :], Bd * lqr.gain[4], heading, 0.0, step)
    return np.asarray(control.step_response(loop, times).outputs).ravel()


def _nonlinear_step(autopilot: Autopilot, plant: CompiledPlant, degrees: float) -> np.ndarray:
    """The heading (1 per unit of step) of the simulated loop over :data:`STOP_TIME` from
    the straight run at the design speed, its set-point stepped by ``degrees`` at t = 0."""
    speed = autopilot.config.design_speed
    run = simulate_closed_loop(
        autopilot, plant.model, state_vector({"u": speed}), STOP_TIME,
        autopilot.config.design_step, yaw_setpoint=math.radians(degrees), compiled=plant,
    )  # fmt: skip
    yaw: np.ndarray = run.state("yaw") / math.radians(degrees)
    return yaw


def _step_info(response: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Rise time (s), 2 % settling time (s) and overshoot (%) of a unit step response."""
    info = control.step_info(response, times, yfinal=1.0, SettlingTimeThreshold=0.02)
    return np.array([info[name] for name in STEP_INFO])


@pytest.mark.slow
def test_a_small_heading_step_follows_the_linear_design(remus: VehicleParameters) -> None:
    """A 0.01 deg heading step in the simulated loop has the linear closed loop's rise
    time, settling time and overshoot within 1 % (the overshoot within 0.05 % of the
    step); the difference between the two responses is first order in the step (twice
    the step, twice the relative difference): the yaw drag N_rr r |r| has no second
    derivative at r = 0, so the linear model's error grows with |r|, not |r|^2."""
    autopilot, model = _lqr(remus, 1.525, 0.01)
    plant = CompiledPlant(model)
    times = np.arange(round(STOP_TIME / 0.01) + 1) * 0.01
    linear = _linear_step(autopilot, times)
    responses = [_nonlinear_step(autopilot, plant, degrees) for degrees in (0.01, 0.02)]
    ours, theirs = _step_info(responses[0], times), _step_info(linear, times)
    np.testing.assert_allclose(ours[:2], theirs[:2], rtol=0.01)
    assert ours[2] == pytest.approx(theirs[2], abs=0.05)
    differences = [np.abs(response - linear).max() for response in responses]
    assert differences[1] / differences[0] == pytest.approx(2.0, rel=0.05)


@pytest.mark.slow
def test_the_agreement_fades_as_the_step_grows_through_the_yaw_drag(
    remus: VehicleParameters,
) -> None:
    """From 0.01 deg to 10 deg of heading step the simulated overshoot falls away from the
    linear design's and the rise time grows (the yaw drag N_rr r |r| damps a faster turn
    more); the plant without that one term follows the linear response at 2 deg as
    closely as the full plant does at 0.05 deg (docs/model.md#lqr)."""
    autopilot, model = _lqr(remus, 1.525, 0.01)
    plant = CompiledPlant(model)
    times = np.arange(round(STOP_TIME / 0.01) + 1) * 0.01
    linear_yaw = _linear_step(autopilot, times)
    linear = _step_info(linear_yaw, times)
    infos = [_step_info(_nonlinear_step(autopilot, plant, d), times) for d in (0.01, 0.5, 2, 10)]
    overshoots, rises = [info[2] for info in infos], [info[0] for info in infos]
    assert linear[2] > overshoots[0] > overshoots[1] > overshoots[2] > overshoots[3]
    assert linear[0] <= rises[0] < rises[1] < rises[2] < rises[3]
    drag_free = CompiledPlant(PlantModel(remus.replace(N_rr=0.0), variant=Variant.LATERAL))
    without = _nonlinear_step(autopilot, drag_free, 2.0)
    full = _nonlinear_step(autopilot, plant, 0.05)
    assert np.abs(without - linear_yaw).max() < np.abs(full - linear_yaw).max()
