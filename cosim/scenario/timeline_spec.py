"""A scenario's ``[[events]]`` and ``[[faults]]``: as written (pydantic), resolved and checked.

Format (docs/events.md; every key checked, unknown keys are errors)::

    [[events]]
    name = "turn"              # optional plain name; default "event-<position>"; unique
    time = 20.0                # s; exactly one of time / when / series
    # when = "plant.yaw > 0.35"  # <instance>.<variable> (recorded or a connection's source)
    #                            # <, <=, > or >= a number: fires on a false -> true crossing
    # repeat = true            # only with when: every crossing [false: the first only]
    set = { "controller.yaw_setpoint" = 0.5 }   # unconnected inputs, tunable parameters
    # ramp = 5.0               # s: linearly from the present value (Real targets only)
    # series = "profile.csv"   # instead of time and set: header time,<instance.variable>,...
    # interpolation = "hold"   # series only: "hold" [default] or "linear"

    [[faults]]
    name = "jam"               # optional plain name; default "fault-<position>"; unique
    kind = "stuck"             # stuck | bias | gain | noise | delay | dropout (connections)
                               # mass-jam | thruster-off | plane-stuck (the plant's actuators)
    target = "plant.mass_position_cmd"  # connection faults: the target of a connection
    start = 3.0                # s [0]
    stop = 10.0                # s [never]
    # value (bias: offset, gain: factor), std + seed (noise), steps (delay),
    # probability + seed (dropout)

Nothing is evaluated: ``when`` is parsed with a regular expression. The resolved
:class:`Event` and :class:`Fault` are frozen; :func:`event_table` and :func:`fault_table`
write them back as TOML tables (``Scenario.to_toml``).
"""

from __future__ import annotations

import csv
import io
import itertools
import math
import operator
import os
import re
import stat
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from pathlib import Path
from typing import Any, Literal

from pydantic import Field, StrictBool, StrictFloat, StrictInt, StrictStr

from cosim.errors import counted, did_you_mean
from cosim.scenario.checks import (
    ReadOnly,
    Source,
    Strict,
    alias_key,
    aliased_target,
    check_value,
    split_ref,
)
from cosim.scenario.toml_file import not_utf8

ACTUATOR_FAULTS = {  # kind -> the plant input it acts on
    "mass-jam": "mass_position_cmd",
    "thruster-off": "tunnel_force",
    "plane-stuck": "fin_angle",
}
MASS_POSITION = "mass_position"  # the plant output a mass-jam holds the command at
_PLAIN = r"^[A-Za-z0-9_-]+$"
PLAIN_EVENT_NAME = _PLAIN  # an event's or fault's name (spec.PATTERN_WORDS says it)
MAX_DELAY_STEPS = 100_000_000  # a run's most communication steps (cosim.scenario.spec)
SERIES_MAX_BYTES = 64 << 20  # a series CSV larger than this is refused, not read
# "<instance>.<variable> <op> <number>": one comparison, nothing evaluated. The variable is
# whatever stands before the last "<op> <number>" (an FMU's names may hold spaces, commas
# and brackets: Modelica's "der(y, 2)"); it must then be one of the instance's variables.
_WHEN = re.compile(
    r"^\s*(?P<ref>[A-Za-z_]\w*\..+?)\s*(?P<op><=|>=|<|>)\s*"
    r"(?P<number>[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*$"
)
_OPERATORS: dict[str, Callable[[float, float], bool]] = {
    "<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge,
}  # fmt: skip
_FAULT_KEYS = {  # the optional keys each kind takes
    "stuck": set(), "bias": {"value"}, "gain": {"value"}, "noise": {"std", "seed"},
    "delay": {"steps"}, "dropout": {"probability", "seed"},
    "mass-jam": set(), "thruster-off": set(), "plane-stuck": set(),
}  # fmt: skip
_REQUIRED = {"bias": "value", "gain": "value", "noise": "std", "delay": "steps",
             "dropout": "probability"}  # fmt: skip
SetValue = StrictBool | StrictInt | StrictFloat | StrictStr
POINT_TOLERANCE = 1e-9  # of a step: a time within it of a communication point counts as it


class TimelineWarning(UserWarning):
    """A valid event or fault that a run never reaches: due after its stop time."""


class EventSpec(Strict):
    """One ``[[events]]`` table as written."""

    name: str | None = Field(default=None, pattern=_PLAIN)
    time: float | None = Field(default=None, ge=0.0, allow_inf_nan=False, description="s")
    when: str | None = None
    repeat: bool | None = None
    set: dict[str, SetValue] | None = None
    ramp: float | None = Field(default=None, gt=0.0, allow_inf_nan=False, description="s")
    series: str | None = Field(default=None, min_length=1)
    interpolation: Literal["hold", "linear"] | None = None


class FaultSpec(Strict):
    """One ``[[faults]]`` table as written."""

    name: str | None = Field(default=None, pattern=_PLAIN)
    kind: Literal[
        "stuck", "bias", "gain", "noise", "delay", "dropout",
        "mass-jam", "thruster-off", "plane-stuck",
    ]  # fmt: skip
    target: str | None = None
    start: float = Field(default=0.0, ge=0.0, allow_inf_nan=False, description="s")
    stop: float | None = Field(default=None, allow_inf_nan=False, description="s")
    value: float | None = Field(default=None, allow_inf_nan=False)
    std: float | None = Field(default=None, ge=0.0, allow_inf_nan=False)
    seed: int | None = Field(default=None, ge=0)
    steps: int | None = Field(default=None, ge=1, le=MAX_DELAY_STEPS)
    probability: float | None = Field(default=None, ge=0.0, le=1.0, allow_inf_nan=False)


@dataclass(frozen=True)
class Condition:
    """``ref op threshold``: true when the value of ``ref`` compares so with ``threshold``."""

    ref: str  # "<instance>.<variable>"
    op: Literal["<", "<=", ">", ">="]
    threshold: float

    def holds(self, value: float) -> bool:
        return _OPERATORS[self.op](value, self.threshold)

    def __str__(self) -> str:
        return f"{self.ref} {self.op} {self.threshold!r}"


@dataclass(frozen=True)
class Series:
    """A CSV profile: ``columns[ref][i]`` applies from ``times[i]`` (s, strictly increasing)."""

    path: Path  # absolute
    interpolation: Literal["hold", "linear"]
    times: tuple[float, ...]
    columns: Mapping[str, tuple[float, ...]]


@dataclass(frozen=True)
class Event:
    """One resolved event: at ``time``, on the crossing of ``when``, or a ``series``."""

    name: str
    time: float | None = None  # s
    when: Condition | None = None
    repeat: bool = False
    set: Mapping[str, bool | int | float | str] = field(default_factory=dict)
    ramp: float | None = None  # s
    series: Series | None = None

    def targets(self) -> tuple[str, ...]:
        """Every ``<instance>.<variable>`` this event writes."""
        return tuple(self.series.columns) if self.series is not None else tuple(self.set)


@dataclass(frozen=True)
class Fault:
    """One resolved fault on the input ``target`` (for actuator faults, the plant's input)."""

    name: str
    kind: str
    target: str  # "<instance>.<input>"
    start: float = 0.0  # s
    stop: float | None = None  # s, None: never
    value: float | None = None  # bias: offset; gain: factor
    std: float | None = None  # noise: standard deviation, the target's unit
    seed: int | None = None  # noise, dropout: numpy default_rng seed
    steps: int | None = None  # delay: communication steps of the target instance
    probability: float | None = None  # dropout
    hold_source: str | None = None  # mass-jam: "<plant>.mass_position"

    @property
    def actuator(self) -> bool:
        """An actuator fault: acts on the plant's input whether connected or not."""
        return self.kind in ACTUATOR_FAULTS

    def whole_run(self, stop_time: float) -> bool:
        """Active at every step of a run to ``stop_time`` (s): from t = 0, and stopping
        never or not before the stop time (at the stop time no step is taken)."""
        return self.start == 0.0 and (self.stop is None or self.stop >= stop_time)


EVENTS_HINT = "a scenario file's [[events]] (then cosim.load_scenario it)"


def point_slack(time: float, h: float) -> float:
    """How far (s) ``time`` (s) may lie from a communication point n ``h`` and count as it:
    :data:`POINT_TOLERANCE` of a step, or, late in a long run, four units of the last place
    of ``time``: a typed time and n h (or time / h and n) differ by their roundings, which
    pass 1e-9 of a step after 2**24 steps (47 h at 10 ms)."""
    return max(POINT_TOLERANCE * h, 4.0 * sys.float_info.epsilon * abs(time))


def first_point(time: float, h: float) -> int:
    """The first communication point n with n h >= ``time`` (s), within
    :func:`point_slack` of it (``h``: the step, s)."""
    return max(0, math.ceil((time - point_slack(time, h)) / h))


def step_decimals(h: float) -> int:
    """How many decimals the step ``h`` (s) is written with (0.04: 2, 0.5: 1, 1.0: 0)."""
    exponent = Decimal(repr(h)).normalize().as_tuple().exponent
    return -exponent if isinstance(exponent, int) and exponent < 0 else 0


def shown_time(t: float, h: float) -> float:
    """A communication point's time ``t`` = n ``h`` (s) as a user reads it: rounded to the
    decimals ``h`` is written with (163 x 0.04 s is 6.5200000000000005 s in floats, 6.52
    here). Only for what is shown or recorded for people; the stepping keeps n h."""
    decimals = step_decimals(h)
    return round(t, decimals) if decimals > 0 else t


def unreached(
    events: Sequence[Event],
    faults: Sequence[Fault],
    stop_time: float,
    step: float,
    grid: float | None = None,
) -> list[str]:
    """One line for each time event due after the last communication point of a run to
    ``stop_time`` (s, communication step ``step``, s), each series starting after it
    and each fault starting after it:
    valid, but the run ends before them (a run shortened by ``--stop-time``, or a time
    typed in the wrong unit), so they are never applied. And one for each fault whose
    start and stop lie between two points (``grid`` s apart, an adaptive run's; else
    ``step``): active at none (start <= t_n < stop), it never acts."""

    def late(time: float) -> bool:
        return first_point(time, step) > round(stop_time / step)

    stop = f"the stop time ({stop_time:g} s)"
    lines = [
        f"events.{event.name}.time = {event.time:g} s is after {stop}: the run ends before "
        "the event, which is never applied"
        for event in events
        if event.time is not None and late(event.time)
    ] + [
        f"events.{event.name}: series {event.series.path.name} starts at "
        f"{event.series.times[0]:g} s, after {stop}: the run ends before the series, "
        "which is never applied"
        for event in events
        if event.series is not None and late(event.series.times[0])
    ]
    h = grid or step
    return lines + [
        f"faults.{fault.name}.start = {fault.start:g} s is after {stop}: the run ends "
        "before the fault, which never acts"
        if late(fault.start)
        else f"faults.{fault.name}: start = {fault.start:g} s and stop = {fault.stop:g} s lie "
        f"between two communication points ({h:g} s apart): the fault is active at none, "
        "and never acts"
        for fault in faults
        if late(fault.start)
        or (fault.stop is not None and first_point(fault.start, h) == first_point(fault.stop, h))
    ]


def resolve_events(
    specs: Sequence[EventSpec],
    scenario: Any,
    base_dir: Path,
    src: Source,
) -> tuple[Event, ...]:
    """Check and resolve ``[[events]]`` against the resolved ``scenario`` (its instances,
    connections, record and stop time); raises :class:`ScenarioError` naming the key."""
    events = []
    for i, spec in enumerate(specs):
        key = f"events[{i}]"
        name = spec.name or f"event-{i + 1}"
        triggers = [k for k in ("time", "when", "series") if getattr(spec, k) is not None]
        if len(triggers) != 1:
            raise src.error(
                key, f"has {triggers or 'none'} of time / when / series: expected exactly one"
            )
        _check_event_keys(spec, key, src)
        when = _condition(spec.when, scenario, f"{key}.when", src) if spec.when else None
        series = _series(spec, scenario, base_dir, f"{key}.series", src) if spec.series else None
        values = {
            ref: event_value(ref, value, scenario, f"{key}.set.{ref}", spec.ramp is not None, src)
            for ref, value in (spec.set or {}).items()
        }
        _check_set_once(values, scenario, f"{key}.set", src)
        shown = ReadOnly(values, f"{key}.set", EVENTS_HINT)
        event = Event(name, spec.time, when, bool(spec.repeat), shown, spec.ramp, series)
        events.append(event)
    _unique([e.name for e in events], [s.name for s in specs], "events", src)
    return tuple(events)


def _check_set_once(values: Mapping[str, Any], scenario: Any, key: str, src: Source) -> None:
    """Refuse an event that sets two names of one variable (aliases): it would set it
    twice, the last silently winning."""
    first: dict[tuple[str, str, int], str] = {}
    for ref in values:
        instance, _, variable = ref.partition(".")
        var = scenario.instances[instance].interface.variables[variable]
        other = first.setdefault((instance, *alias_key(var)), ref)
        if other != ref:
            raise src.error(
                f"{key}.{ref}",
                f"{ref} and {other} are one variable (the same value reference): set one of them",
            )


def _check_event_keys(spec: EventSpec, key: str, src: Source) -> None:
    if spec.repeat is not None and spec.when is None:
        raise src.error(f"{key}.repeat", f"{spec.repeat!r}: repeat is only for a `when` event")
    if spec.series is None:
        if not spec.set:
            raise src.error(f"{key}.set", "missing or empty: a time or when event sets values")
        if spec.interpolation is not None:
            raise src.error(
                f"{key}.interpolation", f"{spec.interpolation!r}: only for a series event"
            )
    else:
        for other in ("set", "ramp"):
            if getattr(spec, other) is not None:
                raise src.error(f"{key}.{other}", "not with series (the file holds the values)")


def _condition(text: str, scenario: Any, key: str, src: Source) -> Condition:
    match = _WHEN.fullmatch(text)
    instance, _, variable = match["ref"].partition(".") if match else ("", "", "")
    known = scenario.instances.get(instance)
    unknown = known is not None and variable not in known.interface.variables
    # an unknown "variable" holding a comparison is a second one ("x > 1 < 2"); any other
    # is a mistyped name, which split_ref names with the nearest one
    if match is None or (unknown and re.search(r"[<>]", variable)):
        raise src.error(
            key,
            f"{text!r} is not one comparison '<instance>.<variable> <op> <number>' with op "
            "one of <, <=, >, >=",
        )
    ref = match["ref"]
    _, var = split_ref(ref, scenario.instances, key, src)
    sources = {c.source for c in scenario.connections}
    if var.type != "Real":
        raise src.error(
            key,
            f"{ref!r} is {var.type}: a `when` compares a Real variable (recorded, or a "
            "connection's source)",
        )
    if ref not in scenario.record and ref not in sources:
        raise src.error(
            key, f"{ref!r} is neither a recorded Real variable nor a connection's source"
        )
    number = float(match["number"])
    if not math.isfinite(number):  # 1e999999 reads as inf: a crossing that never comes
        raise src.error(key, f"{text!r}: {match['number']} is not a finite number")
    return Condition(ref, match["op"], number)  # type: ignore[arg-type]


def settable(
    ref: str, value: Any, scenario: Any, key: str, ramp: bool, src: Source
) -> bool | int | float:
    """The number a live override or a ramp writes to ``ref`` (:func:`event_value`; a
    String variable is refused: those take an event's ``set`` only)."""
    checked = event_value(ref, value, scenario, key, ramp, src)
    if isinstance(checked, str):
        raise src.error(key, f"{ref} is String: set it with an event's set, not here")
    return checked


def event_value(
    ref: str, value: Any, scenario: Any, key: str, ramp: bool, src: Source
) -> bool | int | float | str:
    """The value an event writes to ``ref``: an unconnected input or a tunable parameter."""
    _, var = split_ref(ref, scenario.instances, key, src)
    connection = aliased_target(ref, scenario)
    if connection is not None:
        alias = "" if connection.target == ref else f" (as {connection.target}, one variable)"
        raise src.error(
            key,
            f"{ref} is connected from {connection.source}{alias}: an event sets unconnected "
            "inputs only",
        )
    tunable = var.causality == "parameter" and var.variability == "tunable"
    if var.causality != "input" and not tunable:
        raise src.error(
            key,
            f"{ref} is a {var.variability} {var.causality}: expected an unconnected input or "
            "a tunable parameter",
        )
    if ramp and var.type != "Real":
        raise src.error(key, f"{ref} is {var.type}: a ramp sets Real variables only")
    return check_value(value, var, key, src)


def _series(spec: EventSpec, scenario: Any, base_dir: Path, key: str, src: Source) -> Series:
    path = (base_dir / str(spec.series)).resolve()
    rows = _series_rows(path, key, spec.series, src)
    header = [cell.strip() for cell in rows[0]] if rows else []
    if len(header) < 2 or header[0] != "time":
        raise src.error(
            key,
            f"{spec.series!r}: header {header} is not 'time,<instance.variable>,...'"
            + _separated_otherwise(header),
        )
    twice = sorted({ref for ref in header if header.count(ref) > 1})
    if twice:
        raise src.error(key, f"{spec.series!r}: column {twice[0]!r} appears twice in the header")
    for ref in header[1:]:
        settable(ref, 0.0, scenario, f"{key} = {spec.series!r}, column {ref}", True, src)
    table = _numbers(rows[1:], len(header), key, spec.series, src)
    times = [row[0] for row in table]
    if not times:
        raise src.error(key, f"{spec.series!r}: no rows below the header")
    for line, (before, after) in enumerate(itertools.pairwise(times), start=3):
        if after <= before:
            raise src.error(
                key, f"{spec.series!r} row {line - 1}: time {after!r} s is not after {before!r} s"
            )
    columns = {ref: tuple(row[j + 1] for row in table) for j, ref in enumerate(header[1:])}
    shown = ReadOnly(columns, f"{key}.columns", EVENTS_HINT)
    return Series(path, spec.interpolation or "hold", tuple(times), shown)


_OTHER_SEPARATORS = {";": "';'", "\t": "a tab"}  # a spreadsheet's CSV in some locales


def _separated_otherwise(header: list[str]) -> str:
    """``: its columns are separated by ';', expected ','...`` for a one-cell header
    split by another separator (a spreadsheet's CSV where the decimal mark is a comma),
    else ``""``."""
    for separator, said in _OTHER_SEPARATORS.items():
        if len(header) == 1 and separator in header[0]:
            decimal = " (and a decimal point: 0.5, not 0,5)" if separator == ";" else ""
            return f": its columns are separated by {said}, expected ','{decimal}"
    return ""


def _series_rows(path: Path, key: str, name: Any, src: Source) -> list[list[str]]:
    """The CSV rows of a series file: a regular file of at most SERIES_MAX_BYTES (a device
    like /dev/zero, a FIFO or a huge file is refused, never read)."""
    try:
        info = os.stat(path)  # before opening: opening a FIFO would wait for a writer
        if not stat.S_ISREG(info.st_mode):
            raise src.error(key, f"{name!r}: {path} is not a regular file")
        if info.st_size > SERIES_MAX_BYTES:
            raise src.error(
                key, f"{name!r}: {path} is {info.st_size} bytes; at most {SERIES_MAX_BYTES}"
            )
        with path.open("rb") as file:
            data = file.read(SERIES_MAX_BYTES + 1)
        if len(data) > SERIES_MAX_BYTES:
            raise src.error(key, f"{name!r}: {path} is over {SERIES_MAX_BYTES} bytes")
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise src.error(key, f"{name!r}: {path} is {not_utf8(exc)}") from None
    except OSError as exc:
        raise src.error(key, f"{name!r}: cannot read {path}: {exc}") from None
    return list(csv.reader(io.StringIO(text, newline="")))


def _numbers(
    rows: list[list[str]], width: int, key: str, name: Any, src: Source
) -> list[list[float]]:
    table = []
    for line, row in enumerate(rows, start=2):
        if not any(cell.strip() for cell in row):  # a blank line, or one of spaces
            continue
        try:
            values = [float(cell) for cell in row]
        except ValueError:
            values = []
        if len(values) != width or not all(math.isfinite(v) for v in values):
            raise src.error(key, f"{name!r} row {line - 1}: {row} is not {width} finite numbers")
        table.append(values)
    return table


def resolve_faults(specs: Sequence[FaultSpec], scenario: Any, src: Source) -> tuple[Fault, ...]:
    """Check and resolve ``[[faults]]`` against the resolved ``scenario``."""
    faults = []
    targets = {c.target for c in scenario.connections}
    for i, spec in enumerate(specs):
        key = f"faults[{i}]"
        _check_fault_keys(spec, key, src)
        if spec.kind in ACTUATOR_FAULTS:
            target, hold = _actuator(spec, scenario, key, src)
        else:
            if spec.target is None or spec.target not in targets:
                raise src.error(
                    f"{key}.target",
                    f"{spec.target!r} is not the target of a connection"
                    f"{did_you_mean(str(spec.target), targets)}: expected one of "
                    f"{sorted(targets)}",
                )
            target, hold = spec.target, None
            _, var = split_ref(target, scenario.instances, f"{key}.target", src)
            if var.type != "Real":
                raise src.error(
                    f"{key}.target",
                    f"{target!r} is {var.type}: a connection fault acts on Real connections "
                    f"only, expected one of {sorted(_real_targets(scenario))}",
                )
        faults.append(fault_of(spec, spec.name or f"fault-{i + 1}", target, hold))
    _unique([f.name for f in faults], [s.name for s in specs], "faults", src)
    return tuple(faults)


def fault_of(spec: FaultSpec, name: str, target: str, hold: str | None = None) -> Fault:
    """The fault ``spec`` describes, named ``name``, on the input ``target`` (a mass-jam:
    holding it at ``hold``); a noise or dropout fault without a seed draws from seed 0."""
    values = spec.model_dump(exclude={"name", "kind", "target"})
    if spec.kind in ("noise", "dropout") and values["seed"] is None:
        values["seed"] = 0
    return Fault(name, spec.kind, target, **values, hold_source=hold)


def _real_targets(scenario: Any) -> list[str]:
    """The targets of the scenario's connections between Real variables."""
    return [
        c.target
        for c in scenario.connections
        if scenario.instances[c.target_instance].interface.variables[c.target_variable].type
        == "Real"
    ]


def _check_fault_keys(spec: FaultSpec, key: str, src: Source) -> None:
    for optional in ("value", "std", "seed", "steps", "probability"):
        if getattr(spec, optional) is not None and optional not in _FAULT_KEYS[spec.kind]:
            raise src.error(
                f"{key}.{optional}",
                f"{getattr(spec, optional)!r}: kind {spec.kind!r} takes "
                f"{sorted(_FAULT_KEYS[spec.kind]) or 'none of value/std/seed/steps/probability'}",
            )
    needed = _REQUIRED.get(spec.kind)
    if needed is not None and getattr(spec, needed) is None:
        raise src.error(f"{key}.{needed}", f"missing: kind {spec.kind!r} needs it")
    if spec.kind not in ACTUATOR_FAULTS and spec.target is None:
        raise src.error(f"{key}.target", f"missing: kind {spec.kind!r} acts on a connection")
    if spec.stop is not None and spec.stop <= spec.start:
        raise src.error(f"{key}.stop", f"{spec.stop!r} s is not after start = {spec.start!r} s")


def actuator_owners(kind: str, scenario: Any) -> list[str]:
    """The instances with the plant input the actuator fault ``kind`` acts on."""
    wanted = ACTUATOR_FAULTS[kind]
    owners = []
    for name, inst in scenario.instances.items():
        var = inst.interface.variables.get(wanted)
        if var is not None and var.causality == "input" and var.type == "Real":
            owners.append(name)
    return owners


def _actuator(spec: FaultSpec, scenario: Any, key: str, src: Source) -> tuple[str, str | None]:
    """The input an actuator fault acts on: of its ``target``, else of the one instance
    with that plant input (several vehicles: the target names one), and, for a mass-jam,
    the mass position output on the same instance."""
    kind, wanted = spec.kind, ACTUATOR_FAULTS[spec.kind]
    owners = actuator_owners(kind, scenario)
    have = "has" if len(owners) == 1 else "have"
    acts = (
        f"{kind!r} acts on the plant input {wanted!r}, which "
        f"{counted(len(owners), 'instance')} ({owners}) {have}"
    )
    if not owners:  # a target or none: the kind is what no plant can take
        raise src.error(f"{key}.kind", f"{acts}: expected exactly one")
    if spec.target is not None:
        if spec.target not in [f"{owner}.{wanted}" for owner in owners]:
            expected = f"one of {[f'{o}.{wanted}' for o in owners]}"
            raise src.error(f"{key}.target", f"{spec.target!r}: {acts}: expected {expected}")
        plant = spec.target.rpartition(".")[0]
    elif len(owners) == 1:
        plant = owners[0]
    else:
        raise src.error(
            f"{key}.target",
            f'missing: {acts}: name one, target = "{owners[0]}.{wanted}"',
        )
    if kind != "mass-jam":
        return f"{plant}.{wanted}", None
    out = scenario.instances[plant].interface.variables.get(MASS_POSITION)
    if out is None or out.causality != "output":
        raise src.error(key, f"'mass-jam' needs the output {plant}.{MASS_POSITION}: none")
    return f"{plant}.{wanted}", f"{plant}.{MASS_POSITION}"


def _unique(names: list[str], written: list[str | None], key: str, src: Source) -> None:
    """Each of ``names`` once; ``written`` are the names as the tables give them (None:
    a default by position, ``event-<k>``), so a clash is named where a name is written."""
    first: dict[str, int] = {}
    for i, name in enumerate(names):
        if name not in first:
            first[name] = i
            continue
        j = first[name]
        at = i if written[i] is not None else j  # the table that writes the name
        other = j if at == i else i
        default = (
            "" if written[other] is not None else f" (by position: {key}[{other}] has no name)"
        )
        raise src.error(f"{key}[{at}].name", f"{name!r} is used twice: names are unique{default}")


def event_table(event: Event) -> dict[str, Any]:
    """An event as the ``[[events]]`` table that resolves to it."""
    table: dict[str, Any] = {"name": event.name}
    if event.series is not None:
        table["series"] = str(event.series.path)
        table["interpolation"] = event.series.interpolation
        return table
    if event.when is not None:
        table["when"] = str(event.when)
        table["repeat"] = event.repeat
    else:
        table["time"] = event.time
    table["set"] = dict(event.set)
    if event.ramp is not None:
        table["ramp"] = event.ramp
    return table


def fault_table(fault: Fault, with_target: bool = False) -> dict[str, Any]:
    """A fault as the ``[[faults]]`` table that resolves to it (an actuator fault's
    target only ``with_target``: where several plants have its input)."""
    table: dict[str, Any] = {"name": fault.name, "kind": fault.kind}
    if not fault.actuator or with_target:
        table["target"] = fault.target
    table["start"] = fault.start
    for key in ("stop", "value", "std", "seed", "steps", "probability"):
        if getattr(fault, key) is not None:
            table[key] = getattr(fault, key)
    return table
