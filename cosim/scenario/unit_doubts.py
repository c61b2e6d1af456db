"""Values a scenario may take that look like a slip of units: an angle in degrees where
the FMU declares radians (``yaw_0 = 30``, ``when = "plant.yaw > 20"``), a moving-mass
command in cm where the plant takes m (``mass_position_cmd = 6``), and a guidance's
acceptance radius as long as a leg of its mission (500 for 5 m; the leg's start lies in
its end's acceptance circle, so the leg counts as completed as soon as it begins: the
whole survey "completed" at t = 0), and a plant started above the surface (``down_0 =
-3`` for a depth of 3 m: depth is positive down).

Such a value is valid (the plant counts whole turns, a heading of 30 rad is a heading),
so it is not refused; a run that takes it says so in one warning line each, naming the
key, the value, and what it would be in radians. An angle of more than a full turn in a
variable declared in rad is the sign: degrees typed by habit are mostly beyond 2 pi
(10 to 90 deg), radians meant as such hardly ever are. The same holds for a rate in rad/s
(``r_0 = 10``, 10 deg/s typed by habit): beyond a full turn a second (2 pi rad/s) no
REMUS 100 turns, rolls or pitches. A variable in rad/s that declares another quantity
than an angle's or a turn rate's (FMI 2.0 ``quantity``: ``"AngularFrequency"``, a filter's
or a servo's natural frequency, 10 rad/s by default) is no turn rate, and typed in rad/s
by habit: none is doubted.
"""

from __future__ import annotations

import itertools
import math
import sys
import warnings
from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING, Any

from cosim.fmus.interface import ANGLE_QUANTITIES

if TYPE_CHECKING:
    from cosim.fmus.interface import Variable
    from cosim.scenario.spec import Scenario

FULL_TURN_RAD = 2.0 * math.pi
ANGLE_UNIT = "rad"
RATE_UNIT = "rad/s"


class UnitWarning(UserWarning):
    """A value that is valid but looks like another unit than the variable's."""


def angle_doubts(scenario: Scenario) -> list[str]:
    """One line for each value of ``scenario`` given to (or compared with) a variable
    in rad that is more than a full turn, or in rad/s more than a full turn a second:
    start values, events' ``set`` values, ``when`` thresholds and series columns (their
    largest value), bias and noise faults' ``value`` and ``std``."""

    def variable(ref: str) -> Variable | None:
        instance, _, name = ref.partition(".")
        inst = scenario.instances.get(instance)
        return None if inst is None else inst.interface.variables.get(name)

    found = [
        variable_doubt(key, variable(ref), value) for key, ref, value in given_values(scenario)
    ]
    return [line for line in found if line is not None]


def given_values(scenario: Scenario, faults: bool = True) -> Iterator[tuple[str, str, Any]]:
    """(key, ``<instance>.<variable>``, value) of every value ``scenario`` gives a variable
    or compares it with: start values, events' ``set`` values, ``when`` thresholds and
    series columns (their largest value), and with ``faults`` bias and noise faults'
    ``value`` and ``std``."""
    for name, inst in scenario.instances.items():
        for variable, value in inst.start.items():
            yield f"instances.{name}.start.{variable}", f"{name}.{variable}", value
    for event in scenario.events:
        for ref, value in event.set.items():
            yield f"events.{event.name}.set.{ref}", ref, value
        if event.when is not None:
            yield f"events.{event.name}.when", event.when.ref, event.when.threshold
        if event.series is not None:  # a profile's largest value, column by column
            for ref, column in event.series.columns.items():
                largest = max(column, key=abs, default=0.0)
                yield f"events.{event.name}.series column {ref}", ref, largest
    for fault in scenario.faults if faults else ():
        if fault.kind == "bias":
            yield f"faults.{fault.name}.value", fault.target, fault.value
        if fault.kind == "noise":
            yield f"faults.{fault.name}.std", fault.target, fault.std


def stroke_doubts(scenario: Scenario) -> list[str]:
    """One line for each moving-mass command or start position of a plant (``AuvPlant``)
    beyond the mass's stroke (the ``mass_stroke`` of the set it runs: its vehicle set's, or
    the value written over it): the rail stops hold the mass there, so 6 for 6 cm runs as
    the 0.06 m stop, reached faster."""
    from cosim.scenario.spec import plant_vehicle

    strokes = {
        name: plant_vehicle(str(scenario.start_value(name, "vehicle")), inst.start).mass_stroke
        for name, inst in scenario.instances.items()
        if inst.interface.model_identifier == "AuvPlant"
    }
    found = []
    for key, ref, value in given_values(scenario, faults=False):  # commands, not offsets
        instance, _, variable = ref.partition(".")
        stroke = strokes.get(instance)
        if stroke is None or variable != "mass_position_cmd" or not isinstance(value, float):
            continue
        if abs(value) > stroke:
            in_cm = abs(value) <= 100 * stroke  # then it reads as cm within the stroke
            meant = f"; if {value:g} cm was meant, give {value / 100:g}" if in_cm else ""
            found.append(
                f"{key} = {value:g} m is beyond the moving mass's stroke of {stroke:g} m: the "
                f"rail stops hold the mass there (lengths are in metres{meant})"
            )
    return found


def depth_doubts(scenario: Scenario) -> list[str]:
    """One line for each plant (``AuvPlant``) started above the surface, ``down_0`` < 0 m: a
    depth written with the sign of an altitude (depth is positive down, NED; the plant has
    no free surface, so it runs, as deep water)."""
    found = []
    for name, inst in scenario.instances.items():
        value = inst.start.get("down_0")
        if inst.interface.model_identifier != "AuvPlant" or not isinstance(value, float):
            continue
        if value < 0.0:
            found.append(
                f"instances.{name}.start.down_0 = {value:g} m is above the surface: depths "
                f"are positive down (NED); if a depth of {-value:g} m was meant, give "
                f"{-value:g} (the plant has no free surface)"
            )
    return found


def when_doubts(scenario: Scenario) -> list[str]:
    """One line for each ``when`` event on a plant's (``AuvPlant``) state whose comparison
    holds at its start value (``yaw`` and ``yaw_0``): it fires only when the comparison
    turns true, so not until the value has gone back across the threshold first. The
    slip it names: a heading compared as a compass reads it (``plant.yaw > 0.6`` on a
    vehicle started at 350 deg, 6.109 rad), where the yaw counts whole turns."""
    found = []
    for event in scenario.events:
        if event.when is None:
            continue
        instance, _, variable = event.when.ref.partition(".")
        inst = scenario.instances.get(instance)
        if inst is None or inst.interface.model_identifier != "AuvPlant":
            continue
        start_name = f"{variable}_0"
        start = scenario.start_value(instance, start_name)
        if not isinstance(start, float) or not event.when.holds(start):
            continue
        var = inst.interface.variables.get(variable)
        turned = ""
        if var is not None and var.unit == ANGLE_UNIT and abs(start) > math.pi:
            other, which = (start - FULL_TURN_RAD, "before") if start > 0 else (
                start + FULL_TURN_RAD, "after")  # fmt: skip
            turned = (
                f"; angles count whole turns ({start:.4g} rad is {other:.4g} on the turn {which})"
            )
        found.append(
            f"events.{event.name}.when = '{event.when}' holds from the start "
            f"({instance}.{start_name} = {start:.4g}{f' {var.unit}' if var and var.unit else ''}"
            f"): a when event fires when its comparison turns true, so this one waits for "
            f"the value to go back across {event.when.threshold!r} first{turned}"
        )
    return found


def doubts(scenario: Scenario) -> list[str]:
    """Every doubt of ``scenario``: :func:`angle_doubts`, :func:`stroke_doubts`,
    :func:`radius_doubts`, :func:`depth_doubts` and :func:`when_doubts`."""
    return (
        angle_doubts(scenario)
        + stroke_doubts(scenario)
        + radius_doubts(scenario)
        + depth_doubts(scenario)
        + when_doubts(scenario)
    )


def radius_doubts(scenario: Scenario) -> list[str]:
    """One line for each guidance (``AuvGuidance``) whose acceptance radius is not shorter
    than every leg of its mission: such a leg is completed as soon as it begins."""
    from controller_fmu.los_guidance import parse_waypoints

    found = []
    for name, inst in scenario.instances.items():
        if inst.interface.model_identifier != "AuvGuidance":
            continue
        radius = float(scenario.start_value(name, "acceptance_radius"))  # type: ignore[arg-type]
        waypoints = parse_waypoints(str(scenario.start_value(name, "waypoints")))
        lengths = [math.dist((a.north, a.east), (b.north, b.east))
                   for a, b in itertools.pairwise(waypoints)]  # fmt: skip
        short = [k for k, length in enumerate(lengths, 1) if length <= radius]
        if short:
            found.append(
                f"instances.{name}.start.acceptance_radius = {radius:g} m is not shorter "
                f"than leg {short[0]} ({lengths[short[0] - 1]:.4g} m, waypoint {short[0]} -> "
                f"{short[0] + 1}){f' and {len(short) - 1} more' if len(short) > 1 else ''}: "
                "a leg whose start lies in its end's acceptance circle is completed as soon "
                f"as it begins; the shortest leg is {min(lengths):.4g} m"
            )
    return found


def variable_doubt(key: str, var: Variable | None, value: Any) -> str | None:
    """:func:`value_doubt` of ``key`` = ``value`` given to ``var``, by its unit, unless it
    declares a quantity that is neither an angle nor a turn rate (``ANGLE_QUANTITIES``:
    a natural frequency in rad/s is no turn rate); None for no such variable."""
    if var is None or (var.quantity is not None and var.quantity not in ANGLE_QUANTITIES):
        return None
    return value_doubt(key, var.unit, value)


def value_doubt(key: str, unit: str | None, value: Any) -> str | None:
    """The warning for ``key`` = ``value`` given to a variable of ``unit``, if it is an
    angle in rad of more than a full turn or a rate in rad/s of more than a full turn a
    second; else None."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    if unit == ANGLE_UNIT and abs(value) > FULL_TURN_RAD:
        return doubt_line(key, value)
    if unit == RATE_UNIT and abs(value) > FULL_TURN_RAD:
        return rate_doubt_line(key, value)
    return None


def doubt_line(key: str, value: float) -> str:
    """The warning for ``key`` = ``value`` (rad) beyond a full turn."""
    return (
        f"{key} = {value:g} rad is more than a full turn ({math.degrees(value):.0f} deg): "
        f"angles are in radians; if {value:g} deg was meant, give {math.radians(value):.6g}"
    )


def rate_doubt_line(key: str, value: float) -> str:
    """The warning for ``key`` = ``value`` (rad/s) beyond a full turn a second."""
    return (
        f"{key} = {value:g} rad/s is more than a full turn a second "
        f"({math.degrees(value):.0f} deg/s): rates are in radians per second; if {value:g} "
        f"deg/s was meant, give {math.radians(value):.6g}"
    )


def warn(lines: Iterable[str], category: type[UserWarning] = UnitWarning) -> None:
    """Each line once, as a ``category`` warning pointing at the caller's own code (the
    first frame outside this package: a script's ``cosim.run(...)`` line, not ours)."""
    level, frame = 2, sys._getframe(1)  # 2: the frame that called this one
    while frame is not None and frame.f_globals.get("__name__", "").startswith("cosim"):
        level, frame = level + 1, frame.f_back  # type: ignore[assignment]
    for line in dict.fromkeys(lines):
        warnings.warn(line, category, stacklevel=level)
