"""Backstepping on the moving mass + Lyapunov-redesigned tunnel thruster (6.3.53)-(6.3.73):
model terms from the plant against (6.3.19)'s printed entries, the command filter, and the
bs-*, cur-* and slow-1 outcomes in the in-process closed loop (plant model + Autopilot,
10 ms; the scenarios of docs/model.md#scenarios)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_values import dissertation

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from controller_fmu.backstepping import BacksteppingGains, BacksteppingHeading
from controller_fmu.command_filter import CommandFilterBank
from controller_fmu.lateral_model import LateralDesignModel
from cosim.analysis.closed_loop import simulate_closed_loop
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import state_vector

H = 0.01
GAINS = ("k0", "k1", "k2", "k3", "k4")
CURRENT_GAINS = {"k0": 0.3, "k1": 0.8}  # Sec. 6.3.3: heading into the current, low speed
SLOW = {"thrust_command": 4.0, "design_speed": 1.017}


def test_model_gains_are_the_plants_and_match_the_printed_linearisation(remus):
    """(6.3.19) at U0 = 1.525 prints d r'/d v = -5.629 and d v'/d phi = -0.332; with the
    mass held still, d v'/d y_v = A(1,6) + B(1) = 2.366 - 0.488 and d p'/d y_v =
    A(3,6) + B(3) = 204.76 + 1.140, all with W = m g and g = 9.8 as remus100 states them
    (with g = 9.81 and W = 299 N, g3 and g2 were 0.1 % and 0.6 % off)."""
    A, B = dissertation("equation_6_3_19.A"), dissertation("equation_6_3_19.B")
    bs = BacksteppingHeading(LateralDesignModel(remus, 1.525), BacksteppingGains())
    assert bs.g1 == pytest.approx(A[1, 0], rel=2e-4)
    assert bs.g2 == pytest.approx(A[0, 3], rel=2e-3)
    assert bs.eps4 == pytest.approx(A[0, 5] + B[0], rel=5e-4)
    assert bs.g3 == pytest.approx(A[2, 5] + B[2], rel=1e-4)
    # (6.3.71)'s sway inertia m + a22, up to the mass matrix's sway-roll-yaw coupling.
    assert 1.0 / bs.thruster_gain == pytest.approx(remus.m + remus.a22, rel=0.05)


def test_model_gains_are_designed_once_per_vehicle_and_speed(remus, monkeypatch):
    """Every run of a study designs the same law: the plant's Jacobian is computed once per
    parameter set and U0; each caller gets its own copy, and another U0 its own values."""
    design = LateralDesignModel(remus, 1.525)
    jac = design.static_mass_jacobian()
    jac["r/v"] = 0.0  # a caller's copy: changing it changes no later design
    evaluations = []
    derivative = PlantModel.derivative
    monkeypatch.setattr(
        PlantModel, "derivative", lambda *a: evaluations.append(1) or derivative(*a)
    )
    again = LateralDesignModel(remus.replace(), 1.525).static_mass_jacobian()  # equal set
    assert evaluations == []  # not computed again
    assert again["r/v"] == BacksteppingHeading(design, BacksteppingGains()).g1 != 0.0
    assert LateralDesignModel(remus, 1.2345).static_mass_jacobian()["r/v"] != again["r/v"]
    assert evaluations  # another U0 is another design


def test_command_filter_is_exact_for_any_step_and_settles_on_a_held_input():
    one = CommandFilterBank(2, frequency=10.0)
    two = CommandFilterBank(2, frequency=10.0)
    target = np.array([0.3, -1.2])
    one.advance(target, 0.02)
    two.advance(target, 0.01)
    two.advance(target, 0.01)
    np.testing.assert_allclose(one.value, two.value, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(one.rate, two.rate, rtol=1e-12, atol=1e-15)
    one.advance(target, 3.0)
    np.testing.assert_allclose(one.value, target, atol=1e-9)
    np.testing.assert_allclose(one.rate, 0.0, atol=1e-9)


def test_command_filter_rate_tracks_a_ramp():
    # The input is held between samples (a staircase), so at the sampling instants the
    # rate is off by about 1e-3 relative (0.08 % at omega h = 0.1).
    bank = CommandFilterBank(1, frequency=10.0)
    bank.start(np.zeros(1))
    slope = 0.5
    for k in range(1, 301):
        bank.advance(np.array([slope * k * H]), H)
    assert bank.rate[0] == pytest.approx(slope, rel=2e-3)


def test_gains_are_the_printed_ones():
    """Sec. 6.3.3: 'k0 = 0.5, k1 = k2 = k3 = k4 = 1.0' are the controller's and the autopilot
    FMU's defaults; the gains for heading into the current and for the low speed are
    'k0 = 0.3, k1 = 0.8, k2 = k3 = k4 = 1.0'."""
    printed = list(dissertation("section_6_3_3.backstepping_gains"))
    assert [getattr(BacksteppingGains(), k) for k in GAINS] == printed
    assert [getattr(AutopilotConfig.build(), k) for k in GAINS] == printed
    current = dict(zip(GAINS, printed, strict=True)) | CURRENT_GAINS
    assert list(current.values()) == list(dissertation("section_6_3_3.backstepping_gains_current"))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"k0": 0.0}, "k0 = 0.0"),
        ({"eta0": -1.0}, "eta0 = -1.0"),
        ({"boundary_layer": float("inf")}, "boundary_layer = inf"),
    ],
)
def test_bad_gains_are_refused_with_the_value_named(kwargs, message):
    with pytest.raises(ValueError, match=message):
        BacksteppingGains(**kwargs)


# --- closed loop: the scenarios of docs/model.md#scenarios --------------------------------------


def _run(remus, start, stop_time=30.0, current=None, yaw_setpoint=0.0, **config):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3, **config))
    model = PlantModel(remus, variant=Variant.LATERAL)
    run = simulate_closed_loop(
        autopilot, model, state_vector(start), stop_time, H, current, yaw_setpoint
    )
    assert np.abs(run.command("mass_position_cmd")).max() <= 0.06
    assert np.abs(run.command("tunnel_force")).max() <= 10.0
    return run


def _yaw_error_after(run, t: float, setpoint: float = 0.0) -> float:
    return float(np.abs(np.degrees(run.state("yaw") - setpoint)[run.times >= t]).max())


@pytest.mark.slow
@pytest.mark.parametrize(
    ("name", "start"),
    [("bs-1", {"u": 1.50, "v": -0.05}), ("bs-3", {"u": 1.50, "v": -0.10})],
)
def test_sway_disturbances_are_rejected_within_15_s(remus, name, start):
    run = _run(remus, start)
    assert _yaw_error_after(run, 15.0) < 1.0, name
    assert _yaw_error_after(run, 0.0) > 1.0, name  # the disturbance turned the vehicle first


@pytest.mark.slow
def test_bs2_heading_error_of_30_deg_is_removed(remus):
    run = _run(remus, {"u": 1.50, "yaw": math.radians(30.0)})
    assert _yaw_error_after(run, 20.0) < 1.0


@pytest.mark.slow
def test_slow1_low_speed_vehicle_is_stabilised_within_20_s(remus):
    run = _run(remus, {"u": 1.0, "v": -0.10}, **CURRENT_GAINS, **SLOW)
    assert _yaw_error_after(run, 20.0) < 1.0
    assert run.command("thrust")[0] == 4.0


@pytest.fixture(scope="module")
def in_current(remus):
    """cur-1 (psi_d = 0) and cur-2 (heading into the current by (6.3.74)): 0.2 m/s east,
    the vehicle starting with v = 0 over ground (v_rel = -0.2 m/s)."""
    current = {"current_east": 0.2}
    start = {"u": 1.50}
    drift = _run(remus, start, 60.0, current, **CURRENT_GAINS)
    compensated = _run(remus, start, 60.0, current, **CURRENT_GAINS, compensate_current=True)
    return drift, compensated


def _east_speed(run, since: float) -> float:
    late = run.times >= since
    return float(np.polyfit(run.times[late], run.state("east")[late], 1)[0])


@pytest.mark.slow
def test_cur1_holds_the_heading_and_drifts_east_with_the_current(in_current):
    drift, _ = in_current
    assert _yaw_error_after(drift, 30.0) < 1.0
    # Relative sway decays to 0 (Sec. 5.2.2), so over ground the vehicle moves with the water.
    assert _east_speed(drift, 40.0) == pytest.approx(0.2, abs=0.005)


@pytest.mark.slow
def test_cur2_settles_at_minus_7_55_deg_with_no_eastward_drift(in_current):
    _, compensated = in_current
    late = compensated.times >= 40.0
    printed = dissertation("current.heading_9_newton")  # deg, (6.3.74)
    assert np.degrees(compensated.state("yaw")[late]) == pytest.approx(printed, abs=0.05)
    assert abs(_east_speed(compensated, 40.0)) < 0.002
