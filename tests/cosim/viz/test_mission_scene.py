"""A mission in the 3D scene (cosim.viz.scene): the planned path and the waypoints of a
scenario's guidance, drawn static, and the waypoint it steers for, per step; read back
from the .rrd file with rerun.chunk.RrdReader."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
import rerun as rr
from rerun.chunk import RrdReader
from scenario_factory import auv_scenario

from controller_fmu.los_guidance import DEFAULT_WAYPOINTS, parse_waypoints
from cosim.runner import run_scenario
from cosim.scenario.mission_doubts import MissionWarning
from cosim.scenario.spec import load_scenario
from cosim.viz.layout import time_index
from cosim.viz.mission import mission_waypoints
from cosim.viz.recording import RerunSink
from cosim.viz.scene import SceneWriter, log_static_scene
from plant_fmu.model.parameters import load_vehicle

TARGET = ["guidance.waypoint_north", "guidance.waypoint_east", "guidance.waypoint_down"]


@pytest.fixture(autouse=True)
def scratch_home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Rerun may write settings under HOME and XDG folders: keep them out of the user's."""
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    for name in ("XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME", "XDG_RUNTIME_DIR"):
        monkeypatch.setenv(name, str(tmp_path / "home" / name.lower()))


def _flat(array: pa.Array) -> np.ndarray:
    while pa.types.is_list(array.type) or pa.types.is_fixed_size_list(array.type):
        array = array.flatten()
    return array.to_numpy(zero_copy_only=False)


def components(path: Path, entity: str) -> dict[str, list]:
    """Every component logged on ``entity``: name -> its rows (static and temporal)."""
    found: dict[str, list] = {}
    for chunk in RrdReader(path).stream():
        if chunk.entity_path == entity:
            batch = chunk.to_record_batch()
            for name in batch.schema.names:
                found.setdefault(name, []).extend(batch.column(name).to_pylist())
    assert found, f"nothing on {entity} in {path}"
    return found


def entities(path: Path) -> set[str]:
    return set(RrdReader(path).stream().collect().schema().entity_paths())


def test_mission_waypoints_come_from_the_scenarios_guidance(fmu_paths) -> None:
    fmu_dir = fmu_paths["AuvGuidance"].parent
    survey = load_scenario("survey", fmu_dir=fmu_dir)
    expected = parse_waypoints(survey.instances["guidance"].start["waypoints"])
    points = mission_waypoints(survey.to_toml())
    np.testing.assert_array_equal(points, [[w.north, w.east, w.down] for w in expected])
    assert mission_waypoints(load_scenario("bs-3", fmu_dir=fmu_dir).to_toml()) is None
    default = '[instances.g]\nfmu = "/somewhere/AuvGuidance.fmu"\n'  # no waypoints given
    assert len(mission_waypoints(default)) == len(parse_waypoints(DEFAULT_WAYPOINTS))
    assert mission_waypoints("not toml = [") is None
    assert (
        mission_waypoints('[instances.g]\nfmu = "AuvGuidance"\nstart = {waypoints = "1"}') is None
    )


def test_the_path_waypoints_and_target_are_drawn(tmp_path: Path) -> None:
    path = tmp_path / "mission.rrd"
    waypoints = np.array([[0.0, 0.0, 2.0], [50.0, 0.0, 2.0], [50.0, 20.0, 3.0]])
    columns = ["plant.north", "plant.east", "plant.down", *TARGET]
    times = np.arange(5) * 0.01
    values = np.column_stack(
        [times, 0.1 * times, np.full(5, 2.0), [50, 50, 50, 50, 50], [0, 0, 0, 20, 20],
         [2, 2, 2, 3, 3]]  # the target switches to waypoint 3 at the fourth step
    ).astype(float)  # fmt: skip
    rec = rr.RecordingStream("mission-test")
    rec.set_sinks(rr.FileSink(str(path)))
    vehicle = load_vehicle("remus100")
    log_static_scene(rec, vehicle, columns, show_depth_setpoint=False, waypoints=waypoints)
    scene = SceneWriter(rec, vehicle, show_depth_setpoint=False)

    def column(name: str) -> np.ndarray | None:
        return values[:, columns.index(name)] if name in columns else None

    scene.send(time_index(times), len(times), column)
    rec.flush()
    rec.disconnect()

    strip = components(path, "/world/mission/path")["LineStrips3D:strips"]
    np.testing.assert_array_equal(np.array(strip[0][0]), waypoints)
    marks = components(path, "/world/mission/waypoints")
    np.testing.assert_array_equal(np.array(marks["Points3D:positions"][0]), waypoints)
    assert marks["Points3D:labels"][0] == ["1", "2", "3"]
    target = components(path, "/world/mission/target")
    positions = [row for row in target["Points3D:positions"] if row]
    np.testing.assert_array_equal(np.array(positions)[:, 0, :], values[:, 3:6])


def test_a_run_without_a_mission_draws_none(tmp_path: Path) -> None:
    path = tmp_path / "plain.rrd"
    rec = rr.RecordingStream("plain-test")
    rec.set_sinks(rr.FileSink(str(path)))
    log_static_scene(rec, load_vehicle("remus100"), ["plant.north"], show_depth_setpoint=False)
    rec.flush()
    rec.disconnect()
    assert not [e for e in entities(path) if e.startswith("/world/mission")]


def test_the_sink_draws_the_target_of_a_recorded_guidance(fmu_paths, tmp_path: Path) -> None:
    """A scenario without a waypoint guidance that records a target: the target alone."""
    columns = ["plant.north", "plant.east", "plant.down", *TARGET]
    times = np.arange(3) * 0.01
    values = np.array([[0.0, 0.0, 2.0, 50.0, 0.0, 2.0]] * 3)
    scenario = auv_scenario(fmu_paths["AuvPlant"].parent, "survey", columns, controller=None)
    with RerunSink(scenario, tmp_path / "run.rrd") as sink:
        sink.add_rows(times, values)
    target = components(tmp_path / "run.rrd", "/world/mission/target")
    positions = [row for row in target["Points3D:positions"] if row]
    assert np.array(positions)[:, 0, :].tolist() == [[50.0, 0.0, 2.0]] * 3
    assert "/world/mission/path" not in entities(tmp_path / "run.rrd")


def test_the_survey_runs_recording_shows_its_planned_path(fmu_paths, tmp_path: Path) -> None:
    """`auv-cosim run survey` (its first 2 s): the recording draws the mission's path and
    waypoints, the guidance's own, in the 3D scene, and the target it steers for."""
    fmu_dir = fmu_paths["AuvGuidance"].parent
    with pytest.warns(MissionWarning, match="waypoint 2 onwards will not be reached"):
        outcome = run_scenario("survey", tmp_path / "run", stop_time=2.0, fmu_dir=fmu_dir)
    assert outcome.result.complete, outcome.result.error
    rrd = outcome.paths["recording"]
    guidance = outcome.result.scenario.instances["guidance"].start["waypoints"]
    expected = [[w.north, w.east, w.down] for w in parse_waypoints(guidance)]
    strip = components(rrd, "/world/mission/path")["LineStrips3D:strips"]
    np.testing.assert_array_equal(np.array(strip[0][0]), expected)
    marks = components(rrd, "/world/mission/waypoints")
    np.testing.assert_array_equal(np.array(marks["Points3D:positions"][0]), expected)
    assert marks["Points3D:labels"][0] == [str(k) for k in range(1, len(expected) + 1)]
    assert "/world/mission/target" in entities(rrd)


def test_each_waypoint_the_guidance_turns_to_is_marked_when_it_does(
    fmu_paths, tmp_path: Path
) -> None:
    """The guidance switches the heading set-point at each waypoint, inside the FMU: no
    event marked it, and a survey's recording said nothing of where a leg began. Each
    target it steers for is now an events entry at the step it starts, across the
    sink's batches too (a switch on a batch's first row)."""
    columns = ["plant.north", "plant.east", "plant.down", *TARGET]
    times = np.arange(6) * 0.01
    targets = [[50, 0, 2]] * 3 + [[50, 20, 3]] * 3  # waypoint 3 from the fourth step
    values = np.column_stack([np.zeros((6, 3)), np.array(targets, dtype=float)])
    scenario = auv_scenario(fmu_paths["AuvPlant"].parent, "survey", columns, controller=None)
    with RerunSink(scenario, tmp_path / "run.rrd") as sink:
        sink.add_rows(times[:3], values[:3])
        sink.add_rows(times[3:], values[3:])
    logged = components(tmp_path / "run.rrd", "/events")
    notes = [
        (t, text[0])
        for t, text in zip(logged["sim_time"], logged["TextLog:text"], strict=True)
        if text[0].startswith("guidance")
    ]
    assert [(t.total_seconds(), text) for t, text in notes] == [
        (0.0, "guidance steers for the waypoint north 50 m, east 0 m, down 2 m"),
        (0.03, "guidance steers for the waypoint north 50 m, east 20 m, down 3 m"),
    ]
