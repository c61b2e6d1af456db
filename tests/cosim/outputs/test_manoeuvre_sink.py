"""The manoeuvre metrics of a run as its rows stream by (cosim.outputs.manoeuvre): the same
as from the whole table, whatever the chunks; a run ending on NaN, or with no rows, still
gets every metric name (None), never an exception."""

from __future__ import annotations

import json
import math
import tracemalloc
from pathlib import Path

import numpy as np
import pytest

import cosim
from cosim.metrics.manoeuvres import manoeuvre_metrics, metric_names, zigzag
from cosim.outputs.manoeuvre import ManoeuvreSink, fault_start, scenario_metric_names
from cosim.runner import report, run_scenario
from cosim.scenario.mission_doubts import MissionWarning
from cosim.scenario.spec import load_scenario, scenario_from_toml

H = 0.01
RECORD = ["plant.roll", "plant.north", "plant.east", "plant.yaw", "plant.mass_position_cmd",
          "plant.u"]  # fmt: skip


def turning_rows(t_end: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """A circle of radius 5 m at 1 m/s from t = 0, rolled 0.2 rad, the command at 0.06."""
    t = np.arange(round(t_end / H) + 1) * H
    theta = t / 5.0
    values = np.column_stack([np.full_like(t, 0.2), 5.0 * np.sin(theta),
                              5.0 * (1.0 - np.cos(theta)), theta, np.full_like(t, 0.06),
                              np.ones_like(t)])  # fmt: skip
    return t, values


def test_streamed_metrics_equal_those_of_the_whole_table():
    t, values = turning_rows()
    sink = ManoeuvreSink("turning-circle", RECORD)
    for start in range(0, len(t), 137):  # chunks as the master hands them over
        sink.add_rows(t[start : start + 137], values[start : start + 137])
    values[:, 0] = -1.0  # the sink keeps copies: later changes to the master's buffer
    summary = sink.summary()
    columns = {"time": t, **{name: values[:, k] for k, name in enumerate(RECORD)}}
    columns["plant.roll"] = np.full_like(t, 0.2)
    expected = manoeuvre_metrics("turning-circle", columns)
    assert summary == {"manoeuvre": "turning-circle", **expected}
    assert summary["steady_turning_diameter_m"] == pytest.approx(10.0, rel=1e-6)


def test_a_run_ending_on_nan_or_without_rows_gets_none():
    t, values = turning_rows()
    values[-500:, 1:3] = np.nan  # the track blew up
    sink = ManoeuvreSink("turning-circle", RECORD)
    sink.add_rows(t, values)
    summary = sink.summary()
    assert set(summary) - {"manoeuvre_error"} == {"manoeuvre", *metric_names("turning-circle")}
    assert all(
        v is None or math.isfinite(v) for k, v in summary.items() if k.endswith(("m", "deg", "pct"))
    )
    json.dumps(summary, allow_nan=False)  # what summary.json accepts
    empty = ManoeuvreSink("survey", ["guidance.cross_track_error", "guidance.legs_completed"])
    assert empty.summary() == {"manoeuvre": "survey", **dict.fromkeys(metric_names("survey")),
                               "legs": []}  # fmt: skip


def test_a_column_the_kind_needs_must_be_recorded():
    without_command = [c for c in RECORD if c != "plant.mass_position_cmd"]
    needs = r"'zigzag' needs the variable 'yaw_setpoint' \(or 'mass_position_cmd'\)"
    with pytest.raises(ValueError, match=needs):
        ManoeuvreSink("zigzag", without_command)


MASS_ZIGZAG = """
summary = "10/10 zig-zag on the moving mass alone"
stop_time = 60.0
manoeuvre = "zigzag"
[coupling]
step = 0.01
[instances.plant]
fmu = "AuvPlant"
[instances.plant.start]
variant = "lateral"
u_0 = 1.525
mass_position_cmd = 0.06
[[events]]
when = "plant.yaw > 0.17453292519943295"
repeat = true
set = { "plant.mass_position_cmd" = -0.06 }
[[events]]
when = "plant.yaw < -0.17453292519943295"
repeat = true
set = { "plant.mass_position_cmd" = 0.06 }
"""


def test_a_zigzag_of_the_moving_mass_without_an_autopilot_is_measured(fmu_paths) -> None:
    """The open-loop zig-zag of the standard (the command switched at the test angle, no
    heading autopilot): its executes are the moving-mass command's switches. Such a
    scenario was refused for want of a yaw_setpoint, which only an autopilot has."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = scenario_from_toml(MASS_ZIGZAG, "mass-zigzag", fmu_dir=fmu_dir)
    run = cosim.run(scenario, fmu_dir=fmu_dir)
    results = run.results
    yaw, command = results["plant.yaw"].to_numpy(), results["plant.mass_position_cmd"]
    expected = zigzag(results.index.to_numpy(), yaw, command.to_numpy())
    assert {name: run.summary[name] for name in expected} == pytest.approx(expected)
    assert expected["period_s"] is not None and expected["overshoot_2_deg"] > 0.0


def test_a_scenarios_metric_names_and_fault_start(fmu_paths) -> None:
    """What a study's table is laid out by before any run: a depth step per time event
    that sets a depth set-point; the fault-recovery metrics count from the first fault."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    depth = load_scenario("depth-steps", fmu_dir=fmu_dir)
    assert scenario_metric_names(depth) == metric_names("depth-steps", steps=2)
    jam = load_scenario("mass-jam", fmu_dir=fmu_dir)
    assert fault_start(jam) == 3.0 and scenario_metric_names(jam)[0] == "heading_error_at_fault_deg"
    plain = load_scenario("bs-3", fmu_dir=fmu_dir)
    assert fault_start(plain) == 0.0 and scenario_metric_names(plain) == ()


SURVEY = ["guidance.cross_track_error", "guidance.legs_completed"]


def _survey_rows(rows: int, seed: int = 5) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    legs = np.minimum(np.arange(rows) // 1000, 7).astype(float)
    return np.arange(rows) * H, np.column_stack([rng.normal(0.0, 1.5, rows), legs])


def _held_after(rows: int, chunk: int) -> tuple[int, dict]:
    """Bytes (tracemalloc) a survey's sink holds after ``rows`` rows, and its summary."""
    t, values = _survey_rows(rows)
    tracemalloc.start()
    try:
        sink = ManoeuvreSink("survey", SURVEY)
        for start in range(0, rows, chunk):
            sink.add_rows(t[start : start + chunk], values[start : start + chunk])
        held = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    return held, sink.summary()


def test_a_long_survey_holds_no_row_and_gets_the_same_figures_whatever_the_chunks():
    """A survey of 36000 s kept the time and both columns it reads of every row (24 bytes
    a row, 86 MB, and as much again at its end): its figures need three numbers. What
    the sink holds must not grow with the rows, and the figures must not depend on how
    the master chunked them (hand-offs follow the wall clock)."""
    held = {rows: _held_after(rows, 1000)[0] for rows in (100_000, 400_000)}
    assert held[400_000] < held[100_000] + 100_000, f"bytes held after n rows: {held}"
    _, by_1000 = _held_after(300_000, 1000)
    _, by_777 = _held_after(300_000, 777)
    assert by_1000 == by_777
    assert by_1000["legs_completed"] == 7


def test_a_short_survey_streamed_equals_the_whole_table_bit_for_bit():
    t, values = _survey_rows(20_000)
    _, streamed = _held_after(20_000, 137)
    expected = manoeuvre_metrics("survey", {"time": t, SURVEY[0]: values[:, 0],
                                            SURVEY[1]: values[:, 1]})  # fmt: skip
    assert streamed.pop("legs")[-1]["completed_at_s"] is None  # the last leg goes on
    assert streamed == {"manoeuvre": "survey", **expected}


def test_a_survey_stopped_short_names_the_first_waypoint_it_did_not_reach(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """The survey run for 60 s of its 186 s printed "legs_completed = 2" and summary.json
    had no word of the mission's 7 legs: a planner could not tell a third of a mission from
    a finished one. Now both give the legs of the mission and the first waypoint not
    reached (waypoint 1 is the start, so 2 legs done leave waypoint 4 next)."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    with pytest.warns(MissionWarning, match="waypoint 4 onwards will not be reached"):
        outcome = run_scenario("survey", tmp_path / "run", stop_time=60.0, no_rrd=True,
                               fmu_dir=fmu_dir)  # fmt: skip
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    done = summary["legs_completed"]
    assert 0 < done < 7  # the run ends mid-mission
    assert (summary["legs_total"], summary["first_waypoint_not_reached"]) == (7, done + 2)
    assert f"legs_completed = {done} of 7: waypoints {done + 2} to 8 not reached" in report(outcome)


def test_a_survey_summary_gives_each_leg_its_time_and_largest_cross_track_error():
    """summary.json had whole-run figures only: how long each leg took, which leg the
    vehicle strayed on, and which it never finished were left to be read off the
    legs_completed column of results.csv. Two legs done of three, at 3 s and 7 s."""
    t = np.arange(21) * 0.5
    legs = np.select([t < 3.0, t < 7.0], [0.0, 1.0], 2.0)
    error = np.select([t < 3.0, t < 7.0], [2.0 * np.sin(t), -4.0 * (t == 5.0)], 1.0)
    sink = ManoeuvreSink("survey", SURVEY, legs_total=3)
    for start in range(0, len(t), 4):
        sink.add_rows(t[start : start + 4], np.column_stack([error, legs])[start : start + 4])
    leg_1_max = float(np.max(np.abs(error[t < 3.0])))
    unknown = {"closest_m": None, "within_acceptance_radius": None}  # no mission given
    assert sink.summary()["legs"] == [
        {"leg": 1, "to_waypoint": 2, "completed_at_s": 3.0, "duration_s": 3.0,
         "cross_track_max_m": leg_1_max, **unknown},
        {"leg": 2, "to_waypoint": 3, "completed_at_s": 7.0, "duration_s": 4.0,
         "cross_track_max_m": 4.0, **unknown},
        {"leg": 3, "to_waypoint": 4, "completed_at_s": None, "duration_s": None,
         "cross_track_max_m": 1.0, **unknown},
    ]  # fmt: skip


def test_a_waypoint_passed_outside_its_acceptance_radius_is_not_called_reached(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """Legs 3 m apart (the vehicle turns on a 10 m circle) with a 1 m acceptance radius:
    the guidance counts the 3 m leg done once the vehicle is past its end along the track,
    and the run said "legs_completed = 3 of 3" though the vehicle never came within 1 m
    of waypoint 3. Each leg now gives its closest approach to its end waypoint (over the
    rows it was active, and the row completing it), and the run names the waypoint."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    tight = cosim.load_scenario("survey", fmu_dir=fmu_dir).with_start(
        {"guidance.waypoints": "0, 0, 2; 30, 0, 2; 30, 3, 2; 0, 3, 2",
         "guidance.acceptance_radius": 1.0}
    )  # fmt: skip
    with pytest.warns(MissionWarning, match="waypoint 4 onwards will not be reached"):
        outcome = run_scenario(tight, tmp_path / "run", stop_time=40.0, no_rrd=True,
                               fmu_dir=fmu_dir, keep_rows=True)  # fmt: skip
    legs = json.loads((tmp_path / "run" / "summary.json").read_text())["legs"]
    result = outcome.result
    done = result.column("guidance.legs_completed")
    north, east = result.column("plant.north"), result.column("plant.east")
    for leg, (n, e) in zip(legs[:2], [(30.0, 0.0), (30.0, 3.0)], strict=True):
        k = leg["leg"]
        active = (done == k - 1) | (np.arange(done.size) == np.argmax(done >= k))
        closest = float(np.min(np.hypot(north[active] - n, east[active] - e)))
        assert leg["closest_m"] == pytest.approx(closest, rel=1e-12)
    assert [leg["within_acceptance_radius"] for leg in legs[:2]] == [True, False]
    assert (
        f"waypoint 3 passed {legs[1]['closest_m']:.3g} m off, outside the acceptance radius"
    ) in report(outcome)
