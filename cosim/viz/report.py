"""``auv-cosim report RUN_DIR``: a run's time histories as PNG figures and an index page.

The figures are laid out like the dissertation's Ch. 6 plots:

* ``velocities.png`` - u, v, r, p against time (Figs. 6.11, 6.13, 6.23);
* ``attitude_actuators.png`` - roll, yaw (with its setpoint), the moving mass y_v (with
  its command) and rail speed, the tunnel-thruster force (Figs. 6.12, 6.24, 6.42);
* ``trajectory.png`` - the path over ground, north up and east to the right (Fig. 6.31),
  with a 3-D view when the depth changes (Fig. 6.44);
* ``depth.png`` - depth (with its setpoint), pitch, w, q and the stern-plane angle, when
  the run has a depth loop (Fig. 6.43);
* ``mission.png`` - a waypoint guidance's cross-track error and legs completed; the
  trajectory then also shows the planned path and its waypoints (from the run's
  ``scenario.toml``).

* ``lateral_deviation.png`` - the sideways deviation from the initial course against the
  distance along it (a drift of 0.5 m in 90 m is invisible on the equal-scale trajectory).

A panel that draws the source of a connection a fault acts on (a command, a sensed
value) also draws what the fault delivered to the connection's target (a jammed mass's
held command, a delayed or noisy signal, 0 N from a failed thruster:
:mod:`cosim.viz.delivered`), its legend naming the value as sent and as delivered with the
panel's unit, and the interval where the fault acts shaded. A faulted connection no
figure draws (its source not recorded, or on no panel) is named on the page, with why.

Each event the run fired and each fault's start and stop (``summary.json``'s ``events``
and ``faults``, docs/events.md), and the yaw settling time (its key figure), is a
vertical marker on every time-history panel, named in the first panel's legend. The
actuator limits -- the moving mass's rail stops (the plant's ``mass_stroke``), the
tunnel thruster's force limit (the autopilot's ``tunnel_force_limit``) and the stern
planes' stops (its ``fin_angle_limit``), read from the
run's start values, else from the FMU's model description -- are horizontal lines on
their panels. When the yaw settles within the first third of the run, the velocity and
attitude figures get a second column: the transient, the first
:data:`ZOOM_SETTLING_TIMES` settling times.

A run of a standard manoeuvre (its ``summary.json`` names a ``manoeuvre``) gets its
metrics in a table of their own on the page; a turning circle also gets them marked on
its trajectory: the execute and the original course, advance and transfer at the 90 deg
point, the tactical diameter at the 180 deg point.

A run of more than :data:`DRAWN_POINTS_MAX` rows (1000 s at 10 ms) is drawn through a
subset of its points, each line through the extremes of every bucket of consecutive
points (:func:`drawn_points`): a spike and the line's ends stay, and a 36000 s run's
report takes what one of 1000 s does to draw.

Each figure's title names the run (its scenario id, :func:`run_caption`), so that one
lifted out of the page still says what was run; a run that did not complete (or is still
running) says so there, with the time it reached and its stop time, and its time axes run
to the stop time, so the missing part shows as such.

Every series is optional: a panel whose columns the run did not record is left out, a
figure with no panel is not written. The page ``report/index.html`` in the run folder
shows the run's summary (``summary.json``) and links the figures, each with an alt text
saying what it plots against what, in which units (:func:`figure_alt`); its tables have
captions and row headers (``scope="row"``) for a screen reader.
"""

from __future__ import annotations

import errno
import html
import json
import math
import os
import shutil
import tomllib
import warnings
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from cosim.errors import CosimError
from cosim.fmus.interface import read_interface
from cosim.limits import unwritten
from cosim.metrics.key_figures import why_none_of
from cosim.metrics.manoeuvres import summary_metrics, turning_circle_marks
from cosim.outputs.folder import REPORT_FOLDER
from cosim.outputs.missing_run import missing_run_hint
from cosim.outputs.report_folder import (
    REPORT_MANIFEST,
    check_writable,
    local_time,
    record,
    remove_earlier,
    run_stamp,
)
from cosim.outputs.results import read_csv
from cosim.paths import DEFAULT_FMU_DIR, path_text
from cosim.viz.delivered import (
    Delivery,
    deliveries,
    faulted_connections,
    read_scenario,
)
from cosim.viz.display_units import DEG, NO_UNIT, on_turn_of, scale_to
from cosim.viz.fleet import run_vehicles
from cosim.viz.mission import mission_waypoints
from cosim.viz.rrd_file import STUDY_FILE

INDEX_PAGE = "index.html"
ZOOM_SETTLING_TIMES = 3.0  # the transient column shows this many settling times
SETTLING_FIGURE = "yaw_settling_time_s"
# (FMU model identifier, parameter) -> the column whose panel shows it as +- limit lines
LIMITS = {
    ("AuvPlant", "mass_stroke"): "mass_position",
    ("AuvAutopilot", "tunnel_force_limit"): "tunnel_force",
    ("AuvAutopilot", "fin_angle_limit"): "fin_angle",
}
# The looks of the events' markers, one per event name in the order they first fired:
# colours clear of the curves' blue and gray, the settling time's green and the faults'
# red, solid then dashed when there are more names than colours
EVENT_COLOURS = ("tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")
EVENT_STYLES = ("-", "--")


@dataclass(frozen=True)
class Series:
    """One curve: a results column, its display scale and legend label."""

    column: str
    scale: float = 1.0
    label: str = ""
    dashed: bool = False
    colour: str | None = None  # None: blue, gray when dashed
    # an angle in deg drawn on the whole turn nearest this column's line of the panel: a
    # yaw set-point of 10 deg (or 370, or -350: one heading to the autopilot, which wraps
    # its error) beside a yaw that turned from 350 deg to 370 deg (the plant's yaw counts
    # whole turns) is drawn at 370 deg, on the yaw it is for
    turn_of: str | None = None


@dataclass(frozen=True)
class TurnMarks:
    """Where a turning circle's metrics were measured (``turning_circle_marks``) and their
    values (summary.json)."""

    points: dict[str, Any]
    metrics: dict[str, float | int | None]


@dataclass(frozen=True)
class Marker:
    """A vertical line at ``time`` (s) on every time-history panel."""

    time: float
    label: str
    color: str
    style: str


def markers_of(summary: dict[str, Any]) -> list[Marker]:
    """The events fired, the faults' starts and stops listed in ``summary.json`` and the
    yaw settling time (its key figure); each event name has a look of its own
    (:data:`EVENT_COLOURS`), its every firing the same."""
    markers = []
    settled = (summary.get("key_figures") or {}).get(SETTLING_FIGURE)
    if settled is not None:
        markers.append(Marker(float(settled), f"yaw settled ({settled:g} s)", "tab:green", "-."))
    names: dict[str, int] = {}  # event name -> its look's index
    for event in summary.get("events") or []:
        k = names.setdefault(event["name"], len(names))
        colour = EVENT_COLOURS[k % len(EVENT_COLOURS)]
        style = EVENT_STYLES[k // len(EVENT_COLOURS) % len(EVENT_STYLES)]
        markers.append(Marker(float(event["time"]), f"event {event['name']}", colour, style))
    for fault in summary.get("faults") or []:
        name = f"fault {fault['name']} ({fault['kind']})"
        start = float(fault["start"])
        markers.append(Marker(start, f"{name} starts ({start:g} s)", "tab:red", "--"))
        if fault.get("stop") is not None:
            stop = float(fault["stop"])
            markers.append(Marker(stop, f"{name} stops ({stop:g} s)", "tab:red", ":"))
    return markers


@dataclass(frozen=True)
class Panel:
    """One axis of a figure: its y label and the curves drawn on it (first = main)."""

    ylabel: str
    series: tuple[Series, ...]
    spans: tuple[tuple[str, str], ...] = ()  # (column, legend label): shaded where it is > 0


FIGURES: dict[str, tuple[str, tuple[Panel, ...]]] = {
    "velocities": (
        "Linear and angular velocities",
        (
            Panel("u (m/s)", (Series("plant.u"),)),
            Panel("v (m/s)", (Series("plant.v"),)),
            Panel("r (deg/s)", (Series("plant.r", DEG),)),
            Panel("p (deg/s)", (Series("plant.p", DEG),)),
        ),
    ),
    "attitude_actuators": (
        "Roll and yaw, moving mass and tunnel thruster",
        (
            Panel(r"$\phi$ (deg)", (Series("plant.roll", DEG),)),
            Panel(
                r"$\psi$ (deg)",
                (
                    Series("plant.yaw", DEG, "yaw"),
                    Series(
                        "controller.yaw_setpoint", DEG, "setpoint", dashed=True, turn_of="plant.yaw"
                    ),
                    Series(
                        "guidance.yaw_setpoint",
                        DEG,
                        "guidance set-point",
                        dashed=True,
                        turn_of="plant.yaw",
                    ),
                ),
            ),
            Panel(
                "$y_v$ (cm)",
                (
                    Series("plant.mass_position", 100.0, "position"),
                    Series("controller.mass_position_cmd", 100.0, "command", dashed=True),
                    Series("plant.mass_position_cmd", 100.0, "command (held)", dashed=True),
                ),
            ),
            Panel("$y_{vel}$ (cm/s)", (Series("plant.mass_velocity", 100.0),)),
            Panel("$F_t$ (N)", (Series("controller.tunnel_force"),)),
        ),
    ),
    "depth": (
        "Vertical-plane motion and stern planes",
        (
            Panel(
                "z (m)",
                (
                    Series("plant.down", 1.0, "depth"),
                    Series("controller.depth_setpoint", 1.0, "setpoint", dashed=True),
                    Series("guidance.depth_setpoint", 1.0, "guidance set-point", dashed=True),
                ),
            ),
            Panel(r"$\theta$ (deg)", (Series("plant.pitch", DEG),)),
            Panel("w (m/s)", (Series("plant.w"),)),
            Panel("q (deg/s)", (Series("plant.q", DEG),)),
            Panel(r"$\delta_s$ (deg)", (Series("controller.fin_angle", DEG),)),
        ),
    ),
    "mission": (
        "Waypoint guidance",
        (
            Panel("cross-track error (m)", (Series("guidance.cross_track_error"),)),
            Panel("legs completed", (Series("guidance.legs_completed"),)),
        ),
    ),
}
DELIVERED_COLOUR = "black"  # a fault's delivered value, beside the blue and gray curves
FAULT_SHADE = "tab:red"  # where a fault acts (its start and stop markers are red too)
TITLES = {"trajectory": "Trajectory", "lateral_deviation": "Lateral deviation"}
ZOOMED = ("velocities", "attitude_actuators")  # the figures with a transient column
# The depth figure is drawn only for a run with a depth loop: fins commanded or depth moving.
DEPTH_EVIDENCE = ("controller.fin_angle", "controller.depth_setpoint")


def write_report(run_dir: Path) -> Path:
    """Write the figures and the index page of the run in ``run_dir``; return the page.
    The page is stamped with the run it describes (:func:`run_stamp`); the files are
    recorded in the report's manifest (:mod:`cosim.outputs.report_folder`), and a figure
    an earlier report wrote that this one does not is removed. The report is made in a
    hidden folder inside ``report/`` and moved in whole: one that cannot be written (a
    full disk) leaves the folder as it was, and can be made again once it can.

    Raises:
        CosimError: ``run_dir`` holds no readable ``results.csv`` (or it has no rows), or
            the report folder cannot be written, or holds a file of that name that no
            report wrote (a user's own ``index.html``), which is left as it is.
    """
    run_dir = Path(run_dir)
    stamp = {**run_stamp(run_dir), "made": local_time()}
    table = load_results(run_dir)
    summary, summary_problem = load_summary(run_dir)
    views = vehicle_views(run_dir, summary)
    _check_drawable(run_dir, table, summary, views)
    out = run_dir / REPORT_FOLDER
    names = [f"{name}{view.suffix}" for view in views for name in (*FIGURES, *TITLES)]
    check_writable(out, [INDEX_PAGE, *(f"{name}.png" for name in names)])
    staging = out / f".report.{os.getpid()}.tmp"
    made_out = not out.exists()
    try:
        out.mkdir(exist_ok=True)
        staging.mkdir()
        figures, alts, titles, panelled = {}, {}, {}, set()
        for view in views:
            drawn = _figures(run_dir, table, summary, staging, view)
            for key, (name, path) in drawn.items():
                figures[key] = path
                alts[key] = figure_alt(name, table, summary, run_dir, view)
                titles[key] = (FIGURES[name][0] if name in FIGURES else TITLES[name]) + view.title
                if name in FIGURES:
                    panelled |= {view.source(s.column) for p in FIGURES[name][1] for s in p.series}
        index = staging / INDEX_PAGE
        nulls = null_reasons(run_dir, table, summary)
        undrawn = undrawn_faults(run_dir, table, summary, panelled)
        page = index_page(
            run_dir, summary, summary_problem, figures, stamp, alts, nulls, undrawn, titles
        )
        index.write_text(page, "utf-8", "backslashreplace")  # undecoded text elsewhere
        record(staging, [*figures.values(), index], stamp)
        remove_earlier(out, keep=[INDEX_PAGE, *(path.name for path in figures.values())])
        for name in [*(path.name for path in figures.values()), INDEX_PAGE, REPORT_MANIFEST]:
            os.replace(staging / name, out / name)  # the manifest last: it names the rest
    except OSError as exc:
        shutil.rmtree(staging, ignore_errors=True)
        if made_out:
            shutil.rmtree(out, ignore_errors=True)
        why = unwritten(exc) if exc.strerror else os.strerror(exc.errno) if exc.errno else str(exc)
        denied = exc.errno in (errno.EACCES, errno.EPERM, errno.EROFS)
        raise CosimError(
            f"cannot write the report into {out}: {why}; nothing of it is left "
            f"({'no report made' if made_out else 'the earlier report is as it was'})"
            + (
                "; copy the run folder to a folder you can write and report the copy"
                if denied
                else ""
            )
        ) from None
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return out / INDEX_PAGE


@dataclass(frozen=True)
class VehicleView:
    """One vehicle's figures: its plant and autopilot instances (``names``, each to the
    name the figures give it, ``plant`` or ``controller``) and, in a run of several
    vehicles, its plant's name (``plant``), which its figures' files end with
    (``velocities_plant_a.png``) and their titles name; "" for a run's one vehicle."""

    names: tuple[tuple[str, str], ...] = (("plant", "plant"), ("controller", "controller"))
    plant: str = ""
    others: tuple[str, ...] = ()  # the other vehicles' plants and autopilots

    @property
    def suffix(self) -> str:
        return f"_{self.plant}" if self.plant else ""

    @property
    def title(self) -> str:
        return f" ({self.plant})" if self.plant else ""

    def column(self, column: str) -> str:
        """The name the figures give results column ``column`` (``plant_a.yaw``:
        ``plant.yaw``); a column of another instance (a guidance's) as it is."""
        instance, dot, variable = column.partition(".")
        return f"{dict(self.names).get(instance, instance)}{dot}{variable}"

    def source(self, column: str) -> str:
        """The results column a figure's ``column`` draws (``plant.yaw``: ``plant_a.yaw``)."""
        instance, dot, variable = column.partition(".")
        back = {role: name for name, role in self.names}
        return f"{back.get(instance, instance)}{dot}{variable}"

    def keeps(self, column: str) -> bool:
        """Whether the figures draw ``column``: not one of another vehicle's instance named
        plant or controller (its own are renamed so)."""
        instance = column.partition(".")[0]
        return instance in dict(self.names) or instance not in ("plant", "controller")

    def columns(self, given: Any) -> dict[str, Any]:
        """A mapping by results column (summary.json's ``units``), as the figures name them."""
        each = given.items() if isinstance(given, dict) else ()
        return {self.column(str(k)): v for k, v in each if self.keeps(str(k))}

    def table(self, table: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The run's results with the columns the figures draw, named as they name them."""
        return self.columns(table)

    def summary(self, summary: dict[str, Any]) -> dict[str, Any]:
        """summary.json with this vehicle's key figures under their plain names (a fleet's
        are ``<plant>.yaw_settling_time_s``)."""
        if not self.plant:
            return summary
        figures = summary.get("key_figures")
        each = figures.items() if isinstance(figures, dict) else ()
        prefix = f"{self.plant}."
        own = {k.removeprefix(prefix): v for k, v in each if k.startswith(prefix)}
        faults = [f for f in summary.get("faults") or [] if not self._theirs([f.get("target")])]
        events = [e for e in summary.get("events") or [] if not self._theirs(e.get("set"))]
        return {**summary, "key_figures": own, "faults": faults, "events": events}

    def _theirs(self, references: Any) -> bool:
        """Whether every one of ``references`` (``<instance>.<variable>``; a fault's target,
        the variables an event set) is another vehicle's: its marker is not this one's."""
        instances = [str(r).partition(".")[0] for r in references or []]
        return bool(instances) and all(i in self.others for i in instances)

    def delivery(self, delivery: Delivery) -> Delivery:
        """A faulted connection's delivery with its source named as the figures name it
        (its target keeps its own name: the legend's "delivered to plant_b.thrust")."""
        return replace(delivery, source=self.column(delivery.source))


ONE = VehicleView()  # a run's one vehicle named as the built-in scenarios name it


def vehicle_views(run_dir: Path, summary: dict[str, Any]) -> list[VehicleView]:
    """The vehicles the report draws (:func:`run_vehicles`): one, whatever its instances
    are named, its figures as the built-in scenarios' are; or each of several, its
    figures' files and titles naming its plant, without the markers of faults and events
    that act on another vehicle only."""
    fleet = run_vehicles(run_dir, summary)
    several = len(fleet) > 1
    everyone = {name for v in fleet for name in v.roles.values()}
    return [
        VehicleView(
            ((v.roles["plant"], "plant"), (v.roles["controller"], "controller")),
            v.roles["plant"] if several else "",
            tuple(sorted(everyone - set(v.roles.values()))) if several else (),
        )
        for v in fleet
    ]


# every column some figure draws: the panels' and the trajectory's (north against east)
DRAWN_COLUMNS = frozenset(
    {s.column for _, panels in FIGURES.values() for panel in panels for s in panel.series}
    | {"plant.north", "plant.east"}
)


def _check_drawable(
    run_dir: Path,
    table: dict[str, np.ndarray],
    summary: dict[str, Any],
    views: list[VehicleView] | None = None,
) -> None:
    """Warn of a results.csv holding none of :data:`DRAWN_COLUMNS` of any of its vehicles
    (``views``: their plant and autopilot, whatever they are named; a run of other FMUs,
    or recording other columns): its page has the run's summary and no figure, which it
    got without a word of why."""
    if any(not DRAWN_COLUMNS.isdisjoint(view.table(table)) for view in views or [ONE]):
        return
    shown = ", ".join(sorted(DRAWN_COLUMNS, key=lambda c: (c[:6] != "plant.", c))[:4])
    warnings.warn(
        f"{run_dir / 'results.csv'} holds none of the columns the report draws "
        f"({shown}, ...): the page shows the run's summary and no figure (a scenario's "
        "[output] record chooses the columns)",
        RuntimeWarning,
        stacklevel=3,
    )


def _figures(
    run_dir: Path,
    table: dict[str, np.ndarray],
    summary: dict[str, Any],
    out: Path,
    view: VehicleView | None = None,
) -> dict[str, tuple[str, Path]]:
    """Draw the figures of the run's vehicle ``view`` (its one vehicle by default) into
    ``out``: {key: (figure name, file)} of those drawn, the key the name and the view's
    suffix (``velocities``, ``velocities_plant_a``)."""
    view = view or ONE
    limits = actuator_limits(run_dir)
    found = [view.delivery(d) for d in deliveries(run_dir, table, summary)]
    units = view.columns(summary.get("units"))
    table, summary = view.table(table), view.summary(summary)
    table = {**table, **with_deliveries(found)}
    zoom = _zoom(table, summary)
    caption = run_caption(run_dir, table, summary)
    stop_time = _seconds(summary, "stop_time")
    units.update({d.column: units[d.source] for d in found if d.source in units})
    figures, suffix = {}, view.suffix
    for name, (title, panels) in FIGURES.items():
        if name == "depth" and not _has_depth_loop(table):
            continue
        panels = as_declared(with_delivered(panels, found), units)
        path = plot_time_histories(
            table, panels, caption.format(title + view.title), out / f"{name}{suffix}.png",
            markers_of(summary), limits, zoom if name in ZOOMED else None, stop_time,
        )  # fmt: skip
        if path is not None:
            figures[name + suffix] = (name, path)
    waypoints = _planned_path(run_dir)
    marks = _turning_marks(table, summary)
    title = caption.format(TITLES["trajectory"] + view.title)
    trajectory = plot_trajectory(table, out / f"trajectory{suffix}.png", waypoints, marks, title)
    if trajectory is not None:
        figures["trajectory" + suffix] = ("trajectory", trajectory)
    if waypoints is None and marks is None:
        title = caption.format(TITLES["lateral_deviation"] + view.title)
        deviation = plot_lateral_deviation(table, out / f"lateral_deviation{suffix}.png", title)
        if deviation is not None:
            figures["lateral_deviation" + suffix] = ("lateral_deviation", deviation)
    return figures


def undrawn_faults(
    run_dir: Path, table: dict[str, np.ndarray], summary: dict[str, Any], panelled: set[str]
) -> list[str]:
    """One line for each faulted connection of the run whose delivered value none of the
    written figures draws (``panelled``: the results columns their panels draw), saying
    why: its source is not in results.csv (``table``), no panel draws the source (the
    autopilot's thrust), or the run's files do not tell what was delivered
    (:func:`cosim.viz.delivered.deliveries`)."""
    scenario = read_scenario(run_dir)
    if scenario is None:
        return []
    replayed = {d.target for d in deliveries(run_dir, table, summary)}
    lines = []
    for target, source, faults in faulted_connections(scenario, summary):
        if source not in table:
            why = f"results.csv does not record its source {source}"
        elif source not in panelled:
            why = f"no panel of this report draws its source {source}"
        elif target not in replayed:
            why = "the run's files do not tell what it delivered"
        else:
            continue
        named = ", ".join(f"{f.name} ({f.kind})" for f in faults)
        lines.append(f"fault {named} on {source} -> {target}: not drawn, {why}")
    return lines


def with_deliveries(found: list[Delivery]) -> dict[str, np.ndarray]:
    """The columns :func:`with_delivered` draws: each target's delivered values and
    where its faults act."""
    return {
        **{d.column: d.values for d in found},
        **{d.acting_column: d.acting for d in found},
    }


def with_delivered(panels: tuple[Panel, ...], found: list[Delivery]) -> tuple[Panel, ...]:
    """``panels`` with, after each curve of a faulted connection's source, what its
    faults delivered to the target (:func:`cosim.viz.delivered.deliveries`), both named in
    the legend with the panel's unit, and where the faults act shaded."""
    changed = []
    for panel in panels:
        unit = _label_unit(panel.ylabel)
        suffix = f" ({unit})" if unit != "1" else ""
        series: list[Series] = []
        spans = list(panel.spans)
        for s in panel.series:
            hit = [d for d in found if d.source == s.column]
            if not hit:
                series.append(s)
                continue
            sent = f"{s.label or s.column} as sent"
            series.append(replace(s, label=sent + suffix))
            for d in hit:
                label = f"delivered to {d.target}{suffix}"
                series.append(Series(d.column, s.scale, label, colour=DELIVERED_COLOUR))
                spans.append((d.acting_column, f"{d.label} acting"))
        changed.append(replace(panel, series=tuple(series), spans=tuple(spans)))
    return tuple(changed)


def as_declared(panels: tuple[Panel, ...], units: dict[str, Any]) -> tuple[Panel, ...]:
    """``panels`` with each line scaled from the unit its column's FMU declares (``units``,
    summary.json's) to the unit its panel's label names: a set-point another tool declares
    in deg is drawn as it is, not times 180/pi. A line whose declared unit does not convert
    to its label's is left out, and a panel left without lines with it; a column without
    a declared unit (none in ``units``, or "1": its FMU declares none) keeps its scale."""
    kept = []
    for panel in panels:
        shown = _label_unit(panel.ylabel)
        series = []
        for s in panel.series:
            declared = units.get(s.column)
            known = isinstance(declared, str) and declared != NO_UNIT
            scale = scale_to(str(declared), shown) if known else s.scale
            if scale is not None:
                series.append(replace(s, scale=scale))
        if series:
            kept.append(replace(panel, series=tuple(series)))
    return tuple(kept)


def _label_unit(ylabel: str) -> str:
    """The unit an axis label names in its closing brackets ("z (m)": m); "1" for none."""
    _, bracket, unit = ylabel.rstrip(")").rpartition(" (")
    return unit if bracket and ylabel.endswith(")") else "1"


def run_caption(run_dir: Path, table: dict[str, np.ndarray], summary: dict[str, Any]) -> str:
    """A figure title naming the run, ``{}`` where the figure's own title goes: "bs-3: {}",
    and for a run that did not complete a second line saying where it stopped (the time
    reached and the stop time, s), so a figure lifted out of the page still says what was
    run and that it is partial. The run is named by its scenario id, else its folder."""
    name = summary.get("scenario") or path_text(run_dir.resolve().name)
    caption = str(name).replace("{", "{{").replace("}", "}}") + ": {}"
    reached = _seconds(summary, "time_reached")
    reached = float(table["time"][-1]) if reached is None else reached
    stop = _seconds(summary, "stop_time")
    of_stop = f" of {stop:g} s" if stop is not None else " s"
    if summary.get("status") == "running":
        return caption + f"\nstill running or killed: rows to t = {reached:g}{of_stop}"
    if summary.get("complete") is False:
        return caption + f"\nthe run did not complete: t = {reached:g}{of_stop}"
    return caption


def _seconds(summary: dict[str, Any], key: str) -> float | None:
    """``summary[key]`` (s) when it is a finite number, else None."""
    value = summary.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    try:
        return float(value) if math.isfinite(value) else None
    except OverflowError:  # an integer beyond any double
        return None


# --- input ---------------------------------------------------------------------------------


def load_results(run_dir: Path) -> dict[str, np.ndarray]:
    """``results.csv`` as {column: values}; ``time`` is required."""
    path = run_dir / "results.csv"
    if not run_dir.is_dir():
        raise CosimError(
            f"{run_dir} {'is not a folder' if run_dir.exists() else 'does not exist'}"
            f"{missing_run_hint(run_dir)}: expected the output folder of a run"
        )
    if not path.is_file() and (run_dir / STUDY_FILE).is_file():
        kept = run_dir / "runs"  # the runs a study keeps (its overlay's)
        raise CosimError(
            f"{run_dir} is a study folder: its page is {run_dir / 'index.html'} (the sweep "
            "writes it)"
            + (
                f"; `auv-cosim report {kept / 'RUN_ID'}` reports a run it kept"
                if kept.is_dir()
                else ""
            )
        )
    if not path.is_file():
        raise CosimError(
            f"no results.csv in {run_dir}{missing_run_hint(run_dir)}: expected the output "
            "folder of `auv-cosim run`"
        )
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # "no data": reported below
            columns, values = read_csv(path)
    except (OSError, ValueError) as exc:
        raise CosimError(f"cannot read {path}: {exc}") from None
    if columns[0] != "time":
        raise CosimError(f"{path}: the first column is {columns[0]!r}, expected 'time'")
    if values.shape[0] == 0:
        raise CosimError(f"{path} holds no rows")
    if values.shape[1] != len(columns):
        raise CosimError(f"{path}: {values.shape[1]} values per row for {len(columns)} columns")
    return {name: values[:, k] for k, name in enumerate(columns)}


def load_summary(run_dir: Path) -> tuple[dict[str, Any], str | None]:
    """``summary.json`` and a problem note (missing or unreadable: the report goes on)."""
    path = run_dir / "summary.json"
    if not path.is_file():
        return {}, "no summary.json in the run folder"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        return {}, f"summary.json unreadable: {exc}"
    if not isinstance(data, dict):
        return {}, "summary.json is not a JSON object"
    odd = [key for key in _SHAPES if key in data and not _of_shape(key, data[key])]
    said = [
        f"summary.json: {k} is {_cut(data.pop(k))}, expected {_SHAPES[k]}: left out" for k in odd
    ]
    return data, "; ".join(said) or None


_SHAPES = {  # what the report reads of summary.json's entries, as a run writes them
    "key_figures": f"a table of numbers or nulls (s and SI units; {SETTLING_FIGURE} a number)",
    "events": "a list of events, each with a name and a time (s)",
    "faults": "a list of faults, each with a name, a kind, a start (s) and a stop (s or null)",
    "manoeuvre": "the name of a standard manoeuvre",
}


def _of_shape(key: str, value: object) -> bool:
    """Whether summary.json's ``value`` of ``key`` (of :data:`_SHAPES`) is as a run writes
    it: another tool's (or a hand-edited) file may hold anything there."""
    if key == "key_figures":
        return isinstance(value, dict) and (
            value.get(SETTLING_FIGURE) is None or _seconds(value, SETTLING_FIGURE) is not None
        )
    if key == "manoeuvre":
        return isinstance(value, str)
    times = ("time",) if key == "events" else ("start",)
    return isinstance(value, list) and all(
        isinstance(item, dict)
        and isinstance(item.get("name"), str)
        and (key == "events" or isinstance(item.get("kind"), str))
        and all(_seconds(item, t) is not None for t in times)
        and (item.get("stop") is None or _seconds(item, "stop") is not None)
        for item in value
    )


def _cut(value: object) -> str:
    """``value`` as JSON, cut short for a line of the page."""
    text = json.dumps(value)
    return text if len(text) <= 40 else text[:37] + "..."


def actuator_limits(run_dir: Path) -> dict[str, float]:
    """``{"<instance>.<column>": limit}`` for the actuators of :data:`LIMITS` in the run's
    ``scenario.toml``: the instance's start value of the limit parameter, else the FMU's
    declared start (its model description: the FMU the run used, as ``summary.json``
    names it, else a built-in FMU where runs build it by default). Empty where the
    scenario or the FMU cannot be read."""
    try:
        instances = tomllib.loads((run_dir / "scenario.toml").read_text("utf-8"))["instances"]
    except (OSError, KeyError, tomllib.TOMLDecodeError):
        return {}
    used = load_summary(run_dir)[0].get("fmus")
    used = used if isinstance(used, dict) else {}
    limits = {}
    for name, instance in instances.items():
        fmu = str(instance.get("fmu", ""))
        for (model, parameter), column in LIMITS.items():
            if fmu not in (model, f"{model}.fmu") and not fmu.endswith(f"/{model}.fmu"):
                continue
            value = instance.get("start", {}).get(parameter)
            if value is None:
                path = _fmu_used(used.get(name), run_dir, fmu, model)
                value = _declared_start(path, parameter)
            if isinstance(value, int | float) and value > 0:
                limits[f"{name}.{column}"] = float(value)
    return limits


def _fmu_used(entry: Any, run_dir: Path, fmu: str, model: str) -> Path:
    """The FMU file an instance ran: its ``path`` in summary.json (a run of any working
    folder or ``--fmu-dir``), else where a run builds a built-in FMU by default, or the
    scenario's file beside the run (a run folder copied from another machine)."""
    if isinstance(entry, dict) and isinstance(entry.get("path"), str):
        path = Path(entry["path"])
        if path.is_file():
            return path
    return DEFAULT_FMU_DIR / f"{model}.fmu" if fmu == model else run_dir / fmu


def _declared_start(path: Path, parameter: str) -> Any:
    try:
        variable = read_interface(path).variables.get(parameter)
    except CosimError:
        return None
    return None if variable is None else variable.start


def _zoom(table: dict[str, np.ndarray], summary: dict[str, Any]) -> float | None:
    """The end of the transient column (s): ZOOM_SETTLING_TIMES settling times, when that
    is within the first third of the run; else None (no column)."""
    settled = (summary.get("key_figures") or {}).get(SETTLING_FIGURE)
    if not settled:
        return None
    end = ZOOM_SETTLING_TIMES * float(settled)
    return end if end <= float(table["time"][-1]) / 3.0 else None


def _planned_path(run_dir: Path) -> np.ndarray | None:
    """The waypoints of the run's guidance from its ``scenario.toml``, if any."""
    try:
        text = (run_dir / "scenario.toml").read_text(encoding="utf-8")
    except OSError:
        return None
    return mission_waypoints(text)


def _turning_marks(table: dict[str, np.ndarray], summary: dict[str, Any]) -> TurnMarks | None:
    """A turning circle's marks (see :func:`_plot_turning_marks`), for a run whose summary
    names that manoeuvre."""
    if summary.get("manoeuvre") != "turning-circle":
        return None
    points = turning_circle_marks(table)
    return None if points is None else TurnMarks(points, summary_metrics(summary))


def _has_depth_loop(table: dict[str, np.ndarray]) -> bool:
    if any(c in table and np.any(table[c] != 0.0) for c in DEPTH_EVIDENCE):
        return True
    return "plant.down" in table and np.ptp(table["plant.down"]) > 1e-6


# --- figures -------------------------------------------------------------------------------


# A line of more points than this is drawn through a subset of them (drawn_points): a
# figure is ~1000 pixels wide, so 100 000 points (1000 s at 10 ms) draw every run that fits
# as it is, and a 36000 s run's 3.6 million rows no longer cost minutes and gigabytes
DRAWN_POINTS_MAX = 100_000
WAYPOINT_LABELS = 20  # waypoints numbered on a trajectory at most (and the last)


def drawn_points(*series: np.ndarray) -> np.ndarray | slice:
    """Which points of a line through ``series`` (equal lengths, the line's coordinates)
    to draw: all of them up to :data:`DRAWN_POINTS_MAX`, else, in buckets of consecutive
    points, the first and last of each and each series' smallest and largest in it (its
    extremes: a spike stays, and so do the line's ends), in order; at most about
    :data:`DRAWN_POINTS_MAX` points."""
    n = len(series[0])
    if n <= DRAWN_POINTS_MAX:
        return slice(None)
    per_bucket = 2 + 2 * len(series)
    size = -(-n * per_bucket // DRAWN_POINTS_MAX)  # points per bucket, rounded up
    whole = n // size * size
    starts = np.arange(0, whole, size)
    picked = [starts, starts + size - 1, np.arange(whole, n)]
    for values in series:
        buckets = values[:whole].reshape(-1, size)  # a NaN is the extreme of its bucket
        picked += [starts + np.argmin(buckets, axis=1), starts + np.argmax(buckets, axis=1)]
    return np.unique(np.concatenate(picked))


def plot_time_histories(
    table: dict[str, np.ndarray],
    panels: tuple[Panel, ...],
    title: str,
    path: Path,
    markers: list[Marker] | None = None,
    limits: dict[str, float] | None = None,
    zoom: float | None = None,
    stop_time: float | None = None,
) -> Path | None:
    """Stacked panels sharing the time axis, ``markers`` drawn across each, ``limits``
    (column -> limit, SI) as +-limit lines on the panel of that column; with ``zoom`` (s)
    a second column shows the first ``zoom`` seconds. The time axis runs to the run's
    ``stop_time`` (s), beyond its last row when the run stopped early. None if the run
    recorded none of the panels."""
    present = [p for p in panels if p.series[0].column in table]
    if not present:
        return None
    time = table["time"]
    end = max(time[-1], stop_time or time[-1])
    end = end if end > time[0] else time[0] + 1.0
    spans = [(time[0], end)] if zoom is None else [(time[0], end), (time[0], zoom)]
    fig = Figure(figsize=(9 if zoom is None else 13, 1.9 * len(present) + 0.8))
    axes = fig.subplots(
        len(present), len(spans), sharex="col", squeeze=False, width_ratios=[3, 2][: len(spans)]
    )
    for row, panel in enumerate(present):
        for col, span in enumerate(spans):
            _draw_panel(axes[row, col], table, panel, markers or [], limits or {}, span, row == 0)
            axes[row, col].set_xlim(*span)
    axes[-1, 0].set_xlabel("Time (s)")
    if zoom is not None:
        axes[0, 1].set_title(f"the transient: first {zoom:.3g} s", fontsize="medium")
        axes[-1, 1].set_xlabel("Time (s)")
    fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _on_turns(
    curves: list[tuple[Series, np.ndarray]],
) -> list[tuple[Series, np.ndarray]]:
    """``curves`` (deg) with each angle that names a line to follow (``Series.turn_of``)
    moved by whole turns, sample by sample, to [-180, 180) deg of that line's value: the
    autopilot's wrap of its heading error (``wrap_angle``, controller_fmu/setpoint_shaping.py),
    so a set-point half a turn away is drawn on the side the autopilot turns to."""
    drawn = {series.column: values for series, values in curves}
    moved = []
    for series, values in curves:
        reference = drawn.get(series.turn_of) if series.turn_of else None
        if reference is not None:
            values = on_turn_of(values, reference, 360.0)
        moved.append((series, values))
    return moved


def _draw_panel(
    ax: Axes,
    table: dict[str, np.ndarray],
    panel: Panel,
    markers: list[Marker],
    limits: dict[str, float],
    span: tuple[float, float],
    first: bool,
) -> None:
    """One panel over the time ``span`` (its y range from the data inside it); the
    markers are named in the legend of the ``first`` panel only."""
    time = table["time"]
    inside = (time >= span[0]) & (time <= span[1])
    with np.errstate(over="ignore"):  # beyond a float in the panel's unit: inf, off the axis
        curves = [(s, table[s.column] * s.scale) for s in panel.series if s.column in table]
    curves = _on_turns(curves)
    shown = _main_range([(s, v[inside]) for s, v in curves])
    for series, values in curves:
        clipped = shown is not None and np.any((values < shown[0]) | (values > shown[1]))
        label = series.label + (" (beyond the axis)" if clipped else "")
        t, v = time[inside], values[inside]
        some = drawn_points(v)
        colour = series.colour or ("tab:gray" if series.dashed else "tab:blue")
        ax.plot(t[some], v[some], "--" if series.dashed else "-", color=colour,
                linewidth=1.0 if series.dashed or series.colour else 1.3, label=label or None,
                marker="o" if np.count_nonzero(inside) == 1 else None)  # fmt: skip
        # (one row, a run that failed at its first step: a line of one point shows nothing)
    drawn, named = len(curves), set()
    for marker in markers:  # each name once in the legend (a repeated event)
        new = first and marker.label not in named
        named.add(marker.label)
        ax.axvline(marker.time, color=marker.color, linestyle=marker.style, linewidth=1.0,
                   label=marker.label if new else None)  # fmt: skip
        drawn += new
    for column, label in panel.spans:
        drawn += _shade(ax, time, table.get(column), label)
    limit = limits.get(panel.series[0].column)
    if limit is not None:
        scaled = limit * panel.series[0].scale
        unit = _label_unit(panel.ylabel)
        label = f"limit +-{scaled:g}" + (f" {unit}" if unit != "1" else "")
        for sign in (1.0, -1.0):
            ax.axhline(sign * scaled, color="tab:red", linestyle=":", linewidth=1.0,
                       label=label if sign > 0 else None)  # fmt: skip
        drawn += 1
    if shown is not None:
        ax.set_ylim(*shown)
    ax.set_ylabel(panel.ylabel)
    ax.grid(True, alpha=0.3)
    if drawn > 1:
        ax.legend(loc="upper right", fontsize="small")


def _shade(ax: Axes, time: np.ndarray, flag: np.ndarray | None, label: str) -> int:
    """Shade the times where ``flag`` > 0 (from a row where it is to the next row where it
    is not, s), ``label`` in the legend once; 1 if anything was shaded, else 0."""
    if flag is None or not np.any(flag > 0):
        return 0
    edges = np.diff(np.concatenate([[0], (flag > 0).astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    for k, (first, after) in enumerate(zip(starts, ends, strict=True)):
        end = time[after] if after < len(time) else time[-1]
        ax.axvspan(time[first], end, color=FAULT_SHADE, alpha=0.1, linewidth=0,
                   label=label if k == 0 else None)  # fmt: skip
    return 1


def _main_range(curves: list[tuple[Series, np.ndarray]]) -> tuple[float, float] | None:
    """Axis limits that keep the panel's main (first) curve readable when a reference curve
    (a command, a set-point) strays far outside it, e.g. an unsaturated servo command of
    metres beside a mass that moves centimetres; None when the automatic limits do."""
    if len(curves) < 2:
        return None
    main = curves[0][1][np.isfinite(curves[0][1])]  # a failed run may end on inf or nan
    others = np.concatenate([values for _, values in curves[1:]])
    others = others[np.isfinite(others)]
    if main.size == 0 or others.size == 0:
        return None
    lo, hi = float(np.min(main)), float(np.max(main))
    span = max(hi - lo, 1e-9)
    if np.min(others) >= lo - 2.0 * span and np.max(others) <= hi + 2.0 * span:
        return None
    return lo - 0.25 * span, hi + 0.25 * span


def plot_trajectory(
    table: dict[str, np.ndarray],
    path: Path,
    waypoints: np.ndarray | None = None,
    marks: TurnMarks | None = None,
    title: str = "",
) -> Path | None:
    """North against east (x up, y right, equal scale), and a 3-D view when the depth
    changes; with ``waypoints`` (m, NED, one row each) the planned path through them,
    numbered; with ``marks`` a turning circle's metrics; ``title`` above it all (the run,
    :func:`run_caption`). None without ``plant.north`` and ``plant.east``."""
    if "plant.north" not in table or "plant.east" not in table:
        return None
    north, east = table["plant.north"], table["plant.east"]
    down = table.get("plant.down")
    three_d = _depth_changes(table)
    fig = Figure(figsize=(12 if three_d else 6.5, 6))
    ax = fig.add_subplot(1, 2 if three_d else 1, 1)
    if waypoints is not None:
        _plot_waypoints(ax, waypoints)
    some = drawn_points(east, north, *([] if down is None else [down]))
    ax.plot(east[some], north[some], color="tab:blue", label="track")
    ax.plot(east[0], north[0], "o", color="tab:green", label="start")
    ax.plot(east[-1], north[-1], "s", color="tab:red", label="end")
    if marks is not None:
        _plot_turning_marks(ax, marks)
    ax.set_xlabel("y, east (m)")
    ax.set_ylabel("x, north (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    ax.set_title("path over ground")
    if three_d and down is not None:
        ax3 = fig.add_subplot(1, 2, 2, projection="3d")
        ax3.plot(east[some], north[some], down[some], color="tab:blue")
        ax3.set_xlabel("y, east (m)")
        ax3.set_ylabel("x, north (m)")
        ax3.set_zlabel("z, down (m)")
        ax3.invert_zaxis()
        ax3.set_title("earth frame (NED)")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _depth_changes(table: dict[str, np.ndarray]) -> bool:
    """Whether the run's depth changes by more than a millimetre (its trajectory then gets
    a 3-D view)."""
    down = table.get("plant.down")
    return down is not None and bool(np.ptp(down) > 1e-3)


def plot_lateral_deviation(
    table: dict[str, np.ndarray], path: Path, title: str = ""
) -> Path | None:
    """The sideways deviation from the initial course (m, positive to starboard) against
    the distance along it (m), on axes of their own scales: the initial course is the
    yaw at t = 0, the origin the start; ``title`` above it (the run, :func:`run_caption`).
    None without ``plant.north``, ``plant.east`` and ``plant.yaw``."""
    if not all(c in table for c in ("plant.north", "plant.east", "plant.yaw")):
        return None
    course = float(table["plant.yaw"][0])
    d_north = table["plant.north"] - table["plant.north"][0]
    d_east = table["plant.east"] - table["plant.east"][0]
    along = d_north * math.cos(course) + d_east * math.sin(course)
    across = -d_north * math.sin(course) + d_east * math.cos(course)
    fig = Figure(figsize=(9, 3.2))
    ax = fig.subplots()
    some = drawn_points(along, across)
    ax.plot(along[some], across[some], color="tab:blue", label="track")
    ax.axhline(0.0, color="tab:gray", linestyle="--", linewidth=1.0, label="initial course")
    ax.set_xlabel("distance along the initial course (m)")
    ax.set_ylabel("lateral deviation (m)")
    ax.set_title(f"deviation from the initial course ({math.degrees(course):.3g} deg)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, path)


def _plot_waypoints(ax: Axes, waypoints: np.ndarray) -> None:
    """The planned path (dashed) and its waypoints, numbered from 1, on a north-east plot:
    every one up to :data:`WAYPOINT_LABELS`, else every k-th (evenly, from the first) and
    the last, so that hundreds of them do not overprint into one band."""
    north, east = waypoints[:, 0], waypoints[:, 1]
    ax.plot(east, north, "--", color="tab:orange", linewidth=1.0, label="planned path")
    ax.plot(east, north, "o", color="tab:orange", markersize=4)
    every = math.ceil(len(waypoints) / WAYPOINT_LABELS)
    numbered = sorted({*range(0, len(waypoints), every), len(waypoints) - 1})
    for k in numbered:
        ax.annotate(str(k + 1), (east[k], north[k]), textcoords="offset points", xytext=(4, 4),
                    fontsize=8)  # fmt: skip


def _plot_turning_marks(ax: Axes, marks: TurnMarks) -> None:
    """The execute and the original course (dashed), and from the course line to the 90
    and 180 deg points: the advance along it, the transfer and the tactical diameter
    across it (docs/manoeuvres.md)."""
    execute = np.array(marks.points["execute"])  # north, east
    course = np.array([math.cos(marks.points["course"]), math.sin(marks.points["course"])])
    metrics = marks.metrics
    ax.plot(execute[1], execute[0], "x", color="black", label="execute")
    labels = {
        "at_90": f"90 deg: advance {_metre(metrics.get('advance_m'))}, "
        f"transfer {_metre(metrics.get('transfer_m'))}",
        "at_180": f"180 deg: tactical diameter {_metre(metrics.get('tactical_diameter_m'))}",
    }
    reach = 0.0
    for key, colour in (("at_90", "tab:purple"), ("at_180", "tab:brown")):
        if marks.points[key] is None:
            continue
        point = np.array(marks.points[key])
        along = float((point - execute) @ course)
        foot = execute + along * course  # on the original course line
        reach = max(reach, along)
        ax.plot([foot[1], point[1]], [foot[0], point[0]], ":", color=colour, linewidth=1.2)
        ax.plot(point[1], point[0], "D", color=colour, markersize=5, label=labels[key])
    end = execute + max(reach, 1.0) * 1.1 * course
    ax.plot([execute[1], end[1]], [execute[0], end[0]], "--", color="tab:gray",
            linewidth=1.0, label="original course")  # fmt: skip


def _metre(value: float | int | None) -> str:
    return "n/a" if value is None else f"{value:.2f} m"


def _save(fig: Figure, path: Path) -> Path:
    fig.savefig(path, dpi=100)
    return path


# --- index page ----------------------------------------------------------------------------


def plain(label: str) -> str:
    """An axis label as text a screen reader reads: its mathtext undone, ``$y_{vel}$ (cm/s)``
    is "y_vel (cm/s)", ``$\\phi$ (deg)`` is "phi (deg)"."""
    return label.translate(str.maketrans("", "", "$\\{}"))


LATERAL_ALT = "Lateral deviation (m) from the initial course against the distance along it (m)"


def figure_alt(
    name: str,
    table: dict[str, np.ndarray],
    summary: dict[str, Any],
    run_dir: Path,
    view: VehicleView | None = None,
) -> str:
    """The alt text of the figure ``name`` of the vehicle ``view`` (the run's one vehicle
    by default) of the run in ``run_dir`` (``table``: its results, ``summary``: its
    summary.json): what is plotted against what, with units, as drawn."""
    view = view or ONE
    found = [view.delivery(d) for d in deliveries(run_dir, table, summary)]
    table, summary = view.table(table), view.summary(summary)
    if name == "trajectory":
        turning = summary.get("manoeuvre") == "turning-circle"
        return trajectory_alt(turning, "yes" if _depth_changes(table) else "no")
    if name == "lateral_deviation":
        return LATERAL_ALT
    zoom = _zoom(table, summary) if name in ZOOMED else None
    return time_history_alt(name, table.__contains__, zoom, found)


def trajectory_alt(turning: bool = False, three_d: str = "when the depth changes") -> str:
    """The trajectory figure's alt text; ``three_d``: whether it has a 3-D view ("yes",
    "no", or the condition on which it has one)."""
    text = "Path over ground: x, north (m) against y, east (m), start and end marked"
    text += ", turning-circle metrics marked" if turning else ""
    if three_d == "no":
        return text
    return (
        text
        + "; beside it a 3-D view with z, down (m)"
        + ("" if three_d == "yes" else f", {three_d}")
    )


def time_history_alt(
    name: str,
    recorded: Callable[[str], bool] = lambda column: True,
    zoom: float | None = None,
    delivered: list[Delivery] | None = None,
) -> str:
    """The alt text of the time-history figure ``name`` (a key of :data:`FIGURES`): its
    panels of the ``recorded`` columns, each with its unit and reference curves; with
    ``zoom`` (s), the transient column beside them; ``delivered``: the run's faulted
    connections, drawn beside their sources (:func:`with_delivered`)."""
    title, panels = FIGURES[name]
    panels = with_delivered(panels, delivered or [])
    extra = {d.column for d in delivered or []}

    def drawn(column: str) -> bool:
        return recorded(column) or column in extra

    shown = []
    for panel in panels:
        if drawn(panel.series[0].column):
            others = [s.label for s in panel.series[1:] if drawn(s.column)]
            shown.append(plain(panel.ylabel) + (f" with {', '.join(others)}" if others else ""))
    enlarged = f"; beside them the first {zoom:.3g} s enlarged" if zoom is not None else ""
    return f"{title} against time (s), one panel each: {'; '.join(shown)}{enlarged}"


FIGURE_UNITS = {"s": "s", "m": "m", "N": "N", "deg": "deg", "pct": "%", "rad": "rad"}


def figure_label(name: str) -> str:
    """A key figure's row label, its unit in brackets as the other rows have it:
    ``peak_abs_mass_position_m`` is "peak |mass position| (m)" (it read "peak abs mass
    position m", the unit a word of the name)."""
    per_second = name.endswith("_per_s")  # a rate: tunnel_force_variation_N_per_s, N/s
    words = name.removesuffix("_per_s").split("_")
    unit = FIGURE_UNITS.get(words[-1]) if len(words) > 1 else None
    words = words[:-1] if unit else words
    unit = f"{unit}/s" if unit and per_second else unit
    if "abs" in words:
        at = words.index("abs")
        words = [*words[:at], "|" + " ".join(words[at + 1 :]) + "|"]
    return " ".join(words) + (f" ({unit})" if unit else "")


def null_reasons(
    run_dir: Path, table: dict[str, np.ndarray], summary: dict[str, Any]
) -> dict[str, str]:
    """Why each key figure summary.json holds as null is null (``table``: the run's
    results.csv): :func:`cosim.metrics.key_figures.why_none_of`, with what drives the yaw
    set-point in the run's scenario.toml."""
    figures = summary.get("key_figures") or {}
    fleet = run_vehicles(run_dir, summary)
    complete = summary.get("complete") is not False and summary.get("status") != "running"
    times = table["time"]  # (load_results requires it)
    spanned = len(times) > 1 and bool(times[-1] > times[0])  # a rate needs two rows
    return {
        name: why_none_of(name, list(table), fleet, complete, spanned)
        for name, value in figures.items()
        if value is None
    }


def index_page(
    run_dir: Path,
    summary: dict[str, Any],
    summary_problem: str | None,
    figures: dict[str, Path],
    stamp: dict[str, Any] | None = None,
    alts: dict[str, str] | None = None,
    nulls: dict[str, str] | None = None,
    undrawn: list[str] | None = None,
    titles: dict[str, str] | None = None,
) -> str:
    """The HTML index: which run it describes (``stamp``: :func:`run_stamp` and when it
    was made), summary table, key figures (one summary.json holds as null with its reason
    in ``nulls``, :func:`null_reasons`), the faults and the events fired, each faulted
    connection no figure draws (``undrawn``: :func:`undrawn_faults`), the figures inline
    (linked), each under its title (``titles``, else the figure's own) with its ``alts``
    text (:func:`figure_alt`; the title without one)."""
    name = summary.get("scenario") or path_text(run_dir.resolve().name)
    table = _summary_rows(summary, nulls or {})
    note = _incomplete_note(summary, summary_problem)
    images = _figure_images(figures, alts, titles)
    return f"""<!DOCTYPE html>
<html lang="en">
<head><meta charset="utf-8"><title>auv-cosim run {html.escape(str(name))}</title>
<style>body {{ font-family: sans-serif; max-width: 1100px; margin: 2em auto; }}
th {{ text-align: left; padding-right: 2em; }}
h1, code {{ overflow-wrap: anywhere; }}</style></head>
<body>
<h1>Run {html.escape(str(name))}</h1>
<p>Run folder: <code>{html.escape(path_text(run_dir))}</code> (results.csv, summary.json)</p>
{_stamp_line(stamp, run_dir, summary_problem)}
{note}
<table>
<caption>Run summary</caption>
{table}
</table>
{_manoeuvre_table(summary)}
{_timeline_tables(summary)}
{_undrawn_note(undrawn or [])}
{images}
</body>
</html>
"""


def _summary_rows(summary: dict[str, Any], nulls: dict[str, str]) -> str:
    """The rows of the run summary table: the run's settings and outcome, then its key
    figures, each as given (a setting summary.json lacks has no row; a key figure it
    holds as null reads "none", with its reason in ``nulls``)."""
    rows = [
        ("scenario", summary.get("scenario")),
        ("status", summary.get("status")),
        ("complete", summary.get("complete")),
        ("error", summary.get("error")),
        ("stop time (s)", summary.get("stop_time")),
        ("time reached (s)", summary.get("time_reached")),
        ("communication step (s)", summary.get("step")),
        ("algorithm", summary.get("algorithm")),
        ("wall clock, stepping loop (s)", summary.get("wall_clock_s")),
        ("real-time factor", summary.get("real_time_factor")),
    ]
    key = summary.get("key_figures") or {}
    rows += [
        (figure_label(k), v if v is not None else f"none ({nulls[k]})" if k in nulls else "none")
        for k, v in key.items()
    ]
    return "\n".join(
        f'<tr><th scope="row">{html.escape(label)}</th><td>{html.escape(_text(value))}</td></tr>'
        for label, value in rows
        if value is not None
    )


def _incomplete_note(summary: dict[str, Any], summary_problem: str | None) -> str:
    """What the page says of a summary.json it could not read, a run still running (or
    killed) and a run that did not complete ("" for a complete run)."""
    note = f"<p><em>{html.escape(summary_problem)}</em></p>" if summary_problem else ""
    if summary.get("status") == "running":
        note += (
            "<p><strong>summary.json says the run is still running (or its process was "
            "killed): the figures show the rows written so far.</strong></p>"
        )
    elif summary.get("complete") is False:
        note += (
            "<p><strong>The run did not complete: the figures show its partial "
            "results.</strong></p>"
        )
    return note


def _undrawn_note(undrawn: list[str]) -> str:
    """The faulted connections no figure draws, a paragraph each ("" for none)."""
    return "\n".join(f"<p><em>{html.escape(line)}</em></p>" for line in undrawn)


def _figure_images(
    figures: dict[str, Path], alts: dict[str, str] | None, given: dict[str, str] | None = None
) -> str:
    """Each figure under its title (``given``, else its own), inline and linked, with its
    ``alts`` text (the title without one)."""
    titles = {
        key: (given or {}).get(key) or (FIGURES[key][0] if key in FIGURES else TITLES[key])
        for key in figures
    }
    alt = {key: (alts or {}).get(key) or titles[key] for key in figures}
    return "\n".join(
        f"<h2>{html.escape(titles[key])}</h2>\n"
        f'<p><a href="{path.name}"><img src="{path.name}" alt="{html.escape(alt[key])}" '
        'style="max-width:100%"></a></p>'
        for key, path in figures.items()
    )


def _stamp_line(stamp: dict[str, Any] | None, run_dir: Path, summary_problem: str | None) -> str:
    """Which run the page describes, and when it was made (nothing without a stamp). A run
    without a (readable) summary.json is named by its folder, its status as unknown."""
    if stamp is None:
        return ""
    digest = stamp.get("results_sha256") or "unknown"
    scenario, status = stamp.get("scenario"), stamp.get("status")
    run = (
        f"the run of {scenario}" if scenario else f"the run in {path_text(run_dir.resolve().name)}"
    )
    if not status:
        status = "unknown" + (f": {summary_problem}" if summary_problem else "")
    return (
        f'<p class="stamp">Made {html.escape(str(stamp.get("made")))} from '
        f"{html.escape(run)} (status {html.escape(str(status))}), results.csv SHA-256 "
        f"<code>{html.escape(digest[:16])}</code>. A later run into this folder marks this "
        "page stale.</p>"
    )


def _manoeuvre_table(summary: dict[str, Any]) -> str:
    """The metrics of a manoeuvre run as an HTML table ("" for another run)."""
    metrics = summary_metrics(summary)
    if not metrics:
        return ""
    rows = "\n".join(
        f'<tr><th scope="row">{html.escape(figure_label(name))}</th>'
        f"<td>{html.escape('n/a' if value is None else _text(value))}</td></tr>"
        for name, value in metrics.items()
    )
    kind = html.escape(str(summary["manoeuvre"]))
    return (
        f"<h2>Manoeuvre metrics: {kind}</h2>\n"
        f'<table class="manoeuvre">\n<caption>Metrics of the {kind} manoeuvre</caption>\n'
        f"{rows}\n</table>\n"
        "<p>Definitions: docs/manoeuvres.md of auv-cosim.</p>\n"
    )


def _timeline_tables(summary: dict[str, Any]) -> str:
    """The run's faults (what each corrupts, from when to when) and the events it fired,
    from summary.json, as HTML tables ("" for a run with neither)."""
    faults = [f for f in summary.get("faults") or [] if isinstance(f, dict)]
    events = [e for e in summary.get("events") or [] if isinstance(e, dict)]
    parts = []
    if faults:
        rows = "\n".join(
            f'<tr><th scope="row">{html.escape(_text(f.get("name")))}</th>'
            + "".join(
                f"<td>{html.escape(text)}</td>"
                for text in (
                    _text(f.get("kind")),
                    _text(f.get("target")),
                    _text(f.get("start")),
                    "never: to the end of the run" if f.get("stop") is None else _text(f["stop"]),
                )
            )
            + "</tr>"
            for f in faults
        )
        parts.append(
            '<h2>Faults</h2>\n<table class="faults">\n<caption>Faults: what each corrupts '
            "and when (docs/events.md)</caption>\n"
            + _header_row(("fault", "kind", "target", "start (s)", "stop (s)"))
            + f"\n{rows}\n</table>"
        )
    if events:
        rows = "\n".join(
            f'<tr><th scope="row">{html.escape(_text(e.get("name")))}</th>'
            f"<td>{html.escape(_text(e.get('time')))}</td>"
            f"<td>{html.escape(_set_text(e.get('set')))}</td></tr>"
            for e in events
        )
        parts.append(
            '<h2>Events fired</h2>\n<table class="events">\n<caption>Events fired, each '
            "time it fired</caption>\n"
            + _header_row(("event", "time (s)", "values set (SI)"))
            + f"\n{rows}\n</table>"
        )
    return "\n".join(parts)


def _header_row(names: tuple[str, ...]) -> str:
    return "<tr>" + "".join(f'<th scope="col">{html.escape(n)}</th>' for n in names) + "</tr>"


def _set_text(values: Any) -> str:
    """An event's values as "ref = value, ..." (a series' first values likewise)."""
    if not isinstance(values, dict):
        return ""
    return ", ".join(f"{ref} = {_text(value)}" for ref, value in values.items())


def _text(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    return str(value)
