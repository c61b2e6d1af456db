"""The 3D scene of a recording, in NED: the vehicle, its internal actuators, current, path.

Entity tree (``world`` is the earth frame, FRD = x north, y east, z down; ``world/vehicle``
is the body frame at the centre of buoyancy, FRD = x forward, y starboard, z down)::

    world                      ViewCoordinates.FRD (static)
    world/vehicle              Transform3D per step: translation [north, east, down] and the
                               attitude quaternion (the plant's quat_* outputs, or
                               R = Rz(psi) Ry(theta) Rx(phi) (2.2.8) when not recorded)
    world/chase                Transform3D per step: the same translation, turned by yaw only;
                               the chase view's frame, so its eye stays behind the vehicle
                               and its grid stays level while the vehicle rolls and pitches
    world/vehicle/hull         Capsules3D, length x diameter of the parameter set (static)
    world/vehicle/rudders      Boxes3D, the two vertical tail fins (static)
    world/vehicle/stern_planes Boxes3D, turned per step by fin_angle about the body y axis
    world/vehicle/mass_rail    LineStrips3D, the moving-mass rail at x = x_v, z = z_g,
                               as long as the stroke (static)
    world/vehicle/moving_mass  Ellipsoids3D at [x_v, mass_position, z_g] per step
    world/vehicle/tunnel_force Arrows3D from the thruster at [0, 0, z_t]: F_t along body y
    world/current              Arrows3D, the earth-frame current, drawn above the vehicle
    world/trajectory           LineStrips3D, one segment per step (the blueprint shows every
                               segment up to the time cursor, so the path grows)
    world/depth_setpoint       Boxes3D, a translucent square at the setpoint depth, centred
                               on the vehicle's north and east, when depth control is on
    world/mission/path         LineStrips3D, the planned path through the waypoints of a
                               waypoint guidance (static; :func:`log_static_scene`'s
                               ``waypoints``: :func:`cosim.viz.mission.mission_waypoints`)
    world/mission/waypoints    Points3D, the waypoints, labelled 1, 2, ... (static)
    world/mission/target       Points3D per step: the waypoint the guidance steers for (its
                               ``waypoint_north``/``_east``/``_down`` outputs, when recorded)

Fins, thruster and current show what acts on the vehicle (:func:`acting`).

That is the one vehicle of a run (its plant and autopilot whatever their instance names,
:class:`SceneVehicle`). A run of several vehicles (two or more plants) draws each under
``world/<plant>`` instead of ``world``: ``world/<plant>/vehicle`` (and its hull, fins,
mass and thruster below it), ``world/<plant>/chase``, ``world/<plant>/current``,
``world/<plant>/trajectory`` and ``world/<plant>/depth_setpoint``, each from its own
plant's columns and those of the autopilot joined to it; ``world`` and ``world/mission``
stay as they are, once.

Only what never changes is logged static: a static component would shadow the per-step
values of the same component on that entity.

The geometry comes from the vehicle parameter set; the shapes of the fins and of the mass
are drawn to look right, they do not enter the physics. Arrow lengths are scaled
(``FORCE_SCALE``, ``CURRENT_SCALE``); :func:`scene_legend` states the scales.
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import dataclass

import numpy as np
import pyarrow as pa
import rerun as rr
from scipy.spatial.transform import Rotation

from cosim.viz.layout import (
    CURRENT,
    FIN,
    HULL,
    MASS,
    PALE_SETPOINT,
    SETPOINT,
    THRUSTER,
    TRAJECTORY,
)
from plant_fmu.model.parameters import VehicleParameters

FORCE_SCALE = 0.05  # m of arrow per N of tunnel force (20 N = 1 m)
CURRENT_SCALE = 5.0  # m of arrow per m/s of current (0.2 m/s = 1 m)
CURRENT_ARROW_HEIGHT = 1.0  # m above the vehicle, so the arrow does not hide the hull
FIN_CHORD = 0.08  # m, drawn size of the tail fins
FIN_SPAN = 0.09  # m beyond the hull
FIN_THICKNESS = 0.006  # m
FIN_FROM_TAIL = 0.12  # m, fin root hinge ahead of the tail end
MASS_RADIUS = 0.03  # m, drawn radius of the moving mass
DEPTH_MARKER_HALF_SIZE = 2.0  # m, half side of the depth-setpoint square
WAYPOINT_RADIUS = 0.4  # m, drawn radius of a waypoint (the active one: twice that)
TARGET_COLUMNS = tuple(f"guidance.waypoint_{axis}" for axis in ("north", "east", "down"))

Columns = Callable[[str], np.ndarray | None]  # column name -> values (k,) or None
WORLD = "world"  # the earth frame; the one vehicle of a run hangs under it


@dataclass(frozen=True)
class SceneVehicle:
    """One vehicle the scene draws: the instances of its plant and of the autopilot that
    steers it, and the entity its shapes hang under (:data:`WORLD` for the one vehicle of
    a run, ``world/<plant>`` for each of several)."""

    plant: str = "plant"
    controller: str = "controller"
    root: str = WORLD

    def column(self, name: str) -> str:
        """The results column of ``name`` as the scene names it (``plant.north``,
        ``controller.tunnel_force``): this vehicle's own; another name as it is."""
        instance, _, variable = name.partition(".")
        return {"plant": f"{self.plant}.", "controller": f"{self.controller}."}.get(
            instance, f"{instance}."
        ) + variable

    def canonical(self, recorded: Collection[str]) -> set[str]:
        """The names the scene gives the ``recorded`` columns of this vehicle's plant and
        autopilot (``plant.north``), with every column of other instances as it is."""
        own = {self.plant: "plant", self.controller: "controller"}
        return {
            f"{own.get(instance, instance)}.{variable}"
            for instance, _, variable in (c.partition(".") for c in recorded)
            if instance in own or instance not in ("plant", "controller")  # another's
        }

    def columns(self, column: Columns) -> Columns:
        """``column`` (the results' values by name) read by the scene's names."""
        return lambda name: column(self.column(name))


def acting(column: Columns, name: str) -> np.ndarray | None:
    """Plant input ``name`` as it acts on the vehicle, or None if it is not recorded.

    The plant's own input if recorded (an unconnected input holds its value, whatever the
    autopilot outputs), else the autopilot's output of the same name (connected to it).
    """
    values = column(f"plant.{name}")
    return values if values is not None else column(f"controller.{name}")


def log_static_scene(
    rec: rr.RecordingStream,
    vehicle: VehicleParameters,
    recorded: Collection[str],
    *,
    show_depth_setpoint: bool,
    waypoints: np.ndarray | None = None,
    root: str = WORLD,
    world: bool = True,
) -> None:
    """Log the frames and every shape that does not change with time.

    ``recorded`` are the run's columns, the vehicle's plant and autopilot named ``plant``
    and ``controller`` (:meth:`SceneVehicle.canonical`): what they lack is not drawn.
    ``waypoints`` (m, NED, one row each; :func:`cosim.viz.mission.mission_waypoints`) draw
    a mission's planned path. ``root``: the entity the vehicle's shapes hang under
    (:data:`WORLD` for the one vehicle of a run, ``world/<plant>`` for each of several);
    ``world``: also the earth frame and the mission (once per recording).
    """

    def has(name: str) -> bool:
        return f"plant.{name}" in recorded or f"controller.{name}" in recorded

    if world:
        rec.log(WORLD, rr.ViewCoordinates.FRD, static=True)
    _log_hull_and_fins(rec, vehicle, root, show_fins=has("fin_angle"))
    if "plant.mass_position" in recorded:
        _log_mass_rail(rec, vehicle, root)
    if has("tunnel_force"):
        rec.log(
            f"{root}/vehicle/tunnel_force",
            rr.Arrows3D.from_fields(
                origins=[[0.0, 0.0, vehicle.z_t]],
                colors=[THRUSTER],
                radii=[0.015],
            ),
            static=True,
        )
    if any(has(f"current_{axis}") for axis in ("north", "east", "down")):
        rec.log(
            f"{root}/current",
            rr.Arrows3D.from_fields(
                colors=[CURRENT],
                radii=[0.02],
            ),
            static=True,
        )
    rec.log(
        f"{root}/trajectory",
        rr.LineStrips3D.from_fields(colors=[TRAJECTORY], radii=rr.Radius.ui_points(1.5)),
        static=True,
    )
    if world and waypoints is not None:
        log_mission(rec, waypoints)
    if world and all(column in recorded for column in TARGET_COLUMNS):
        rec.log(
            "world/mission/target",
            rr.Points3D.from_fields(colors=[SETPOINT], radii=[2.0 * WAYPOINT_RADIUS]),
            static=True,
        )
    if show_depth_setpoint:
        half = DEPTH_MARKER_HALF_SIZE
        rec.log(
            f"{root}/depth_setpoint",
            rr.Boxes3D(
                half_sizes=[[half, half, 0.005]],
                colors=[(*SETPOINT, 70)],
                fill_mode="solid",
            ),
            static=True,
        )


def log_mission(rec: rr.RecordingStream, waypoints: np.ndarray) -> None:
    """The planned path through ``waypoints`` (m, NED, one row each) and the waypoints,
    labelled from 1 (static)."""
    points = np.asarray(waypoints, dtype=float).reshape(-1, 3)
    rec.log(
        "world/mission/path",
        rr.LineStrips3D([points], colors=[PALE_SETPOINT], radii=rr.Radius.ui_points(1.5)),
        static=True,
    )
    rec.log(
        "world/mission/waypoints",
        rr.Points3D(
            points,
            radii=[WAYPOINT_RADIUS],
            colors=[SETPOINT],
            labels=[str(k) for k in range(1, len(points) + 1)],
        ),
        static=True,
    )


def _log_hull_and_fins(
    rec: rr.RecordingStream, vehicle: VehicleParameters, root: str, *, show_fins: bool
) -> None:
    """The hull capsule, the rudders and the stern planes (posed per step if recorded)."""
    radius = 0.5 * vehicle.diameter
    cylinder = vehicle.length - vehicle.diameter  # the capsule's caps add one diameter
    # Capsules3D are built along local +z: turn +z onto body +x (90 deg about y).
    rec.log(
        f"{root}/vehicle/hull",
        rr.Capsules3D(
            lengths=[cylinder],
            radii=[radius],
            translations=[[-0.5 * cylinder, 0.0, 0.0]],
            quaternions=[Rotation.from_euler("y", 90.0, degrees=True).as_quat()],
            colors=[(*HULL, 150)],
            fill_mode="solid",
        ),
        static=True,
    )
    hinge = -0.5 * vehicle.length + FIN_FROM_TAIL
    offset = radius + 0.5 * FIN_SPAN
    rec.log(
        f"{root}/vehicle/rudders",
        rr.Boxes3D(
            centers=[[hinge - 0.5 * FIN_CHORD, 0.0, -offset], [hinge - 0.5 * FIN_CHORD, 0, offset]],
            half_sizes=[[0.5 * FIN_CHORD, 0.5 * FIN_THICKNESS, 0.5 * FIN_SPAN]] * 2,
            colors=[HULL],
            fill_mode="solid",
        ),
        static=True,
    )
    # Stern planes: their frame sits at the hinge (leading edge) and turns by fin_angle per
    # step about body +y, so a positive angle puts the trailing edge down: an upward force
    # at the tail and a nose-down moment, as Z_ds < 0 and M_ds < 0 say (Table 6.1).
    rec.log(
        f"{root}/vehicle/stern_planes",
        rr.Boxes3D(
            centers=[[-0.5 * FIN_CHORD, -offset, 0.0], [-0.5 * FIN_CHORD, offset, 0.0]],
            half_sizes=[[0.5 * FIN_CHORD, 0.5 * FIN_SPAN, 0.5 * FIN_THICKNESS]] * 2,
            colors=[FIN if show_fins else HULL],
            fill_mode="solid",
        ),
        static=True,
    )
    if not show_fins:  # else SceneWriter poses them per step (static data would shadow it)
        rec.log(
            f"{root}/vehicle/stern_planes",
            rr.Transform3D(translation=[hinge, 0.0, 0.0]),
            static=True,
        )


def _log_mass_rail(rec: rr.RecordingStream, vehicle: VehicleParameters, root: str) -> None:
    """The moving mass's rail (as long as the stroke) and the mass itself."""
    rail = [[vehicle.x_v, -vehicle.mass_stroke, vehicle.z_g]]
    rail.append([vehicle.x_v, vehicle.mass_stroke, vehicle.z_g])
    rec.log(
        f"{root}/vehicle/mass_rail",
        rr.LineStrips3D([rail], colors=[MASS], radii=[0.004]),
        static=True,
    )
    rec.log(
        f"{root}/vehicle/moving_mass",
        rr.Ellipsoids3D(half_sizes=[[MASS_RADIUS] * 3], colors=[MASS], fill_mode="solid"),
        static=True,
    )


def scene_legend() -> str:
    """Markdown that explains the 3D scene's shapes, colours and arrow scales."""
    return (
        "## 3D scene (NED: x north, y east, z down)\n\n"
        "- yellow body: the hull; green stern planes turn with `fin_angle`\n"
        "- purple ball on its rail: the moving mass at `mass_position`\n"
        f"- cyan arrow: tunnel-thruster force, 1 m = {1 / FORCE_SCALE:g} N\n"
        f"- blue arrow above the vehicle: water current, 1 m = {1 / CURRENT_SCALE:g} m/s\n"
        "- white line: the path so far; orange square: the depth setpoint\n"
        "- pale orange line and orange dots: a mission's planned path and its waypoints; "
        "the large dot is the waypoint the guidance steers for\n"
        "- chase view: follows position and heading; its grid is level through the vehicle\n"
    )


def euler_to_quaternions(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """Quaternions [x, y, z, w] of R = Rz(yaw) Ry(pitch) Rx(roll) (2.2.8), one per row.

    The product q_z(yaw) q_y(pitch) q_x(roll) of the three elementary quaternions, written
    out: what scipy's ``Rotation.from_euler("ZYX", ...).as_quat()`` returns (same sign,
    to rounding; the test compares), at a tenth of its cost per batch, which a recording
    pays for every row of the run (``scripts/bench_cosim.py``, recording overhead).
    """
    cr, sr = np.cos(0.5 * roll), np.sin(0.5 * roll)
    cp, sp = np.cos(0.5 * pitch), np.sin(0.5 * pitch)
    cy, sy = np.cos(0.5 * yaw), np.sin(0.5 * yaw)
    return np.column_stack(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )


def pitch_quaternions(angle: np.ndarray) -> np.ndarray:
    """Quaternions [x, y, z, w] of rotations by ``angle`` (rad) about the body y axis."""
    zeros = np.zeros_like(angle)
    return np.column_stack([zeros, np.sin(0.5 * angle), zeros, np.cos(0.5 * angle)])


def strips_of_segments(segments: np.ndarray) -> pa.Array:
    """The LineStrips3D strips column of n two-point segments ((n, 2, 3) array), built as
    one Arrow list array: rerun's own conversion loops in Python over the strips (~5 us
    each), the rows of the run here."""
    n = len(segments)
    points = rr.components.LineStrip3DBatch._ARROW_DATATYPE  # list<fixed_size_list<f32, 3>>
    flat = pa.array(segments.reshape(-1).astype(np.float32))
    inner = pa.FixedSizeListArray.from_arrays(flat, type=points.value_type)
    offsets = pa.array(np.arange(0, 2 * n + 1, 2, dtype=np.int32))
    return pa.ListArray.from_arrays(offsets, inner, type=points)


class SceneWriter:
    """Sends the time-varying part of the scene in columns, batch by batch."""

    def __init__(
        self,
        rec: rr.RecordingStream,
        vehicle: VehicleParameters,
        *,
        show_depth_setpoint: bool,
        root: str = WORLD,
        target: bool = True,
    ) -> None:
        self._rec = rec
        self._vehicle = vehicle
        self._show_depth_setpoint = show_depth_setpoint
        self._root = root  # the entity the vehicle hangs under (log_static_scene)
        self._target = target  # whether it sends the mission's target (once per recording)
        self._last_position: np.ndarray | None = None

    @staticmethod
    def _attitude(column: Columns, yaw: np.ndarray, get: Callable[[str], np.ndarray]) -> np.ndarray:
        """Quaternions [x, y, z, w] of the vehicle: the plant's own (``plant.quat_w`` ...,
        exact through pitch +-90 deg, where roll and yaw alone are ill-defined) when
        recorded, else built from roll, pitch and yaw."""
        parts = [column(f"plant.quat_{axis}") for axis in "xyzw"]
        recorded = [part for part in parts if part is not None]
        if len(recorded) == len(parts):
            return np.column_stack(recorded)
        return euler_to_quaternions(get("plant.roll"), get("plant.pitch"), yaw)

    def send(self, index: list[rr.TimeColumn], n: int, column: Columns) -> None:
        """Send the poses, actuator states, current and path of n rows at ``index``."""
        zeros = np.zeros(n)

        def get(name: str) -> np.ndarray:
            values = column(name)
            return zeros if values is None else values

        position = np.column_stack([get("plant.north"), get("plant.east"), get("plant.down")])
        yaw = get("plant.yaw")
        self._send_pose(index, position, self._attitude(column, yaw, get), yaw)
        self._send_trajectory(index, position)
        self._send_actuators(index, n, column)
        self._send_current(index, position, column)
        if self._target:
            self._send_target(index, column)
        self._send_depth_setpoint(index, position, column)

    def _send_pose(
        self,
        index: list[rr.TimeColumn],
        position: np.ndarray,
        quaternions: np.ndarray,
        yaw: np.ndarray,
    ) -> None:
        """The vehicle's pose (position in m, NED; attitude as quaternions [x, y, z, w]) and
        the chase camera's, which turns with the yaw (rad) only."""
        zeros = np.zeros(len(yaw))
        self._rec.send_columns(
            f"{self._root}/vehicle",
            indexes=index,
            columns=rr.Transform3D.columns(translation=position, quaternion=quaternions),
        )
        self._rec.send_columns(
            f"{self._root}/chase",
            indexes=index,
            columns=rr.Transform3D.columns(
                translation=position, quaternion=euler_to_quaternions(zeros, zeros, yaw)
            ),
        )

    def _send_actuators(self, index: list[rr.TimeColumn], n: int, column: Columns) -> None:
        """The stern planes turned by the fin angle (rad), the moving mass at its rail
        position (m) and the tunnel thruster's force (N) as an arrow, each if recorded."""
        fin = acting(column, "fin_angle")
        if fin is not None:
            hinge = np.tile([-0.5 * self._vehicle.length + FIN_FROM_TAIL, 0.0, 0.0], (n, 1))
            turn = pitch_quaternions(fin)
            self._rec.send_columns(
                f"{self._root}/vehicle/stern_planes",
                indexes=index,
                columns=rr.Transform3D.columns(translation=hinge, quaternion=turn),
            )
        mass = column("plant.mass_position")
        if mass is not None:
            centers = np.column_stack(
                [np.full(n, self._vehicle.x_v), mass, np.full(n, self._vehicle.z_g)]
            )
            self._rec.send_columns(
                f"{self._root}/vehicle/moving_mass",
                indexes=index,
                columns=rr.Ellipsoids3D.columns(centers=centers),
            )
        force = acting(column, "tunnel_force")
        if force is not None:
            zeros = np.zeros(n)
            vectors = np.column_stack([zeros, FORCE_SCALE * force, zeros])
            self._rec.send_columns(
                f"{self._root}/vehicle/tunnel_force",
                indexes=index,
                columns=rr.Arrows3D.columns(vectors=vectors),
            )

    def _send_current(
        self, index: list[rr.TimeColumn], position: np.ndarray, column: Columns
    ) -> None:
        """The water current (m/s, NED) as an arrow above the vehicle, if recorded."""
        current = [acting(column, f"current_{axis}") for axis in ("north", "east", "down")]
        if any(c is not None for c in current):
            zeros = np.zeros(len(position))
            vectors = np.column_stack([zeros if c is None else c for c in current])
            above = position - [0.0, 0.0, CURRENT_ARROW_HEIGHT]
            self._rec.send_columns(
                f"{self._root}/current",
                indexes=index,
                columns=rr.Arrows3D.columns(origins=above, vectors=CURRENT_SCALE * vectors),
            )

    def _send_depth_setpoint(
        self, index: list[rr.TimeColumn], position: np.ndarray, column: Columns
    ) -> None:
        """The autopilot's depth set-point (m) as a box at the vehicle's north and east, if
        recorded and asked for."""
        depth = column("controller.depth_setpoint")
        if self._show_depth_setpoint and depth is not None:
            centers = np.column_stack([position[:, 0], position[:, 1], depth])
            self._rec.send_columns(
                f"{self._root}/depth_setpoint",
                indexes=index,
                columns=rr.Boxes3D.columns(centers=centers),
            )

    def _send_target(self, index: list[rr.TimeColumn], column: Columns) -> None:
        """The waypoint a guidance steers for, if its outputs are recorded."""
        target = [values for name in TARGET_COLUMNS if (values := column(name)) is not None]
        if len(target) == len(TARGET_COLUMNS):
            self._rec.send_columns(
                "world/mission/target",
                indexes=index,
                columns=rr.Points3D.columns(positions=np.column_stack(target)),
            )

    def _send_trajectory(self, index: list[rr.TimeColumn], position: np.ndarray) -> None:
        # One segment per step, from the previous row's position (or itself on the first).
        previous = np.empty_like(position)
        previous[1:] = position[:-1]
        previous[0] = position[0] if self._last_position is None else self._last_position
        self._last_position = position[-1].copy()
        segments = np.stack([previous, position], axis=1)
        self._rec.send_columns(
            f"{self._root}/trajectory",
            indexes=index,
            columns=rr.LineStrips3D.columns(strips=strips_of_segments(segments)),
        )
