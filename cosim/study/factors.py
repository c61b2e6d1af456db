"""Factors: what a study's ``<instance>.<variable>`` names, and how a value is applied.

A factor is resolved once, up front, against :class:`ScenarioFacts` (plain data the
adapter :mod:`cosim.study.task` reads from the scenario and its FMUs) by the kinds in
:data:`FACTOR_KINDS`, tried in order; the first that recognises the name wins. A resolved
:class:`FactorKind` then writes each run's value into the resolved scenario's TOML data. Today
there is one kind, start values (parameters and unconnected inputs); event times and fault
parameters will be further kinds. A name no kind recognises is an error naming the factor
and the instance's known start values.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

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


class FactorKind(Protocol):
    """A kind of factor: recognises its names and writes a value into the scenario."""

    name: str

    @classmethod
    def recognise(cls, name: str, facts: ScenarioFacts) -> FactorKind | None:
        """The resolved factor if ``name`` is of this kind (StudyError if it is, but
        cannot be varied), else None."""

    def apply(self, data: dict[str, Any], value: Value) -> None:
        """Write ``value`` into the resolved scenario's TOML data (in place)."""

    def normalize(self, value: Value) -> Value:
        """The value as the scenario will hold it (a Real's integer becomes a float)."""


@dataclass(frozen=True)
class StartValue:
    """``<instance>.<parameter or unconnected input>``: the instance's start value."""

    name: str
    instance: str
    variable: str
    real: bool

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
        return cls(name, instance, variable, var.type == "Real")

    def apply(self, data: dict[str, Any], value: Value) -> None:
        data["instances"][self.instance].setdefault("start", {})[self.variable] = value

    def normalize(self, value: Value) -> Value:
        real_int = self.real and isinstance(value, int) and not isinstance(value, bool)
        return float(value) if real_int else value


FACTOR_KINDS: tuple[type[FactorKind], ...] = (StartValue,)


def resolve_factor(name: str, facts: ScenarioFacts) -> FactorKind:
    """The first kind that recognises ``name``; :class:`StudyError` if none does."""
    for kind in FACTOR_KINDS:
        factor = kind.recognise(name, facts)
        if factor is not None:
            return factor
    instance, _, variable = name.partition(".")
    if instance not in facts.instances:
        raise StudyError(
            f"factor {name!r}: the scenario has no instance {instance!r} "
            f"(instances: {', '.join(facts.instances)})"
        )
    known = [v.name for v in facts.instances[instance].values() if v.takes_start_value]
    raise StudyError(
        f"factor {name!r}: {instance} has no parameter or input {variable!r}; "
        f"its start values are: {', '.join(known)}"
    )


def apply_values(
    data: dict[str, Any], factors: Mapping[str, FactorKind], values: Mapping[str, Value]
) -> None:
    """Write one run's factor values into the scenario's TOML data (in place)."""
    for name, value in values.items():
        factors[name].apply(data, value)
