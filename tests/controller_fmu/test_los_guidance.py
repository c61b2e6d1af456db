"""The LOS waypoint guidance (controller_fmu.los_guidance): waypoint text and its errors,
the cross-track error's sign, waypoint switching and legs completed, the depth set-point,
and the closed loop with the plant model: the heading converges to the path, and in a
cross current the dissertation's compensation (6.3.74) or the integral LOS removes the
offset the proportional law leaves."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from reference_values import dissertation

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from controller_fmu.los_guidance import (
    GuidanceConfig,
    GuidanceConfigError,
    LosGuidance,
    Waypoint,
    leg_position,
    parse_waypoints,
)
from controller_fmu.setpoint_shaping import crab_angle, wrap_angle
from cosim.analysis.closed_loop import simulate_closed_loop
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import state_vector
from plant_fmu.model.parameters import load_vehicle

H = 0.01


def format_waypoints(waypoints: Sequence[Waypoint]) -> str:
    """The text :func:`parse_waypoints` reads back to ``waypoints`` (exact floats)."""
    return "; ".join(f"{w.north!r}, {w.east!r}, {w.down!r}" for w in waypoints)


def guidance(waypoints: str, **values) -> LosGuidance:
    return LosGuidance(GuidanceConfig.build(waypoints=waypoints, **values))


# --- waypoints ------------------------------------------------------------------------------


def test_waypoints_parse_with_spaces_newlines_and_a_trailing_semicolon():
    text = " 0, 0, 2;\n 50.5,-1e1 ,2 ;\n50, 20, 3.25;"
    assert parse_waypoints(text) == (
        Waypoint(0.0, 0.0, 2.0),
        Waypoint(50.5, -10.0, 2.0),
        Waypoint(50.0, 20.0, 3.25),
    )
    waypoints = parse_waypoints("0.1, 0.2, 0.3; 1e-17, 3.0000000000000004, 2")
    assert parse_waypoints(format_waypoints(waypoints)) == waypoints  # exact round trip


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("0, 0, 2; 50, x, 2", r"waypoint 2 \('50, x, 2'\): east = 'x' is not a finite number"),
        ("0, 0, 2; 50, 0", r"waypoint 2 \('50, 0'\): expected 'north, east, down'.*got 2 values"),
        ("0,0,2; 10,0,2; nan,0,2", r"waypoint 3 .*north = 'nan' is not a finite number"),
        ("0,0,2; inf,0,2", r"waypoint 2 .*north = 'inf' is not a finite"),
        ("0,0,2;; 10,0,2", r"waypoint 2 \(''\): expected 'north, east, down'.*got 1 value\b"),
        ("0, 0, 2", r"expected at least two entries .* got 1"),
        ("", r"expected at least two entries .* got 0"),
        ("0,0,2; 0,0,5", r"waypoint 2 \('0,0,5'\) is at the same north and east as waypoint 1"),
        ("0,0,2; 50,0,-5", r"waypoint 2 \('50,0,-5'\): down = -5\.0 m is above the surface"),
    ],
)
def test_a_bad_waypoint_is_named_with_what_was_expected(text, message):
    with pytest.raises(GuidanceConfigError, match=message):
        parse_waypoints(text)
    with pytest.raises(GuidanceConfigError, match=message):  # the FMU's parameter check
        GuidanceConfig.build(waypoints=text)


def test_bad_parameters_are_named():
    with pytest.raises(GuidanceConfigError, match=r"lookahead = 0\.0: .*greater than 0"):
        GuidanceConfig.build(lookahead=0.0)
    with pytest.raises(GuidanceConfigError, match=r"integral_gain = -1\.0: .*greater than or"):
        GuidanceConfig.build(integral_gain=-1.0)
    with pytest.raises(GuidanceConfigError, match=r"unknown guidance parameter 'lookahaed'"):
        GuidanceConfig.build(lookahaed=5.0)


# --- the law -------------------------------------------------------------------------------


@given(
    alpha=st.floats(-math.pi, math.pi),
    along=st.floats(-50.0, 150.0),
    offset=st.floats(-30.0, 30.0).filter(lambda y: abs(y) > 1e-3),
)
def test_cross_track_error_is_positive_to_starboard_and_the_course_turns_back(alpha, along, offset):
    start = Waypoint(3.0, -2.0, 0.0)
    end = Waypoint(start.north + 200.0 * math.cos(alpha), start.east + 200.0 * math.sin(alpha), 0)
    # a point `along` down the leg and `offset` to its right (starboard when following it)
    north = start.north + along * math.cos(alpha) - offset * math.sin(alpha)
    east = start.east + along * math.sin(alpha) + offset * math.cos(alpha)
    where = leg_position(start, end, north, east)
    assert where.along_track == pytest.approx(along, abs=1e-9)
    assert where.cross_track == pytest.approx(offset, abs=1e-9)
    los = guidance(format_waypoints([start, end]), lookahead=8.0, acceptance_radius=1.0)
    out = los.step(north, east)
    turn = wrap_angle(out.course_setpoint - where.alpha)
    assert math.copysign(1.0, turn) == -math.copysign(1.0, offset)  # back towards the path
    assert turn == pytest.approx(-math.atan(offset / 8.0), abs=1e-12)
    assert out.yaw_setpoint == out.course_setpoint  # no current compensation asked


def test_the_next_leg_starts_inside_the_acceptance_radius():
    los = guidance("0,0,1; 50,0,1; 50,20,3; 0,20,3", acceptance_radius=5.0, lookahead=8.0)
    assert los.n_legs == 3
    out = los.step(44.9, 0.5)  # 5.12 m short of waypoint 2: still leg 1
    assert (out.legs_completed, out.target) == (0, Waypoint(50.0, 0.0, 1.0))
    assert out.course_setpoint == pytest.approx(-math.atan(0.5 / 8.0))
    out = los.step(45.1, 0.5)  # 4.92 m from it: leg 2, heading east
    assert (out.legs_completed, out.target) == (1, Waypoint(50.0, 20.0, 3.0))
    assert out.cross_track_error == pytest.approx(4.9)  # south of an eastward leg: starboard
    assert out.course_setpoint == pytest.approx(math.pi / 2 - math.atan(4.9 / 8.0))


def test_passing_a_waypoint_outside_the_radius_still_switches():
    los = guidance("0,0,0; 50,0,0; 50,20,0; 0,20,0", acceptance_radius=2.0)
    assert los.step(49.0, -10.0).legs_completed == 0  # 10 m off the end, not yet past it
    assert los.step(50.0, -10.0).legs_completed == 1  # abreast of it: past along the track


def test_legs_completed_counts_to_the_end_and_the_last_leg_is_then_extended():
    los = guidance("0,0,0; 50,0,0; 50,20,0", acceptance_radius=5.0, lookahead=10.0)
    assert los.step(49.0, 18.0).legs_completed == 0  # near the final waypoint, but on leg 1
    assert los.step(49.0, 0.0).legs_completed == 1
    out = los.step(49.0, 18.0)
    assert out.legs_completed == 2  # mission complete
    out = los.step(52.0, 40.0)  # beyond the end: still steered along the last leg's line
    assert (out.legs_completed, out.target) == (2, Waypoint(50.0, 20.0, 0.0))
    assert out.cross_track_error == pytest.approx(-2.0)  # north of an eastward line: port
    assert out.course_setpoint == pytest.approx(math.pi / 2 + math.atan(2.0 / 10.0))


def test_one_position_can_complete_several_short_legs():
    los = guidance("0,0,0; 1,0,0; 1,1,0; 30,1,0", acceptance_radius=3.0)
    assert los.step(0.5, 0.5).legs_completed == 2  # within 3 m of waypoints 2 and 3


def test_depth_setpoint_is_the_paths_depth_one_lookahead_ahead():
    los = guidance("0,0,1; 100,0,5; 100,50,5", lookahead=10.0, acceptance_radius=2.0)
    assert los.step(-20.0, 0.0).depth_setpoint == 1.0  # before the leg: its start depth
    assert los.step(30.0, 3.0).depth_setpoint == pytest.approx(1.0 + 4.0 * 40.0 / 100.0)
    assert los.step(95.0, 0.0).depth_setpoint == 5.0  # the lookahead point is past the end


def test_set_points_are_on_the_branch_of_the_measured_yaw():
    los = guidance("0,0,0; -100,0,0")  # a leg due south: chi_d = -pi, wrapped
    assert los.step(0.0, 0.0).course_setpoint == -math.pi
    turns = 4.0 * math.pi  # the plant's yaw after two whole turns to starboard, heading south
    out = los.step(0.0, 0.0, yaw=turns + math.pi - 0.1)
    assert out.course_setpoint == pytest.approx(turns + math.pi)
    assert out.yaw_setpoint == out.course_setpoint
    out = los.step(0.0, 0.0, yaw=-turns - math.pi + 0.1)  # two turns to port
    assert out.course_setpoint == pytest.approx(-turns - math.pi)


def test_current_compensation_heads_into_the_cross_current_by_the_crab_angle():
    current = dissertation("current.speed")
    los = guidance("0,0,0; 100,0,0", compensate_current=True, design_speed=1.525)
    out = los.step(0.0, 0.0, current_north=0.0, current_east=current)
    assert out.course_setpoint == 0.0
    assert out.yaw_setpoint == pytest.approx(-crab_angle(0.0, 0.0, current, 1.525))
    printed = dissertation("current.heading_9_newton")  # (6.3.74)
    assert math.degrees(out.yaw_setpoint) == pytest.approx(printed, abs=0.02)
    with pytest.raises(ValueError, match="cross-current 2 m/s is not slower"):
        los.step(0.0, 0.0, current_east=2.0)


def test_a_failed_step_leaves_the_state_unchanged():
    los = guidance("0,0,0; 100,0,0", integral_gain=0.5)
    los.step(10.0, 3.0, step=1.0)
    before = los.state
    assert before.integral != 0.0
    with pytest.raises(ValueError, match="north = nan: expected a finite number"):
        los.step(math.nan, 0.0, step=1.0)
    with pytest.raises(ValueError, match=r"step = -1\.0 s"):
        los.step(10.0, 0.0, step=-1.0)
    assert los.state == before


def test_the_integral_restarts_on_each_leg():
    los = guidance("0,0,0; 50,0,0; 50,50,0", integral_gain=0.5, acceptance_radius=2.0)
    for _ in range(10):
        los.step(20.0, 2.0, step=1.0)
    assert los.state.integral == pytest.approx(10 * 8.0 * 2.0 / (64.0 + 4.0), rel=0.2)
    los.step(49.0, 0.0, step=1.0)
    assert (los.state.leg, los.state.legs_completed) == (1, 1)
    assert los.state.integral == pytest.approx(8.0 * 1.0 / 65.0)  # restarted, one step on


# --- closed loop with the plant model -------------------------------------------------------


def fly(los: LosGuidance, x0: dict, stop_time: float, current_east: float = 0.0, **autopilot):
    """The lateral plant with the backstepping autopilot, steered by ``los``."""
    run = simulate_closed_loop(
        Autopilot(AutopilotConfig.build(heading_mode=3, **autopilot)),
        PlantModel(load_vehicle("remus100"), variant=Variant.LATERAL),
        state_vector(x0),
        stop_time,
        H,
        current={"current_east": current_east},
        guidance=los,
    )
    start, end = los.waypoints[0], los.waypoints[1]
    cross = np.array(
        [leg_position(start, end, n, e).cross_track for n, e in run.states[:, :2].tolist()]
    )
    return run, cross


@pytest.mark.slow
def test_heading_converges_to_the_path_from_an_offset_start():
    # 15 m to port of a leg heading 30 deg, pointing north: joins it and stays on it
    alpha = math.radians(30.0)
    los = guidance(f"0,0,0; {500 * math.cos(alpha)!r},{500 * math.sin(alpha)!r},0")
    run, cross = fly(los, {"north": 15 * math.sin(alpha), "east": -15 * math.cos(alpha),
                           "u": 1.5}, 60.0)  # fmt: skip
    assert cross[0] == pytest.approx(-15.0)
    assert np.abs(cross[run.times >= 40.0]).max() < 0.05  # on the path, m
    yaw = run.state("yaw")[run.times >= 40.0]
    assert np.abs(np.degrees(yaw - alpha)).max() < 0.5  # heading along it


@pytest.mark.slow
@pytest.mark.parametrize(
    ("settings", "offset_m"),
    [
        ({}, (0.9, 1.2)),  # proportional LOS: y = Delta tan(beta) ~ 8 m x tan(7.5 deg)
        ({"compensate_current": True}, (0.0, 0.01)),  # psi_d = chi_d - beta (6.3.74)
        ({"integral_gain": 0.5}, (0.0, 0.02)),  # integral LOS, no current measured
    ],
)
def test_a_cross_current_offset_is_removed_by_compensation_or_integral_action(settings, offset_m):
    los = guidance("0,0,0; 1000,0,0", lookahead=8.0, **settings)
    run, cross = fly(los, {"u": 1.5}, 60.0, current_east=0.2, k0=0.3, k1=0.8)
    steady = np.abs(cross[run.times >= 50.0])
    assert offset_m[0] <= steady.min() and steady.max() <= offset_m[1], steady.max()


@pytest.mark.parametrize("gain", [1e200, 1e300, 1.7976931348623157e308])
def test_a_huge_integral_gain_steers_without_overflowing(gain):
    """With integral_gain = 1e300 the corrected cross-track error passed 1e154 on the
    second step and its square overflowed: the guidance FMU's doStep failed with
    "OverflowError: (34, 'Numerical result out of range')". The integral's rate,
    lookahead * cross_track / (lookahead^2 + corrected^2), is then as good as 0."""
    los = guidance("0,0,0; 100,0,0", integral_gain=gain)
    for _ in range(3):
        out = los.step(10.0, -1.0, step=0.05)
        assert math.isfinite(out.yaw_setpoint) and math.isfinite(los.state.integral)
    assert abs(wrap_angle(out.course_setpoint)) == pytest.approx(math.pi / 2, abs=1e-9)
