"""What a recording shows: the scalar series catalogue, its colours, and the default blueprint.

Every recorded column ``<instance>.<variable>`` becomes a line in one scalar entity. The
catalogue below groups the columns by meaning (attitude, rates, velocities, position,
moving mass, actuators, energy, environment) and puts each setpoint or command beside the
value it steers (yaw with the yaw setpoint, depth with the depth setpoint, the moving-mass
position with its command). Entity names carry the display unit (``attitude/yaw_deg``);
angles are shown in degrees, the moving mass in centimetres, everything else in SI.
A column the catalogue does not know still gets its own entity, ``other/<instance>/<variable>``
(the variable's name one escaped part, whatever it holds), in the unit its FMU declares,
named in its line's label; so does a catalogue column whose FMU declares another unit than
its plot converts from (an FMU's ``yaw_setpoint`` in deg is not scaled from rad again).
Every plot's entity also says, for a reader of the recording, which results.csv column
each of its lines shows and in what unit (:func:`series_sources`). A run of several
vehicles gives each vehicle the catalogue's plots of its own plant and autopilot under
``vehicles/<plant>/`` (:func:`vehicle_entity`), each loop of the layout once per vehicle.

Colours follow one rule everywhere, in the plots and in the 3D scene: the first, second and
third axis of a frame (north/u/p/roll, east/v/q/pitch, down/w/r/yaw) are red, green and
blue; a value relative to the water is a paler shade of its axis colour; every setpoint or
command is orange; each actuator has its own colour, reused for its arrow or body in 3D.
An actuator command appears as the autopilot's output (``controller.tunnel_force``) and,
when the plant's input of that name is recorded too (an unconnected, held input, as in a
run without autopilot), as a paler line "at the plant"; the current likewise as the
plant's (the water that moves the vehicle) and, paler, the autopilot's knowledge of it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from cosim.viz.display_units import DEG, source_unit

Rgb = tuple[int, int, int]


def pale(color: Rgb) -> Rgb:
    """Half-way to white: the same quantity seen from the other side (plant vs autopilot)."""
    return (128 + color[0] // 2, 128 + color[1] // 2, 128 + color[2] // 2)


RED: Rgb = (231, 76, 60)
GREEN: Rgb = (46, 204, 113)
BLUE: Rgb = (52, 152, 219)
PALE_RED: Rgb = (245, 170, 160)
PALE_GREEN: Rgb = (160, 235, 190)
PALE_BLUE: Rgb = (160, 205, 240)
SETPOINT: Rgb = (255, 165, 0)  # every setpoint and command
PALE_SETPOINT: Rgb = (255, 210, 130)
MASS: Rgb = (190, 90, 220)  # the internal moving mass
THRUSTER: Rgb = (0, 200, 200)  # the tunnel thruster
FIN: Rgb = (160, 210, 60)  # the stern planes
THRUST: Rgb = (200, 140, 90)  # the propeller
# Neutral lines (the track, the energy, an unknown column) in a slate grey that stands out
# on both of the viewer's themes: contrast 4.9 on the light theme's white, 3.8 on the dark
# theme's near-black (WCAG 2 contrast ratios; a near-white line vanished on the light theme)
NEUTRAL: Rgb = (112, 112, 128)
ENERGY: Rgb = NEUTRAL
CURRENT: Rgb = (90, 200, 250)  # the water current
HULL: Rgb = (250, 200, 40)  # REMUS yellow
TRAJECTORY: Rgb = NEUTRAL

PLOT_COLUMNS = 2  # time-series plots side by side in a loop's grid
TIMELINE = "sim_time"
VEHICLE_ENTITY = "/world/vehicle"  # the body frame in the 3D scene (cosim.viz.scene)
# What the world view's eye tracks: the hull, a shape in the body frame. The viewer tracks
# an entity by its shapes: the frame itself, a transform alone, left the eye where it was.
TRACKED_ENTITY = f"{VEHICLE_ENTITY}/hull"
WORLD_EYE = (-10.0, -6.0, -5.0)  # m from the vehicle: behind, to port, above (13 m away)
NOTES_ENTITY = "events"  # TextLog: events fired, faults started and stopped, live overrides
CHASE_EYE = (-1.6, -0.9, -0.6)  # m in the chase frame: behind, to port, above the vehicle
DIMENSIONLESS = "1"  # a quantity without a unit, as SI (and summary.json's units) write it
# a column no panel knows, declared in rad or rad/s: drawn in (unit, per declared unit)
IN_DEGREES: dict[str, tuple[str, float]] = {"rad": ("deg", DEG), "rad/s": ("deg/s", DEG)}


def time_index(times: np.ndarray) -> list[rr.TimeColumn]:
    """The ``sim_time`` index of rows at ``times`` (s), rounded to whole nanoseconds.

    rerun-sdk truncates float seconds (0.57 s would become 569999999 ns); rounding keeps
    the step times exact, so a time cursor set to a step lands on it.
    """
    nanos = np.rint(np.asarray(times, dtype=float) * 1e9).astype("timedelta64[ns]")
    return [rr.TimeColumn(TIMELINE, duration=nanos)]


@dataclass(frozen=True)
class Series:
    """One line of a plot: a recorded column shown as ``value * scale``."""

    column: str  # "<instance>.<variable>"
    label: str  # legend text, with the display unit
    color: Rgb
    scale: float = 1.0  # display unit per SI unit
    # an angle drawn on the turn of this column's (a heading set-point on the yaw's:
    # display_units.on_turn_of), within half a turn of it
    turn_of: str | None = None


@dataclass(frozen=True)
class Panel:
    """One scalar entity (one plot) holding the series of related columns."""

    entity: str  # entity path, display unit in the last segment
    title: str  # view name
    unit: str  # the display unit of every line, as FMUs write units (N.m)
    series: tuple[Series, ...]


PANELS: tuple[Panel, ...] = (
    Panel("attitude/yaw_deg", "Yaw ψ (deg)", "deg", (
        Series("plant.yaw", "yaw ψ (deg)", BLUE, DEG),
        Series("controller.yaw_setpoint", "yaw setpoint (deg)", SETPOINT, DEG, "plant.yaw"),
        Series("guidance.yaw_setpoint", "guidance yaw setpoint ψ_d (deg)", SETPOINT, DEG,
               "plant.yaw"),
        Series("guidance.course_setpoint", "guidance course setpoint χ_d (deg)",
               PALE_SETPOINT, DEG, "plant.yaw"),
    )),
    Panel("attitude/roll_deg", "Roll φ (deg)", "deg", (
        Series("plant.roll", "roll φ (deg)", RED, DEG),
    )),
    Panel("attitude/pitch_deg", "Pitch θ (deg)", "deg", (
        Series("plant.pitch", "pitch θ (deg)", GREEN, DEG),
    )),
    Panel("rates/roll_yaw_deg_s", "Roll and yaw rates (deg/s)", "deg/s", (
        Series("plant.p", "roll rate p (deg/s)", RED, DEG),
        Series("plant.r", "yaw rate r (deg/s)", BLUE, DEG),
    )),
    Panel("rates/pitch_deg_s", "Pitch rate (deg/s)", "deg/s", (
        Series("plant.q", "pitch rate q (deg/s)", GREEN, DEG),
    )),
    Panel("velocity/surge_m_s", "Surge (m/s)", "m/s", (
        Series("plant.u", "u over ground (m/s)", RED),
        Series("plant.u_rel", "u through water (m/s)", PALE_RED),
    )),
    Panel("velocity/sway_m_s", "Sway (m/s)", "m/s", (
        Series("plant.v", "v over ground (m/s)", GREEN),
        Series("plant.v_rel", "v through water (m/s)", PALE_GREEN),
    )),
    Panel("velocity/heave_m_s", "Heave (m/s)", "m/s", (
        Series("plant.w", "w over ground (m/s)", BLUE),
        Series("plant.w_rel", "w through water (m/s)", PALE_BLUE),
    )),
    Panel("position/horizontal_m", "Position (m)", "m", (
        Series("plant.north", "north (m)", RED),
        Series("plant.east", "east (m)", GREEN),
    )),
    Panel("position/depth_m", "Depth (m)", "m", (
        Series("plant.down", "depth (m)", BLUE),
        Series("controller.depth_setpoint", "depth setpoint (m)", SETPOINT),
        Series("guidance.depth_setpoint", "guidance depth setpoint z_d (m)", SETPOINT),
    )),
    Panel("moving_mass/position_cm", "Moving mass y_v (cm)", "cm", (
        Series("plant.mass_position", "mass position y_v (cm)", MASS, 100.0),
        Series("controller.mass_position_cmd", "mass command y_d (cm)", SETPOINT, 100.0),
        Series("plant.mass_position_cmd", "mass command at the plant (cm)", PALE_SETPOINT, 100.0),
    )),
    Panel("moving_mass/velocity_cm_s", "Moving-mass rail speed (cm/s)", "cm/s", (
        Series("plant.mass_velocity", "rail speed (cm/s)", MASS, 100.0),
    )),
    Panel("actuators/tunnel_force_N", "Tunnel thruster (N)", "N", (
        Series("controller.tunnel_force", "tunnel force F_t (N)", THRUSTER),
        Series("plant.tunnel_force", "F_t at the plant (N)", pale(THRUSTER)),
    )),
    Panel("actuators/fin_angle_deg", "Stern planes (deg)", "deg", (
        Series("controller.fin_angle", "fin angle δs (deg)", FIN, DEG),
        Series("plant.fin_angle", "δs at the plant (deg)", pale(FIN), DEG),
    )),
    Panel("actuators/thrust_N", "Propeller thrust (N)", "N", (
        Series("controller.thrust", "thrust T (N)", THRUST),
        Series("plant.thrust", "T at the plant (N)", pale(THRUST)),
    )),
    Panel("actuators/roll_torque_Nm", "Propeller roll torque (N m)", "N.m", (
        Series("plant.roll_torque", "roll torque Q (N m)", THRUST),
    )),
    Panel("energy/kinetic_J", "Kinetic energy (J)", "J", (
        Series("plant.kinetic_energy", "kinetic energy (J)", ENERGY),
    )),
    Panel("environment/current_m_s", "Current, earth axes (m/s)", "m/s", (
        Series("plant.current_north", "current north (m/s)", RED),
        Series("plant.current_east", "current east (m/s)", GREEN),
        Series("plant.current_down", "current down (m/s)", BLUE),
        Series("controller.current_north", "north, as the autopilot knows it (m/s)", PALE_RED),
        Series("controller.current_east", "east, as the autopilot knows it (m/s)", PALE_GREEN),
    )),
)  # fmt: skip

HEADING_LOOP = (
    "attitude/yaw_deg",
    "rates/roll_yaw_deg_s",
    "attitude/roll_deg",
    "velocity/sway_m_s",
    "moving_mass/position_cm",
    "actuators/tunnel_force_N",
)
DEPTH_LOOP = (
    "position/depth_m",
    "attitude/pitch_deg",
    "rates/pitch_deg_s",
    "velocity/heave_m_s",
    "actuators/fin_angle_deg",
    "velocity/surge_m_s",
)
VEHICLE = (
    "position/horizontal_m",
    "moving_mass/velocity_cm_s",
    "actuators/thrust_N",
    "actuators/roll_torque_Nm",
    "energy/kinetic_J",
    "environment/current_m_s",
)


@dataclass(frozen=True)
class PlannedPanel:
    """A panel restricted to the columns a run records: ``indices`` index into them;
    ``vehicle``: in a run of several vehicles, the plant whose panel it is ("" else)."""

    entity: str
    title: str
    series: tuple[Series, ...]
    indices: tuple[int, ...]
    scales: tuple[float, ...]
    units: tuple[str, ...]  # the display unit of each line
    vehicle: str = ""


VEHICLES_ENTITY = "vehicles"  # a fleet's panels: vehicles/<plant>/attitude/yaw_deg, ...


def vehicle_entity(plant: str, entity: str) -> str:
    """Where the panel ``entity`` (``attitude/yaw_deg``) of the vehicle of plant ``plant``
    is in a run of several vehicles: ``vehicles/<plant>/attitude/yaw_deg``."""
    return f"{VEHICLES_ENTITY}/{rr.escape_entity_path_part(plant)}/{entity}"


def _own(series: Series, plant: str, controller: str) -> Series:
    """``series`` of the catalogue (``plant.yaw``) read from a vehicle's own instances
    (``plant_a.yaw``); a column of another instance (a guidance's) is not the vehicle's."""
    names = {"plant": plant, "controller": controller}

    def own(column: str) -> str:
        instance, _, variable = column.partition(".")
        return f"{names[instance]}.{variable}" if instance in names else ""

    turn_of = own(series.turn_of) if series.turn_of else None
    return replace(series, column=own(series.column), turn_of=turn_of)


def _labelled(label: str, unit: str | None) -> str:
    """A line's legend text: ``label`` with its unit, if it has one that says something."""
    return label if unit in (None, "", DIMENSIONLESS) else f"{label} ({unit})"


def plan_panels(
    columns: list[str],
    units: Mapping[str, str] | None = None,
    fleet: Sequence[tuple[str, str]] = (),
) -> list[PlannedPanel]:
    """The panels a run with these columns shows; unknown columns go to ``other/...``,
    drawn in the unit ``units`` gives them (column -> the unit its FMU declares, as
    summary.json's ``units``; ``"1"`` for a column it lacks).

    A panel none of whose columns is recorded is dropped; one with some of them keeps
    those (a run without a controller still shows yaw, without the setpoint). ``fleet``:
    the (plant, autopilot) instances of each vehicle of a run of several; each vehicle's
    columns get panels of their own (:func:`vehicle_entity`, titled with its plant), as
    the catalogue draws ``plant`` and ``controller``'s; the panels of one vehicle, or of
    none, are the catalogue's, unchanged.
    """
    index = {name: i for i, name in enumerate(columns)}
    planned: list[PlannedPanel] = []
    shown: set[int] = set()
    owners = [(plant, controller) for plant, controller in fleet] if len(fleet) > 1 else []
    for plant, controller in owners:
        for panel in PANELS:
            own = replace(panel, series=tuple(_own(s, plant, controller) for s in panel.series))
            found = _planned(own, index, units, shown)
            if found is not None:
                entity, title = vehicle_entity(plant, panel.entity), f"{plant}: {panel.title}"
                planned.append(replace(found, entity=entity, title=title, vehicle=plant))
    for panel in PANELS:
        if (found := _planned(panel, index, units, shown)) is not None:
            planned.append(found)
    for i, name in enumerate(columns):
        if i not in shown:
            declared = (units or {}).get(name) or DIMENSIONLESS
            unit, scale = IN_DEGREES.get(declared, (declared, 1.0))  # angles as every plot
            series = Series(name, _labelled(name, unit), ENERGY, scale)
            entity = "other/" + "/".join(map(rr.escape_entity_path_part, name.split(".", 1)))
            planned.append(PlannedPanel(entity, name, (series,), (i,), (scale,), (unit,)))
    return planned


def _planned(
    panel: Panel, index: Mapping[str, int], units: Mapping[str, str] | None, shown: set[int]
) -> PlannedPanel | None:
    """``panel`` restricted to its recorded columns not ``shown`` in another panel (which
    it adds them to), or None if it has none."""
    present = tuple(
        s
        for s in panel.series
        if s.column in index and index[s.column] not in shown and _fits(s.column, panel, units)
    )
    if not present:
        return None
    indices = tuple(index[s.column] for s in present)
    shown.update(indices)
    scales = tuple(s.scale for s in present)
    return PlannedPanel(
        panel.entity, panel.title, present, indices, scales, (panel.unit,) * len(present)
    )


def _fits(column: str, panel: Panel, units: Mapping[str, str] | None) -> bool:
    """Whether ``column`` is declared in the unit ``panel``'s scale converts from (or no
    unit of it is known, "1" included): a column in deg is not scaled by DEG again, it is
    drawn apart."""
    declared = (units or {}).get(column)
    return declared in (None, DIMENSIONLESS) or declared == source_unit(panel.unit)


def series_style(panel: PlannedPanel) -> rr.SeriesLines:
    """The static legend names and colours of a panel's lines."""
    return rr.SeriesLines(
        names=[s.label for s in panel.series],
        colors=[s.color for s in panel.series],
        widths=[1.5] * len(panel.series),
    )


def series_sources(panel: PlannedPanel) -> rr.AnyValues:
    """What a panel's lines are, for a reader of the recording: ``results_columns``, the
    results.csv column of each line in the lines' order, and ``units``, the unit each is
    drawn in (a column's value in SI times the line's scale)."""
    return rr.AnyValues(results_columns=[s.column for s in panel.series], units=list(panel.units))


def world_eye(tracked: str = TRACKED_ENTITY) -> rrb.EyeControls3D:
    """The world view's eye: it follows the vehicle (its hull, :data:`TRACKED_ENTITY`, or
    ``tracked``: the first of several vehicles') as it moves, from :data:`WORLD_EYE` (the
    vehicle at the start: the origin), so a run that goes far does not leave the view, nor
    shrink the vehicle to a dot."""
    return rrb.EyeControls3D(
        kind=rrb.Eye3DKind.Orbital,
        position=WORLD_EYE,
        look_target=(0.0, 0.0, 0.0),
        eye_up=(0.0, 0.0, -1.0),  # NED: up is -z
        tracking_entity=tracked,
    )


def tracked_entity(roots: Sequence[str] = ()) -> str:
    """The shape the world view follows: the hull of the first drawn vehicle (``roots``:
    the entities the drawn vehicles hang under, :func:`build_blueprint`), else
    :data:`TRACKED_ENTITY`."""
    return f"/{roots[0]}/vehicle/hull" if roots else TRACKED_ENTITY


def _loop_grids(
    panels: list[PlannedPanel], title: str, entities: tuple[str, ...], legend: bool = True
) -> list[rrb.Grid]:
    """The grids of the loop ``title`` (its plots ``entities``): the catalogue's panels',
    then each vehicle's of a run of several (:func:`plan_panels`' ``fleet``), named
    ``<title> (<plant>)``; a grid without a recorded panel is left out."""
    present = {p.entity: p for p in panels}
    vehicles = list(dict.fromkeys(p.vehicle for p in panels if p.vehicle))
    legend_at = rrb.PlotLegend(corner=rrb.Corner2D.RightTop, visible=True) if legend else None
    grids = []
    for plant in ["", *vehicles]:
        views = [
            rrb.TimeSeriesView(
                origin="/" + entity, name=present[entity].title, plot_legend=legend_at
            )
            for entity in (vehicle_entity(plant, e) if plant else e for e in entities)
            if entity in present
        ]
        if views:
            name = f"{title} ({plant})" if plant else title
            grids.append(rrb.Grid(*views, grid_columns=PLOT_COLUMNS, name=name))
    return grids


def build_blueprint(
    panels: list[PlannedPanel], depth_control: bool, roots: Sequence[str] = ("world",)
) -> rrb.Blueprint:
    """The default layout: 3D world and chase views, heading-loop and depth-loop plots.

    Left: the world view (whole trajectory, NED grid at the surface) above a chase view
    in the frame ``world/chase`` (the vehicle's position and heading, see
    :mod:`cosim.viz.scene`): its eye stays behind the vehicle, which rolls and pitches
    against a level grid. Middle: the heading loop (yaw and its setpoint, roll and
    yaw rates, roll, sway, the moving mass and its command, the tunnel thruster). Right,
    in tabs: the depth loop (depth and setpoint, pitch, pitch rate, heave, fins, surge),
    the rest of the vehicle state, any unknown columns, the log of what happened at a time
    (:data:`NOTES_ENTITY`: events, faults, live overrides; with auto views off, nothing
    would show it otherwise) and the scenario text. ``roots``: the entities the drawn
    vehicles hang under (:class:`cosim.viz.scene.SceneVehicle`; ``world`` for one, each
    ``world/<plant>`` of several): every vehicle's track grows with the time cursor, the
    world view follows the first vehicle and the chase view rides on it. A run of several
    vehicles with panels of their own (:func:`plan_panels`' ``fleet``) has each loop once
    per vehicle, a tab each (``Heading loop (plant_a)``). The depth tab (the first
    vehicle's) is the active one when depth control is on, the vehicle tab otherwise.

    The plots of a loop sit in a grid of :data:`PLOT_COLUMNS` columns, not one stack: six
    stacked plots of ~130 px each leave the viewer room for a single y tick ("0") on most
    of them; three rows of ~300 px show several ticks, so values can be read off.
    """
    trajectory_history = rrb.VisibleTimeRanges(
        timeline=TIMELINE,
        start=rrb.TimeRangeBoundary.infinite(),
        end=rrb.TimeRangeBoundary.cursor_relative(),
    )
    first = f"/{roots[0]}" if roots else "/world"
    tracks = [f"/{root}/trajectory" for root in roots or ("world",)]
    world = rrb.Spatial3DView(
        origin="/world",
        name="World (NED, grid 10 m)",
        line_grid=rrb.LineGrid3D(visible=True, spacing=10.0),
        eye_controls=world_eye(tracked_entity(roots)),
        overrides={track: trajectory_history for track in tracks},
    )
    chase = rrb.Spatial3DView(
        origin=f"{first}/chase",
        contents="/world/**",
        name="Chase view (level grid 1 m)",
        line_grid=rrb.LineGrid3D(visible=True, spacing=1.0),
        eye_controls=rrb.EyeControls3D(
            kind=rrb.Eye3DKind.Orbital,
            position=CHASE_EYE,
            look_target=[0.0, 0.0, 0.0],
            eye_up=[0.0, 0.0, -1.0],
        ),
        overrides={track: trajectory_history for track in tracks},
    )
    columns: list[rrb.Container | rrb.View] = [rrb.Vertical(world, chase, row_shares=[3, 2])]
    heading = _loop_grids(panels, "Heading loop", HEADING_LOOP)
    if len(heading) == 1:
        columns.append(heading[0])
    elif heading:
        columns.append(rrb.Tabs(*heading, active_tab=0))
    tabs: list[rrb.Container | rrb.View] = []
    for title, entities in (("Depth loop", DEPTH_LOOP), ("Vehicle", VEHICLE)):
        tabs += _loop_grids(panels, title, entities)
    if any(p.entity.startswith("other/") for p in panels):
        tabs.append(rrb.TimeSeriesView(origin="/other", name="Other signals"))
    tabs.append(rrb.TextLogView(origin=f"/{NOTES_ENTITY}", name="Events"))
    tabs.append(rrb.TextDocumentView(origin="/scenario", name="Scenario"))
    shown = "Depth loop" if depth_control else "Vehicle"
    names = [str(tab.name) for tab in tabs]
    active = next((k for k, name in enumerate(names) if name.startswith(shown)), 0)
    columns.append(rrb.Tabs(*tabs, active_tab=active))
    return rrb.Blueprint(
        rrb.Horizontal(*columns, column_shares=[4, 5, 4][: len(columns)]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
        auto_views=False,
    )


def notebook_blueprint(panels: list[PlannedPanel], roots: Sequence[str] = ()) -> rrb.Blueprint:
    """The layout for a notebook cell (``cosim.viz.notebook``): the world view beside the
    heading loop's plots (a run of several vehicles: each vehicle's, a tab each), two
    columns in the cell's width, every side panel collapsed; the events log
    (:data:`NOTES_ENTITY`: events, faults, how the run ended) a tab behind the plots.
    ``roots``: the entities the drawn vehicles hang under (:func:`build_blueprint`); the
    world view follows the first."""
    world = rrb.Spatial3DView(
        origin="/world",
        name="World (NED, grid 10 m)",
        line_grid=rrb.LineGrid3D(visible=True, spacing=10.0),
        eye_controls=world_eye(tracked_entity(roots)),
    )
    tabs: list[rrb.Container | rrb.View] = []
    tabs += _loop_grids(panels, "Heading loop", HEADING_LOOP, legend=False)
    tabs.append(rrb.TextLogView(origin=f"/{NOTES_ENTITY}", name="Events"))
    views: list[rrb.Container | rrb.View] = [world, rrb.Tabs(*tabs, active_tab=0)]
    return rrb.Blueprint(
        rrb.Horizontal(*views, column_shares=[2, 3][: len(views)]),
        rrb.BlueprintPanel(state="collapsed"),
        rrb.SelectionPanel(state="collapsed"),
        rrb.TimePanel(state="collapsed"),
        auto_views=False,
    )
