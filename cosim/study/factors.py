"""Factors: what a study's ``<instance>.<variable>`` names, and how a value is applied.

A factor is resolved once, up front, against :class:`ScenarioFacts` (plain data the
adapter :mod:`cosim.study.task` reads from the scenario and its FMUs) by the kinds in
:data:`FACTOR_KINDS`, tried in order; the first that recognises the name wins. A resolved
:class:`FactorKind` then writes each run's value into the resolved scenario's TOML data,
which the scenario's own checks then resolve again. The kinds:

* ``<instance>.<variable>``: a start value (a parameter or an unconnected input);
* ``events.<name>.time``, ``events.<name>.ramp``, ``events.<name>.set.<instance>.<variable>``:
  a key of the ``[[events]]`` table of that name (``event-<k>`` by position if unnamed);
* ``faults.<name>.<key>`` (start, stop, value, std, seed, steps, probability): a key of
  the ``[[faults]]`` table of that name (``fault-<k>``); whether the fault's kind takes
  the key is the scenario's own check, made on every grid value before the first run.

A name no kind recognises is an error naming the factor and what it could name.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, get_args

from pydantic.fields import FieldInfo

from cosim.errors import did_you_mean
from cosim.scenario.timeline_spec import EventSpec, FaultSpec
from cosim.study.spec import StudyError

Value = bool | int | float | str


@dataclass(frozen=True)
class Variable:
    """One FMU variable as a factor needs to know it (from modelDescription.xml)."""

    name: str
    type: str  # Real, Integer, Enumeration, Boolean or String
    causality: str
    variability: str
    driven_by: str | None = None  # the connection source, if an input driven by one
    min: float | None = None  # the declared range, None where it declares none
    max: float | None = None
    names: Mapping[str, int] = field(default_factory=dict)  # named values: name -> value

    @property
    def takes_start_value(self) -> bool:
        settable = self.causality in ("parameter", "input") and self.variability != "constant"
        return settable and self.driven_by is None


@dataclass(frozen=True)
class ScenarioFacts:
    """What the study needs to know about the scenario: each instance's variables and
    the metric names a run reports."""

    instances: Mapping[str, Mapping[str, Variable]]
    metrics: tuple[str, ...]
    events: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # name -> table
    faults: Mapping[str, Mapping[str, Any]] = field(default_factory=dict)  # name -> table


class FactorKind(Protocol):
    """A kind of factor: recognises its names and writes a value into the scenario."""

    @property
    def name(self) -> str:
        """The factor's name as the study file writes it (read-only: kinds are frozen)."""

    @classmethod
    def recognise(cls, name: str, facts: ScenarioFacts) -> FactorKind | None:
        """The resolved factor if ``name`` is of this kind (StudyError if it is, but
        cannot be varied), else None."""

    def apply(self, data: dict[str, Any], value: Value) -> None:
        """Write ``value`` into the resolved scenario's TOML data (in place)."""

    def normalize(self, value: Value) -> Value:
        """The value as the scenario will hold it (a Real's integer becomes a float)."""

    def value_range(self, facts: ScenarioFacts) -> tuple[float, float]:
        """The range a number for it must be in (what the scenario's checks refuse outside
        it; -inf, inf where there is none): a study's samples are checked against it."""


@dataclass(frozen=True)
class StartValue:
    """``<instance>.<parameter or unconnected input>``: the instance's start value."""

    name: str
    instance: str
    variable: str
    real: bool
    named: tuple[tuple[int, str], ...] = ()  # an Integer's or Enumeration's named values

    @classmethod
    def recognise(cls, name: str, facts: ScenarioFacts) -> StartValue | None:
        instance, _, variable = name.partition(".")
        var = facts.instances.get(instance, {}).get(variable)
        if var is None:
            return None
        if var.driven_by is not None:
            raise StudyError(
                f"factor {name!r}: input {name} is connected from {var.driven_by}, so a "
                "start value would be overwritten; remove the connection in the scenario "
                "to vary it"
            )
        if not var.takes_start_value:
            raise StudyError(
                f"factor {name!r}: {name} is a {var.variability} {var.causality}; only "
                "parameters and unconnected inputs take start values"
            )
        named = tuple((number, text) for text, number in var.names.items())
        return cls(name, instance, variable, var.type == "Real", named)

    def apply(self, data: dict[str, Any], value: Value) -> None:
        data["instances"][self.instance].setdefault("start", {})[self.variable] = value

    def normalize(self, value: Value) -> Value:
        """A Real's integer as a float; a named value's number as its name (``2`` as
        ``"horizontal"``, as the scenario file may write it), so that a factor's values
        are of one type and the same value written both ways is one run."""
        if self.real:
            return _real(value)
        if type(value) is int:
            return dict(self.named).get(value, value)
        return value

    def value_range(self, facts: ScenarioFacts) -> tuple[float, float]:
        return _declared_range(facts, f"{self.instance}.{self.variable}")


# a fault's numeric keys and which of them are integers, as the scenario's FaultSpec has them
FAULT_KEYS = tuple(k for k in FaultSpec.model_fields if k not in ("name", "kind", "target"))
INTEGER_FAULT_KEYS = tuple(
    k for k in FAULT_KEYS if int in get_args(FaultSpec.model_fields[k].annotation)
)


def _entry(
    facts: ScenarioFacts, section: str, factor: str
) -> tuple[str, str, Mapping[str, Any]] | None:
    """For a factor ``<section>.<name>.<rest>`` (section "events" or "faults", unless an
    instance has that name): (name, rest, the ``[[section]]`` table called name); None for
    any other factor; StudyError listing the known names if no table has that name."""
    head, _, tail = factor.partition(".")
    if head != section or section in facts.instances:
        return None
    name, _, rest = tail.partition(".")
    tables = facts.events if section == "events" else facts.faults
    if name not in tables:
        known = ", ".join(tables) if tables else "none"
        raise StudyError(
            f"factor {factor!r}: the scenario has no {section[:-1]} {name!r} ({section}: {known})"
        )
    return name, rest, tables[name]


def _table(data: dict[str, Any], section: str, name: str) -> dict[str, Any]:
    """The TOML table of that name in ``data[section]`` (default names by position)."""
    for k, table in enumerate(data[section], start=1):
        if table.get("name", f"{section[:-1]}-{k}") == name:
            return table
    raise KeyError(f"{section}.{name}")  # resolve_factor checked it exists


@dataclass(frozen=True)
class EventKey:
    """``events.<name>.time`` or ``events.<name>.ramp`` (s), or
    ``events.<name>.set.<instance>.<variable>``: a value the event sets."""

    name: str
    event: str
    key: str  # "time", "ramp" or "set"
    target: str | None  # the set's "<instance>.<variable>"
    real: bool

    @classmethod
    def recognise(cls, name: str, facts: ScenarioFacts) -> EventKey | None:
        found = _entry(facts, "events", name)
        if found is None:
            return None
        event, key, table = found
        key, _, target = key.partition(".")
        if key in ("time", "ramp") and not target:
            if "set" not in table or (key == "time" and "time" not in table):
                fires = "a series" if "series" in table else "a condition (when)"
                raise StudyError(
                    f"factor {name!r}: event {event!r} follows {fires}; it has no {key} to vary"
                )
            return cls(name, event, key, None, True)
        if key == "set" and target in table.get("set", {}):
            instance, _, variable = target.partition(".")
            var = facts.instances.get(instance, {}).get(variable)
            return cls(name, event, key, target, var is not None and var.type == "Real")
        sets = ", ".join(f"events.{event}.set.{t}" for t in table.get("set", {}))
        raise StudyError(
            f"factor {name!r}: expected events.{event}.time, events.{event}.ramp or one of "
            f"the values it sets ({sets or 'none'}); to vary another value, add it to the "
            "event's set in the scenario"
        )

    def apply(self, data: dict[str, Any], value: Value) -> None:
        table = _table(data, "events", self.event)
        if self.target is None:
            table[self.key] = value
        else:
            table["set"][self.target] = value

    def normalize(self, value: Value) -> Value:
        return _real(value) if self.real else value

    def value_range(self, facts: ScenarioFacts) -> tuple[float, float]:
        if self.target is not None:
            return _declared_range(facts, self.target)
        return _field_range(EventSpec.model_fields[self.key])


@dataclass(frozen=True)
class FaultKey:
    """``faults.<name>.<key>``: start, stop (s), value, std, seed, steps or probability of
    the fault called ``name``."""

    name: str
    fault: str
    key: str

    @classmethod
    def recognise(cls, name: str, facts: ScenarioFacts) -> FaultKey | None:
        found = _entry(facts, "faults", name)
        if found is None:
            return None
        fault, key, table = found
        if key not in FAULT_KEYS:
            raise StudyError(
                f"factor {name!r}: a fault's factor is faults.{fault}.<key>, key one of "
                f"{', '.join(FAULT_KEYS)}; got {key!r} (fault {fault!r} is "
                f"{table.get('kind')!r})"
            )
        return cls(name, fault, key)

    def apply(self, data: dict[str, Any], value: Value) -> None:
        _table(data, "faults", self.fault)[self.key] = value

    def normalize(self, value: Value) -> Value:
        return value if self.key in INTEGER_FAULT_KEYS else _real(value)

    def value_range(self, facts: ScenarioFacts) -> tuple[float, float]:
        return _field_range(FaultSpec.model_fields[self.key])


def _declared_range(facts: ScenarioFacts, ref: str) -> tuple[float, float]:
    """The declared min and max of the variable ``ref`` ("<instance>.<variable>")."""
    instance, _, variable = ref.partition(".")
    var = facts.instances.get(instance, {}).get(variable)
    low = -math.inf if var is None or var.min is None else float(var.min)
    high = math.inf if var is None or var.max is None else float(var.max)
    return low, high


def _field_range(field: FieldInfo) -> tuple[float, float]:
    """The bounds a scenario file's key declares (pydantic's ge/gt, le/lt), as a range."""
    low, high = -math.inf, math.inf
    for item in field.metadata:
        for name in ("ge", "gt"):
            if getattr(item, name, None) is not None:
                low = max(low, float(getattr(item, name)))
        for name in ("le", "lt"):
            if getattr(item, name, None) is not None:
                high = min(high, float(getattr(item, name)))
    return low, high


def _real(value: Value) -> Value:
    """An integer as the float a Real holds (booleans and strings stay as they are)."""
    return float(value) if isinstance(value, int) and not isinstance(value, bool) else value


FACTOR_KINDS: tuple[type[FactorKind], ...] = (EventKey, FaultKey, StartValue)


def resolve_factor(name: str, facts: ScenarioFacts) -> FactorKind:
    """The first kind that recognises ``name``; :class:`StudyError` if none does."""
    for kind in FACTOR_KINDS:
        factor = kind.recognise(name, facts)
        if factor is not None:
            return factor
    instance, _, variable = name.partition(".")
    if instance not in facts.instances:
        raise StudyError(
            f"factor {name!r}: the scenario has no instance {instance!r}"
            f"{did_you_mean(instance, facts.instances)} (instances: {', '.join(facts.instances)})"
        )
    known = [v.name for v in facts.instances[instance].values() if v.takes_start_value]
    raise StudyError(
        f"factor {name!r}: {instance} has no parameter or input {variable!r}"
        f"{did_you_mean(variable, known)}; its start values are: {', '.join(known)}"
    )


def apply_values(
    data: dict[str, Any], factors: Mapping[str, FactorKind], values: Mapping[str, Value]
) -> None:
    """Write one run's factor values into the scenario's TOML data (in place)."""
    for name, value in values.items():
        factors[name].apply(data, value)
