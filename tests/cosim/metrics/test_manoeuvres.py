"""Manoeuvre metrics (cosim.metrics.manoeuvres): on synthetic signals whose answers are
known in closed form, and on the plant itself: the turning circle of the lateral plant
with the moving mass at its stop against the plant's own steady turn."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cosim.analysis.equilibria import find_equilibrium
from cosim.metrics.manoeuvres import (
    KINDS,
    VARIABLES,
    LegTracker,
    depth_steps,
    fault_recovery,
    fit_circle,
    manoeuvre_columns,
    manoeuvre_metrics,
    metric_names,
    survey,
    turning_circle,
    zigzag,
)
from plant_fmu.model.dynamics import STATE_INDEX, STATE_NAMES, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import simulate

H = 0.01


# --- turning circle -------------------------------------------------------------------------


def circle_track(turn: float, psi0: float, t_end: float = 50.0) -> dict[str, np.ndarray]:
    """Straight at U0 = 1.5 m/s for 2 s after the execute at t = 0, then a circle of radius
    5 m at 1.2 m/s towards ``turn`` (+1 starboard, -1 port), rolled 0.3 rad into it."""
    radius, u0, u1, t_straight = 5.0, 1.5, 1.2, 2.0
    t = np.arange(round(t_end / H) + 1) * H
    theta = np.clip(u1 * (t - t_straight) / radius, 0.0, None)
    along = np.where(t < t_straight, u0 * t, u0 * t_straight + radius * np.sin(theta))
    side = radius * (1.0 - np.cos(theta))  # towards the turn
    forward, starboard = (
        np.array([math.cos(psi0), math.sin(psi0)]),
        turn * np.array([-math.sin(psi0), math.cos(psi0)]),
    )
    north, east = np.outer(along, forward).T + np.outer(side, starboard).T + [[3.0], [-7.0]]
    yaw = np.angle(np.exp(1j * (psi0 + turn * theta)))  # wrapped, as a master may record it
    roll = np.where(t < t_straight, 0.0, turn * 0.3)
    return {"time": t, "north": north, "east": east, "yaw": yaw, "roll": roll}


@pytest.mark.parametrize(("turn", "psi0"), [(1.0, 0.0), (-1.0, 0.0), (1.0, 2.5), (-1.0, -3.0)])
def test_turning_circle_of_a_known_track(turn, psi0):
    track = circle_track(turn, psi0)
    metrics = turning_circle(track["time"], track["north"], track["east"], track["yaw"],
                             track["roll"])  # fmt: skip
    assert metrics["advance_m"] == pytest.approx(3.0 + 5.0, abs=1e-4)  # straight 3 m + R
    assert metrics["transfer_m"] == pytest.approx(5.0, abs=1e-4)  # R, towards the turn
    assert metrics["tactical_diameter_m"] == pytest.approx(10.0, abs=1e-4)
    assert metrics["steady_turning_diameter_m"] == pytest.approx(10.0, rel=1e-9)
    assert metrics["steady_roll_deg"] == pytest.approx(turn * math.degrees(0.3))
    # 1.5 -> 1.2 m/s; central differences on the circle read U (1 - (r h)^2 / 6)
    assert metrics["speed_loss_pct"] == pytest.approx(20.0, abs=1e-4)


def test_turning_circle_metrics_the_run_cannot_give_are_none():
    short = circle_track(1.0, 0.0, t_end=10.0)  # 1.92 rad: past 90 deg, not 180
    metrics = turning_circle(short["time"], short["north"], short["east"], short["yaw"],
                             short["roll"])  # fmt: skip
    assert metrics["advance_m"] == pytest.approx(8.0, abs=1e-4)
    assert metrics["tactical_diameter_m"] is None
    assert metrics["steady_turning_diameter_m"] is None and metrics["speed_loss_pct"] is None
    # a full turn after 180 deg is needed for the steady part: 1.5 turns are not enough
    medium = circle_track(1.0, 0.0, t_end=2.0 + 3.0 * math.pi * 5.0 / 1.2 - 0.5)
    assert turning_circle(medium["time"], medium["north"], medium["east"], medium["yaw"],
                          medium["roll"])["steady_turning_diameter_m"] is None  # fmt: skip


def test_circle_fit_is_exact_on_a_circle_far_from_the_origin():
    angle = np.linspace(0.0, 2.0 * math.pi, 400, endpoint=False)
    centre, radius = fit_circle(1e4 + 7.5 * np.cos(angle), -3e3 + 7.5 * np.sin(angle))
    assert radius == pytest.approx(7.5, rel=1e-10)
    assert centre == pytest.approx((1e4, -3e3), abs=1e-7)


@pytest.fixture(scope="module")
def lateral_turn():
    """The lateral plant from straight running at 1.525 m/s (T = 9 N), the moving mass
    commanded to its +6 cm stop at t = 0 and held, 60 s at 10 ms."""
    model = PlantModel(load_vehicle("remus100"), variant=Variant.LATERAL)
    inputs = input_vector({"thrust": 9.0, "mass_position_cmd": 0.06})
    times, states = simulate(model, state_vector({"u": 1.525}), inputs, 60.0, H)
    return model, inputs, times, states


@pytest.mark.slow
def test_steady_turning_diameter_is_2U_over_r_of_the_plants_own_steady_turn(lateral_turn):
    model, inputs, times, states = lateral_turn

    def state(name: str) -> np.ndarray:
        return states[:, STATE_INDEX[name]]

    metrics = turning_circle(times, state("north"), state("east"), state("yaw"), state("roll"))
    # The plant's own steady turn: the equilibrium of its reduced dynamics (the mass at its
    # stop), from the end of the run; U and the turn rate are its kinematics' own rates.
    guess = dict(zip(STATE_NAMES, states[-1].tolist(), strict=True))
    steady = find_equilibrium(model, guess, inputs)
    rates = model.derivative(steady.state, inputs)
    speed = math.hypot(rates[STATE_INDEX["north"]], rates[STATE_INDEX["east"]])
    diameter = 2.0 * speed / rates[STATE_INDEX["yaw"]]
    assert metrics["steady_turning_diameter_m"] == pytest.approx(diameter, rel=0.01)
    assert metrics["steady_roll_deg"] == pytest.approx(math.degrees(steady.value("roll")), abs=0.5)
    approach = states[0, STATE_INDEX["u"]]
    assert metrics["speed_loss_pct"] == pytest.approx(100 * (1 - speed / approach), abs=0.5)
    # the turn builds up: the vehicle runs on before it turns, and the tactical diameter
    # (at 180 deg) exceeds the steady one
    assert metrics["advance_m"] > metrics["transfer_m"] > 0.0
    assert metrics["tactical_diameter_m"] > metrics["steady_turning_diameter_m"]


# --- zig-zag --------------------------------------------------------------------------------


def zigzag_run(t_end: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading 25 sin(2 pi t / 30 s) + 2 deg with a +-20 deg set-point switched each time
    the heading crosses it (a 20/20 zig-zag with peaks at +27 and -23 deg)."""
    t = np.arange(round(t_end / H) + 1) * H
    yaw = np.radians(25.0 * np.sin(2.0 * math.pi * t / 30.0) + 2.0)
    setpoint = np.empty_like(t)
    value = math.radians(20.0)
    for k, psi in enumerate(yaw):
        if (value > 0.0 and psi >= value) or (value < 0.0 and psi <= value):
            value = -value
        setpoint[k] = value
    return t, yaw, setpoint


def test_zigzag_overshoots_and_period_of_a_known_heading():
    t, yaw, setpoint = zigzag_run(100.0)
    metrics = zigzag(t, yaw, setpoint)
    slope = 25.0 * 2.0 * math.pi / 30.0 * H  # deg the heading moves in one sample, at most
    assert 7.0 - slope <= metrics["overshoot_1_deg"] <= 7.0
    assert 3.0 - slope <= metrics["overshoot_2_deg"] <= 3.0
    assert metrics["period_s"] == pytest.approx(30.0, abs=H)
    # the same with the heading mirrored (a first turn to port)
    mirrored = zigzag(t, -yaw, -setpoint)
    assert mirrored["overshoot_1_deg"] == pytest.approx(metrics["overshoot_1_deg"])


def test_a_zigzag_from_another_course_executes_where_its_set_point_first_moves():
    """A zig-zag about a course of 30 deg: the set-point holds the course until the first
    execute at 5 s. The held set-point, non-zero from the start, was taken for an
    execute at t = 0, and the overshoots came out as the test angles (19.99 and 40 deg
    of a run whose heading overshot by about 1 deg)."""
    t, yaw, setpoint = zigzag_run(100.0)
    course = math.radians(30.0)
    held = t < 5.0  # straight on the course, then the same zig-zag, 5 s later
    later = np.searchsorted(t, t - 5.0)
    shifted_yaw = np.where(held, course, yaw[later] + course)
    shifted_setpoint = np.where(held, course, setpoint[later] + course)
    expected = zigzag(t[: len(t) - 500], yaw[: len(t) - 500], setpoint[: len(t) - 500])
    columns = {"time": t, "plant.yaw": shifted_yaw, "controller.yaw_setpoint": shifted_setpoint}
    got = manoeuvre_metrics("zigzag", columns)
    assert got == pytest.approx(expected, abs=1e-9)
    # a moving-mass command, neutral at 0, is an execute from the start when non-zero
    mass = {"time": t, "plant.yaw": yaw, "plant.mass_position_cmd": 0.06 * np.sign(setpoint)}
    assert manoeuvre_metrics("zigzag", mass) == zigzag(t, yaw, setpoint)


def test_a_zigzag_across_north_takes_a_set_point_a_turn_away_as_the_same_heading():
    """A zig-zag about a course of 350 deg, the vehicle starting at 350 deg (6.109 rad)
    and the set-point holding the course written as -10 deg: one heading to the autopilot,
    which wraps its error. The held set-point, a full turn from the heading, was taken
    for an execute at t = 0, and the overshoots came out as the test angles."""
    t, yaw, setpoint = zigzag_run(100.0)
    held = t < 5.0
    later = np.searchsorted(t, t - 5.0)
    columns = {
        "time": t,
        "plant.yaw": np.where(held, 0.0, yaw[later]) + math.radians(350.0),
        "controller.yaw_setpoint": np.where(held, 0.0, setpoint[later]) + math.radians(-10.0),
    }
    expected = zigzag(t[: len(t) - 500], yaw[: len(t) - 500], setpoint[: len(t) - 500])
    assert manoeuvre_metrics("zigzag", columns) == pytest.approx(expected, abs=1e-9)


def test_zigzag_metrics_need_the_executes_after_them():
    t, yaw, setpoint = zigzag_run(20.0)  # executes at 0 s and 3.9 s only
    assert zigzag(t, yaw, setpoint) == {
        "overshoot_1_deg": None,
        "overshoot_2_deg": None,
        "period_s": None,
    }
    t, yaw, setpoint = zigzag_run(30.0)  # a third execute (20.1 s), no fourth
    metrics = zigzag(t, yaw, setpoint)
    assert metrics["overshoot_1_deg"] is not None and metrics["overshoot_2_deg"] is None


def ramped(command: np.ndarray, samples: int) -> np.ndarray:
    """``command`` with every jump spread over ``samples`` samples (a ramp event)."""
    out = command.copy()
    for k in np.flatnonzero(np.diff(command) != 0.0) + 1:
        end = min(k + samples, len(out))
        out[k:end] = (
            command[k - 1] + (command[k] - command[k - 1]) * np.arange(1, end - k + 1) / samples
        )
    return out


def test_a_ramped_command_executes_where_its_ramp_starts():
    """A set-point switched with a ramp changes at every sample of the ramp; each sample
    was an execute, so a ramped 20/20 zig-zag gave overshoots of 0 deg and a period of
    0.08 s. An execute is where a change starts."""
    t, yaw, setpoint = zigzag_run(100.0)
    stepped = zigzag(t, yaw, setpoint)
    assert zigzag(t, yaw, ramped(setpoint, 100)) == stepped  # 1 s ramps, the same executes
    t, depth, setpoint = depth_run()
    steps = depth_steps(t, depth, ramped(setpoint, 200))  # 2 s ramps of the set-point
    assert len(steps) == 2
    assert [step["steady_error_m"] for step in steps] == pytest.approx([0.05, 0.0], abs=1e-9)


# --- depth steps ----------------------------------------------------------------------------


def depth_run() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Set-point 1 -> 3 m at 10 s -> 2 m at 60 s. The first step a first-order response
    (tau = 2 s) that stops 5 cm short; the second an underdamped second-order one
    (zeta = 0.5, omega_n = 1 rad/s) onto 2 m."""
    t = np.arange(round(120.0 / H) + 1) * H
    setpoint = np.where(t < 10.0, 1.0, np.where(t < 60.0, 3.0, 2.0))
    first = 1.0 + 1.95 * (1.0 - np.exp(-(t - 10.0) / 2.0))
    top = first[t < 60.0][-1]
    zeta, s = 0.5, t - 60.0
    damped = math.sqrt(1.0 - zeta**2)
    unit = 1.0 - np.exp(-zeta * s) / damped * np.sin(damped * s + math.acos(zeta))
    depth = np.where(t < 10.0, 1.0, np.where(t < 60.0, first, top + (2.0 - top) * unit))
    return t, depth, setpoint


def test_depth_steps_of_known_responses():
    t, depth, setpoint = depth_run()
    first, second = depth_steps(t, depth, setpoint)
    assert first["rise_time_s"] == pytest.approx(2.0 * math.log(9.0), abs=1e-3)  # tau ln 9
    assert first["settling_time_s"] == pytest.approx(2.0 * math.log(50.0), abs=H)  # 2 %
    assert first["overshoot_pct"] == 0.0
    assert first["steady_error_m"] == pytest.approx(0.05, abs=1e-9)
    overshoot = 100.0 * math.exp(-0.5 * math.pi / math.sqrt(0.75))  # 16.3 %
    assert second["overshoot_pct"] == pytest.approx(overshoot, abs=1e-3)
    assert second["steady_error_m"] == pytest.approx(0.0, abs=1e-9)
    assert 0.0 < second["rise_time_s"] < second["settling_time_s"] < 10.0


def test_a_coarsely_sampled_rise_is_timed_on_the_segments_that_cross_the_levels() -> None:
    """Samples 1 s apart, depth 0 -> 0.2 -> 0.6 -> 0.95 -> 1 m after a 1 m step, linear
    between samples: 10 % is reached on the first segment (half way, 0.5 s), 90 % on the
    third (2 + 0.3 / 0.35 s); the segments' slopes differ, so a crossing read off the
    wrong segment would move the rise time. The 2 % band around the final 1 m is last
    left at 3 s (0.95 m is 5 % off), so the step settles at the next sample, 4 s."""
    t = np.arange(8.0)
    setpoint = np.array([0.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    depth = np.array([0.0, 0.0, 0.2, 0.6, 0.95, 1.0, 1.0, 1.0])
    (step,) = depth_steps(t, depth, setpoint)
    assert step["rise_time_s"] == pytest.approx((2.0 + 0.3 / 0.35) - 0.5)
    assert step["settling_time_s"] == 4.0
    assert step["overshoot_pct"] == 0.0 and step["steady_error_m"] == 0.0


# --- survey ---------------------------------------------------------------------------------


def test_survey_metrics():
    metrics = survey(np.array([3.0, -4.0, 3.0, -4.0]), np.array([0.0, 1.0, 1.0, 2.0]))
    assert metrics == {
        "cross_track_rms_m": pytest.approx(math.sqrt(12.5)),
        "cross_track_max_m": 4.0,
        "legs_completed": 2,
        "legs_total": None,  # the columns alone do not say how long the mission is
        "first_waypoint_not_reached": None,
    }


def test_survey_names_the_first_waypoint_not_reached_from_the_mission_legs():
    """Two legs done of five: waypoints 1 (the start) to 3 reached, 4 is the first not;
    every leg done: none left."""
    errors, legs = np.array([3.0, -4.0, 3.0, -4.0]), np.array([0.0, 1.0, 1.0, 2.0])
    short = survey(errors, legs, legs_total=5)
    assert (short["legs_total"], short["first_waypoint_not_reached"]) == (5, 4)
    done = survey(errors, legs, legs_total=2)
    assert (done["legs_total"], done["first_waypoint_not_reached"]) == (2, None)


# --- the one call ---------------------------------------------------------------------------


def test_manoeuvre_metrics_finds_the_columns_by_variable_name():
    track = circle_track(1.0, 0.0)
    columns = {"time": track["time"]}
    columns.update({f"plant.{name}": track[name] for name in ("north", "east", "yaw", "roll")})
    command = np.where(track["time"] < 0.5, 0.0, 0.06)  # the execute at 0.5 s
    columns["controller.mass_position_cmd"] = command
    late = manoeuvre_metrics("turning-circle", columns)
    columns["controller.mass_position_cmd"] = np.full_like(command, 0.06)  # from t = 0
    assert manoeuvre_metrics("turning-circle", columns)["advance_m"] == pytest.approx(8.0, 1e-4)
    assert late["advance_m"] == pytest.approx(8.0 - 0.75, abs=1e-4)  # 0.5 s less straight
    t, depth, setpoint = depth_run()
    steps = manoeuvre_metrics("depth-steps", {"time": t, "plant.down": depth,
                                              "guidance.depth_setpoint": setpoint})  # fmt: skip
    assert steps["step_1_steady_error_m"] == pytest.approx(0.05)
    names = ("rise_time_s", "overshoot_pct", "settling_time_s", "steady_error_m")
    assert set(steps) == {f"step_{k}_{name}" for k in (1, 2) for name in names}
    t, yaw, setpoint = zigzag_run(100.0)
    zig = manoeuvre_metrics("zigzag", {"time": t, "plant.yaw": yaw,
                                       "controller.yaw_setpoint": setpoint})  # fmt: skip
    assert zig == zigzag(t, yaw, setpoint)


def test_manoeuvre_metrics_names_what_is_missing_or_ambiguous():
    with pytest.raises(ValueError, match=r"unknown manoeuvre 'zig-zag': expected one of \["):
        manoeuvre_metrics("zig-zag", {})
    columns = {"time": np.zeros(3), "guidance.cross_track_error": np.zeros(3)}
    missing = r"'survey' needs the variable 'legs_completed', but the run has no column for it "
    missing += r"\(columns: guidance\.cross_track_error\)"
    with pytest.raises(ValueError, match=missing):
        manoeuvre_metrics("survey", columns)
    columns["a.legs_completed"] = columns["b.legs_completed"] = np.ones(3)
    with pytest.raises(ValueError, match=r"several columns \['a\.legs_completed', 'b\.legs"):
        manoeuvre_metrics("survey", columns)
    columns["plant.legs_completed"] = np.full(3, 4.0)  # the plant's wins
    assert manoeuvre_metrics("survey", columns)["legs_completed"] == 4


def test_manoeuvre_columns_are_what_a_run_must_record():
    recorded = ["plant.yaw", "controller.yaw_setpoint", "guidance.yaw_setpoint", "plant.roll"]
    assert manoeuvre_columns("fault-recovery", recorded[:2]) == {
        "yaw": "plant.yaw",
        "yaw_setpoint": "controller.yaw_setpoint",
    }
    ambiguous = r"'zigzag' needs the variable 'yaw_setpoint', but the run has several columns "
    ambiguous += r"\['controller\.yaw_setpoint', 'guidance"
    with pytest.raises(ValueError, match=ambiguous):
        manoeuvre_columns("zigzag", recorded)
    # a zig-zag's command: the heading set-point, else the moving-mass command
    mass = ["plant.yaw", "plant.mass_position_cmd", "controller.mass_position_cmd"]
    assert manoeuvre_columns("zigzag", mass) == {
        "yaw": "plant.yaw",
        "mass_position_cmd": "plant.mass_position_cmd",
    }
    both = [*mass, "controller.yaw_setpoint"]
    assert manoeuvre_columns("zigzag", both)["yaw_setpoint"] == "controller.yaw_setpoint"


@pytest.mark.parametrize("kind", sorted(KINDS))
@pytest.mark.parametrize("rows", [0, 1, 2])
def test_a_run_stopped_early_gets_its_metric_names_with_none(kind, rows):
    """A run killed or stopped after a few rows: every metric it names, None or finite,
    never an exception (the summary of a partial run is still written)."""
    columns = {"time": np.arange(rows) * H}
    columns.update({f"plant.{name}": np.full(rows, 0.1) for name in VARIABLES[kind]})
    metrics = manoeuvre_metrics(kind, columns, fault_start=0.0)
    assert tuple(metrics) == metric_names(kind, steps=0)
    assert all(v is None or math.isfinite(v) for v in metrics.values())


@pytest.mark.parametrize("fault_start", [None, math.nan, math.inf])
def test_a_fault_recovery_without_its_fault_start_is_refused_naming_it(fault_start):
    """Without fault_start a fault recovery was measured from t = 0, whatever the fault's
    time: a heading error 'at the fault' and a settling time from the run's start, with no
    word. The call now names what it needs."""
    t = np.arange(0.0, 20.0, H)
    columns = {"time": t, "plant.yaw": 0.1 * np.exp(-t), "controller.yaw_setpoint": 0 * t}
    kwargs = {} if fault_start is None else {"fault_start": fault_start}
    with pytest.raises(ValueError, match=r"'fault-recovery' needs fault_start=.*\(s\)"):
        manoeuvre_metrics("fault-recovery", columns, **kwargs)
    assert manoeuvre_metrics("fault-recovery", columns, fault_start=5.0)[
        "heading_error_at_fault_deg"
    ] == pytest.approx(np.degrees(0.1 * np.exp(-5.0)), rel=1e-2)


def test_metric_names_number_the_depth_steps():
    t, depth, setpoint = depth_run()
    steps = manoeuvre_metrics("depth-steps", {"time": t, "down": depth, "depth_setpoint": setpoint})
    assert tuple(steps) == metric_names("depth-steps", steps=2)


def test_row_times_and_a_zigzags_period_are_given_to_the_ns_as_durations_are() -> None:
    """A leg's completion is a row's time k * h, and a zig-zag's period a mean of
    differences of row times: both kept the doubles' noise (0.35000000000000003 s,
    5.790000000000001 s) in summary.json while a leg's duration beside them was rounded to
    the ns. Every time the metrics take from rows is given to the ns."""
    t = np.arange(1300) * H  # t[35] is 0.35000000000000003 in doubles
    legs = np.where(t < t[35], 0.0, 1.0)
    tracker = LegTracker(legs_total=1)
    tracker.add(t, np.zeros_like(t), legs)
    (leg,) = tracker.legs()
    assert (leg["completed_at_s"], leg["duration_s"]) == (0.35, 0.35)
    command = np.zeros_like(t)
    for k, execute in enumerate((100, 400, 825, 1130, 1253)):  # e2 -> e4, e3 -> e5
        command[execute:] = (-1.0) ** k
    metrics = zigzag(t, np.zeros_like(t), command)
    assert metrics["period_s"] == 5.79  # the mean of 7.3 s and 4.28 s


def test_times_taken_between_two_rows_carry_no_float_noise() -> None:
    """A leg's duration and a depth step's settling time are differences of two row times
    k * h: 8.21 - 1.0 is 7.210000000000001 in doubles, which summary.json would show; they
    are given to the nanosecond, as the recording's sim_time (docs/runs.md)."""
    t = np.arange(1200) * H  # t[100] = 1.0 s, t[821] = 8.21 s
    legs = np.where(t < t[100], 0.0, np.where(t < t[821], 1.0, 2.0))
    tracker = LegTracker(legs_total=2)
    tracker.add(t, np.zeros_like(t), legs)
    assert [leg["duration_s"] for leg in tracker.legs()] == [1.0, 7.21]
    setpoint = np.where(t < t[100], 0.0, 1.0)
    depth = np.where(t < t[821], 0.5 * (t >= t[100]), 1.0)  # inside the band from 8.21 s
    (step,) = depth_steps(t, depth, setpoint)
    assert step["settling_time_s"] == 7.21
    error = np.radians(np.where(t < t[821], 10.0, 0.0))
    metrics = fault_recovery(t, error, np.zeros_like(t), start=float(t[100]))
    assert metrics["heading_settling_time_s"] == pytest.approx(7.2, abs=H)
    assert metrics["heading_settling_time_s"] == round(metrics["heading_settling_time_s"], 9)


# --- fault recovery -------------------------------------------------------------------------


def test_fault_recovery_of_a_known_heading():
    """Heading error 10 deg decaying with tau = 2 s from the fault at t = 3 s: below 1 deg
    from 3 + 2 ln 10 s on."""
    t = np.arange(2001) * H
    error = np.radians(np.where(t < 3.0, 10.0, 10.0 * np.exp(-(t - 3.0) / 2.0)))
    setpoint = np.full_like(t, 3.0)  # near pi: the error is taken on the circle
    metrics = fault_recovery(t, setpoint - error - 2 * math.pi, setpoint, start=3.0)
    assert metrics["heading_error_at_fault_deg"] == pytest.approx(10.0)
    assert metrics["heading_error_max_deg"] == pytest.approx(10.0)
    assert metrics["heading_error_final_deg"] == pytest.approx(10.0 * math.exp(-8.5), rel=1e-6)
    assert metrics["heading_settling_time_s"] == pytest.approx(2.0 * math.log(10.0), abs=H)
    drifting = fault_recovery(t, np.radians(0.1 * t), np.zeros_like(t), start=3.0)
    assert drifting["heading_settling_time_s"] is None  # 2 deg at the end: not recovered
    assert drifting["heading_error_max_deg"] == pytest.approx(2.0)
    assert (
        fault_recovery(t, np.zeros_like(t), np.zeros_like(t), 3.0)["heading_settling_time_s"] == 0.0
    )
    assert set(fault_recovery(t, t, t, start=30.0).values()) == {None}  # stopped before it
