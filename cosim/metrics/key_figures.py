"""Key figures of a run, computed as its rows stream by (no row is kept).

``yaw_settling_time_s``: the first time after which |yaw - yaw_setpoint| stays below
1 deg to the end of the run (angles compared on the circle), where the error crosses into
the band, interpolated linearly between the two rows around the crossing (so the figure
moves continuously with the step instead of by whole rows); None if the last sample is
outside the band, and for a run that did not complete (where the yaw stays after its
last row is not known). The setpoint is ``controller.yaw_setpoint`` if recorded, else 0 (with
the autopilot's ``compensate_current`` on, that set-point is the course; the heading then
settles off it by the crab angle, so the figure is None); a set-point a connection drives
and that is not recorded (a waypoint guidance's, which moves with the mission) gives no
settling time at all (``setpoint_driver``).
``peak_abs_mass_position_m``, ``peak_abs_tunnel_force_N``: the largest magnitudes
(``controller.tunnel_force``, else ``plant.tunnel_force``).
``mass_position_cmd_variation_m_per_s``, ``tunnel_force_variation_N_per_s``,
``fin_angle_variation_rad_per_s``: each actuator command's activity, its total variation
sum |c_k - c_(k-1)| over the rows divided by the simulated time they span (the command's
unit per s; the autopilot's output, else the plant's input): near 0 for a settled
command, large for one that chatters (vert-1's, a sliding-mode law's, a gain past the
loop's margins), whose plots a user would otherwise have to open; None over rows that span
no time (a run that stopped at its first row). A figure whose columns were not
recorded is None, and so is one that is not finite. ``plant`` and ``controller`` stand for
the instances running the plant and the autopilot, whatever a scenario names them
(``Scenario.key_instances``).

A scenario of several vehicles (two or more instances of the plant FMU) has the figures of
each, named after its plant, ``<plant>.yaw_settling_time_s`` and so on, each read with the
autopilot a connection joins to that plant (:func:`vehicles`, :class:`FleetKeyFigures`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from typing import NamedTuple

import numpy as np

YAW_TOLERANCE_RAD = math.radians(1.0)  # "settled" band of the yaw settling time
ROLES = {"plant": "plant", "controller": "controller"}  # role -> instance, as the built-ins
MODELS = {"plant": "AuvPlant", "controller": "AuvAutopilot"}  # role -> model identifier
TIME_DECIMALS = 9  # a time the metrics take from rows, to the ns (the recording's sim_time)


def row_time(time: float) -> float:
    """A row's time (s), or a mean of times taken between rows, rounded to
    :data:`TIME_DECIMALS`: row k's time is k * h in doubles, 0.35000000000000003 for
    35 x 0.01 s (docs/runs.md), which a figure shows as 0.35 s, as :func:`elapsed` does."""
    return round(float(time), TIME_DECIMALS)


def elapsed(end: float, start: float) -> float:
    """The time (s) from ``start`` to ``end``, rounded to :data:`TIME_DECIMALS`.

    Row times are k * h in doubles, so their difference carries the doubles' noise
    (8.21 - 1.0 is 7.210000000000001); docs/runs.md matches times to the ns, as here.
    """
    return round(end - start, TIME_DECIMALS)


def settling_time(
    times: np.ndarray, error: np.ndarray, tolerance: float, angle: bool = False
) -> float | None:
    """First time after which |error| < tolerance to the end; None if the end is outside.

    The time is where |error| crosses ``tolerance`` on the line between the last sample
    outside and the first inside (the first sample's time if every sample is inside).
    With ``angle`` the error is wrapped to (-pi, pi] first.
    """
    tracker = SettlingTime(tolerance, angle)
    tracker.add(np.asarray(times), np.asarray(error))
    return tracker.value


class SettlingTime:
    """:func:`settling_time` over a series given in consecutive pieces."""

    def __init__(self, tolerance: float, angle: bool = False) -> None:
        self.tolerance = tolerance
        self.angle = angle
        self.since: float | None = None  # start of the current run of samples inside
        self.pending = True  # the last sample seen was outside (or none seen yet)
        self.last: tuple[float, float] | None = None  # (t, |error|) of the last sample

    def add(self, times: np.ndarray, error: np.ndarray) -> None:
        if times.size == 0:
            return
        if self.angle:
            error = np.angle(np.exp(1j * error))
        magnitude = np.abs(error)
        outside = np.flatnonzero(~(magnitude < self.tolerance))
        if outside.size == 0:
            if self.pending:
                self.since = self._entry(self.last, float(times[0]), float(magnitude[0]))
                self.pending = False
        elif outside[-1] == len(times) - 1:
            self.since, self.pending = None, True
        else:
            i = int(outside[-1])
            before = (float(times[i]), float(magnitude[i]))
            self.since = self._entry(before, float(times[i + 1]), float(magnitude[i + 1]))
            self.pending = False
        self.last = (float(times[-1]), float(magnitude[-1]))

    def _entry(self, before: tuple[float, float] | None, t: float, inside: float) -> float:
        """Where the error enters the band between the sample ``before`` (outside; None:
        there was none) and the sample (t, ``inside``)."""
        if before is None or not math.isfinite(before[1]):
            return t
        t0, outside = before
        return t0 + (t - t0) * (outside - self.tolerance) / (outside - inside)

    @property
    def value(self) -> float | None:
        return None if self.pending else self.since


class TotalVariation:
    """A command's total variation sum |c_k - c_(k-1)| per simulated second over the rows
    it is given in consecutive pieces (numpy's diff per piece, the piece before's last
    value carried over). The sum is math.fsum's, carried from piece to piece as the
    rounded total and its remainder, so it is the same however a run's rows are cut
    into pieces (a plain running sum rounds differently per cut)."""

    def __init__(self) -> None:
        self.total = (0.0, 0.0)  # the sum and its remainder, the command's unit
        self.last: float | None = None  # the previous piece's last value
        self.span: tuple[float, float] | None = None  # first and last time, s

    def add(self, times: np.ndarray, values: np.ndarray) -> None:
        if not len(times):
            return
        before = [] if self.last is None else [self.last]
        steps = np.abs(np.diff(np.concatenate([before, values]))).tolist()
        rounded = math.fsum([*self.total, *steps])
        finite = math.isfinite(rounded)  # an inf's remainder (inf - inf) is not a number
        self.total = (rounded, math.fsum([*self.total, *steps, -rounded]) if finite else 0.0)
        self.last = float(values[-1])
        start = float(times[0]) if self.span is None else self.span[0]
        self.span = (start, float(times[-1]))

    @property
    def value(self) -> float | None:
        """Unit of the command per s; None over no time spanned or if not finite."""
        if self.span is None or self.span[1] <= self.span[0]:
            return None
        return _finite(self.total[0] / (self.span[1] - self.span[0]))


_COLUMNS = {  # key figure -> the columns it is computed from (any one of them), by role
    "yaw_settling_time_s": (("plant", "yaw"),),
    "peak_abs_mass_position_m": (("plant", "mass_position"),),
    "peak_abs_tunnel_force_N": (("controller", "tunnel_force"), ("plant", "tunnel_force")),
    "mass_position_cmd_variation_m_per_s": (
        ("controller", "mass_position_cmd"),
        ("plant", "mass_position_cmd"),
    ),
    "tunnel_force_variation_N_per_s": (("controller", "tunnel_force"), ("plant", "tunnel_force")),
    "fin_angle_variation_rad_per_s": (("controller", "fin_angle"), ("plant", "fin_angle")),
}
MASS_COMMAND_ACTIVITY = "mass_position_cmd_variation_m_per_s"  # the moving mass's command's
ACTIVITY_FIGURES = (  # the commands' total variation per simulated second
    MASS_COMMAND_ACTIVITY,
    "tunnel_force_variation_N_per_s",
    "fin_angle_variation_rad_per_s",
)


def _columns(name: str, roles: dict[str, str]) -> list[str]:
    """The columns the key figure ``name`` is computed from, of the instances ``roles``."""
    return [f"{roles[role]}.{variable}" for role, variable in _COLUMNS.get(name, ())]


def why_none(
    name: str,
    columns: tuple[str, ...] | list[str],
    roles: dict[str, str] = ROLES,
    complete: bool = True,
    setpoint_driver: str | None = None,
    spanned: bool = True,
) -> str:
    """Why the key figure ``name`` of a run recording ``columns`` is None, in a few words:
    its columns were not recorded, its yaw set-point moves (``setpoint_driver``, as for
    :class:`KeyFigures`), the run did not complete, the yaw never settled into its band,
    or (not ``spanned``: the run's rows span no time, its one row at its start) a
    command's activity, a rate, has no two rows to be taken over."""
    if not any(column in columns for column in _columns(name, roles)):
        return "not recorded"
    if name in ACTIVITY_FIGURES and not spanned:
        return "none: the rows span no time (a rate needs two)"
    setpoint = f"{roles['controller']}.yaw_setpoint"
    if name == "yaw_settling_time_s" and _moving(setpoint, columns, setpoint_driver):
        return (
            f"not measured: {setpoint} follows {setpoint_driver}, a set-point that moves (a "
            "mission's tracking: its survey metrics)"
        )
    if name == "yaw_settling_time_s" and not complete:
        return "none: the run did not complete"
    if name == "yaw_settling_time_s":
        band = f"{math.degrees(YAW_TOLERANCE_RAD):g} deg"
        if setpoint not in columns:  # no autopilot, or its set-point left out: held at 0
            return (
                f"not settled: the yaw is not within {band} of 0 at the end (0: {setpoint} "
                "is not recorded)"
            )
        return f"not settled: the yaw is not within {band} of its set-point at the end"
    return "not finite"


def _moving(setpoint: str, columns: Sequence[str], driver: str | None) -> bool:
    """Whether the yaw ``setpoint`` is driven by a connection from ``driver`` and not
    recorded: its value, which moves, is not known (it is not 0)."""
    return driver is not None and setpoint not in columns


class KeyFigures:
    """A row sink that keeps the key figures of the rows it is given (see the module).

    ``setpoint_driver``: the output a connection drives the controller's yaw set-point
    from, if one does (``Scenario.key_setpoint_source``); unrecorded, the set-point is
    then not known, and the yaw settling time is not measured."""

    def __init__(
        self,
        columns: tuple[str, ...] | list[str],
        roles: dict[str, str] = ROLES,
        setpoint_driver: str | None = None,
    ) -> None:
        index = {name: i for i, name in enumerate(columns)}

        def first(figure: str) -> int | None:  # the first of the figure's columns recorded
            return next((index[c] for c in _columns(figure, roles) if c in index), None)

        setpoint = f"{roles['controller']}.yaw_setpoint"
        moving = _moving(setpoint, columns, setpoint_driver)
        self._yaw = None if moving else first("yaw_settling_time_s")
        self._setpoint = index.get(setpoint)
        self._mass = first("peak_abs_mass_position_m")
        self._force = first("peak_abs_tunnel_force_N")
        self._settling = SettlingTime(YAW_TOLERANCE_RAD, angle=True)
        self._peaks = {"mass": -math.inf, "force": -math.inf}
        self._activity = {name: (first(name), TotalVariation()) for name in ACTIVITY_FIGURES}

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        if self._yaw is not None:
            setpoint = values[:, self._setpoint] if self._setpoint is not None else 0.0
            self._settling.add(times, values[:, self._yaw] - setpoint)
        for key, i in (("mass", self._mass), ("force", self._force)):
            if i is not None and len(times):  # np.max: a NaN anywhere makes the peak NaN
                peak = np.max(np.abs(values[:, i]))
                self._peaks[key] = float(np.max([self._peaks[key], peak]))
        for i, variation in self._activity.values():
            if i is not None:
                variation.add(times, values[:, i])

    def add_notes(self, notes: object) -> None:
        """Events and faults change no key figure: ``notes`` are dropped."""

    def names(self) -> tuple[str, ...]:
        """The figures the columns can give, in :meth:`figures`' order: the others stay
        None whatever the rows (a scenario of FMUs without the plant's yaw, mass or
        thruster force)."""
        columns = (self._yaw, self._mass, self._force, *(i for i, _ in self._activity.values()))
        return tuple(name for name, i in zip(self.figures(), columns, strict=True) if i is not None)

    def figures(self, complete: bool = True) -> dict[str, float | None]:
        """The figures of the rows so far (plain floats or None); of a run that did not
        complete, no settling time (its rows end before the run's end: where the yaw stays
        is not known), the peaks so far."""
        settled = self._settling.value if self._yaw is not None and complete else None
        return {
            "yaw_settling_time_s": settled,
            "peak_abs_mass_position_m": _finite(self._peaks["mass"]),
            "peak_abs_tunnel_force_N": _finite(self._peaks["force"]),
            **{name: variation.value for name, (_, variation) in self._activity.items()},
        }


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


class Vehicle(NamedTuple):
    """One vehicle's key figures: the ``prefix`` of their names ("" for the one vehicle of
    a scenario, else ``"<plant>."``), the instances of its ``roles`` and the output a
    connection drives its autopilot's yaw set-point from (``setpoint_driver``, if any)."""

    prefix: str
    roles: dict[str, str]
    setpoint_driver: str | None


def vehicles(
    models: Mapping[str, str | None], connections: Iterable[tuple[str, str]]
) -> list[Vehicle]:
    """The vehicles of a scenario whose instances run the FMUs ``models`` (instance ->
    model identifier) joined by ``connections`` ((source, target) references). One plant
    or none: one vehicle, the first plant and the first autopilot (the role's name where
    there is none). Several: one a plant, with the first autopilot a connection joins to
    it either way (none: a name no column has, so its autopilot's figures are None)."""
    links = [(s.split(".", 1)[0], t.split(".", 1)[0], s, t) for s, t in connections]
    drivers = {target: source for _, _, source, target in links}
    of = {role: [n for n, m in models.items() if m == model] for role, model in MODELS.items()}

    def vehicle(prefix: str, plant: str, controller: str) -> Vehicle:
        roles = {"plant": plant, "controller": controller}
        return Vehicle(prefix, roles, drivers.get(f"{controller}.yaw_setpoint"))

    if len(of["plant"]) <= 1:
        return [vehicle("", *(next(iter(of[r]), r) for r in ("plant", "controller")))]
    fleet = []
    for plant in of["plant"]:
        joined = {b if a == plant else a for a, b, _, _ in links if plant in (a, b)}
        controller = next((c for c in of["controller"] if c in joined), "")
        fleet.append(vehicle(f"{plant}.", plant, controller))
    return fleet


class FleetKeyFigures:
    """The key figures of several vehicles (:func:`vehicles`), each named with its
    vehicle's prefix, as a row sink like :class:`KeyFigures`."""

    def __init__(self, columns: tuple[str, ...] | list[str], fleet: Sequence[Vehicle]) -> None:
        self._each = [(v.prefix, KeyFigures(columns, v.roles, v.setpoint_driver)) for v in fleet]

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        for _, figures in self._each:
            figures.add_rows(times, values)

    def add_notes(self, notes: object) -> None:
        """Events and faults change no key figure: ``notes`` are dropped."""

    def names(self) -> tuple[str, ...]:
        """As :meth:`KeyFigures.names`, every vehicle's, prefixed."""
        return tuple(prefix + name for prefix, figures in self._each for name in figures.names())

    def figures(self, complete: bool = True) -> dict[str, float | None]:
        """As :meth:`KeyFigures.figures`, every vehicle's, prefixed."""
        return {
            prefix + name: value
            for prefix, figures in self._each
            for name, value in figures.figures(complete).items()
        }


def key_figures(
    columns: tuple[str, ...] | list[str], fleet: Sequence[Vehicle]
) -> KeyFigures | FleetKeyFigures:
    """The sink of the key figures of the vehicles ``fleet`` (:func:`vehicles`) from the
    rows of ``columns``: the plain names for one vehicle, prefixed for several."""
    if len(fleet) == 1 and not fleet[0].prefix:
        only = fleet[0]
        return KeyFigures(columns, only.roles, only.setpoint_driver)
    return FleetKeyFigures(columns, fleet)


def why_none_of(
    name: str,
    columns: tuple[str, ...] | list[str],
    fleet: Sequence[Vehicle],
    complete: bool = True,
    spanned: bool = True,
) -> str:
    """:func:`why_none` of the figure ``name`` of one of the vehicles ``fleet`` (the one
    whose prefix ``name`` starts with)."""
    v = next((v for v in fleet if v.prefix and name.startswith(v.prefix)), fleet[0])
    bare = name.removeprefix(v.prefix)
    return why_none(bare, columns, v.roles, complete, v.setpoint_driver, spanned)
