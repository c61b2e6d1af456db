"""LQR heading autopilot on the moving mass (6.3.17)-(6.3.19): why the design is discrete,
that it is stable at the steps users pick, that it follows the vehicle, and the lqr-1 /
lqr-2 outcomes in the in-process closed loop (plant model + Autopilot, 10 ms)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_values import dissertation
from unity_feedback import unity_feedback_poles

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.lqr import (
    DISSERTATION_Q_Y,
    DISSERTATION_R_U,
    LqrHeading,
    continuous_gain,
    delayed_poles,
    discrete_gain,
    state_weight,
)
from controller_fmu.matrix_exponential import zero_order_hold
from cosim.analysis.closed_loop import simulate_closed_loop
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import state_vector

U0 = 1.525  # m/s: (6.3.19)'s linearisation speed


@pytest.fixture(scope="module")
def linear(remus):
    return LateralDesignModel(remus, U0).linearize()


def test_weights_are_the_printed_ones_and_the_autopilot_uses_them():
    """Sec. 6.3.1 (the design with the servo): Q_y = diag(1, 5e3, 1e2, 1e3, 1e3, 1e6) on
    y = [r, p, phi, psi, y_v, y_vel], R_u = 1; they are the autopilot FMU's defaults."""
    q_y = dissertation("section_6_3_1.lqr_output_weights")
    r_u = dissertation("section_6_3_1.lqr_input_weight")
    assert list(DISSERTATION_Q_Y) == list(q_y) and r_u == DISSERTATION_R_U
    config = AutopilotConfig.build()
    weights = ("r", "p", "roll", "yaw", "mass_position", "mass_velocity")
    assert [getattr(config, f"lqr_q_{name}") for name in weights] == list(q_y)
    assert config.lqr_r == r_u


def test_continuous_design_puts_a_servo_pole_no_sampled_loop_can_realise(linear):
    A, B = linear
    K, poles = continuous_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U)
    # A closed-loop pole near -5760 1/s (the rail speed weight 1e6; docs/model.md#lqr).
    assert poles.real.min() < -1000.0
    # The same gains held over 10 ms steps: the sampled loop is violently unstable.
    Ad, Bd = zero_order_hold(A, B, 0.01)
    sampled = np.linalg.eigvals(Ad - Bd @ K[None, :])
    assert np.abs(sampled).max() > 2.0


@pytest.mark.parametrize("dt", [0.001, 0.01, 0.05])
def test_discrete_design_is_stable_at_the_communication_steps_users_pick(linear, dt):
    A, B = linear
    K, poles = discrete_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U, dt)
    Ad, Bd = zero_order_hold(A, B, dt)
    closed = np.linalg.eigvals(Ad - Bd @ K[None, :])
    assert np.abs(closed).max() < 1.0
    np.testing.assert_allclose(np.sort_complex(closed), np.sort_complex(poles), atol=1e-9)


def test_discrete_design_keeps_the_continuous_designs_slow_dynamics(linear):
    """Away from the servo pole, the 10 ms design's poles (as s = ln z / h) are the
    continuous LQR's: the discrete design changes only what sampling cannot realise."""
    A, B = linear
    h = 0.01
    _, continuous = continuous_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U)
    _, discrete = discrete_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U, h)
    slow_c = np.sort_complex(continuous[np.abs(continuous) < 100.0])
    as_s = np.log(discrete.astype(complex)) / h
    slow_d = np.sort_complex(as_s[np.abs(as_s) < 100.0])
    assert len(slow_c) == len(slow_d) == 6
    np.testing.assert_allclose(slow_d, slow_c, rtol=0.02)


def test_gains_are_designed_from_the_current_parameters(remus):
    base = LqrHeading(LateralDesignModel(remus, U0), 0.01).gain
    heavier_keel = LqrHeading(LateralDesignModel(remus.replace(z_g=0.03), U0), 0.01).gain
    slower = LqrHeading(LateralDesignModel(remus, 1.017), 0.01).gain
    coarser = LqrHeading(LateralDesignModel(remus, U0), 0.05).gain
    for other in (heavier_keel, slower, coarser):
        assert np.abs(other - base).max() > 1e-3 * np.abs(base).max()


def test_bad_weights_and_sample_times_are_refused_with_the_value_named(linear):
    A, B = linear
    with pytest.raises(ValueError, match=r"Q_y = \[1\.0, 2\.0\]: expected 6"):
        state_weight([1.0, 2.0])
    with pytest.raises(ValueError, match=r"Q_y .*-1"):
        state_weight([1.0, 5e3, 1e2, -1.0, 1e3, 1e6])
    with pytest.raises(ValueError, match=r"sample time 0\.0"):
        discrete_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U, 0.0)
    with pytest.raises(ValueError, match=r"R_u = 0\.0"):
        discrete_gain(A, B, DISSERTATION_Q_Y, 0.0, 0.01)


@pytest.mark.parametrize("dt", [0.001, 0.01, 0.05])
def test_delayed_poles_are_python_controls_loop_closed_through_a_delay(linear, dt):
    """The loop with its command one whole sample late closes on the poles of
    python-control's L(z) z^-1 fed back (the whole-step delay the master's coupling adds);
    with no delay, on the design's poles and the held command's z = 0."""
    import control

    A, B = linear
    K, poles = discrete_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U, dt)
    loop = control.c2d(control.ss(A, B, K[None, :], 0.0), dt, method="zoh")
    late = control.series(control.tf([1.0], [1.0, 0.0], dt), loop)
    np.testing.assert_allclose(
        np.sort_complex(delayed_poles(A, B, K, dt, dt)),
        np.sort_complex(unity_feedback_poles(late)),
        atol=1e-9,
    )
    np.testing.assert_allclose(
        np.sort_complex(delayed_poles(A, B, K, dt, 0.0)),
        np.sort_complex(np.append(poles, 0.0)),
        atol=1e-9,
    )
    with pytest.raises(ValueError, match=r"delay -0\.01 s: expected a delay >= 0 s"):
        delayed_poles(A, B, K, 0.01, -0.01)


@pytest.mark.parametrize("samples", [2, 3, 7])
def test_delayed_poles_take_a_delay_of_several_samples(linear, samples):
    """A command several whole samples late (a delay fault of k steps on it) closes on the
    poles of python-control's L(z) z^-k fed back; the loop took a delay of one sample at
    most, so a delay fault past the delay margin went unchecked. A delay between two whole
    samples lies between them: its largest pole's modulus between theirs."""
    import control

    A, B = linear
    dt = 0.01
    K, _ = discrete_gain(A, B, DISSERTATION_Q_Y, DISSERTATION_R_U, dt)
    loop = control.c2d(control.ss(A, B, K[None, :], 0.0), dt, method="zoh")
    late = control.series(control.tf([1.0], [1.0] + [0.0] * samples, dt), loop)
    np.testing.assert_allclose(
        np.sort_complex(delayed_poles(A, B, K, dt, samples * dt)),
        np.sort_complex(unity_feedback_poles(late)),
        atol=1e-7,
    )
    sizes = [
        np.abs(delayed_poles(A, B, K, dt, late * dt)).max()
        for late in (samples - 1, samples - 0.5, samples)
    ]
    assert min(sizes[0], sizes[2]) <= sizes[1] <= max(sizes[0], sizes[2])


# --- closed loop: the scenarios of docs/model.md#scenarios -------------------------------------


def _run(remus, v0: float, stop_time: float):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=1))
    model = PlantModel(remus, variant=Variant.LATERAL)
    x0 = state_vector({"u": 1.50, "v": v0})
    return simulate_closed_loop(autopilot, model, x0, stop_time, 0.01)


def _after(run, t: float) -> np.ndarray:
    return np.abs(np.degrees(run.state("yaw")[run.times >= t]))


@pytest.mark.slow
def test_lqr1_small_sway_disturbance_settles_within_25_s(remus):
    run = _run(remus, v0=-0.01, stop_time=40.0)
    assert _after(run, 25.0).max() < 1.0
    assert _after(run, 0.0).max() > 1.0  # it was disturbed, and came back


@pytest.mark.slow
def test_lqr2_mass_reaches_its_stop_and_heading_returns_within_45_s(remus):
    run = _run(remus, v0=-0.05, stop_time=60.0)
    assert run.state("mass_position").min() == pytest.approx(-0.06, abs=1e-12)
    assert np.abs(run.command("mass_position_cmd")).max() <= 0.06
    assert _after(run, 45.0).max() < 1.0
    assert math.isfinite(run.states[-1].sum())


@pytest.mark.parametrize(
    ("weights", "state"), [({"lqr_q_yaw": 0.0}, "yaw"), ({"lqr_q_yaw": 0.0, "lqr_q_r": 0.0}, "yaw")]
)
def test_a_design_without_a_weight_on_the_free_heading_names_it(weights, state):
    """lqr_q_yaw = 0 was refused as "the discrete Riccati equation has no stabilising
    solution", naming no weight: psi is the plant's free integrator (z = 1), and a cost
    that does not see it has no stabilising gain."""
    config = AutopilotConfig.build(heading_mode=1, **weights)
    with pytest.raises(ValueError, match=rf"along {state}\) has no weight.*weight > 0 on {state}"):
        Autopilot(config)
    with pytest.raises(ValueError, match=r"LQR at design_speed 1\.525 m/s.*Q_y = \[.*0\.0"):
        Autopilot(config)


def test_a_sliding_mode_with_no_weight_on_the_unstable_sway_yaw_mode_is_designed():
    """Its reduced LQR without psi, weights all 0 but psi's: refused before (the Riccati
    solver stopped at X = 0); control.dlqr gives the stabilising gain, and so do we."""
    zero = {f"lqr_q_{n}": 0.0 for n in ("r", "p", "roll", "mass_position", "mass_velocity")}
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=2, **zero))
    assert autopilot.sliding_mode is not None and np.any(autopilot.sliding_mode.k != 0.0)
