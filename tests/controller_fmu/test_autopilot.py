"""The Autopilot composition: guidance (6.3.74)-(6.3.75), the depth PD of Fig. 6.40 with
Table 6.2's gains on the 6-DOF plant (vert-1, vert-2), the moving-mass lock, exact
snapshot/restore (frozen snapshots), the heading and depth modes, and bad input."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest
from reference_values import dissertation

from controller_fmu.autopilot import (
    MEASUREMENT_NAMES,
    Autopilot,
    AutopilotConfig,
    AutopilotConfigError,
    AutopilotSnapshot,
)
from controller_fmu.depth_pd import DepthPd, check_depth_loop, loop_poles
from controller_fmu.modes import DepthMode, HeadingMode
from controller_fmu.setpoint_shaping import crab_angle, desired_heading, mass_locked
from cosim.analysis.closed_loop import measurements, simulate_closed_loop
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import VehicleParameterError

H = 0.01


# --- guidance -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("speed", "printed", "digits"),
    [(1.525, "current.heading_9_newton", 0.02), (1.017, "current.heading_4_newton", 0.05)],
)
def test_heading_into_a_cross_current_is_the_sideslip_angle(speed, printed, digits):
    """(6.3.74) at 9 N (U0 = 1.525 m/s), (6.3.75) at 4 N (U0 = 1.017 m/s)."""
    current = dissertation("current.speed")
    psi_d = desired_heading(0.0, 0.0, current, speed, compensate_current=True)
    assert math.degrees(psi_d) == pytest.approx(dissertation(printed), abs=digits)
    # Only the component across the course counts: heading east, the same current is along it.
    assert desired_heading(math.pi / 2, 0.0, current, speed, True) == pytest.approx(math.pi / 2)
    assert desired_heading(0.3, 0.0, current, speed, compensate_current=False) == 0.3


def test_a_cross_current_faster_than_the_vehicle_is_refused():
    with pytest.raises(ValueError, match=r"cross-current 1\.6 m/s .* design speed 1\.525"):
        crab_angle(0.0, 0.0, 1.6, 1.525)


def test_mass_lock_starts_at_the_lock_time_and_never_when_negative():
    assert not mass_locked(14.99, 15.0) and mass_locked(15.0, 15.0)
    assert not mass_locked(1e6, -1.0)


def test_mass_lock_starts_at_a_point_that_rounds_just_below_the_lock_time():
    """A host computing its points as n h reaches 0.9 s as 3 x 0.3 s = 0.8999999999999999 s
    (and 10.8 s as 36 x 0.3 s = 10.799999999999999 s): that point is the lock
    time, so the mass locks there and not one step late; a point clearly before it is not."""
    for n, h, lock in ((3, 0.3, 0.9), (36, 0.3, 10.8)):
        point = n * h
        assert point < lock, "the arithmetic this test guards changed"
        assert mass_locked(point, lock), f"not locked at t = {point!r} s, lock at {lock} s"
        assert not mass_locked((n - 1) * h, lock)
        assert not mass_locked(lock - 1e-6, lock)


# --- depth PD ---------------------------------------------------------------------------------


def test_depth_pd_signs_and_limit():
    pd = DepthPd()
    gamma, k_p, tau_d = dissertation("table_6_2.gains")
    assert (pd.gamma, pd.k_p, pd.tau_d) == (gamma, k_p, tau_d)
    # Too shallow: nose down (theta_d < 0) by a positive fin (M_ds < 0 pitches nose down).
    assert pd.pitch_setpoint(1.0, 0.9) == pytest.approx(0.1 * gamma)
    assert pd.pitch_setpoint(1.0, 0.9) < 0.0
    assert pd.fin_angle(1.0, 0.99, 0.0, 0.0) == pytest.approx(-k_p * 0.01 * gamma)
    assert pd.fin_angle(1.0, 0.99, 0.0, 0.0) > 0.0
    # Pitching up (q > 0) is damped by a nose-down fin.
    assert pd.fin_angle(1.0, 1.0, 0.0, 0.01) == pytest.approx(k_p * tau_d * 0.01)
    assert pd.fin_angle(1.0, 1.0, 0.0, 0.01) > 0.0
    assert pd.fin_angle(5.0, 0.0, 0.0, 0.0) == pd.fin_limit
    with pytest.raises(ValueError, match=r"fin_limit = 0\.0"):
        DepthPd(fin_limit=0.0)


def test_the_pitch_setpoint_is_held_within_depth_pitch_limit_when_set():
    """Table 6.2's outer gain asks 44 deg of pitch per metre of depth error: 50 m below the
    set-point it asked -38.6 rad (-2212 deg), no attitude at all. With a pitch limit the
    set-point stops there; without one (0, the default) it is the linear law, as before."""
    gamma = DepthPd().gamma
    assert DepthPd().pitch_setpoint(51.0, 1.0) == gamma * 50.0  # off by default
    limited = DepthPd(pitch_limit=0.5)
    assert limited.pitch_setpoint(51.0, 1.0) == -0.5  # too shallow: nose down, at most 0.5
    assert limited.pitch_setpoint(1.0, 51.0) == 0.5  # too deep: nose up, at most 0.5
    assert limited.pitch_setpoint(1.0, 0.9) == pytest.approx(0.1 * gamma)  # inside: unchanged


def test_a_pitch_limit_beyond_the_vertical_is_refused():
    """A pitch of more than 90 deg is no Euler pitch (the plant's pitch stays in +-90 deg)."""
    expected = (
        r"depth_pitch_limit = 2\.0 rad: expected 0 \(no limit\) or an angle in \(0, 1\.571\] rad"
    )
    with pytest.raises(AutopilotConfigError, match=expected):
        AutopilotConfig.build(depth_pitch_limit=2.0)


@pytest.mark.slow
def test_a_50_m_depth_step_dives_at_the_pitch_limit_without_going_over_the_top(remus):
    """The 6-DOF plant at 1.5 m/s told to go from 1 m to 51 m: without a pitch limit the
    fins stayed on their stop, the vehicle pitched through -89 deg and over the vertical
    (roll and yaw swung by 170 and 200 deg within 30 s). With depth_pitch_limit = 0.5 rad it
    dives at about that pitch, upright, and arrives."""
    model = PlantModel(remus, variant=Variant.FULL)
    x0 = state_vector({"u": 1.50, "down": 1.0})
    config = AutopilotConfig.build(
        heading_mode=3, depth_mode=1, mass_lock_time=0.0, depth_pitch_limit=0.5
    )
    run = simulate_closed_loop(Autopilot(config), model, x0, 120.0, H, depth_setpoint=51.0)
    assert np.abs(run.state("pitch")).max() < 0.6  # rad: the limit and a small overshoot
    assert np.abs(np.degrees(run.state("roll"))).max() < 5.0
    assert np.abs(np.degrees(run.state("yaw"))).max() < 5.0
    assert abs(run.state("down")[-1] - 51.0) < 1.0  # m: there (a P loop's steady error)


@pytest.mark.parametrize(
    ("gains", "why"),
    [
        ({"depth_gamma": 0.772}, "gamma's sign slipped: vert-2 ran to 38 m above the surface"),
        ({"depth_k_p": -10.345}, "K_p's sign slipped: the pitch loop feeds back positively"),
        ({"depth_k_p": 0.0}, "no fin command at all"),
        ({"depth_gamma": 0.0}, "no depth feedback: the depth drifts"),
        ({"depth_tau_d": 0.0}, "no pitch damping: Table 6.2's loop oscillates, growing"),
        ({"depth_k_p": 1e4}, "stable in continuous time, the 10 ms sampling is not"),
        ({"depth_tau_d": 100.0}, "the fins banged; vert-2 ended 5.8 m deep for 1 m"),
    ],
)
def test_depth_gains_that_hold_no_depth_are_refused_naming_them(gains, why):
    """Each ran silently before; the depth loop closed on the plant's depth plane at the
    design speed has a pole with real part >= 0, so the autopilot is not built."""
    config = AutopilotConfig.build(depth_mode=DepthMode.PD, **gains)
    with pytest.raises(
        ValueError, match=r"depth_gamma = .* rad/m, depth_k_p = .*every 0\.01 s.*holds no depth"
    ):
        Autopilot(config)
    name, value = next(iter(gains.items()))
    with pytest.raises(ValueError, match=rf"{name} = {value!r}"):
        Autopilot(config)


def test_table_6_2_depth_loop_poles_are_the_plants_and_stable(remus):
    """The poles the check judges are those docs/model.md quotes for Table 6.2's gains on
    the plant at 1.525 m/s (-1.42 +- 0.94i, -3.70 +- 3.14i 1/s); the same gains without the
    depth loop (depth_mode off) are not checked."""
    poles = loop_poles(DepthPd(), remus, 1.525)
    assert sorted(np.round(poles, 2), key=lambda z: (z.real, z.imag)) == [
        -3.7 - 3.14j, -3.7 + 3.14j, -1.42 - 0.94j, -1.42 + 0.94j,
    ]  # fmt: skip
    check_depth_loop(DepthPd(), remus, 1.017, 0.01)  # the slow scenarios' design speed
    for step in (0.001, 0.05, 0.2):  # the steps users pick
        check_depth_loop(DepthPd(), remus, 1.525, step)
    Autopilot(AutopilotConfig.build(depth_mode=DepthMode.OFF, depth_k_p=-1.0))


@pytest.fixture(scope="module")
def vertical(remus):
    """vert-1 and vert-2 (Sec. 6.3.4): 6-DOF from the surface, u0 = 1.5, v0 = 0.1, z_d = 1 m,
    psi_d = 0, backstepping + thruster and the depth PD; vert-2 locks the mass at 15 s."""
    model = PlantModel(remus, variant=Variant.FULL)
    x0 = state_vector({"u": 1.50, "v": 0.10})
    runs = {}
    for name, lock in (("vert-1", -1.0), ("vert-2", 15.0)):
        config = AutopilotConfig.build(heading_mode=3, depth_mode=1, mass_lock_time=lock)
        runs[name] = simulate_closed_loop(Autopilot(config), model, x0, 60.0, H, depth_setpoint=1.0)
    return runs


@pytest.mark.slow
def test_vert2_both_loops_settle_where_the_dissertation_reports(vertical):
    run = vertical["vert-2"]
    late = run.times >= 45.0
    # Sec. 6.3.4 prints w ~ -0.07 m/s, theta ~ -0.045 rad, mean delta_s ~ -5 deg (buoyancy
    # offset) for vert-1's run (Fig. 6.43); with the mass locked vert-2 settles near it.
    w, theta, fin_deg = dissertation("scenarios.depth_steady_state")
    assert run.state("w")[late].mean() == pytest.approx(w, abs=0.01)
    assert run.state("pitch")[late].mean() == pytest.approx(theta, abs=0.01)
    assert np.degrees(run.command("fin_angle")[late]).mean() == pytest.approx(fin_deg, abs=0.5)
    assert np.ptp(run.state("down")[late]) < 0.01  # settled
    assert 0.9 < run.state("down")[-1] < 1.0  # a P depth loop keeps a steady error
    assert np.all(run.command("mass_position_cmd")[run.times >= 15.0] == 0.0)
    assert np.abs(run.state("mass_position")[-1]) < 1e-3
    assert np.abs(np.degrees(run.state("yaw")[late])).max() < 1.0


@pytest.mark.slow
def test_vert1_keeps_rolling_while_the_mass_is_active(vertical):
    """Sec. 6.3.4: without the lock the (m + a33) p w coupling keeps the roll oscillating."""
    late_1 = vertical["vert-1"].times >= 40.0
    roll_1 = np.degrees(vertical["vert-1"].state("roll")[late_1])
    roll_2 = np.degrees(vertical["vert-2"].state("roll")[late_1])
    assert roll_1.std() > 3.0
    assert roll_1.std() > 5.0 * roll_2.std()


# --- composition ----------------------------------------------------------------------------


def _measured(remus, **state) -> dict[str, float]:
    model = PlantModel(remus, variant=Variant.LATERAL)
    return measurements(model, state_vector(state), input_vector(thrust=9.0))


def test_heading_off_commands_nothing_but_the_thrust(remus):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=0, thrust_command=4.0))
    commands = autopilot.step(0.0, _measured(remus, u=1.5, v=-0.1, yaw=0.5))
    assert commands.values() == (0.0, 0.0, 0.0, 4.0)


def test_a_non_finite_command_leaves_the_autopilot_as_it_was(remus):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3))
    good = _measured(remus, u=1.5, v=-0.1)
    autopilot.step(0.0, good)
    before = autopilot.snapshot().to_json()
    with np.errstate(all="ignore"), pytest.raises(ValueError, match="non-finite command"):
        autopilot.step(0.01, {**good, "r": 1e300, "p": -1e300})  # the model terms overflow
    assert autopilot.snapshot().to_json() == before
    untouched = Autopilot(autopilot.config)
    untouched.step(0.0, good)
    assert autopilot.step(0.01, good) == untouched.step(0.01, good)


def test_snapshot_and_restore_continue_bit_identically(remus):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3))
    model = PlantModel(remus, variant=Variant.LATERAL)
    run = simulate_closed_loop(autopilot, model, state_vector({"u": 1.5, "v": -0.1}), 2.0, H)
    saved = autopilot.snapshot()

    def replay() -> list[tuple[float, ...]]:
        return [
            autopilot.step(2.0 + k * H, measurements(model, x, input_vector(thrust=9.0))).values()
            for k, x in enumerate(run.states[::20])
        ]

    first = replay()
    autopilot.restore(saved)
    assert replay() == first
    # The snapshot is a value: frozen, not shared with the autopilot, and it survives the
    # JSON round trip of the FMU's serialised state exactly.
    with pytest.raises(dataclasses.FrozenInstanceError):
        saved.heading_setpoint = 1.0
    assert saved.backstepping.last_time == pytest.approx(2.0 - H)
    autopilot.restore(AutopilotSnapshot.from_json(json.loads(json.dumps(saved.to_json()))))
    assert replay() == first


def test_a_heading_mode_switched_while_running_starts_as_a_fresh_autopilot(remus):
    """Retuned to backstepping after 1 s with heading off, the autopilot commands what one
    built in backstepping mode commands from the same measurements: the law is designed at
    the switch and starts fresh."""
    switched = Autopilot(AutopilotConfig.build(heading_mode=0))
    fresh = Autopilot(AutopilotConfig.build(heading_mode=3))
    model = PlantModel(remus, variant=Variant.LATERAL)
    run = simulate_closed_loop(switched, model, state_vector({"u": 1.5, "v": -0.1}), 1.0, H)
    switched.retune(heading_mode=3)
    assert switched.heading_mode is HeadingMode.BACKSTEPPING
    assert switched.backstepping is not None and switched.lqr is None
    for k, x in enumerate(run.states[::10]):
        m = measurements(model, x, input_vector(thrust=9.0))
        assert switched.step(1.0 + k * H, m) == fresh.step(1.0 + k * H, m)
    assert switched.config == fresh.config


def test_a_mass_lock_set_while_running_holds_the_mass_from_then_and_releases(remus):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3))
    m = _measured(remus, u=1.5, v=-0.1, yaw=0.3)
    assert autopilot.step(0.0, m).mass_position_cmd != 0.0
    autopilot.retune(mass_lock_time=0.5)
    assert autopilot.step(0.01, m).mass_position_cmd != 0.0  # not yet
    assert autopilot.step(0.5, m).mass_position_cmd == 0.0
    autopilot.retune(mass_lock_time=-1.0)
    assert autopilot.step(0.51, m).mass_position_cmd != 0.0


def test_retuning_a_fixed_parameter_or_out_of_range_is_refused_unchanged():
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3))
    before = autopilot.config
    with pytest.raises(AutopilotConfigError, match="k0: not tunable while running"):
        autopilot.retune(k0=0.3, heading_mode=1)
    with pytest.raises(AutopilotConfigError, match="heading_mode"):
        autopilot.retune(heading_mode=7)
    assert autopilot.config is before and autopilot.heading_mode is HeadingMode.BACKSTEPPING


@pytest.mark.slow
@pytest.mark.parametrize(
    ("mode", "controller", "designed_for_step"),
    [
        (HeadingMode.OFF, None, False),
        (HeadingMode.LQR, "lqr", True),
        (HeadingMode.SLIDING_MODE, "sliding_mode", True),
        (HeadingMode.BACKSTEPPING, "backstepping", False),
    ],
)
def test_each_heading_mode_designs_only_its_own_controller(mode, controller, designed_for_step):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=int(mode)))
    designed = [n for n in ("lqr", "sliding_mode", "backstepping") if getattr(autopilot, n)]
    assert designed == ([controller] if controller else [])
    assert autopilot.heading_mode is mode
    assert autopilot.designed_for_step is designed_for_step
    snapshot = autopilot.snapshot()
    assert (snapshot.backstepping is not None) == (mode is HeadingMode.BACKSTEPPING)


def test_depth_mode_off_leaves_the_fins_at_zero_and_pd_moves_them(remus):
    deep = _measured(remus, u=1.5, down=0.2)
    deep["depth_setpoint"] = 1.0
    off = Autopilot(AutopilotConfig.build(depth_mode=int(DepthMode.OFF)))
    on = Autopilot(AutopilotConfig.build(depth_mode=int(DepthMode.PD)))
    assert off.step(0.0, deep).fin_angle == 0.0
    assert on.step(0.0, deep).fin_angle == DepthPd().fin_angle(1.0, 0.2, 0.0, 0.0) != 0.0


def test_a_depth_setpoint_above_the_surface_is_refused_while_the_depth_loop_is_on(remus):
    """z_d < 0 m would fly the vehicle above the water (the plant has no free surface);
    the surface itself (0 m) is a depth, and with the depth loop off z_d is not used."""
    above = {**_measured(remus, u=1.5, down=0.2), "depth_setpoint": -1.0}
    on = Autopilot(AutopilotConfig.build(depth_mode=int(DepthMode.PD)))
    with pytest.raises(ValueError, match=r"depth_setpoint = -1\.0 m is above the surface"):
        on.step(0.0, above)
    assert on.step(0.0, {**above, "depth_setpoint": 0.0}).fin_angle < 0.0  # up: nose up
    off = Autopilot(AutopilotConfig.build(depth_mode=int(DepthMode.OFF)))
    assert off.step(0.0, above).fin_angle == 0.0


def test_a_non_finite_or_missing_measurement_is_refused_by_name(remus):
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=1))
    good = _measured(remus, u=1.5)
    with pytest.raises(ValueError, match=r"measurement v_rel = nan: expected a finite number"):
        autopilot.step(0.0, {**good, "v_rel": float("nan")})
    missing = {k: v for k, v in good.items() if k != "depth_setpoint"}
    with pytest.raises(ValueError, match="measurement 'depth_setpoint' is missing"):
        autopilot.step(0.0, missing)
    assert set(good) == set(MEASUREMENT_NAMES)


@pytest.mark.parametrize(
    ("values", "message"),
    [
        (
            {"heading_mode": 7},
            r"heading_mode = 7: .*expected one of 0 \(OFF\), 1 \(LQR\), 2 \(SLIDING_MODE\), "
            r"3 \(BACKSTEPPING\)",
        ),
        ({"depth_mode": -1}, r"depth_mode = -1: .*expected one of 0 \(OFF\), 1 \(PD\)"),
        ({"design_speed": 0.0}, "design_speed = 0.0"),
        ({"k0": float("nan")}, "k0 = nan"),
        ({"rudder": 1.0}, "unknown autopilot parameter 'rudder'"),
    ],
)
def test_bad_parameters_are_refused_with_the_name_and_what_is_allowed(values, message):
    with pytest.raises(AutopilotConfigError, match=message):
        AutopilotConfig.build(**values)


def test_unknown_vehicle_is_refused_listing_the_known_sets():
    with pytest.raises(VehicleParameterError, match=r"unknown vehicle 'remus200'.*remus100"):
        Autopilot(AutopilotConfig.build(vehicle="remus200"))
