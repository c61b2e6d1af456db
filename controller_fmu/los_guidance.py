"""Waypoint missions: line-of-sight (LOS) guidance for heading and depth.

A mission is a list of waypoints ``(north, east, down)`` in metres (NED, earth frame); leg
k runs from waypoint k to waypoint k + 1. At each sample the guidance reads the vehicle's
position and returns the heading, course and depth set-points of the active leg
(lookahead-based steering, T. I. Fossen, *Handbook of Marine Craft Hydrodynamics and
Motion Control*, Wiley 2011, the chapter on guidance systems; integral LOS after Borhaug,
Pavlov and Pettersen, "Integral LOS control for path following of underactuated marine
surface vessels in the presence of constant ocean currents", IEEE CDC 2008):

* path-tangential angle of leg k: ``alpha = atan2(east_k+1 - east_k, north_k+1 - north_k)``;
* along-track distance and cross-track error, the position in the leg's frame::

      s = (n - n_k) cos(alpha) + (e - e_k) sin(alpha)
      y = -(n - n_k) sin(alpha) + (e - e_k) cos(alpha)    (> 0: starboard of the leg)

* desired course over ground, with lookahead ``Delta`` and integral gain ``kappa`` (0 gives
  the proportional LOS law ``alpha - atan(y / Delta)``)::

      chi_d = alpha - atan((y + kappa y_int) / Delta)
      y_int' = Delta y / (Delta^2 + (y + kappa y_int)^2)

  ``y_int`` is advanced once per sample (explicit Euler over the step, the guidance being a
  sampled system) and restarts at 0 on every new leg: the crab angle the integral learns
  belongs to the leg's direction relative to the current;
* desired heading: ``psi_d = chi_d`` or, with the current compensation of the dissertation
  (6.3.74) (``compensate_current``), ``psi_d = chi_d - beta``, the crab angle from the
  measured current and the design speed (:func:`controller_fmu.setpoint_shaping.desired_heading`,
  the function the autopilot uses, so the two agree exactly). Both set-points are given
  on the branch nearest the measured yaw, ``psi + wrap(psi_d - psi)``: the plant's yaw is
  continuous (it counts whole turns), and so are the set-points then, while the autopilot,
  which wraps the heading error, sees the same error as with wrapped angles;
* depth: the depth of the path at the lookahead point,
  ``z_d = z_k + (z_k+1 - z_k) clip((s + Delta) / L, 0, 1)`` with L the leg's horizontal
  length. The autopilot's depth loop tracks a depth, not a flight-path angle, so the
  vertical LOS law hands it the path's depth one lookahead ahead (a ramp between two
  waypoints of different depths, a constant on a level leg);
* switching: the next leg becomes active once the vehicle is within the acceptance radius
  of the active leg's end (horizontal distance, Fossen's circle of acceptance) or has
  passed it along the track (``s >= L``). The second test is ours: a vehicle whose turning
  circle is wider than the acceptance circle would otherwise circle back for a waypoint it
  missed. After the last waypoint the guidance keeps steering along the last leg, extended.

Units: m, rad, s. The waypoint text and every parameter are validated on construction, and
every error names the bad entry and what was expected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

from controller_fmu.setpoint_shaping import desired_heading, wrap_angle
from plant_fmu.model.validated import CheckedRecord, checked_field

DEFAULT_WAYPOINTS = "0, 0, 0; 100, 0, 0"
WAYPOINT_FORMAT = "'north, east, down' (three numbers in m, NED)"


class GuidanceConfigError(ValueError):
    """A waypoint or guidance parameter is invalid (the message names it and why)."""


@dataclass(frozen=True)
class Waypoint:
    """A point of the planned path, earth frame (NED), m."""

    north: float
    east: float
    down: float


def parse_waypoints(text: str) -> tuple[Waypoint, ...]:
    """The waypoints of ``"north, east, down; north, east, down; ..."`` (m, NED).

    Entries are separated by ``;`` (a trailing ``;`` is allowed), numbers by ``,``;
    whitespace and newlines are ignored.

    Raises:
        GuidanceConfigError: naming the first bad entry (its number and text): not three
            finite numbers, a depth above the surface (down < 0), fewer than two
            waypoints, or a waypoint at the same north and east as the one before it (a
            leg needs a horizontal direction).
    """
    entries = [entry.strip() for entry in str(text).split(";")]
    if entries and not entries[-1]:
        entries.pop()
    waypoints: list[Waypoint] = []
    for number, entry in enumerate(entries, start=1):
        waypoint = _parse_entry(number, entry)
        if waypoints and _horizontal_distance(waypoints[-1], waypoint) == 0.0:
            raise GuidanceConfigError(
                f"waypoint {number} ({entry!r}) is at the same north and east as waypoint "
                f"{number - 1}: expected a horizontal distance > 0 between consecutive "
                "waypoints (a leg needs a direction)"
            )
        waypoints.append(waypoint)
    if len(waypoints) < 2:
        raise GuidanceConfigError(
            f"waypoints {text!r}: expected at least two entries {WAYPOINT_FORMAT} "
            f"separated by ';', got {len(waypoints)}"
        )
    return tuple(waypoints)


def _parse_entry(number: int, entry: str) -> Waypoint:
    parts = [part.strip() for part in entry.split(",")]
    if len(parts) != 3:
        raise GuidanceConfigError(
            f"waypoint {number} ({entry!r}): expected {WAYPOINT_FORMAT}, got {len(parts)} "
            f"value{'s' if len(parts) != 1 else ''}"
        )
    values = []
    for axis, part in zip(("north", "east", "down"), parts):
        try:
            value = float(part)
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise GuidanceConfigError(
                f"waypoint {number} ({entry!r}): {axis} = {part!r} is not a finite number "
                f"of metres; expected {WAYPOINT_FORMAT}"
            )
        values.append(value)
    if values[2] < 0.0:
        raise GuidanceConfigError(
            f"waypoint {number} ({entry!r}): down = {values[2]!r} m is above the surface; "
            "expected a depth >= 0 m (NED, down positive: the plant has no free surface)"
        )
    return Waypoint(*values)


def _horizontal_distance(a: Waypoint, b: Waypoint) -> float:
    return math.hypot(b.north - a.north, b.east - a.east)


@dataclass(frozen=True)
class GuidanceConfig(CheckedRecord):
    """Every parameter of the guidance (SI). Field names are the FMU parameter names.

    Validated and immutable (:class:`plant_fmu.model.validated.CheckedRecord`); the
    waypoints are parsed to check them."""

    error_type = GuidanceConfigError
    unknown_key = "unknown guidance parameter {name!r}"

    waypoints: str = checked_field(
        default=DEFAULT_WAYPOINTS,
        description="the mission: waypoints 'north, east, down; ...' in m (NED), at least "
        "two; leg k runs from waypoint k to waypoint k+1",
        check=parse_waypoints,
        standalone=True,  # its message names the waypoint and what was expected
    )
    lookahead: float = checked_field(
        default=8.0,
        gt=0.0,
        description="LOS lookahead distance Delta along the leg",
        unit="m",
    )
    acceptance_radius: float = checked_field(
        default=5.0,
        gt=0.0,
        description="radius of acceptance: the next leg starts within it of the leg's end "
        "(or once past the end along the track)",
        unit="m",
    )
    integral_gain: float = checked_field(
        default=0.0,
        ge=0.0,
        description="integral LOS gain kappa on the cross-track error (0: proportional LOS)",
        unit="1",
    )
    compensate_current: bool = checked_field(
        default=False,
        description="head into the measured current by the crab angle, psi_d = chi_d - beta "
        "(6.3.74); leave the autopilot's compensate_current off then",
    )
    design_speed: float = checked_field(
        default=1.525,
        gt=0.0,
        description="U0: speed through the water the crab angle is computed for (6.3.74)",
        unit="m/s",
    )

    @classmethod
    def build(cls, **values: Any) -> GuidanceConfig:
        """Validate ``values``; raise :class:`GuidanceConfigError` naming every bad one."""
        return cls.from_mapping(values)


def field_unit(name: str) -> str:
    """The unit of a :class:`GuidanceConfig` field ('' for text and switches)."""
    return GuidanceConfig.field_info()[name].unit


@dataclass(frozen=True)
class LegPosition:
    """Where the vehicle is relative to a leg: the leg's angle alpha (rad), its horizontal
    length L (m), the along-track distance s and the cross-track error y (m, > 0 to
    starboard of the leg's direction)."""

    alpha: float
    length: float
    along_track: float
    cross_track: float


def leg_position(start: Waypoint, end: Waypoint, north: float, east: float) -> LegPosition:
    """The vehicle at (north, east) in the frame of the leg start -> end (module docstring)."""
    d_north, d_east = end.north - start.north, end.east - start.east
    alpha = math.atan2(d_east, d_north)
    c, s = math.cos(alpha), math.sin(alpha)
    p_north, p_east = north - start.north, east - start.east
    return LegPosition(
        alpha=alpha,
        length=math.hypot(d_north, d_east),
        along_track=p_north * c + p_east * s,
        cross_track=-p_north * s + p_east * c,
    )


@dataclass(frozen=True)
class GuidanceState:
    """What the guidance remembers between samples: the active leg (index of its start
    waypoint), the legs completed so far and the integral of the cross-track error (m s)."""

    leg: int = 0
    legs_completed: int = 0
    integral: float = 0.0


@dataclass(frozen=True)
class GuidanceOutput:
    """The set-points held over one sample, and what the guidance saw."""

    yaw_setpoint: float  # psi_d, rad, within pi of the measured yaw
    course_setpoint: float  # chi_d, rad, within pi of the measured yaw
    depth_setpoint: float  # z_d, m
    cross_track_error: float  # y on the active leg, m (> 0: starboard of the leg)
    legs_completed: int
    target: Waypoint  # the active leg's end


class LosGuidance:
    """The LOS guidance of one mission (module docstring); all state in :attr:`state`.

    Args:
        config: a :class:`GuidanceConfig` (its waypoints are parsed here).
    """

    def __init__(self, config: GuidanceConfig) -> None:
        self.config = config
        self.waypoints = parse_waypoints(config.waypoints)
        self.state = GuidanceState()

    @property
    def n_legs(self) -> int:
        return len(self.waypoints) - 1

    def step(
        self,
        north: float,
        east: float,
        current_north: float = 0.0,
        current_east: float = 0.0,
        step: float = 0.0,
        yaw: float = 0.0,
    ) -> GuidanceOutput:
        """The set-points for the vehicle at (north, east), m; the state then advances over
        ``step`` seconds (0: evaluate without integrating, e.g. at initialisation).

        ``current_north``, ``current_east`` (m/s, earth frame) are the measured current,
        used with ``compensate_current`` only; ``yaw`` (rad) the measured heading, whose
        branch the angles are given on.

        Raises:
            ValueError: a non-finite input or step, or (with ``compensate_current``) a
                cross-current at least as fast as the design speed. The state is then
                unchanged.
        """
        for name, value in (("north", north), ("east", east), ("current_north", current_north),
                            ("current_east", current_east), ("yaw", yaw)):  # fmt: skip
            if not math.isfinite(value):
                raise ValueError(f"{name} = {value!r}: expected a finite number")
        if not (math.isfinite(step) and step >= 0.0):
            raise ValueError(f"step = {step!r} s: expected a finite number >= 0")
        state = self._switched(self.state, north, east)
        start, end = self.waypoints[state.leg], self.waypoints[state.leg + 1]
        where = leg_position(start, end, north, east)
        c = self.config
        corrected = where.cross_track + c.integral_gain * state.integral
        chi_d = wrap_angle(where.alpha - math.atan(corrected / c.lookahead))
        psi_d = desired_heading(
            chi_d, current_north, current_east, c.design_speed, c.compensate_current
        )
        fraction = min(max((where.along_track + c.lookahead) / where.length, 0.0), 1.0)
        output = GuidanceOutput(
            yaw_setpoint=yaw + wrap_angle(psi_d - yaw),
            course_setpoint=yaw + wrap_angle(chi_d - yaw),
            depth_setpoint=start.down + (end.down - start.down) * fraction,
            cross_track_error=where.cross_track,
            legs_completed=state.legs_completed,
            target=end,
        )
        if c.integral_gain > 0.0 and step > 0.0:
            state = replace(state, integral=state.integral + step * _integral_rate(
                c.lookahead, where.cross_track, corrected))  # fmt: skip
        self.state = state
        return output

    def _switched(self, state: GuidanceState, north: float, east: float) -> GuidanceState:
        """The state after every waypoint switch the position at (north, east) triggers."""
        while state.legs_completed < self.n_legs:
            end = self.waypoints[state.leg + 1]
            where = leg_position(self.waypoints[state.leg], end, north, east)
            inside = math.hypot(north - end.north, east - end.east) <= self.config.acceptance_radius
            if not (inside or where.along_track >= where.length):
                break
            completed = state.legs_completed + 1
            leg = min(state.leg + 1, self.n_legs - 1)
            integral = 0.0 if leg != state.leg else state.integral
            state = GuidanceState(leg=leg, legs_completed=completed, integral=integral)
        return state


def _integral_rate(lookahead: float, cross_track: float, corrected: float) -> float:
    """The integral LOS state's rate, 1 (m/s per m/s of the step),
    lookahead * cross_track / (lookahead^2 + corrected^2), with ``corrected`` the
    cross-track error plus integral_gain times the integral (m). Past |corrected| = 1e154
    its square overflows (a float's ``**`` raises): there the same quotient through the
    hypotenuse, which does not (and is as good as 0)."""
    try:
        return lookahead * cross_track / (lookahead**2 + corrected**2)
    except OverflowError:
        hypotenuse = math.hypot(lookahead, corrected)
        return (lookahead / hypotenuse) * (cross_track / hypotenuse)
