"""The Rerun sink, read back with rerun.chunk.RrdReader.

The data is a real plant run (plant_fmu.model.stepping.simulate, 6-DOF, 4 s at 10 ms) with the
controller's columns held constant, fed to the sink in uneven batches as the master does.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader
from scenario_factory import auv_scenario

import cosim
from cosim.cli import main
from cosim.errors import CosimError
from cosim.viz import recording
from cosim.viz.recording import RECORDING_FILE, RerunSink, rerun_executable, view_run
from cosim.viz.scene import CURRENT_SCALE, FORCE_SCALE, MASS_RADIUS
from plant_fmu.model.dynamics import (
    INPUT_INDEX,
    INPUT_NAMES,
    STATE_INDEX,
    STATE_NAMES,
    PlantModel,
    Variant,
)
from plant_fmu.model.kinematics import rotation_matrix
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import simulate

STEP = 0.01
CONTROLLER = {  # recorded controller column -> plant input it drives (or a constant)
    "controller.thrust": 9.0,
    "controller.tunnel_force": 6.0,
    "controller.fin_angle": 0.08,
    "controller.mass_position_cmd": 0.05,
    "controller.current_north": 0.05,
    "controller.current_east": 0.2,
    "controller.yaw_setpoint": math.radians(-7.55),
    "controller.depth_setpoint": 1.0,
}
PLANT_START = 'vehicle = "remus100"\nvariant = 0'
CONTROLLER_START = "depth_mode = 1\nheading_mode = 3"


@pytest.fixture(scope="module", autouse=True)
def scratch_home(tmp_path_factory: pytest.TempPathFactory):
    """Rerun writes settings under HOME and XDG folders: keep them out of the user's."""
    home = tmp_path_factory.mktemp("home")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("HOME", str(home))
        for name in ("XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME", "XDG_RUNTIME_DIR"):
            mp.setenv(name, str(home / name.lower()))
        yield home


def plant_run(duration: float = 4.0) -> tuple[np.ndarray, list[str], np.ndarray]:
    """(times, columns, values) of a 6-DOF plant run named as the master names them."""
    vehicle = load_vehicle("remus100")
    model = PlantModel(vehicle, variant=Variant.FULL)
    inputs = np.zeros(len(INPUT_NAMES))
    for column, value in CONTROLLER.items():
        name = column.split(".", 1)[1]
        if name in INPUT_INDEX:
            inputs[INPUT_INDEX[name]] = value
    x0 = np.zeros(len(STATE_NAMES))
    x0[STATE_INDEX["u"]] = 1.5
    x0[STATE_INDEX["v"]] = -0.1
    times, states = simulate(model, x0, inputs, duration, STEP)
    relative = np.array([model.relative_velocity(x, inputs)[:3] for x in states])
    energy = np.array([model.kinetic_energy(x, inputs) for x in states])
    columns = [f"plant.{name}" for name in STATE_NAMES]
    columns += ["plant.u_rel", "plant.v_rel", "plant.w_rel", "plant.kinetic_energy"]
    columns += list(CONTROLLER)
    controller = np.tile(list(CONTROLLER.values()), (len(times), 1))
    return times, columns, np.column_stack([states, relative, energy, controller])


def feed(sink: RerunSink, times: np.ndarray, values: np.ndarray) -> None:
    """Uneven batches (1, 57, 150, 193, ...) cross the sink's own batching boundaries."""
    sizes = [1, 57, 150, 193]
    k = i = 0
    while k < len(times):
        n = sizes[i % len(sizes)]
        sink.add_rows(times[k : k + n], values[k : k + n])
        k += n
        i += 1


def sink_for(fmu_dir: Path, path: Path | None, scenario_id: str, columns, url=None) -> RerunSink:
    """A sink for a plant + autopilot scenario recording ``columns``."""
    return RerunSink(auv_scenario(fmu_dir, scenario_id, columns), path, url)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory: pytest.TempPathFactory, scratch_home: Path, fmu_dir: Path):
    times, columns, values = plant_run()
    path = tmp_path_factory.mktemp("rec") / RECORDING_FILE
    scenario = auv_scenario(fmu_dir, "rec-test", columns, PLANT_START, CONTROLLER_START)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(
            "cosim.viz.recording.BATCH_BYTES", 100 * 8 * (1 + len(columns))
        )  # several sends, not one at close
        with RerunSink(scenario, path) as sink:
            feed(sink, times, values)
    return path, times, columns, values


def col(columns: list[str], values: np.ndarray, name: str) -> np.ndarray:
    return values[:, columns.index(name)]


def _flat(array: pa.Array) -> np.ndarray:
    while pa.types.is_list(array.type) or pa.types.is_fixed_size_list(array.type):
        array = array.flatten()
    return array.to_numpy(zero_copy_only=False)


def read_temporal(path: Path, entity: str, component: str, width: int):
    """(nanoseconds (n,), values (n, instances, width)) of a component on sim_time."""
    times, rows = [], []
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != entity:
            continue
        batch = chunk.to_record_batch()
        if "sim_time" not in batch.schema.names or component not in batch.schema.names:
            continue
        column = batch.column(component)
        counts = column.value_lengths().to_numpy(zero_copy_only=False)
        assert np.all(counts == counts[0]), f"{entity} {component}: ragged rows"
        times.append(batch.column("sim_time").cast(pa.int64()).to_numpy())
        rows.append(_flat(column).reshape(len(batch), -1, width))
    assert times, f"no {component} on {entity} in {path}"
    t = np.concatenate(times)
    order = np.argsort(t, kind="stable")
    return t[order], np.concatenate(rows)[order]


def read_static(path: Path, entity: str, component: str) -> list:
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        if chunk.entity_path == entity and component in batch.schema.names:
            return batch.column(component).to_pylist()
    raise AssertionError(f"no static {component} on {entity}")


def step_nanos(times: np.ndarray) -> np.ndarray:
    return np.rint(times * 1e9).astype(np.int64)


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of the unit quaternion [x, y, z, w] (written out, not scipy)."""
    x, y, z, w = np.asarray(q, dtype=float)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def euler_angles(r: np.ndarray) -> tuple[float, float, float]:
    """(roll, pitch, yaw) of R = Rz(yaw) Ry(pitch) Rx(roll) (2.2.8), |pitch| < 90 deg."""
    return math.atan2(r[2, 1], r[2, 2]), -math.asin(r[2, 0]), math.atan2(r[1, 0], r[0, 0])


def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(angle)))


def test_yaw_series_equals_the_input_exactly_at_every_step(recorded):
    path, times, columns, values = recorded
    t, scalars = read_temporal(path, "/attitude/yaw_deg", "Scalars:scalars", 1)
    np.testing.assert_array_equal(t, step_nanos(times))  # one value per step, at its time
    yaw = col(columns, values, "plant.yaw")
    assert np.ptp(yaw) > 0.05  # the vehicle really turned
    np.testing.assert_array_equal(scalars[:, 0, 0], np.degrees(yaw))
    setpoint = col(columns, values, "controller.yaw_setpoint")
    np.testing.assert_array_equal(scalars[:, 1, 0], np.degrees(setpoint))


def test_every_column_is_one_series_in_its_display_unit(recorded):
    path, times, columns, values = recorded
    expected = {  # entity -> (columns, display unit per SI unit), from the brief and the catalogue
        "/attitude/roll_deg": (["plant.roll"], math.degrees(1)),
        "/attitude/pitch_deg": (["plant.pitch"], math.degrees(1)),
        "/rates/roll_yaw_deg_s": (["plant.p", "plant.r"], math.degrees(1)),
        "/rates/pitch_deg_s": (["plant.q"], math.degrees(1)),
        "/velocity/surge_m_s": (["plant.u", "plant.u_rel"], 1.0),
        "/velocity/sway_m_s": (["plant.v", "plant.v_rel"], 1.0),
        "/velocity/heave_m_s": (["plant.w", "plant.w_rel"], 1.0),
        "/position/horizontal_m": (["plant.north", "plant.east"], 1.0),
        "/position/depth_m": (["plant.down", "controller.depth_setpoint"], 1.0),
        "/moving_mass/position_cm": (
            ["plant.mass_position", "controller.mass_position_cmd"],
            100.0,
        ),
        "/moving_mass/velocity_cm_s": (["plant.mass_velocity"], 100.0),
        "/actuators/tunnel_force_N": (["controller.tunnel_force"], 1.0),
        "/actuators/fin_angle_deg": (["controller.fin_angle"], math.degrees(1)),
        "/actuators/thrust_N": (["controller.thrust"], 1.0),
        "/energy/kinetic_J": (["plant.kinetic_energy"], 1.0),
        "/environment/current_m_s": (["controller.current_north", "controller.current_east"], 1.0),
    }
    seen = {"plant.yaw", "controller.yaw_setpoint"}  # checked above
    for entity, (names, scale) in expected.items():
        t, scalars = read_temporal(path, entity, "Scalars:scalars", 1)
        np.testing.assert_array_equal(t, step_nanos(times))
        for i, name in enumerate(names):
            np.testing.assert_array_equal(scalars[:, i, 0], col(columns, values, name) * scale)
        seen.update(names)
    assert seen == set(columns)


def scalar_entities(path: Path) -> set[str]:
    """Every entity of the recording holding scalar series."""
    return {
        chunk.entity_path
        for chunk in RrdReader(path).stream()
        if "Scalars:scalars" in chunk.to_record_batch().schema.names
    }


def test_each_plot_names_the_results_columns_it_shows_and_their_units(recorded):
    """The recording alone maps every line back to results.csv: each plot's entity names
    the column of each of its lines (``results_columns``, in the lines' order) and the
    unit it is drawn in (``units``); the values are the column's in that unit."""
    path, _, columns, values = recorded
    in_si = {"deg": math.degrees(1), "deg/s": math.degrees(1), "cm": 100.0, "cm/s": 100.0}
    found = {}
    for entity in scalar_entities(path):
        [names] = read_static(path, entity, "results_columns")
        [units] = read_static(path, entity, "units")
        _, scalars = read_temporal(path, entity, "Scalars:scalars", 1)
        assert scalars.shape[1] == len(names) == len(units), entity
        for i, (name, unit) in enumerate(zip(names, units, strict=True)):
            expected = col(columns, values, name) * in_si.get(unit, 1.0)
            np.testing.assert_array_equal(scalars[:, i, 0], expected, err_msg=name)
            found[name] = unit
    assert set(found) == set(columns)
    assert [found[c] for c in ("plant.yaw", "plant.r", "plant.u", "plant.mass_position")] == [
        "deg", "deg/s", "m/s", "cm"
    ]  # fmt: skip
    assert (found["controller.tunnel_force"], found["plant.kinetic_energy"]) == ("N", "J")


def test_pose_has_one_transform_per_step_matching_position_and_euler_angles(recorded):
    path, times, columns, values = recorded
    t, translation = read_temporal(path, "/world/vehicle", "Transform3D:translation", 3)
    tq, quaternion = read_temporal(path, "/world/vehicle", "Transform3D:quaternion", 4)
    np.testing.assert_array_equal(t, step_nanos(times))
    np.testing.assert_array_equal(tq, t)
    ned = np.column_stack(
        [col(columns, values, n) for n in ("plant.north", "plant.east", "plant.down")]
    )
    assert np.ptp(ned[:, 2]) > 0.01  # 6-DOF: the depth changes too
    np.testing.assert_array_equal(translation[:, 0], ned.astype(np.float32))
    roll, pitch, yaw = (col(columns, values, f"plant.{n}") for n in ("roll", "pitch", "yaw"))
    for k in range(len(times)):
        r = quaternion_matrix(quaternion[k, 0])
        np.testing.assert_allclose(r, rotation_matrix(roll[k], pitch[k], yaw[k]), atol=3e-7)
        error = wrap(np.array(euler_angles(r)) - [roll[k], pitch[k], yaw[k]])
        np.testing.assert_allclose(error, 0.0, atol=1e-6)


def test_chase_frame_follows_position_and_heading_only(recorded):
    path, _, columns, values = recorded
    _, pose = read_temporal(path, "/world/vehicle", "Transform3D:translation", 3)
    _, translation = read_temporal(path, "/world/chase", "Transform3D:translation", 3)
    _, q = read_temporal(path, "/world/chase", "Transform3D:quaternion", 4)
    np.testing.assert_array_equal(translation, pose)
    np.testing.assert_allclose(q[:, 0, :2], 0.0, atol=1e-7)  # no roll, no pitch
    heading = 2 * np.arctan2(q[:, 0, 2], q[:, 0, 3])
    error = wrap(heading - col(columns, values, "plant.yaw"))
    np.testing.assert_allclose(error, 0.0, atol=1e-6)


def test_moving_mass_sits_on_its_rail_inside_the_hull(recorded):
    path, times, columns, values = recorded
    vehicle = load_vehicle("remus100")
    t, centers = read_temporal(path, "/world/vehicle/moving_mass", "Ellipsoids3D:centers", 3)
    np.testing.assert_array_equal(t, step_nanos(times))
    y_v = col(columns, values, "plant.mass_position")
    assert np.max(np.abs(y_v)) > 0.04  # the 5 cm command moved it
    expected = np.column_stack(
        [np.full_like(y_v, vehicle.x_v), y_v, np.full_like(y_v, vehicle.z_g)]
    )
    np.testing.assert_array_equal(centers[:, 0], expected.astype(np.float32))
    # Even at the stop, the drawn mass stays within the hull's cylinder.
    at_stop = math.hypot(vehicle.mass_stroke, vehicle.z_g) + MASS_RADIUS
    assert at_stop <= 0.5 * vehicle.diameter
    assert abs(vehicle.x_v) + MASS_RADIUS <= 0.5 * (vehicle.length - vehicle.diameter)


def test_arrows_show_tunnel_force_in_body_y_and_current_in_earth_axes(recorded):
    path, _, columns, values = recorded
    _, force = read_temporal(path, "/world/vehicle/tunnel_force", "Arrows3D:vectors", 3)
    f = col(columns, values, "controller.tunnel_force")
    expected = np.column_stack([0 * f, FORCE_SCALE * f, 0 * f]).astype(np.float32)
    np.testing.assert_array_equal(force[:, 0], expected)
    _, current = read_temporal(path, "/world/current", "Arrows3D:vectors", 3)
    cn, ce = (col(columns, values, f"controller.current_{d}") for d in ("north", "east"))
    expected = CURRENT_SCALE * np.column_stack([cn, ce, 0 * cn])
    np.testing.assert_array_equal(current[:, 0], expected.astype(np.float32))


def test_stern_planes_turn_trailing_edge_down_by_the_fin_angle(recorded):
    path, times, columns, values = recorded
    t, q = read_temporal(path, "/world/vehicle/stern_planes", "Transform3D:quaternion", 4)
    np.testing.assert_array_equal(t, step_nanos(times))
    fin = col(columns, values, "controller.fin_angle")
    for k in (0, len(times) - 1):
        r = quaternion_matrix(q[k, 0])
        trailing_edge = r @ [-1.0, 0.0, 0.0]  # the planes extend aft of their hinge
        np.testing.assert_allclose(trailing_edge, [-np.cos(fin[k]), 0, np.sin(fin[k])], atol=1e-7)
        assert trailing_edge[2] > 0  # positive fin angle: trailing edge down (z down)


def test_trajectory_segments_chain_across_batches(recorded):
    path, times, columns, values = recorded
    t, segments = read_temporal(path, "/world/trajectory", "LineStrips3D:strips", 3)
    np.testing.assert_array_equal(t, step_nanos(times))
    ned = np.column_stack(
        [col(columns, values, n) for n in ("plant.north", "plant.east", "plant.down")]
    )
    np.testing.assert_array_equal(segments[:, 1], ned.astype(np.float32))
    np.testing.assert_array_equal(segments[1:, 0], segments[:-1, 1])


def _blueprint_views(path: Path) -> dict[str, tuple[str, str]]:
    """View name -> (class, origin) of the recording's blueprint store."""
    reader = RrdReader(path)
    assert reader.blueprints(), "no blueprint in the recording"
    views, containers = {}, []
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        names = batch.schema.names
        if "ViewBlueprint:display_name" in names:
            for name, kind, origin in zip(
                batch.column("ViewBlueprint:display_name").to_pylist(),
                batch.column("ViewBlueprint:class_identifier").to_pylist(),
                batch.column("ViewBlueprint:space_origin").to_pylist(),
                strict=True,
            ):
                views[name[0]] = (kind[0], origin[0])
        if "ContainerBlueprint:display_name" in names:
            containers += [
                n[0] for n in batch.column("ContainerBlueprint:display_name").to_pylist()
            ]
    views.update({name: ("container", "") for name in containers})
    return views


def test_blueprint_has_world_chase_and_loop_panels_over_recorded_entities(recorded):
    path = recorded[0]
    views = _blueprint_views(path)
    spatial = {origin for kind, origin in views.values() if kind == "3D"}
    assert spatial == {"/world", "/world/chase"}
    assert {"Heading loop", "Depth loop"} <= set(views)
    plotted = {origin for kind, origin in views.values() if kind == "TimeSeries"}
    assert {"/attitude/yaw_deg", "/position/depth_m", "/moving_mass/position_cm"} <= plotted
    entities = set(RrdReader(path).stream().collect().schema().entity_paths())
    assert plotted <= entities  # every plot shows data that exists


def test_metadata_holds_scenario_id_and_resolved_toml(recorded, fmu_dir: Path):
    path, _, columns, _ = recorded
    scenario = auv_scenario(fmu_dir, "rec-test", columns, PLANT_START, CONTROLLER_START)
    text = read_static(path, "/scenario", "TextDocument:text")[0][0]
    assert scenario.to_toml().strip() in text
    assert read_static(path, "/__properties/scenario", "id")[0] == ["rec-test"]
    assert read_static(path, "/__properties", "RecordingInfo:name")[0] == [
        f"rec-test ({path.parent.name})"  # written outside a folder named for the scenario
    ]


def test_metadata_traces_the_recording_to_the_tool_and_fmus_that_made_it(recorded, fmu_dir):
    """A recording handed on alone named no version and no FMU: summary.json did, the
    recording did not. Its properties now hold both, as summary.json states them."""
    path, _, columns, _ = recorded
    scenario = auv_scenario(fmu_dir, "rec-test", columns, PLANT_START, CONTROLLER_START)
    assert read_static(path, "/__properties/versions", "auv-cosim")[0] == [cosim.__version__]
    for name, instance in scenario.instances.items():
        guid = read_static(path, "/__properties/fmu_guids", name)[0]
        assert guid == [instance.interface.guid], name


@pytest.mark.parametrize(
    ("written_to", "name"),
    [
        ("rec-test/recording.rrd", "rec-test"),  # the default run folder, runs/<id>
        ("coarse/recording.rrd", "rec-test (coarse)"),  # --out coarse
        ("fine/recording.rrd", "rec-test (fine)"),
        ("kept/step-20ms.rrd", "rec-test (step-20ms.rrd)"),  # --rrd kept/step-20ms.rrd
    ],
)
def test_recordings_of_one_scenario_in_two_places_are_named_apart(
    tmp_path: Path, fmu_dir: Path, written_to: str, name: str
):
    """Two runs of one scenario (another --step, another algorithm) opened side by side in
    the viewer were both listed as the scenario's id: the recording's name says where it
    was written when that is not the scenario's own run folder."""
    path = tmp_path / written_to
    sink_for(fmu_dir, path, "rec-test", ["plant.yaw"]).close()
    assert read_static(path, "/__properties", "RecordingInfo:name")[0] == [name]


def test_two_sinks_in_one_process_do_not_mix(tmp_path: Path, fmu_dir: Path):
    times, columns, values = plant_run(1.0)
    other = values.copy()
    other[:, columns.index("plant.yaw")] += 1.0
    a = sink_for(fmu_dir, tmp_path / "a.rrd", "a", columns)
    b = sink_for(fmu_dir, tmp_path / "b.rrd", "b", columns)
    for k in range(0, len(times), 40):  # interleaved
        a.add_rows(times[k : k + 40], values[k : k + 40])
        b.add_rows(times[k : k + 40], other[k : k + 40])
    a.close()
    b.close()
    for name, data in (("a", values), ("b", other)):
        t, yaw = read_temporal(tmp_path / f"{name}.rrd", "/attitude/yaw_deg", "Scalars:scalars", 1)
        np.testing.assert_array_equal(t, step_nanos(times))
        np.testing.assert_array_equal(yaw[:, 0, 0], np.degrees(col(columns, data, "plant.yaw")))


def test_missing_and_unknown_columns_degrade_gracefully(tmp_path: Path, fmu_dir: Path):
    columns = ["plant.yaw", "controller.tunnel_force", "plant.battery_level"]
    times = np.arange(5) * 0.1
    values = np.column_stack([times, 2 * times, 3 * times])
    scenario = auv_scenario(fmu_dir, "partial", columns, "", None)
    plant = scenario.instances["plant"]  # its vehicle file gone since the scenario loaded
    plant = dataclasses.replace(plant, start={**plant.start, "vehicle": "nosuch"})
    scenario = dataclasses.replace(scenario, instances={**scenario.instances, "plant": plant})
    with pytest.warns(UserWarning, match="vehicle 'nosuch' not loadable"):
        sink = RerunSink(scenario, tmp_path / "r.rrd")
    with sink:
        sink.add_rows(times, values)
    entities = set(RrdReader(tmp_path / "r.rrd").stream().collect().schema().entity_paths())
    assert "/world/vehicle/moving_mass" not in entities
    _, yaw = read_temporal(tmp_path / "r.rrd", "/attitude/yaw_deg", "Scalars:scalars", 1)
    assert yaw.shape == (5, 1, 1)  # no setpoint recorded, so yaw alone
    _, other = read_temporal(tmp_path / "r.rrd", "/other/plant/battery_level", "Scalars:scalars", 1)
    np.testing.assert_array_equal(other[:, 0, 0], 3 * times)
    _, pose = read_temporal(tmp_path / "r.rrd", "/world/vehicle", "Transform3D:translation", 3)
    np.testing.assert_array_equal(pose, 0.0)  # no position recorded: the vehicle stays put


def test_two_vehicles_draw_no_hull_that_no_plant_moves(tmp_path: Path, fmu_dir: Path):
    """Two vehicles (plant_a, plant_b; no instance named plant, the one the scene draws):
    the 3-D scene showed a hull standing at the origin with a track along it, a vehicle
    neither plant is. No hull is drawn at world/vehicle (each plant's is under
    world/<plant>); each plant's columns have their plots."""
    from two_vehicles import two_vehicles_toml

    from cosim.scenario.spec import scenario_from_toml

    scenario = scenario_from_toml(two_vehicles_toml(stop_time=0.4), fmu_dir=fmu_dir)
    times = np.arange(5) * 0.1
    with RerunSink(scenario, tmp_path / "r.rrd") as sink:
        sink.add_rows(times, np.ones((5, len(scenario.columns))))
    entities = set(RrdReader(tmp_path / "r.rrd").stream().collect().schema().entity_paths())
    assert not any(entity.startswith("/world/vehicle") for entity in entities), entities
    assert {f"/vehicles/{p}/attitude/yaw_deg" for p in ("plant_a", "plant_b")} <= entities


def test_two_vehicles_each_draw_their_own_hull_and_track(tmp_path: Path, fmu_dir: Path):
    """Two vehicles (plant_a, plant_b): the 3-D scene drew neither (it drew the instance
    named plant only). Each is drawn under world/<plant>/, its hull posed where its own
    plant is and its own track, the world view following the first."""
    from two_vehicles import two_vehicles_toml

    from cosim.scenario.spec import scenario_from_toml

    scenario = scenario_from_toml(two_vehicles_toml(stop_time=0.4), fmu_dir=fmu_dir)
    columns = list(scenario.columns)
    times = np.arange(5) * 0.1
    values = np.zeros((5, len(columns)))
    for plant, east in (("plant_a", 0.0), ("plant_b", 10.0)):
        values[:, columns.index(f"{plant}.north")] = 1.5 * times
        values[:, columns.index(f"{plant}.east")] = east
    path = tmp_path / "r.rrd"
    with RerunSink(scenario, path) as sink:
        sink.add_rows(times, values)
    entities = set(RrdReader(path).stream().collect().schema().entity_paths())
    for plant, east in (("plant_a", 0.0), ("plant_b", 10.0)):
        assert {f"/world/{plant}/vehicle/hull", f"/world/{plant}/trajectory"} <= entities, entities
        _, pose = read_temporal(path, f"/world/{plant}/vehicle", "Transform3D:translation", 3)
        np.testing.assert_allclose(pose[:, 0], np.column_stack([1.5 * times, [east] * 5, [0] * 5]))
        _, mass = read_temporal(
            path, f"/world/{plant}/vehicle/moving_mass", "Ellipsoids3D:centers", 3
        )
        assert len(mass) == 5


def test_each_vehicle_of_a_fleet_has_its_own_plots(tmp_path: Path, fmu_dir: Path):
    """Two vehicles (plant_a with ctrl_a, plant_b with ctrl_b): the recording's plots drew
    the instances named plant and controller only, so a fleet's yaw, mass position and
    commands were bare lines under other/<instance>/<variable>, in radians and metres.
    Each vehicle has the catalogue's plots of its own, under vehicles/<plant>/, in their
    display units, its set-point and commands beside its own values, and the file's
    layout shows them, a heading loop for each."""
    from two_vehicles import two_vehicles_toml

    from cosim.scenario.spec import scenario_from_toml

    scenario = scenario_from_toml(two_vehicles_toml(stop_time=0.4), fmu_dir=fmu_dir)
    columns = list(scenario.columns)
    times = np.arange(5) * 0.1
    values = np.zeros((5, len(columns)))
    for k, (plant, controller) in enumerate((("plant_a", "ctrl_a"), ("plant_b", "ctrl_b"))):
        values[:, columns.index(f"{plant}.yaw")] = (k + 1) * 0.1 * times
        values[:, columns.index(f"{plant}.mass_position")] = (k + 1) * 0.01
        values[:, columns.index(f"{controller}.mass_position_cmd")] = -(k + 1) * 0.02
    path = tmp_path / "r.rrd"
    with RerunSink(scenario, path) as sink:
        sink.add_rows(times, values)
    entities = set(RrdReader(path).stream().collect().schema().entity_paths())
    for k, (plant, controller) in enumerate((("plant_a", "ctrl_a"), ("plant_b", "ctrl_b"))):
        _, yaw = read_temporal(path, f"/vehicles/{plant}/attitude/yaw_deg", "Scalars:scalars", 1)
        np.testing.assert_allclose(yaw[:, 0, 0], np.degrees((k + 1) * 0.1 * times))
        entity = f"/vehicles/{plant}/moving_mass/position_cm"
        _, mass = read_temporal(path, entity, "Scalars:scalars", 2)
        np.testing.assert_allclose(mass[0, 0], [(k + 1) * 1.0, -(k + 1) * 2.0])  # cm
        assert read_static(path, entity, "results_columns") == [
            [f"{plant}.mass_position", f"{controller}.mass_position_cmd"]
        ]
        assert f"/other/{plant}/yaw" not in entities and f"/other/{controller}/yaw" not in entities
    layout = recording.build_blueprint(
        recording.plan_panels(columns, fleet=[("plant_a", "ctrl_a"), ("plant_b", "ctrl_b")]),
        depth_control=False,
    )
    origins = {str(view.origin) for view in _all_views(layout.root_container)}
    assert {f"/vehicles/{p}/attitude/yaw_deg" for p in ("plant_a", "plant_b")} <= origins


def _all_views(container) -> list:
    """Every view under a blueprint ``container``, depth first."""
    import rerun.blueprint as rrb

    found = []
    for item in container.contents or []:
        found += _all_views(item) if isinstance(item, rrb.Container) else [item]
    return found


def test_one_vehicle_named_otherwise_is_drawn_where_the_built_ins_are(
    tmp_path: Path, fmu_dir: Path
):
    """bs-3 with its instances named auv and ap: the 3-D scene held no vehicle (it drew
    the instance named plant only). One vehicle is drawn under world/vehicle whatever its
    instances are named, its thruster arrow from its own autopilot's force."""
    from cosim.scenario.spec import scenario_from_toml

    text = (Path(cosim.__file__).parent / "scenarios" / "bs-3.toml").read_text("utf-8")
    renamed = re.sub(r"\bplant\b", "auv", re.sub(r"\bcontroller\b", "ap", text))
    scenario = scenario_from_toml(renamed, fmu_dir=fmu_dir)
    columns = list(scenario.columns)
    values = np.zeros((3, len(columns)))
    values[:, columns.index("auv.north")] = [0.0, 1.0, 2.0]
    values[:, columns.index("ap.tunnel_force")] = 20.0
    path = tmp_path / "r.rrd"
    with RerunSink(scenario, path) as sink:
        sink.add_rows(np.arange(3) * 0.1, values)
    _, pose = read_temporal(path, "/world/vehicle", "Transform3D:translation", 3)
    np.testing.assert_allclose(pose[:, 0, 0], [0.0, 1.0, 2.0])
    _, force = read_temporal(path, "/world/vehicle/tunnel_force", "Arrows3D:vectors", 3)
    np.testing.assert_allclose(force[:, 0, 1], 20.0 * FORCE_SCALE)


def test_a_column_outside_the_catalogue_is_drawn_with_its_fmus_unit(tmp_path: Path, fmu_dir: Path):
    """A column no plot of the catalogue shows gets a plot of its own under ``other/``,
    in the unit its FMU declares (an angle or a rate declared in rad or rad/s in degrees,
    as every plot), and says it: in its line's name and its ``units``."""
    columns = ["plant.yaw", "controller.r", "plant.quat_w"]
    with sink_for(fmu_dir, tmp_path / "r.rrd", "other", columns) as sink:
        sink.add_rows(np.arange(3) * 0.1, np.ones((3, 3)))
    path = tmp_path / "r.rrd"
    assert read_static(path, "/other/controller/r", "SeriesLines:names") == [
        ["controller.r (deg/s)"]
    ]
    assert read_static(path, "/other/controller/r", "units") == [["deg/s"]]
    _, rate = read_temporal(path, "/other/controller/r", "Scalars:scalars", 1)
    np.testing.assert_allclose(rate, math.degrees(1.0))  # 1 rad/s drawn as 57.3 deg/s
    assert read_static(path, "/other/controller/r", "results_columns") == [["controller.r"]]
    assert read_static(path, "/other/plant/quat_w", "SeriesLines:names") == [["plant.quat_w"]]
    assert read_static(path, "/other/plant/quat_w", "units") == [["1"]]


def test_bad_input_is_refused_with_what_was_expected(tmp_path: Path, fmu_dir: Path):
    with pytest.raises(ValueError, match="rrd_path, a connect_url"):
        sink_for(fmu_dir, None, "x", ["plant.yaw"])
    with pytest.raises(ValueError, match=r"duplicates \['plant.yaw'\]"):
        sink_for(fmu_dir, tmp_path / "d.rrd", "x", ["plant.yaw", "plant.yaw"])
    with pytest.raises(ValueError, match=re.escape("--connect URL 'http://127.0.0.1:9876'")):
        sink_for(fmu_dir, None, "x", ["plant.yaw"], url="http://127.0.0.1:9876")
    # a bare HOST:PORT got rerun-sdk's "Unexpected URI" alone: the form it takes is named
    with pytest.raises(ValueError, match=re.escape("expected rerun+http://HOST:PORT/proxy")):
        sink_for(fmu_dir, None, "x", ["plant.yaw"], url="127.0.0.1:9876")
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        url = f"rerun+http://127.0.0.1:{s.getsockname()[1]}/proxy"
    with pytest.raises(ValueError, match=re.escape(f"no Rerun viewer listens at {url}")):
        sink_for(fmu_dir, tmp_path / "v.rrd", "x", ["plant.yaw"], url=url)
    # a listener that never answers: rerun-sdk's sink blocked the run for ever, deaf to
    # Ctrl-C and SIGTERM (only SIGKILL ended it)
    with socket.create_server(("127.0.0.1", 0), backlog=4) as silent:
        url = f"rerun+http://127.0.0.1:{silent.getsockname()[1]}/proxy"
        with pytest.raises(ValueError, match=re.escape(f"something listens at {url} but does")):
            sink_for(fmu_dir, tmp_path / "w.rrd", "x", ["plant.yaw"], url=url)
    with pytest.raises(OSError, match=re.escape(f"cannot write the recording {tmp_path}")):
        sink_for(fmu_dir, tmp_path, "x", ["plant.yaw"])  # a folder, not a file
    sink = sink_for(fmu_dir, tmp_path / "s.rrd", "x", ["plant.yaw", "plant.north"])
    with pytest.raises(ValueError, match=r"\(k, 2\), got \(3,\) and \(3, 3\)"):
        sink.add_rows(np.zeros(3), np.zeros((3, 3)))
    sink.close()
    sink.close()  # twice is fine
    with pytest.raises(ValueError, match="closed"):
        sink.add_rows(np.zeros(1), np.zeros((1, 2)))


@contextmanager
def _server_group(command: list[str]) -> Iterator[subprocess.Popen]:
    """Run ``command`` in its own process group and stop the whole group at the end: the
    ``rerun`` launcher is a Python script that starts the viewer binary as its child, so
    stopping the launcher alone would leave the server running."""
    server = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    try:
        yield server
    finally:
        _stop_group(server)


def _stop_group(leader: subprocess.Popen, timeout: float = 10.0) -> None:
    """SIGTERM the process group ``leader`` leads, SIGKILL what is left after ``timeout``."""
    signals = [signal.SIGTERM, signal.SIGKILL]
    deadline = time.monotonic() + timeout
    with contextlib.suppress(ProcessLookupError):
        os.killpg(leader.pid, signals.pop(0))
        while True:
            leader.poll()  # reap the launcher
            os.killpg(leader.pid, 0)  # ProcessLookupError once the group is empty
            if time.monotonic() > deadline and signals:
                os.killpg(leader.pid, signals.pop(0))
                deadline = time.monotonic() + timeout
            elif time.monotonic() > deadline:
                raise AssertionError(f"process group {leader.pid} does not stop")
            time.sleep(0.05)


def _port_open(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


@pytest.mark.slow
@pytest.mark.skipif(rerun_executable() is None, reason="the rerun CLI is not installed")
@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # the server was still writing
def test_connect_streams_to_a_running_server_as_well_as_the_file(tmp_path: Path, fmu_dir: Path):
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    received = tmp_path / "received.rrd"
    command = [rerun_executable(), "--serve-grpc", "--bind", "127.0.0.1", "--port", str(port)]
    command += ["--save", str(received)]
    with _server_group(command) as server:
        deadline = time.monotonic() + 30
        while not _port_open(port):
            assert server.poll() is None and time.monotonic() < deadline, "server did not start"
            time.sleep(0.1)
        times, columns, values = plant_run(1.0)
        url = f"rerun+http://127.0.0.1:{port}/proxy"
        with sink_for(fmu_dir, tmp_path / "file.rrd", "live", columns, url=url) as sink:
            feed(sink, times, values)
        expected = np.degrees(col(columns, values, "plant.yaw"))
        for path in (tmp_path / "file.rrd", received):
            deadline = time.monotonic() + 30
            while True:  # the server writes what it receives a little later
                try:  # a file still being written may end in a torn frame (RuntimeError)
                    _, yaw = read_temporal(path, "/attitude/yaw_deg", "Scalars:scalars", 1)
                    if len(yaw) == len(times) and RrdReader(path).blueprints():
                        break
                except (AssertionError, OSError, ValueError, RuntimeError):
                    pass
                assert time.monotonic() < deadline, f"{path.name}: not every row, or no blueprint"
                time.sleep(0.2)
            np.testing.assert_array_equal(yaw[:, 0, 0], expected)


def test_view_without_display_fails_saying_how_to_open(
    recorded, tmp_path: Path, monkeypatch, capsys
):
    """The commands it suggests work when pasted, in a folder whose name has spaces too."""
    run_dir = tmp_path / "my runs" / "bs 3"
    run_dir.mkdir(parents=True)
    shutil.copyfile(recorded[0], run_dir / RECORDING_FILE)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    assert main(["view", str(run_dir)]) == 1  # a script sees that nothing was shown
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    # the web viewer's command, and the native viewer's on a machine with a display
    web, native = re.findall(r"`((?:auv-cosim|rerun) [^`]+)`", err)
    assert shlex.split(web) == ["auv-cosim", "view", str(run_dir), "--web"]
    assert shlex.split(native) == ["rerun", str(run_dir / RECORDING_FILE)]


@contextmanager
def _x_server(folder: Path, number: int) -> Iterator[None]:
    """A socket listening where a local X server of that display number would."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as server:
        server.bind(str(folder / f"X{number}"))
        server.listen(1)
        yield


def _viewer_calls(monkeypatch, code: int = 0) -> list[list[str]]:
    """The command lines the native viewer is started with (it exits with ``code``)."""
    calls: list[list[str]] = []
    monkeypatch.setattr("cosim.viz.recording.rerun_executable", lambda: "/opt/rerun")
    monkeypatch.setattr(
        "cosim.viz.recording.subprocess.call", lambda argv: calls.append(argv) or code
    )
    return calls


def test_view_with_display_runs_the_viewer_on_the_file(recorded, tmp_path: Path, monkeypatch):
    shutil.copyfile(recorded[0], tmp_path / RECORDING_FILE)
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("cosim.viz.recording.X11_SOCKETS", tmp_path)
    calls = _viewer_calls(monkeypatch)
    with _x_server(tmp_path, 99):
        assert view_run(tmp_path) == 0
    # its gRPC server on 127.0.0.1 only, as --web's (rerun binds every interface by default)
    assert calls == [["/opt/rerun", "--bind", "127.0.0.1", str(tmp_path / RECORDING_FILE)]]


@pytest.mark.parametrize("display", [":77", "localhost:77.0"])
def test_view_where_no_display_server_answers_fails_in_one_line_saying_to_use_web(
    recorded, tmp_path: Path, monkeypatch, capsys, display: str
):
    """A DISPLAY left over from another session (ssh without X forwarding, a container):
    the viewer was started and failed after a screen of its own log."""
    shutil.copyfile(recorded[0], tmp_path / RECORDING_FILE)
    monkeypatch.setenv("DISPLAY", display)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("cosim.viz.recording.X11_SOCKETS", tmp_path)  # no X77 there
    calls = _viewer_calls(monkeypatch)
    assert main(["view", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert calls == [] and err.count("\n") == 1, err
    assert f"no display server answers at DISPLAY={display}" in err
    assert f"`auv-cosim view {tmp_path} --web`" in err


def test_view_on_windows_opens_the_viewer_without_display_variables(
    recorded, tmp_path: Path, monkeypatch
):
    """Windows (and macOS) have no DISPLAY: the viewer opens all the same."""
    shutil.copyfile(recorded[0], tmp_path / RECORDING_FILE)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("cosim.viz.recording.sys.platform", "win32")
    calls = _viewer_calls(monkeypatch)
    assert view_run(tmp_path) == 0
    assert calls == [["/opt/rerun", "--bind", "127.0.0.1", str(tmp_path / RECORDING_FILE)]]


def test_a_viewer_that_fails_is_followed_by_a_line_saying_to_use_web(
    recorded, tmp_path: Path, monkeypatch, capsys
):
    shutil.copyfile(recorded[0], tmp_path / RECORDING_FILE)
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("cosim.viz.recording.X11_SOCKETS", tmp_path)
    _viewer_calls(monkeypatch, code=1)
    with _x_server(tmp_path, 99):
        assert main(["view", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exited with status 1" in err
    assert f"`auv-cosim view {tmp_path} --web`" in err


def test_view_of_something_that_is_not_a_recording_exits_non_zero(tmp_path: Path, capsys):
    """Regression: `view some-file` opened the viewer on any file and exited 0."""
    some_file = tmp_path / "notes.txt"
    some_file.write_text("not a recording\n")
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / RECORDING_FILE).write_text("results,not,a,recording\n")
    for target in (some_file, tmp_path / "run"):
        assert main(["view", str(target)]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "is not a Rerun recording" in err


def test_view_of_a_file_starting_like_a_recording_then_junk_says_so_in_one_line(
    tmp_path: Path, capsys
):
    """Guards against reading junk after the magic bytes as the version that wrote the
    file: `view --web` said "written by Rerun 103.97.114" (pip install that) and then
    failed on a second line. A header whose encoding options are no rerun's (bytes 8-11:
    compression 0 or 1, serializer 1 or 2, two zero bytes) is no recording."""
    junk = tmp_path / "junk.rrd"
    junk.write_bytes(b"RRF2garbage and more garbage\n")
    assert main(["view", str(junk), "--web"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not a Rerun recording" in err, err


@pytest.mark.parametrize("kind", ["missing", "fifo"])
def test_view_of_an_rrd_path_that_is_no_file_names_that_path(tmp_path: Path, capsys, kind: str):
    """Guards the line a mistyped or odd .rrd path gets: `view typo.rrd` said "no
    recording at typo.rrd/recording.rrd", as if it had been given a folder."""
    named = tmp_path / "typo.rrd"
    if kind == "fifo":
        os.mkfifo(named)
    assert main(["view", str(named), "--web"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{named}:" in err and f"{named}/" not in err, err


def test_view_of_a_folder_without_recording_names_it(tmp_path: Path, capsys):
    with pytest.raises(CosimError, match=str(tmp_path / RECORDING_FILE)):
        view_run(tmp_path)
    assert main(["view", str(tmp_path)]) == 1
    assert "no recording at" in capsys.readouterr().err


REAL_RUNS = """
import sys
from pathlib import Path
from cosim.runner import run_scenario
from cosim.scenario.spec import load_scenario, scenario_from_toml

fmu_dir, out = Path(sys.argv[1]), Path(sys.argv[2])
closed = load_scenario("bs-3", fmu_dir=fmu_dir).with_overrides(stop_time=2.0)
alone = scenario_from_toml(sys.argv[3], fmu_dir=fmu_dir)
for scenario in (closed, alone):
    outcome = run_scenario(scenario, out / scenario.id, fmu_dir=fmu_dir)
    assert outcome.result.complete, outcome.result.error
"""
OPEN_LOOP = """
id = "open-loop"
stop_time = 2.0
[coupling]
step = 0.01
[instances.plant]
fmu = "AuvPlant"
[instances.plant.start]
variant = 0
u_0 = 1.5
v_0 = -0.1
tunnel_force = 6.0
mass_position_cmd = 0.05
fin_angle = 0.08
current_east = 0.2
[[events]]
name = "planes-down"
time = 1.0
set = { "plant.fin_angle" = 0.1, "plant.tunnel_force" = 3.0 }
"""


@pytest.fixture(scope="module")
def real_runs(fmu_paths, run_python, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """bs-3 (2 s) and the AuvPlant alone through the master, in a fresh process
    (pythonfmu caches modules); returns the folder holding both run folders."""
    out = tmp_path_factory.mktemp("runs")
    done = run_python(REAL_RUNS, fmu_paths["AuvPlant"].parent, out, OPEN_LOOP)
    assert done.returncode == 0, done.stderr
    return out


def read_results(run: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    from cosim.outputs.results import read_csv

    names, table = read_csv(run / "results.csv")
    return table[:, 0], dict(zip(names, table.T, strict=True))


@pytest.mark.slow
def test_closed_loop_recording_equals_results_csv(real_runs: Path):
    rrd = real_runs / "bs-3" / RECORDING_FILE
    times, csv = read_results(real_runs / "bs-3")
    t, yaw = read_temporal(rrd, "/attitude/yaw_deg", "Scalars:scalars", 1)
    np.testing.assert_array_equal(t, step_nanos(times))
    assert np.ptp(csv["plant.yaw"]) > 0.1  # bs-3 turns away and back
    np.testing.assert_array_equal(yaw[:, 0, 0], np.degrees(csv["plant.yaw"]))
    np.testing.assert_array_equal(yaw[:, 1, 0], np.degrees(csv["controller.yaw_setpoint"]))
    _, force = read_temporal(rrd, "/actuators/tunnel_force_N", "Scalars:scalars", 1)
    assert np.max(np.abs(csv["controller.tunnel_force"])) > 1.0
    np.testing.assert_array_equal(force[:, 0, 0], csv["controller.tunnel_force"])
    t, pose = read_temporal(rrd, "/world/vehicle", "Transform3D:translation", 3)
    np.testing.assert_array_equal(t, step_nanos(times))
    ned = np.column_stack([csv[f"plant.{n}"] for n in ("north", "east", "down")])
    np.testing.assert_array_equal(pose[:, 0], ned.astype(np.float32))
    _, q = read_temporal(rrd, "/world/vehicle", "Transform3D:quaternion", 4)
    euler = np.array([euler_angles(quaternion_matrix(row)) for row in q[:, 0]])
    expected = np.column_stack([csv[f"plant.{n}"] for n in ("roll", "pitch", "yaw")])
    np.testing.assert_allclose(wrap(euler - expected), 0.0, atol=1e-6)


@pytest.mark.slow
def test_plant_alone_recording_shows_its_held_inputs(real_runs: Path):
    """Without an autopilot the plant's held inputs fill the actuator plots and arrows."""
    rrd = real_runs / "open-loop" / RECORDING_FILE
    times, csv = read_results(real_runs / "open-loop")
    t, yaw = read_temporal(rrd, "/attitude/yaw_deg", "Scalars:scalars", 1)
    np.testing.assert_array_equal(t, step_nanos(times))
    np.testing.assert_array_equal(yaw[:, 0, 0], np.degrees(csv["plant.yaw"]))
    _, force = read_temporal(rrd, "/actuators/tunnel_force_N", "Scalars:scalars", 1)
    np.testing.assert_array_equal(force[:, 0, 0], csv["plant.tunnel_force"])
    _, mass = read_temporal(rrd, "/moving_mass/position_cm", "Scalars:scalars", 1)
    np.testing.assert_array_equal(mass[:, 1, 0], 100.0 * csv["plant.mass_position_cmd"])
    _, arrow = read_temporal(rrd, "/world/vehicle/tunnel_force", "Arrows3D:vectors", 3)
    np.testing.assert_array_equal(
        arrow[:, 0, 1], (FORCE_SCALE * csv["plant.tunnel_force"]).astype(np.float32)
    )
    _, current = read_temporal(rrd, "/world/current", "Arrows3D:vectors", 3)
    np.testing.assert_array_equal(
        current[:, 0, 1], (CURRENT_SCALE * csv["plant.current_east"]).astype(np.float32)
    )


def _viewer_as_file(monkeypatch, shown: Path) -> str:
    """Make ``--connect`` stream to the file ``shown`` instead (what a viewer would get);
    returns a URL to give the sink."""
    import rerun as rr

    monkeypatch.setattr(recording, "_viewer_sink", lambda url: rr.FileSink(str(shown)))
    return "rerun+http://127.0.0.1:9/proxy"


def _times_shown(shown: Path) -> np.ndarray:
    """The sim_time (ns) of every yaw the viewer got so far (empty before any)."""
    try:
        return read_temporal(shown, "/attitude/yaw_deg", "Scalars:scalars", 1)[0]
    except (AssertionError, OSError, ValueError, RuntimeError):  # none yet, or a torn tail
        return np.zeros(0, dtype=np.int64)


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # read while being written
def test_a_viewer_sees_new_rows_each_second_however_long_the_run(
    tmp_path: Path, fmu_dir: Path, monkeypatch
):
    """A run streamed to a viewer (``--connect``) sends it what is new about once a second
    all along. The file's sends grow further apart with the run's age (memory); a viewer
    fed in the same sends lagged 12 s behind a live run after 10 minutes."""
    now = [0.0]
    monkeypatch.setattr(recording, "time", SimpleNamespace(monotonic=lambda: now[0]))
    shown = tmp_path / "viewer.rrd"
    url = _viewer_as_file(monkeypatch, shown)
    columns = ["plant.yaw", "plant.north", "plant.east", "plant.down"]
    sink = sink_for(fmu_dir, tmp_path / "file.rrd", "live", columns, url=url)
    try:
        for k in range(601):  # ten minutes of a live run at 1x: a row each second
            now[0] = float(k)
            sink.add_rows(np.array([float(k)]), np.full((1, len(columns)), 0.01 * k))
        now[0] += 1.0  # a second later
        sink.add_rows(np.array([601.0]), np.full((1, len(columns)), 6.01))
        assert step_nanos(np.array([601.0]))[0] in _times_shown(shown)
    finally:
        sink.close()
    assert len(read_temporal(tmp_path / "file.rrd", "/attitude/yaw_deg", "Scalars:scalars", 1)[0])
    ids = {entry.recording_id for p in (shown, tmp_path / "file.rrd") for entry in
           RrdReader(p).recordings()}  # fmt: skip
    assert len(ids) == 1  # one recording, in the viewer and in the file


@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # read while being written
def test_a_paused_live_run_shows_the_viewer_where_it_paused(
    tmp_path: Path, fmu_dir: Path, monkeypatch
):
    """A paced run's sink (fed from a thread) sends a viewer the rows it holds back once
    their time has come, although no new rows come while the run is paused: the viewer
    showed the vehicle where it was up to a send interval before the pause, for as long as
    the pause lasted."""
    from cosim.outputs.background import BackgroundSink

    shown = tmp_path / "viewer.rrd"
    url = _viewer_as_file(monkeypatch, shown)
    sink = BackgroundSink(sink_for(fmu_dir, None, "paused", ["plant.yaw"], url=url))
    try:
        sink.add_rows(np.array([0.0, 0.01]), np.array([[0.0], [0.1]]))  # then it pauses
        deadline = time.monotonic() + 10.0
        while len(_times_shown(shown)) < 2:
            assert time.monotonic() < deadline, "the viewer never got the rows before the pause"
            time.sleep(0.1)
    finally:
        sink.close()


@pytest.mark.slow
def test_an_events_note_gives_each_value_with_its_unit_and_an_angle_in_degrees(
    real_runs: Path,
):
    """The plots show angles in degrees: a note saying an angle in rad without its unit
    (``plant.fin_angle = 0.1`` beside a fin plot at 5.7) read as the wrong number."""
    notes = [
        text
        for chunk in RrdReader(real_runs / "open-loop" / RECORDING_FILE).stream()
        if chunk.entity_path == "/events"
        for row in chunk.to_record_batch().column("TextLog:text").to_pylist()
        for text in row
    ]
    assert notes[:-1] == [  # the last says how the run ended
        "event planes-down: plant.fin_angle = 0.1 rad (5.72958 deg), plant.tunnel_force = 3.0 N"
    ]


STREAM_THREADS = """
import os, sys, time
from pathlib import Path
import numpy as np
from scenario_factory import auv_scenario
from cosim.viz.recording import RerunSink

fmu_dir, out, recordings = Path(sys.argv[1]), Path(sys.argv[2]), int(sys.argv[3])
scenario = auv_scenario(fmu_dir, "threads", ["plant.yaw"])


def record(k):
    with RerunSink(scenario, out / f"{k}.rrd") as sink:
        sink.add_rows(np.array([0.0, 0.01]), np.array([[0.0], [0.1]]))


def settled(at_most):  # the thread count once a lazily ending one has gone (5 s at most)
    for _ in range(100):
        count = len(os.listdir("/proc/self/task"))
        if count <= at_most:
            break
        time.sleep(0.05)
    return count


threads = []
for k in range(3 + recordings):
    record(k)
    if k in (2, 2 + recordings):
        threads.append(settled(threads[0]) if threads else len(os.listdir("/proc/self/task")))
print("threads", *threads)
"""


def _threads_after_recordings(run_python, fmu_dir: Path, out: Path, recordings: int):
    """The threads of a fresh process (``/proc/self/task``) after 3 recordings written
    through :class:`RerunSink`, then after ``recordings`` more (at most as many once a
    lazily ending one has gone: the first count may still hold one ending, so fewer after
    is no leak; a busy machine showed 4 after 5)."""
    done = run_python(STREAM_THREADS, fmu_dir, out, recordings)
    assert done.returncode == 0, done.stderr[-3000:]
    return tuple(map(int, re.findall(r"^threads (\d+) (\d+)$", done.stdout, re.M)[0]))


def test_a_closed_recording_leaves_no_thread_behind(run_python, fmu_dir: Path, tmp_path: Path):
    """A notebook re-running ``cosim.run(..., out=...)`` writes a recording per run: each
    one's Rerun streams (its data and its blueprint, each a batcher and a forwarding
    thread) are dropped when it is closed. Before, rerun-sdk kept every stream a process
    made, with its threads: 4 threads and about 3 MB more per run."""
    before, after = _threads_after_recordings(run_python, fmu_dir, tmp_path, 10)
    assert after <= before


@pytest.mark.slow
def test_200_closed_recordings_leave_no_thread_behind(run_python, fmu_dir: Path, tmp_path: Path):
    """The twin above over 200 recordings (800 threads kept before)."""
    before, after = _threads_after_recordings(run_python, fmu_dir, tmp_path, 200)
    assert after <= before
