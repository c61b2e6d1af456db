"""Missions a waypoint guidance (``AuvGuidance``) cannot fly as planned, seen before a run:
a leg against a current the vehicle is not faster than (no heading holds the leg's course,
or the vehicle drifts back along it: the run would go on to its stop time without
reaching the leg's end), waypoints the stop time ends before the vehicle could reach, and
waypoints that look like latitude and longitude in degrees (the guidance takes metres).

The vehicle's speed through the water is the straight-run speed of the plant the
guidance reads its position from, on the thrust of the autopilot connected to that plant
(:func:`cosim.scenario.design_doubts.straight_run_speed`), else the guidance's
``design_speed``; the current is the plant's start value, then each value an event sets
on the plant's ``current_north`` or ``current_east`` (a time event's from its time, ramp
included, in time order; each row of a series from its time; a ``when`` event's on the
start value), and the first current some leg cannot be flown in is named with the event.
Along a leg of course chi the vehicle holds the course by crabbing into the current's
part across it, ``c_across``, and the part along it, ``c_along``, adds::

    speed over ground = sqrt(U^2 - c_across^2) + c_along     (none if |c_across| >= U)

The time to a waypoint is the legs' lengths over those speeds, the turns not counted: a
lower bound. With several vehicles, a guidance whose set-points feed an autopilot that
drives another plant than the one whose position it reads (the same-name rule connects one
guidance's ``yaw_setpoint`` and ``depth_setpoint`` to every autopilot) is named too, with
each such connection: that plant follows set-points computed for where the other is. Such
a mission is valid all the same (a planner may mean to see it fail), so a run says so in
one warning line each (:class:`MissionWarning`), naming the waypoint.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from controller_fmu.los_guidance import Waypoint, parse_waypoints

if TYPE_CHECKING:
    from cosim.scenario.spec import Connection, Instance, Scenario
    from cosim.scenario.timeline_spec import Event

GUIDANCE, PLANT, AUTOPILOT = "AuvGuidance", "AuvPlant", "AuvAutopilot"


class MissionWarning(UserWarning):
    """A valid mission the vehicle cannot fly as planned."""


@dataclass(frozen=True)
class Leg:
    """Leg ``number`` (from waypoint ``number`` to ``number + 1``, numbered from 1): its
    horizontal length (m), course (rad, from north) and the vehicle's speed over ground
    along it holding that course (m/s; None if no heading holds it)."""

    number: int
    length: float
    course: float
    ground_speed: float | None


def ground_speed(
    course: float, speed: float, current_north: float, current_east: float
) -> float | None:
    """The speed over ground (m/s) along ``course`` (rad) of a vehicle making ``speed``
    (m/s) through the water in the current (m/s, earth frame), crabbing to hold the
    course; negative if the current carries it back, None if the current across the
    course is not slower than the vehicle (no heading holds it)."""
    along = current_north * math.cos(course) + current_east * math.sin(course)
    across = -current_north * math.sin(course) + current_east * math.cos(course)
    if abs(across) >= speed:
        return None
    return math.sqrt(speed**2 - across**2) + along


def mission_legs(
    waypoints: Sequence[Waypoint], speed: float, current_north: float, current_east: float
) -> list[Leg]:
    """The legs of a mission flown at ``speed`` (m/s through the water) in the current."""
    legs = []
    for number, (a, b) in enumerate(itertools.pairwise(waypoints), start=1):
        course = math.atan2(b.east - a.east, b.north - a.north)
        length = math.hypot(b.north - a.north, b.east - a.east)
        legs.append(Leg(number, length, course, ground_speed(course, speed, current_north,
                                                             current_east)))  # fmt: skip
    return legs


def mission_doubts(scenario: Scenario) -> list[str]:
    """One line for each guidance with a leg the vehicle cannot fly in the plant's
    current (the start value or one an event sets), and one for each whose waypoints the
    stop time ends before (module)."""
    found = []
    for name, guidance in _instances(scenario, GUIDANCE).items():
        plant = _plant_of(scenario, name)
        if plant is None:  # no plant feeds its position: no current, no speed known
            continue
        found += _steering_doubts(scenario, name, plant)
        speed, source = _speed(scenario, name, guidance, plant)
        waypoints = parse_waypoints(str(scenario.start_value(name, "waypoints")))
        key = f"instances.{name}.start.waypoints"
        found.append(_degrees_doubt(key, waypoints))
        for when, current in plant_currents(scenario, plant):
            legs = mission_legs(waypoints, speed, *current)
            line = _current_doubt(key, legs, speed, source, plant, current, when)
            if line:
                found.append(line)
                break
        start = mission_legs(waypoints, speed, *plant_currents(scenario, plant)[0][1])
        found.append(_time_doubt(key, start, speed, source, scenario.stop_time))
    return [line for line in found if line]


CURRENT_NAMES = ("current_north", "current_east")


def plant_currents(scenario: Scenario, plant: str) -> list[tuple[str, tuple[float, float]]]:
    """The horizontal currents (m/s, north and east) the plant meets, each with when it
    holds ('' for the start value, else " from t = ... s (event ...)" or " when ...
    (event ...)"): the start value first, then the values events set (module)."""
    start = {n: _float(scenario, plant, n) for n in CURRENT_NAMES}
    timed: list[tuple[float, str, dict[str, float]]] = []
    triggered: list[tuple[str, dict[str, float]]] = []
    for event in scenario.events:
        for time, values in _event_currents(event, plant):
            if time is None:
                triggered.append((f" when {event.when} (event {event.name})", values))
            else:
                timed.append((time, f" from t = {time:g} s (event {event.name})", values))
    held = dict(start)
    found = [("", _pair(held))]
    for _, when, values in sorted(timed, key=lambda item: item[0]):
        held.update(values)
        found.append((when, _pair(held)))
    return found + [(when, _pair({**start, **values})) for when, values in triggered]


def _pair(current: dict[str, float]) -> tuple[float, float]:
    """The (north, east) of a current given by variable name, m/s."""
    return current["current_north"], current["current_east"]


def _event_currents(event: Event, plant: str) -> list[tuple[float | None, dict[str, float]]]:
    """The plant's current components ``event`` sets, by name, each with the time (s) it
    holds from (None for a ``when`` event; a series gives one per row)."""
    refs = {f"{plant}.{n}": n for n in CURRENT_NAMES}
    if event.series is not None:
        columns = {refs[r]: c for r, c in event.series.columns.items() if r in refs}
        if not columns:
            return []
        return [
            (t, {n: c[i] for n, c in columns.items()}) for i, t in enumerate(event.series.times)
        ]
    values = {refs[r]: float(v) for r, v in event.set.items() if r in refs}
    if not values:
        return []
    if event.time is None:
        return [(None, values)]
    return [(event.time + (event.ramp or 0.0), values)]


DEGREES_SPAN = 1.0  # m: a mission within this, far from the origin, reads as degrees


def _degrees_doubt(key: str, waypoints: Sequence[Waypoint]) -> str:
    """The warning if the waypoints look like latitude and longitude in degrees: within
    +-90 and +-180, all within :data:`DEGREES_SPAN` of each other and more than ten spans
    (and 1 m) from the origin, where the vehicle starts ('' if not)."""
    north = [w.north for w in waypoints]
    east = [w.east for w in waypoints]
    span = math.hypot(max(north) - min(north), max(east) - min(east))
    away = min(math.hypot(w.north, w.east) for w in waypoints)
    looks = all(abs(n) <= 90.0 for n in north) and all(abs(e) <= 180.0 for e in east)
    if not (looks and span < DEGREES_SPAN and away > max(10.0 * span, 1.0)):
        return ""
    return (
        f"{key}: the mission spans {span:.4g} m, {away:.4g} m from the origin: waypoints are "
        "north, east, down in metres (NED) from the origin the plant's north_0 and east_0 "
        "count from; if these are latitude and longitude in degrees, convert them to metres "
        "north and east of a reference point first (1e-5 deg of latitude is 1.11 m)"
    )


def _current_doubt(
    key: str,
    legs: Sequence[Leg],
    speed: float,
    source: str,
    plant: str,
    current: tuple[float, float],
    when: str = "",
) -> str:
    """The warning for the first leg no heading flies in the current, which holds
    ``when`` ('' from the start; the warning is '' if every leg flies)."""
    for leg in legs:
        if leg.ground_speed is not None and leg.ground_speed > 0.0:
            continue
        north, east = current
        along = north * math.cos(leg.course) + east * math.sin(leg.course)
        across = -north * math.sin(leg.course) + east * math.cos(leg.course)
        why = (
            f"it sets {abs(across):.3g} m/s across the leg, not slower than the vehicle"
            if leg.ground_speed is None
            else f"it sets {-along:.3g} m/s against the leg, leaving no speed over ground"
        )
        return (
            f"{key}: leg {leg.number} (waypoint {leg.number} -> {leg.number + 1}, course "
            f"{math.degrees(leg.course) % 360:.0f} deg) cannot be flown in {plant}'s current "
            f"of {north:g} m/s north, {east:g} m/s east{when} at {speed:.4g} m/s through the water "
            f"({source}): {why}; waypoint {leg.number + 1} onwards will not be reached"
            + (" if the vehicle is not past it by then" if when else "")
        )
    return ""


def _time_doubt(key: str, legs: Sequence[Leg], speed: float, source: str, stop_time: float) -> str:
    """The warning for the first waypoint the vehicle cannot reach by ``stop_time`` (s)
    even at its speed over ground on every leg ('' if it can reach them all)."""
    distance = time = 0.0
    for leg in legs:
        if leg.ground_speed is None or leg.ground_speed <= 0.0:
            return ""  # the current's warning says it
        distance += leg.length
        time += leg.length / leg.ground_speed
        if time > stop_time:
            return (
                f"{key}: waypoint {leg.number + 1} is {distance:.4g} m along the path, at "
                f"least {time:.4g} s at {speed:.4g} m/s through the water ({source}) in the "
                f"current, turns not counted, past the stop time of {stop_time:g} s: "
                f"waypoint {leg.number + 1} onwards will not be reached"
            )
    return ""


def _instances(scenario: Scenario, model: str) -> dict[str, Instance]:
    return {
        name: inst
        for name, inst in scenario.instances.items()
        if inst.interface.model_identifier == model
    }


def _plant_of(scenario: Scenario, guidance: str) -> str | None:
    """The plant whose ``north`` the guidance reads, if one does."""
    plants = _instances(scenario, PLANT)
    for connection in scenario.connections:
        if connection.target == f"{guidance}.north" and connection.source_instance in plants:
            return connection.source_instance
    return None


def _steering_doubts(scenario: Scenario, guidance: str, plant: str) -> list[str]:
    """One line for each autopilot the guidance's set-points feed that drives a plant
    other than ``plant``, the one whose position the guidance reads (two vehicles with
    the same-name connections on: one guidance's ``yaw_setpoint`` and ``depth_setpoint``
    feed every autopilot), naming every such connection to it: that plant follows
    set-points computed for where ``plant`` is."""
    plants, autopilots = _instances(scenario, PLANT), _instances(scenario, AUTOPILOT)
    fed: dict[str, list[Connection]] = {}  # autopilot -> the guidance's connections to it
    for c in sorted(scenario.connections, key=lambda c: _SET_POINTS.get(c.source_variable, 2)):
        if c.source_instance == guidance and c.target_instance in autopilots:
            fed.setdefault(c.target_instance, []).append(c)
    lines = []
    for autopilot, feeds in fed.items():
        driven = {c.target_instance for c in scenario.connections if c.source_instance == autopilot}
        for other in sorted(driven & set(plants) - {plant}):
            lines.append(_steering_text(guidance, autopilot, feeds, other, plant))
    return lines


_SET_POINTS = {"yaw_setpoint": 0, "depth_setpoint": 1}  # their order in a line
_FOLLOWED = {"yaw_setpoint": "headings", "depth_setpoint": "depths"}


def _steering_text(
    guidance: str, autopilot: str, feeds: list[Connection], other: str, plant: str
) -> str:
    """:func:`_steering_doubts`'s line: ``feeds`` from ``guidance`` steer ``autopilot``,
    which drives ``other``, while the guidance reads ``plant``'s position."""
    variables = " and ".join(c.source_variable for c in feeds)
    followed = " and ".join(_FOLLOWED.get(c.source_variable, "set-points") for c in feeds)
    several = len(feeds) > 1
    connections = " and ".join(f"{c.source} -> {c.target}" for c in feeds)
    removed = ", ".join(f'"{c.target}"' for c in feeds)
    return (
        f"instances.{guidance}: its {variables} steer{'' if several else 's'} {autopilot}, "
        f"which drives {other}, but the guidance reads the position of {plant} "
        f"({guidance}.north from {plant}.north): {other} follows {followed} computed for "
        f"where {plant} is; remove the connection{'s' if several else ''} {connections} "
        f"(connections.remove = [{removed}]), or give {other} a guidance of its own"
    )


def _speed(scenario: Scenario, name: str, guidance: Instance, plant: str) -> tuple[float, str]:
    """The vehicle's speed through the water (m/s) and where it comes from: the plant's
    straight run on the thrust of an autopilot connected to it, else the guidance's
    ``design_speed``."""
    from cosim.scenario.design_doubts import plant_parameters, straight_run_speed

    for autopilot in _instances(scenario, AUTOPILOT):
        pairs = {(c.source, c.target) for c in scenario.connections}
        if (f"{autopilot}.thrust", f"{plant}.thrust") in pairs:
            thrust = _float(scenario, autopilot, "thrust_command")
            speed = straight_run_speed(plant_parameters(scenario.instances[plant]), thrust)
            if speed is not None:
                return speed, f"{plant} on {autopilot}.thrust_command = {thrust:g} N"
    design = float(guidance.start.get("design_speed", _float(scenario, name, "design_speed")))
    return design, f"instances.{name}.start.design_speed"


def _float(scenario: Scenario, instance: str, variable: str) -> float:
    """The start value of ``instance.variable`` as a number (0 without one)."""
    value = scenario.start_value(instance, variable)
    return float(value) if isinstance(value, int | float) else 0.0
