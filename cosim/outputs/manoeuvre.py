"""A run's manoeuvre metrics (``manoeuvre`` key of the scenario), for its summary.json.

The metrics (:mod:`cosim.metrics.manoeuvres`) need a whole time series (a turning
circle's last full turn, a zig-zag's executes), so :class:`ManoeuvreSink` keeps, as the
rows stream by, only the time and the few columns its kind reads (a turning circle: five;
8 bytes a value, about 50 MB over a million rows) and measures them when asked, over the
rows it has: a run stopped early gets the metrics of what it ran, None where they cannot
be measured, never an exception. A survey's figures need no whole series (a sum, a
largest value, the last row): :class:`cosim.metrics.manoeuvres.SurveyTracker` takes its
rows as they come and keeps none, so a survey of any length holds the same memory.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from controller_fmu.los_guidance import parse_waypoints
from cosim.engine.rows import NotesIgnored
from cosim.metrics.manoeuvres import (
    VARIABLES,
    LegTracker,
    Mission,
    SurveyTracker,
    manoeuvre_columns,
    manoeuvre_metrics,
    metric_names,
)

if TYPE_CHECKING:
    from cosim.scenario.spec import Scenario

DEPTH_SETPOINT = "depth_setpoint"  # what a depth-steps scenario's time events set
GUIDANCE_FMU = "AuvGuidance"  # the waypoint guidance: a survey's mission is its waypoints
SURVEY = VARIABLES["survey"]  # cross_track_error, legs_completed: what SurveyTracker reads


class ManoeuvreSink(NotesIgnored):
    """A row sink keeping the columns manoeuvre ``kind`` reads (see the module).

    Args:
        kind: a :data:`cosim.metrics.manoeuvres.KINDS` name.
        record: the run's columns (``<instance>.<variable>``, the rows' order).
        fault_start: s, when the fault of a ``fault-recovery`` run starts.
        legs_total: a ``survey``'s mission legs (:func:`mission_legs`), None if unknown.
        mission: a ``survey``'s waypoints and acceptance radius, and ``position``: the
            columns of the vehicle's north and east (:func:`survey_mission`), for each
            leg's closest approach to its end (None: not measured).

    Raises:
        ValueError: the run does not record a column ``kind`` needs.
    """

    def __init__(
        self,
        kind: str,
        record: Sequence[str],
        fault_start: float = 0.0,
        legs_total: int | None = None,
        mission: Mission | None = None,
        position: tuple[str, str] | None = None,
    ) -> None:
        self.kind = kind
        self.fault_start = fault_start
        used = manoeuvre_columns(kind, list(record))
        self._names = list(used)
        self._index = [list(record).index(column) for column in used.values()]
        self._times: list[np.ndarray] = []
        self._values: list[np.ndarray] = []
        # a survey's figures stream: none of its rows is kept
        self._survey = SurveyTracker(legs_total) if kind == "survey" else None
        self._legs = LegTracker(legs_total, mission) if kind == "survey" else None
        where = None if position is None else [list(record).index(c) for c in position]
        self._position = where if mission is not None else None

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        if self._survey is not None:
            error, legs = (values[:, self._index[self._names.index(name)]] for name in SURVEY)
            self._survey.add(np.asarray(error, dtype=float), legs)
            if self._legs is not None:
                at = None
                if self._position is not None:
                    at = (np.asarray(values[:, self._position[0]], float),
                          np.asarray(values[:, self._position[1]], float))  # fmt: skip
                self._legs.add(np.asarray(times, dtype=float), np.asarray(error, float), legs, at)
            return
        self._times.append(np.array(times, dtype=float))
        self._values.append(np.asarray(values, dtype=float)[:, self._index])  # a copy

    def summary(self) -> dict[str, Any]:
        """``{"manoeuvre": kind, <metric>: value, ...}`` over the rows so far; a value that
        is not finite is None. A failure to measure (a run that ended on NaN) leaves every
        metric None and says why in ``manoeuvre_error``. A survey's also has ``legs``, one
        entry per leg (:meth:`cosim.metrics.manoeuvres.LegTracker.legs`)."""
        result: dict[str, Any] = {"manoeuvre": self.kind}
        try:
            with np.errstate(all="ignore"):  # NaN in, None out
                metrics = self._measure()
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as exc:
            result.update(dict.fromkeys(metric_names(self.kind)))
            result["manoeuvre_error"] = f"cannot measure the {self.kind} metrics: {exc}"
        else:
            result.update({name: _finite(value) for name, value in metrics.items()})
        if self._legs is not None:
            result["legs"] = self._legs.legs()
        return result

    def _measure(self) -> dict[str, float | int | None]:
        """The metrics over the rows so far (may raise what the metrics raise)."""
        if self._survey is not None:
            return self._survey.metrics()
        times = np.concatenate(self._times) if self._times else np.empty(0)
        values = np.concatenate(self._values) if self._values else np.empty((0, len(self._index)))
        columns = {"time": times, **dict(zip(self._names, values.T, strict=True))}
        return manoeuvre_metrics(self.kind, columns, self.fault_start)


def fault_start(scenario: Scenario) -> float:
    """When the first of the scenario's faults starts (s); 0 without any."""
    return min((fault.start for fault in scenario.faults), default=0.0)


def mission_legs(scenario: Scenario) -> int | None:
    """The legs of the mission a ``survey`` run measures: the waypoints, less one, of the
    waypoint guidance (``AuvGuidance``) whose ``legs_completed`` it reads; None for another
    manoeuvre, or a ``legs_completed`` of another FMU (its mission is not known here)."""
    if scenario.manoeuvre != "survey":
        return None
    column = manoeuvre_columns("survey", list(scenario.record))["legs_completed"]
    name = column.partition(".")[0]
    instance = scenario.instances.get(name)
    if instance is None or instance.interface.model_identifier != GUIDANCE_FMU:
        return None
    return len(parse_waypoints(str(scenario.start_value(name, "waypoints")))) - 1


def survey_mission(scenario: Scenario) -> tuple[Mission, tuple[str, str] | None] | None:
    """The mission of a ``survey`` run's guidance (:func:`mission_legs`' instance): its
    waypoints and acceptance radius, and the recorded columns of the north and east of the
    plant that feeds its position (None if not recorded); None where
    :func:`mission_legs` is."""
    if mission_legs(scenario) is None:
        return None
    column = manoeuvre_columns("survey", list(scenario.record))["legs_completed"]
    name = column.partition(".")[0]
    points = parse_waypoints(str(scenario.start_value(name, "waypoints")))
    radius = float(scenario.start_value(name, "acceptance_radius"))  # type: ignore[arg-type]
    mission = Mission(np.array([[w.north, w.east] for w in points]), radius)
    sources = {c.target: c.source for c in scenario.connections}
    position = (sources.get(f"{name}.north"), sources.get(f"{name}.east"))
    recorded = all(c is not None and c in scenario.record for c in position)
    return mission, (position if recorded else None)  # type: ignore[return-value]


def scenario_metric_names(scenario: Scenario) -> tuple[str, ...]:
    """The manoeuvre metrics a run of ``scenario`` reports (none without a manoeuvre).

    A ``depth-steps`` run has one set per step: each distinct time at which a time event
    sets a ``depth_setpoint`` (with a ramp too: a step starts where its ramp starts)."""
    if scenario.manoeuvre is None:
        return ()
    times = {
        event.time
        for event in scenario.events
        if event.time is not None and any(k.endswith(f".{DEPTH_SETPOINT}") for k in event.set)
    }
    return metric_names(scenario.manoeuvre, steps=len(times))


def _finite(value: float | int | None) -> float | int | None:
    return value if value is None or math.isfinite(value) else None
