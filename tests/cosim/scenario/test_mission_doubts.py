"""Missions a waypoint guidance cannot fly as planned are named before the run: a leg
against a current the vehicle is not faster than, and waypoints the stop time ends before
the vehicle could reach them (cosim.scenario.mission_doubts)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

import cosim
from cosim.scenario.mission_doubts import MissionWarning, ground_speed, mission_doubts

WEST_CURRENT = {  # 2 m/s to the west: faster than the vehicle's 1.5 m/s through the water
    "plant.current_east": -2.0,
    "controller.current_east": -2.0,
    "guidance.current_east": -2.0,
    "guidance.compensate_current": False,  # (its crab angle would refuse the cross-current)
}


def test_ground_speed_along_a_leg_in_a_current() -> None:
    """Holding the course of the leg through a current: the speed across the leg is spent
    on the crab angle, the speed along it adds; None when no heading holds the course."""
    north = 0.0  # course (rad)
    assert ground_speed(north, 1.5, 0.0, 0.0) == pytest.approx(1.5)
    assert ground_speed(north, 1.5, -0.5, 0.0) == pytest.approx(1.0)  # head current
    assert ground_speed(north, 1.5, 0.0, 0.9) == pytest.approx(1.2)  # 0.9 across: 1.2 along
    assert ground_speed(north, 1.5, 0.0, 1.5) is None  # as fast across as the vehicle
    assert ground_speed(math.pi / 2, 1.5, 0.0, -2.0) == pytest.approx(-0.5)  # drifts back


def test_a_leg_against_a_current_faster_than_the_vehicle_is_named_and_the_run_warns(
    fmu_paths: dict[str, Path],
) -> None:
    """A survey in a 2 m/s current ran to its stop time without a word: the vehicle, at
    1.5 m/s through the water, drifted west, "legs_completed = 0", nothing said why."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    survey = cosim.load_scenario("survey", fmu_dir=fmu_dir)
    assert mission_doubts(survey) == []  # the built-in survey flies every leg in time
    (line,) = [d for d in mission_doubts(survey.with_start(WEST_CURRENT)) if "current" in d]
    assert line.startswith("instances.guidance.start.waypoints: leg 1 (waypoint 1 -> 2, "
                           "course 0 deg) cannot be flown")  # fmt: skip
    assert "2 m/s across the leg" in line and "waypoint 2 onwards will not be reached" in line
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cosim.run("survey", stop_time=0.1, start=WEST_CURRENT, fmu_dir=fmu_dir)
    lines = [str(w.message) for w in caught if issubclass(w.category, MissionWarning)]
    assert any("leg 1 (waypoint 1 -> 2, course 0 deg) cannot be flown" in x for x in lines)


def test_waypoints_beyond_the_stop_time_are_named(fmu_paths: dict[str, Path]) -> None:
    """The survey stopped at 60 s of its 186 s ran without a word of the waypoints it
    could not reach: its first two legs (70 m) take at least 45 s at 1.525 m/s in the
    current, the third (50 m more) 78 s, so waypoint 4 is the first it cannot reach."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    survey = cosim.load_scenario("survey", fmu_dir=fmu_dir).with_overrides(stop_time=60.0)
    (line,) = mission_doubts(survey)
    assert line.startswith("instances.guidance.start.waypoints: waypoint 4 is 120 m along "
                           "the path")  # fmt: skip
    assert line.endswith("past the stop time of 60 s: waypoint 4 onwards will not be reached")


def test_waypoints_that_look_like_latitude_and_longitude_are_named(
    fmu_paths: dict[str, Path],
) -> None:
    """Halifax harbour given as latitude, longitude (44.6488 N, 63.5752 W to 44.6500 N,
    63.5700 W, about 440 m) ran as a mission of 5 mm, 78 m from the vehicle: the guidance
    takes metres, north, east, down. Only the acceptance radius's doubt spoke, of a leg of
    0.005 m, and not of the units."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    survey = cosim.load_scenario("survey", fmu_dir=fmu_dir)
    harbour = survey.with_start({"guidance.waypoints": "44.6488, -63.5752, 2; 44.65, -63.57, 2"})
    lines = [line for line in mission_doubts(harbour) if "latitude" in line]
    away = min(math.hypot(44.6488, 63.5752), math.hypot(44.65, 63.57))  # m, the nearest
    assert len(lines) == 1 and lines[0].startswith(
        f"instances.guidance.start.waypoints: the mission spans 0.005337 m, {away:.4g} m from "
        "the origin: waypoints are north, east, down in metres (NED)"
    ), lines
    small = survey.with_start({"guidance.waypoints": "0, 0, 2; 0.5, 0, 2"})  # near the origin
    assert not [line for line in mission_doubts(small) if "latitude" in line]


def _survey_with_events(tmp_path: Path, fmu_dir: Path, events: str) -> cosim.Scenario:
    """The built-in survey with ``events`` (TOML ``[[events]]`` tables) appended."""
    from cosim.scenario.spec import SCENARIO_FOLDER

    text = (SCENARIO_FOLDER / "survey.toml").read_text(encoding="utf-8") + events
    path = tmp_path / "tide.toml"
    path.write_text(text, encoding="utf-8")
    return cosim.load_scenario(path, fmu_dir=fmu_dir)


def test_a_current_an_event_sets_too_strong_for_a_leg_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A tide turning at 60 s to 2 m/s west (an event on the plant's current_east) ran
    without a word: the doubts read only the start value, 0.2 m/s east, which every leg
    beats. The line names the event and its time; one the vehicle beats says nothing."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    tide = '\n[[events]]\nname = "tide"\ntime = 60.0\nset = { "plant.current_east" = -2.0 }\n'
    lines = [d for d in mission_doubts(_survey_with_events(tmp_path, fmu_dir, tide))
             if "current" in d]  # fmt: skip
    assert len(lines) == 1, lines
    assert "leg 1 (waypoint 1 -> 2, course 0 deg) cannot be flown" in lines[0]
    assert "from t = 60 s (event tide)" in lines[0] and "-2 m/s east" in lines[0]
    slack = tide.replace("-2.0", "-0.5")
    assert mission_doubts(_survey_with_events(tmp_path, fmu_dir, slack)) == []


def test_a_current_a_series_sets_too_strong_for_a_leg_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A tide profile (an events series on the plant's current_north) that reaches 2 m/s
    south at 90 s is named from that row's time, on the survey's first leg north."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    (tmp_path / "tide.csv").write_text("time,plant.current_north\n0,0\n45,-1\n90,-2\n")
    series = '\n[[events]]\nname = "ebb"\nseries = "tide.csv"\n'
    lines = [d for d in mission_doubts(_survey_with_events(tmp_path, fmu_dir, series))
             if "current" in d]  # fmt: skip
    assert len(lines) == 1, lines
    assert "from t = 90 s (event ebb)" in lines[0] and "-2 m/s north" in lines[0]


def two_vehicles_one_guidance(
    fmu_dir: Path, steer: str | None, depths: bool = False
) -> cosim.Scenario:
    """Two vehicles (plant_a with ctrl_a, plant_b with ctrl_b, same-name connections on)
    and one guidance reading plant_a's position; its yaw set-point feeds the autopilot
    ``steer`` alone, or (None) every autopilot, as the same-name rule connects it; its depth
    set-point every autopilot too where ``depths``, else none."""
    from two_vehicles import two_vehicles_toml

    from cosim.scenario.spec import scenario_from_toml

    text = two_vehicles_toml(same_names=True, stop_time=60.0)
    text = text.replace('order = ["ctrl_a"', 'order = ["guidance", "ctrl_a"')
    guidance = (
        '[instances.guidance]\nfmu = "AuvGuidance"\n[instances.guidance.start]\n'
        'waypoints = "0, 0, 0; 50, 0, 0; 50, 20, 0"\n[connections]'
    )
    text = text.replace("[connections]", guidance)
    reads = [f'{{ from = "plant_a.{v}", to = "guidance.{v}" }}' for v in ("north", "east", "yaw")]
    unsteered = ["ctrl_a.yaw_setpoint", "ctrl_b.yaw_setpoint"]
    if steer is not None:
        unsteered.remove(f"{steer}.yaw_setpoint")
    removed = ", ".join(f'"{r}"' for r in ["ctrl_a.depth_setpoint", "ctrl_b.depth_setpoint"])
    if not depths:
        text = text.replace("remove = [", f"remove = [{removed}, ")
    if steer is not None:
        text = text.replace("remove = [", f'remove = ["{unsteered[0]}", ')
    text = text.replace("add = [", f"add = [{', '.join(reads)}, ")
    return scenario_from_toml(text, fmu_dir=fmu_dir)


def test_a_guidance_steering_a_vehicle_by_another_ones_position_is_named(
    fmu_dir: Path,
) -> None:
    """Two vehicles and one guidance reading plant_a's position: the same-name rule fed
    its yaw set-point to both autopilots, so plant_b flew headings computed for plant_a's
    position, and the checks before the run said nothing of it. Now they name it; a
    guidance steering only the vehicle it reads is not doubted."""
    both = mission_doubts(two_vehicles_one_guidance(fmu_dir, steer=None))
    assert both == [
        "instances.guidance: its yaw_setpoint steers ctrl_b, which drives plant_b, but the "
        "guidance reads the position of plant_a (guidance.north from plant_a.north): "
        "plant_b follows headings computed for where plant_a is; remove the connection "
        "guidance.yaw_setpoint -> ctrl_b.yaw_setpoint (connections.remove = "
        '["ctrl_b.yaw_setpoint"]), or give plant_b a guidance of its own'
    ]
    assert mission_doubts(two_vehicles_one_guidance(fmu_dir, steer="ctrl_a")) == []


def test_a_guidance_steering_another_vehicle_by_both_set_points_names_both(
    fmu_dir: Path,
) -> None:
    """With the same-name rule's connections as they come, one guidance feeds both its
    set-points to both autopilots. The line named the first connection only, the depth
    set-point ("its depth_setpoint steers ctrl_b ... follows headings"), and told to remove
    that one: done so, the yaw set-point still steered plant_b. It names both."""
    (line,) = mission_doubts(two_vehicles_one_guidance(fmu_dir, steer=None, depths=True))
    assert line == (
        "instances.guidance: its yaw_setpoint and depth_setpoint steer ctrl_b, which drives "
        "plant_b, but the guidance reads the position of plant_a (guidance.north from "
        "plant_a.north): plant_b follows headings and depths computed for where plant_a is; "
        "remove the connections guidance.yaw_setpoint -> ctrl_b.yaw_setpoint and "
        "guidance.depth_setpoint -> ctrl_b.depth_setpoint (connections.remove = "
        '["ctrl_b.yaw_setpoint", "ctrl_b.depth_setpoint"]), or give plant_b a guidance of '
        "its own"
    )
