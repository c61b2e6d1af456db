"""Standard manoeuvre metrics, as pure functions over a run's time series (numpy only).

``docs/manoeuvres.md`` states every definition; in short (IMO MSC.137(76) "Standards for
ship manoeuvrability" with its explanatory notes MSC/Circ.1053, and T. I. Fossen,
*Handbook of Marine Craft Hydrodynamics and Motion Control*, Wiley 2011, on the
turning-circle and zig-zag tests):

* turning circle (:func:`turning_circle`): from the execute (the turning command), the
  advance (along the original course) and transfer (across it, towards the turn) where the
  heading has changed by 90 deg, the tactical diameter (across the original course) where
  it has changed by 180 deg, the steady turning diameter of the circle fitted to the last
  full turn, the mean roll and the speed loss over that turn;
* zig-zag (:func:`zigzag`): the first and second overshoot angles and the period;
* depth steps (:func:`depth_steps`): rise time, overshoot, settling time and steady error
  of each step of the depth set-point;
* survey (:func:`survey`): RMS and largest cross-track error over the run, legs completed;
* fault recovery (:func:`fault_recovery`): what a heading autopilot still achieves after
  a fault: the largest and the final heading error from the fault on, and the time it
  takes to settle within 1 deg.

Positions are the body origin (the centre of buoyancy, mid-length on REMUS 100), the
point IMO calls the midship point. Times in s, lengths in m, angles in the inputs in rad;
the metrics carry their unit in their name. A metric the run cannot give (the heading
never turned 90 deg, a step never settled, a run stopped before it had any rows) is None.

:func:`manoeuvre_metrics` is the one call a run's summary needs: ``kind`` and the run's
columns (``results.csv`` names: ``time``, ``plant.yaw``, ...) in, a flat
``{name: value}`` out; :func:`manoeuvre_columns` says which columns it reads (what a
run must record), :func:`metric_names` which metrics it gives.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from cosim.metrics.key_figures import elapsed, row_time, settling_time

Metrics = dict[str, float | int | None]
STEADY_TURN_RAD = 2.0 * math.pi  # the steady part of a turning circle: its last full turn
SETTLING_BAND = 0.02  # settled: within 2 % of the step's change of its final value
DEPTH_STEP_METRICS = ("rise_time_s", "overshoot_pct", "settling_time_s", "steady_error_m")
HEADING_BAND_DEG = 1.0  # fault recovery: the heading has settled within 1 deg
TURNING_CIRCLE_METRICS = (
    "advance_m",
    "transfer_m",
    "tactical_diameter_m",
    "steady_turning_diameter_m",
    "steady_roll_deg",
    "speed_loss_pct",
)


# --- turning circle ------------------------------------------------------------------------


def turning_circle(
    times: np.ndarray,
    north: np.ndarray,
    east: np.ndarray,
    yaw: np.ndarray,
    roll: np.ndarray,
    execute: int = 0,
) -> Metrics:
    """Advance, transfer, tactical and steady turning diameters, steady roll, speed loss.

    Args:
        times, north, east, yaw, roll: the run's samples (s, m, m, rad, rad), yaw as the
            plant integrates it (continuous, or wrapped: it is unwrapped here).
        execute: index of the sample at which the turning command was given.

    The original course is the direction of the track at the execute and the heading
    change is counted from the heading there, in the direction the vehicle turns. The
    steady part is the last full turn (360 deg of heading) of the run, and only when it
    starts after the 180 deg point: then the track there is fitted with a circle
    (``steady_turning_diameter_m``), and roll and speed over ground are averaged over it.
    Speed over ground is the track's own rate (central differences).
    """
    times, north, east = (np.asarray(a, dtype=float) for a in (times, north, east))
    if times.size < 3:  # a run stopped at once: no track to measure
        return dict.fromkeys(TURNING_CIRCLE_METRICS)
    turn = _Turn(times, north, east, yaw, execute)
    change, at_90, at_180 = turn.change, turn.at_90, turn.at_180
    metrics: Metrics = dict.fromkeys(TURNING_CIRCLE_METRICS)
    metrics["advance_m"] = _interpolate(turn.along, at_90)
    metrics["transfer_m"] = _interpolate(turn.across, at_90)
    metrics["tactical_diameter_m"] = _interpolate(turn.across, at_180)
    steady = np.flatnonzero(change >= change[-1] - STEADY_TURN_RAD)
    if at_180 is None or change[-1] - STEADY_TURN_RAD < math.pi or steady.size < 3:
        return metrics
    if not np.isfinite(np.concatenate([north[steady], east[steady]])).all():
        return metrics  # a track that blew up has no steady turn (and LAPACK would complain)
    _, radius = fit_circle(north[steady], east[steady])
    metrics["steady_turning_diameter_m"] = 2.0 * radius
    metrics["steady_roll_deg"] = math.degrees(float(np.mean(np.asarray(roll)[steady])))
    approach = float(turn.speed[execute])
    metrics["speed_loss_pct"] = 100.0 * (approach - float(np.mean(turn.speed[steady]))) / approach
    return metrics


class _Turn:
    """A turning circle's frame: the original course and the heading change from the
    execute (see :func:`turning_circle`), and the track along and across that course."""

    def __init__(
        self, times: np.ndarray, north: np.ndarray, east: np.ndarray, yaw: np.ndarray, execute: int
    ) -> None:
        heading = np.unwrap(np.asarray(yaw, dtype=float))
        speed_north = np.gradient(north, times, edge_order=2)
        speed_east = np.gradient(east, times, edge_order=2)
        self.speed = np.hypot(speed_north, speed_east)
        self.course = math.atan2(speed_east[execute], speed_north[execute])
        self.direction = math.copysign(1.0, heading[-1] - heading[execute])
        self.change = self.direction * (heading - heading[execute])
        dn, de = north - north[execute], east - east[execute]
        self.along = dn * math.cos(self.course) + de * math.sin(self.course)
        self.across = self.direction * (-dn * math.sin(self.course) + de * math.cos(self.course))
        self.at_90 = _first_crossing(self.change, math.pi / 2, execute)
        self.at_180 = _first_crossing(self.change, math.pi, execute)


def turning_circle_marks(columns: Mapping[str, np.ndarray]) -> dict[str, object] | None:
    """Where a turning circle's metrics are measured, to draw them on its track: the
    ``execute``, ``at_90`` and ``at_180`` points (north, east in m; None where the run
    does not get there), the original ``course`` (rad) and the turn's ``direction`` (+1
    to starboard). ``columns`` as for :func:`manoeuvre_metrics`; None for a run too short
    (fewer than 3 rows) or without the columns."""
    try:
        used = manoeuvre_columns("turning-circle", [c for c in columns if c != "time"])
    except ValueError:
        return None
    column = {name: np.asarray(columns[c], dtype=float) for name, c in used.items()}
    times = np.asarray(columns["time"], dtype=float)
    if times.size < 3:
        return None
    execute = _execute(column)
    north, east = column["north"], column["east"]
    turn = _Turn(times, north, east, column["yaw"], execute)

    def point(index: float | None) -> tuple[float, float] | None:
        if index is None:
            return None
        return (_interpolate(north, index), _interpolate(east, index))  # type: ignore[return-value]

    return {
        "execute": (float(north[execute]), float(east[execute])),
        "at_90": point(turn.at_90),
        "at_180": point(turn.at_180),
        "course": turn.course,
        "direction": turn.direction,
    }


def fit_circle(x: np.ndarray, y: np.ndarray) -> tuple[tuple[float, float], float]:
    """Centre and radius of the circle through points (x, y), least squares.

    The algebraic (Kasa) fit: x^2 + y^2 + D x + E y + F = 0 is linear in D, E, F, so one
    ``numpy.linalg.lstsq`` gives them; exact for points on a circle and unbiased for
    points spread round a whole one, which is how it is used here (numpy has no circle
    fit, and scipy's general least squares would add an iteration for nothing).
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    # Centred first, so the linear system is well conditioned far from the origin.
    x0, y0 = float(np.mean(x)), float(np.mean(y))
    dx, dy = x - x0, y - y0
    design = np.column_stack([dx, dy, np.ones_like(dx)])
    (d, e, f), *_ = np.linalg.lstsq(design, -(dx**2 + dy**2), rcond=None)
    centre = (x0 - d / 2.0, y0 - e / 2.0)
    return centre, math.sqrt(d * d / 4.0 + e * e / 4.0 - f)


# --- zig-zag -------------------------------------------------------------------------------


def zigzag(
    times: np.ndarray, yaw: np.ndarray, command: np.ndarray, heading_command: bool = False
) -> Metrics:
    """First and second overshoot angles (deg) and the period (s) of a zig-zag.

    Args:
        times, yaw: s, rad.
        command: what is switched at each execute (the heading set-point, a rudder or
            moving-mass command): the executes are the samples at which it starts to
            change value (:func:`switch_indices`: a ramp is one execute), and the first
            sample too when it asks for a turn there: a rudder or moving-mass command
            that is non-zero, or with ``heading_command`` a heading set-point (rad) more
            than :data:`HEADING_BAND_DEG` off the heading, compared on the circle (one
            that holds the course until the first execute is none, whichever turn it is
            written on).

    With executes e1, e2, e3, ... (e2 the first counter-command): the first overshoot is
    how far the heading goes on beyond its value at e2 before e3 (in the direction of the
    first turn), the second how far it goes beyond its value at e3 before e4 (the other
    way). The period is the mean time from an execute to the next-but-one, from e2 on
    (e2 -> e4, e3 -> e5, ...): one full cycle, to the ns (:func:`row_time`). Each needs
    the executes after it.
    """
    times = np.asarray(times, dtype=float)
    heading = np.unwrap(np.asarray(yaw, dtype=float))
    command = np.asarray(command, dtype=float)
    neutral = 0.0
    if heading_command and heading.size and command.size:  # the heading, on the set-point's
        # turn: -10 deg holds a course of 350 deg (the autopilot wraps its error)
        neutral = float(command[0] - np.angle(np.exp(1j * (command[0] - heading[0]))))
    tolerance = math.radians(HEADING_BAND_DEG) if heading_command else 0.0
    executes = switch_indices(command, neutral, tolerance)
    metrics: Metrics = {"overshoot_1_deg": None, "overshoot_2_deg": None, "period_s": None}
    if len(executes) < 3:
        return metrics
    first, second, third = executes[:3]
    direction = math.copysign(1.0, heading[second] - heading[first])
    metrics["overshoot_1_deg"] = math.degrees(
        float(np.max(direction * (heading[second:third] - heading[second])))
    )
    if len(executes) >= 4:
        fourth = executes[3]
        metrics["overshoot_2_deg"] = math.degrees(
            float(np.max(-direction * (heading[third:fourth] - heading[third])))
        )
        cycles = times[executes[3:]] - times[executes[1:-2]]
        metrics["period_s"] = row_time(np.mean(cycles))
    return metrics


def switch_indices(command: np.ndarray, neutral: float = 0.0, tolerance: float = 0.0) -> list[int]:
    """Samples at which ``command`` starts to change value (a ramp, changing at every
    sample, is one change: from its first sample), with 0 first if it starts more than
    ``tolerance`` off ``neutral`` (the command that asks for no turn)."""
    changes = change_starts(command)
    turning = command.size and abs(command[0] - neutral) > tolerance
    return [0, *changes] if turning else changes


def change_starts(values: np.ndarray) -> list[int]:
    """Samples k at which ``values`` changes (from sample k - 1) where it did not change
    at the sample before: the first sample of each jump or ramp."""
    changed = np.diff(values) != 0.0
    starts = changed & ~np.concatenate([[False], changed[:-1]])
    return (np.flatnonzero(starts) + 1).tolist()


# --- depth steps ---------------------------------------------------------------------------


def depth_steps(
    times: np.ndarray, depth: np.ndarray, setpoint: np.ndarray, band: float = SETTLING_BAND
) -> list[Metrics]:
    """Rise time, overshoot, settling time and steady error of each depth set-point step.

    A step starts at a sample where the set-point starts to change (a ramp is one step)
    and ends at the next change (or the end of the run). Its final value is the depth at
    its end, so a loop with a steady error (the depth PD of Fig. 6.40 has no integral
    term) still gets a rise and a settling time, and ``steady_error_m`` = set-point (at
    the step's end) - final depth says how far off it
    stayed. ``rise_time_s``: from 10 % to 90 % of the change from the depth at the step to
    the final value; ``overshoot_pct``: the largest excursion beyond the final value, in %
    of that change; ``settling_time_s``: from the step to the last entry into the band of
    ``band`` times the change around the final value.
    """
    times, depth = np.asarray(times, dtype=float), np.asarray(depth, dtype=float)
    setpoint = np.asarray(setpoint, dtype=float)
    starts = change_starts(setpoint)  # a ramped set-point: from the ramp's start
    result: list[Metrics] = []
    for start, end in zip(starts, [*starts[1:], len(times)][: len(starts)], strict=True):
        t, z = times[start:end] - times[start], depth[start:end]
        final, change = z[-1], z[-1] - z[0]
        metrics: Metrics = dict.fromkeys(DEPTH_STEP_METRICS)
        metrics["steady_error_m"] = float(setpoint[end - 1] - final)
        if change != 0.0:
            progress = (z - z[0]) / change
            t10, t90 = _crossing_time(t, progress, 0.1), _crossing_time(t, progress, 0.9)
            if t10 is not None and t90 is not None:
                metrics["rise_time_s"] = t90 - t10
            metrics["overshoot_pct"] = 100.0 * max(0.0, float(np.max(progress)) - 1.0)
            outside = np.flatnonzero(np.abs(z - final) > band * abs(change))
            metrics["settling_time_s"] = (
                elapsed(float(times[start + outside[-1] + 1]), float(times[start]))
                if outside.size
                else 0.0
            )
        result.append(metrics)
    return result


# --- survey --------------------------------------------------------------------------------


SURVEY_METRICS = (
    "cross_track_rms_m",
    "cross_track_max_m",
    "legs_completed",
    "legs_total",
    "first_waypoint_not_reached",
)


def survey(
    cross_track_error: np.ndarray, legs_completed: np.ndarray, legs_total: int | None = None
) -> Metrics:
    """RMS and largest |cross-track error| over the whole run (m), and the legs completed
    at its end (the guidance's own outputs, sampled every communication step).

    ``legs_total``: the mission's legs (waypoints - 1), which the columns do not hold;
    given, the metrics also name the first waypoint not reached (numbered from 1, the
    first being the start: ``legs_completed + 2``), None once every leg is completed.
    """
    tracker = SurveyTracker(legs_total)
    tracker.add(np.asarray(cross_track_error, dtype=float), np.asarray(legs_completed))
    return tracker.metrics()


SURVEY_BLOCK_ROWS = 1 << 16  # rows of cross-track error squared and summed as one block


class SurveyTracker:
    """:func:`survey` over a run's rows given in consecutive pieces, holding one block of
    :data:`SURVEY_BLOCK_ROWS` errors and one sum per block before it (a long mission's
    figures need no row kept). The squares are summed a whole block at a time, so the
    figures do not depend on how the rows were cut into pieces; a run of one block or less
    gets the sum over its whole column (numpy's ``mean``)."""

    def __init__(self, legs_total: int | None = None) -> None:
        self.legs_total = legs_total  # the mission's legs, if known
        self._block = np.empty(SURVEY_BLOCK_ROWS)
        self._filled = 0  # errors in the block
        self._sums: list[float] = []  # of the squares of each full block, m^2
        self._count = 0
        self._largest = -math.inf  # |cross-track error| (m); NaN once one was NaN
        self._legs = math.nan  # the last row's legs completed

    def add(self, cross_track_error: np.ndarray, legs_completed: np.ndarray) -> None:
        """The next rows' cross-track errors (m) and legs completed (same length)."""
        if cross_track_error.size == 0:
            return
        self._count += cross_track_error.size
        self._largest = float(np.maximum(self._largest, np.max(np.abs(cross_track_error))))
        self._legs = float(legs_completed[-1])
        taken = 0
        while taken < cross_track_error.size:
            k = min(SURVEY_BLOCK_ROWS - self._filled, cross_track_error.size - taken)
            self._block[self._filled : self._filled + k] = cross_track_error[taken : taken + k]
            self._filled += k
            taken += k
            if self._filled == SURVEY_BLOCK_ROWS:
                self._sums.append(float(np.sum(self._block**2)))
                self._filled = 0

    def metrics(self) -> Metrics:
        """The survey's figures over the rows so far (None each without a row)."""
        if self._count == 0:  # a run stopped before its first row
            return {**dict.fromkeys(SURVEY_METRICS), "legs_total": self.legs_total}
        total = np.sum(self._block[: self._filled] ** 2)
        if self._sums:
            total = np.sum(np.asarray([*self._sums, total]))
        legs = round(self._legs)
        return {
            "cross_track_rms_m": float(np.sqrt(total / self._count)),
            "cross_track_max_m": self._largest,
            "legs_completed": legs,
            "legs_total": self.legs_total,
            "first_waypoint_not_reached": first_waypoint_not_reached(legs, self.legs_total),
        }


LegFigures = dict[str, float | int | bool | None]


@dataclass(frozen=True)
class Mission:
    """A survey's mission as :class:`LegTracker` needs it: the waypoints' north and east
    (m, one row each, in the order flown) and the guidance's acceptance radius (m)."""

    waypoints: np.ndarray
    acceptance_radius: float


class LegTracker:
    """Each leg of a survey as its rows stream by (no row kept): when it was completed
    (the time of the first row counting it in ``legs_completed``; several legs completed
    by one row share its time), how long it took (from the previous leg's completion, or
    the first row for leg 1) and the largest |cross-track error| while it was the active
    leg. Leg k runs to waypoint k + 1; the rows after the last leg's completion (the
    guidance then follows the last leg, extended) are no leg's. Given the ``mission`` and
    the vehicle's position, also the closest the vehicle came to the leg's end waypoint
    (horizontally, over the rows the leg was active and the row completing it) and whether
    that was within the acceptance radius: the guidance also completes a leg whose end
    the vehicle passes along the track, however far off."""

    def __init__(self, legs_total: int | None = None, mission: Mission | None = None) -> None:
        self.legs_total = legs_total  # the mission's legs, if known
        self.mission = mission
        self._closest: dict[int, float] = {}  # leg -> m
        self._first: float | None = None  # the first row's time, s
        self._previous = 0.0  # the legs completed before the next row
        self._completed: list[float] = []  # s, leg k's completion at k - 1
        self._largest: dict[int, float] = {}  # legs completed (k - 1) -> |error|, m

    def add(
        self,
        times: np.ndarray,
        cross_track_error: np.ndarray,
        legs: np.ndarray,
        position: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> None:
        """The next rows' times (s), cross-track errors (m), legs completed and, if
        known, the vehicle's north and east (m)."""
        if times.size == 0:
            return
        if self._first is None:
            self._first = float(times[0])
        done = np.asarray(legs, dtype=float)
        before = np.concatenate(([self._previous], done[:-1]))
        for i in np.flatnonzero(done > before):  # NaN compares false: no leg
            self._completed += [row_time(times[i])] * (round(done[i]) - round(before[i]))
        if self.mission is not None and position is not None:
            self._approach(done, before, *position)
        self._previous = float(done[-1]) if math.isfinite(done[-1]) else self._previous
        for value in np.unique(done[np.isfinite(done)]):
            largest = float(np.max(np.abs(cross_track_error[done == value])))
            key = round(value)
            self._largest[key] = float(np.fmax(self._largest.get(key, -math.inf), largest))

    def _approach(
        self, done: np.ndarray, before: np.ndarray, north: np.ndarray, east: np.ndarray
    ) -> None:
        """Each leg's closest approach to its end waypoint over these rows: those on the
        leg (``done`` legs completed before it) and the row completing it."""
        assert self.mission is not None
        ends = self.mission.waypoints
        for value in np.unique(done[np.isfinite(done)]):
            leg = round(value) + 1  # the active leg, ending at waypoint index leg
            if leg < len(ends):
                rows = done == value
                self._nearer(leg, np.hypot(north[rows] - ends[leg, 0], east[rows] - ends[leg, 1]))
        for i in np.flatnonzero(done > before):
            for leg in range(round(before[i]) + 1, min(round(done[i]), len(ends) - 1) + 1):
                self._nearer(leg, np.hypot(north[i : i + 1] - ends[leg, 0],
                                           east[i : i + 1] - ends[leg, 1]))  # fmt: skip

    def _nearer(self, leg: int, distances: np.ndarray) -> None:
        closest = float(np.nanmin(distances, initial=math.inf))
        self._closest[leg] = min(self._closest.get(leg, math.inf), closest)

    def legs(self) -> list[LegFigures]:
        """One entry per leg of the mission (per leg begun if its length is unknown):
        ``leg``, ``to_waypoint``, ``completed_at_s``, ``duration_s`` (None while not
        completed), ``cross_track_max_m`` (None if it was never the active leg),
        ``closest_m`` and ``within_acceptance_radius`` (None without the mission and the
        position, or a leg never active)."""
        begun = max([*self._largest, len(self._completed) - 1], default=-1) + 1
        total = self.legs_total if self.legs_total is not None else begun
        entries = []
        for k in range(1, total + 1):
            end = self._completed[k - 1] if k <= len(self._completed) else None
            start = self._first if k == 1 else self._completed[k - 2] if end is not None else None
            closest = _finite_or_none(self._closest.get(k))
            radius = None if self.mission is None else self.mission.acceptance_radius
            entries.append({
                "leg": k,
                "to_waypoint": k + 1,
                "completed_at_s": end,
                "duration_s": None if end is None or start is None else elapsed(end, start),
                "cross_track_max_m": _finite_or_none(self._largest.get(k - 1)),
                "closest_m": closest,
                "within_acceptance_radius": None if closest is None or radius is None
                else closest <= radius,
            })  # fmt: skip
        return entries


def _finite_or_none(value: float | None) -> float | None:
    return value if value is not None and math.isfinite(value) else None


def first_waypoint_not_reached(legs_completed: int, legs_total: int | None) -> int | None:
    """The first waypoint (numbered from 1, the start being 1) a mission of ``legs_total``
    legs has not reached after ``legs_completed``; None if every one was, or the mission's
    legs are unknown."""
    if legs_total is None or legs_completed >= legs_total:
        return None
    return legs_completed + 2


# --- fault recovery ------------------------------------------------------------------------


def fault_recovery(
    times: np.ndarray, yaw: np.ndarray, setpoint: np.ndarray, start: float = 0.0
) -> Metrics:
    """What a heading autopilot still achieves after a fault that starts at ``start`` (s).

    Args:
        times, yaw, setpoint: s, rad, rad (the heading error is yaw - set-point, wrapped
            to (-180, 180] deg).
        start: when the fault starts (s).

    ``heading_error_at_fault_deg``: |error| at the fault's start; ``heading_error_max_deg``
    and ``heading_error_final_deg``: the largest |error| from the start on and |error| at
    the end of the run; ``heading_settling_time_s``: the time from the start after which
    |error| stays below :data:`HEADING_BAND_DEG` to the end (0 if it never leaves that
    band), None if the run ends outside it (the autopilot does not recover).
    """
    times = np.asarray(times, dtype=float)
    error = np.angle(np.exp(1j * (np.asarray(yaw, dtype=float) - np.asarray(setpoint))))
    after = times >= start - 1e-9
    metrics: Metrics = dict.fromkeys(
        ("heading_error_at_fault_deg", "heading_error_max_deg", "heading_error_final_deg",
         "heading_settling_time_s")
    )  # fmt: skip
    if not after.any():  # the run stopped before the fault
        return metrics
    degrees = np.degrees(np.abs(error[after]))
    settled = settling_time(times[after], error[after], math.radians(HEADING_BAND_DEG))
    metrics["heading_error_at_fault_deg"] = float(degrees[0])
    metrics["heading_error_max_deg"] = float(np.max(degrees))
    metrics["heading_error_final_deg"] = float(degrees[-1])
    metrics["heading_settling_time_s"] = None if settled is None else elapsed(settled, float(start))
    return metrics


# --- one call for a run's summary ----------------------------------------------------------

# The variables each kind reads besides ``time`` (looked up as in manoeuvre_metrics).
VARIABLES: dict[str, tuple[str, ...]] = {
    "turning-circle": ("north", "east", "yaw", "roll", "mass_position_cmd"),
    "zigzag": ("yaw", "yaw_setpoint"),
    "depth-steps": ("down", "depth_setpoint"),
    "survey": ("cross_track_error", "legs_completed"),
    "fault-recovery": ("yaw", "yaw_setpoint"),
}
# What a run without a column for a variable may give in its place, in order: a zig-zag
# switches the heading set-point of an autopilot or, without one, the moving-mass command
# (the open-loop test of IMO MSC.137(76), the vehicle's own means of turning).
STAND_INS: dict[str, dict[str, tuple[str, ...]]] = {
    "zigzag": {"yaw_setpoint": ("mass_position_cmd",)},
}


def manoeuvre_metrics(
    kind: str, columns: Mapping[str, np.ndarray], fault_start: float | None = None
) -> Metrics:
    """The metrics of manoeuvre ``kind`` from a run's columns (``results.csv`` names).

    Kinds: ``turning-circle``, ``zigzag``, ``depth-steps``, ``survey``,
    ``fault-recovery`` (:data:`KINDS`; ``fault_start``, s, is when the fault starts, needed
    by the last and not read by the others: :func:`cosim.outputs.manoeuvre.fault_start`
    reads it from a scenario). The columns are found by :func:`manoeuvre_columns`; depth
    steps come out numbered, ``step_1_rise_time_s``, ...

    Raises:
        ValueError: an unknown kind, a column it needs missing or ambiguous (the message
            names it and the columns there are), or a fault-recovery without a finite
            ``fault_start``.
    """
    names = manoeuvre_columns(kind, [name for name in columns if name != "time"])
    if kind == "fault-recovery" and (fault_start is None or not math.isfinite(fault_start)):
        raise ValueError(
            f"'fault-recovery' needs fault_start=, the time the fault starts (s), not "
            f"{fault_start!r}: cosim.outputs.manoeuvre.fault_start(scenario) reads it"
        )
    values = {name: np.asarray(columns[column], dtype=float) for name, column in names.items()}
    values["time"] = np.asarray(columns["time"], dtype=float)
    return KINDS[kind](values, 0.0 if fault_start is None else fault_start)


def manoeuvre_columns(kind: str, columns: Sequence[str]) -> dict[str, str]:
    """Which of ``columns`` (``<instance>.<variable>``) manoeuvre ``kind`` reads: variable
    -> column. A variable is the column of its own name if there is one, else
    ``plant.<name>`` when the plant records it (what acts on the vehicle), else the one
    column ``<instance>.<name>`` of any instance; a run with no column for it may give
    one of its :data:`STAND_INS` instead (a zig-zag's moving-mass command), under the
    stand-in's own name.

    Raises:
        ValueError: an unknown kind, or a variable with no column (nor a stand-in) or
            several.
    """
    if kind not in KINDS:
        raise ValueError(f"unknown manoeuvre {kind!r}: expected one of {sorted(KINDS)}")
    found = {}
    for name in VARIABLES[kind]:
        stand_ins = STAND_INS.get(kind, {}).get(name, ())
        for candidate in (name, *stand_ins):
            matches = _columns_of(candidate, columns)
            if matches:
                break
        if len(matches) != 1:
            problem = f"several columns {matches}" if matches else "no column"
            instead = "" if matches else "".join(f" (or {other!r})" for other in stand_ins)
            raise ValueError(
                f"manoeuvre {kind!r} needs the variable {name!r}{instead}, but the run has "
                f"{problem} for it (columns: {', '.join(columns)})"
            )
        found[candidate] = matches[0]
    return found


def _columns_of(name: str, columns: Sequence[str]) -> list[str]:
    """The columns variable ``name`` may be read from (:func:`manoeuvre_columns`): itself
    or the plant's alone if there is one, else every ``<instance>.<name>``."""
    exact = [c for c in (name, f"plant.{name}") if c in columns]
    return exact[:1] or [c for c in columns if c.endswith(f".{name}")]


def metric_names(kind: str, steps: int = 0) -> tuple[str, ...]:
    """The metrics manoeuvre ``kind`` gives, in order; ``steps``: the depth-set-point
    steps of a ``depth-steps`` run (its names are numbered per step)."""
    if kind == "depth-steps":
        return tuple(f"step_{k}_{m}" for k in range(1, steps + 1) for m in DEPTH_STEP_METRICS)
    empty = {name: np.empty(0) for name in ("time", *VARIABLES[kind])}
    return tuple(KINDS[kind](empty, 0.0))


def summary_metrics(summary: Mapping[str, object]) -> Metrics:
    """The manoeuvre metrics of a run's ``summary.json`` (its top level): those of its
    ``manoeuvre``, the depth steps as many as it has; {} for a run without one."""
    kind = summary.get("manoeuvre")
    if kind not in KINDS:
        return {}
    steps = 0
    while f"step_{steps + 1}_{DEPTH_STEP_METRICS[0]}" in summary:
        steps += 1
    names = metric_names(str(kind), steps)
    return {name: _number(summary.get(name)) for name in names}


def _number(value: object) -> float | int | None:
    """A metric as read from JSON: a number, else None."""
    is_number = isinstance(value, int | float) and not isinstance(value, bool)
    return value if is_number else None  # type: ignore[return-value]


Columns = Mapping[str, np.ndarray]


def _turning_circle_metrics(column: Columns, _: float) -> Metrics:
    return turning_circle(
        column["time"], column["north"], column["east"], column["yaw"], column["roll"],
        execute=_execute(column),
    )  # fmt: skip


def _execute(column: Columns) -> int:
    """A turning circle's execute: the first sample with a moving-mass command."""
    active = np.flatnonzero(np.asarray(column["mass_position_cmd"]) != 0.0)
    return int(active[0]) if active.size else 0


def _zigzag_metrics(column: Columns) -> Metrics:
    """A zig-zag of the heading set-point, or of the moving-mass command it stands in
    for (:data:`STAND_INS`)."""
    heading = "yaw_setpoint" in column
    command = column["yaw_setpoint" if heading else "mass_position_cmd"]
    return zigzag(column["time"], column["yaw"], command, heading_command=heading)


def _depth_steps_metrics(column: Columns, _: float) -> Metrics:
    steps = depth_steps(column["time"], column["down"], column["depth_setpoint"])
    return {f"step_{k}_{name}": v for k, step in enumerate(steps, 1) for name, v in step.items()}


KINDS: dict[str, Callable[[Columns, float], Metrics]] = {
    "turning-circle": _turning_circle_metrics,
    "zigzag": lambda column, _: _zigzag_metrics(column),
    "depth-steps": _depth_steps_metrics,
    "survey": lambda column, _: survey(column["cross_track_error"], column["legs_completed"]),
    "fault-recovery": lambda column, start: fault_recovery(
        column["time"], column["yaw"], column["yaw_setpoint"], start
    ),
}


# --- helpers -------------------------------------------------------------------------------


def _first_crossing(values: np.ndarray, level: float, start: int) -> float | None:
    """Fractional index at which ``values`` first reaches ``level`` from ``start`` on
    (linear between samples); None if it never does."""
    above = np.flatnonzero(values[start:] >= level)
    if above.size == 0:
        return None
    k = start + int(above[0])
    if k == start:
        return float(k)
    fraction = (level - values[k - 1]) / (values[k] - values[k - 1])
    return k - 1 + float(fraction)


def _interpolate(values: np.ndarray, index: float | None) -> float | None:
    """``values`` at a fractional index (linear), or None."""
    if index is None:
        return None
    return float(np.interp(index, np.arange(len(values)), values))


def _crossing_time(times: np.ndarray, values: np.ndarray, level: float) -> float | None:
    """Time at which ``values`` first reaches ``level`` (linear between samples)."""
    index = _first_crossing(values, level, 0)
    return _interpolate(times, index)
