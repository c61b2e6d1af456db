"""What the claims compute from: the dissertation's printed values, the two vehicles, the
weight convention of each chapter, and results computed once and shared between claims
and figures (equilibria, sweeps, scenario runs).

The weight convention: the dissertation computed Chapter 5 with Table 5.4's printed
W = 299 N (Example 5.3's printed Jacobian holds with it, not with m g) and Chapter 6 with
W = m g, g = 9.8 ((6.3.19)), which is what ``remus100`` states (``docs/model.md``, one
gravity). :meth:`Context.chapter_5` gives a vehicle the Chapter 5 weight; every Chapter 5
claim uses it, every Chapter 6 claim the vehicle as shipped.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from cosim.analysis.bifurcation import OperatingConditions, find_equilibria
from cosim.analysis.equilibria import Equilibrium
from cosim.analysis.reference_values import Reference
from plant_fmu.model.parameters import VehicleParameters, load_vehicle

T = TypeVar("T")
CHAPTER_5_WEIGHT = "table_5_4.weight"  # the reference value Chapter 5 was computed with


Runner = Callable[[str, float, Mapping[str, float], bool], "RunData"]
"""Runs a built-in scenario (id, communication step in s, start values, whether the
exchanged values are held over each step instead of the scenario's extrapolation) and
reads it."""


class NotRunError(Exception):
    """Ours was not computed (scenarios skipped); the reason."""


@dataclass(frozen=True)
class RunData:
    """A scenario's results: the columns of its results.csv by name, and its run folder."""

    table: Mapping[str, np.ndarray]
    folder: Path

    def __getitem__(self, name: str) -> np.ndarray:
        return self.table[name]


@dataclass
class Context:
    """The inputs of every claim and a memo of what several claims share.

    Attributes:
        references: the printed values, ``docs/dissertation-values.toml`` by dotted key.
        remus: ``remus100`` as shipped.
        long_fins: ``remus100-long-fins`` (Table 5.3) as shipped.
        runner: runs a built-in scenario by id at a communication step (s) with start
            values added (``{"<instance>.<variable>": value}``); None when scenarios are
            skipped.
    """

    references: Mapping[str, Reference]
    remus: VehicleParameters
    long_fins: VehicleParameters
    runner: Runner | None = None
    _memo: dict[Any, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def create(cls, references: Mapping[str, Reference], runner: Runner | None = None) -> Context:
        """A context on the shipped vehicles."""
        return cls(references, load_vehicle("remus100"), load_vehicle("remus100-long-fins"), runner)

    def ref(self, key: str) -> Reference:
        """The printed value ``key``."""
        return self.references[key]

    @property
    def chapter_5_weight(self) -> float:
        """W (N) of every Chapter 5 claim: Table 5.4's printed 299 N."""
        return float(self.ref(CHAPTER_5_WEIGHT).value)

    def chapter_5(self, params: VehicleParameters) -> VehicleParameters:
        """``params`` with the Chapter 5 weight (inertia and g unchanged)."""
        return params.replace(W=self.chapter_5_weight)

    def memo(self, key: Any, compute: Callable[[], T]) -> T:
        """``compute()`` once per ``key``."""
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def equilibria(self, key: Any, conditions: OperatingConditions) -> list[Equilibrium]:
        """Every equilibrium in the search box (5.1.50), sorted by v, once per ``key``."""
        return self.memo(
            ("equilibria", key),
            lambda: sorted(find_equilibria(conditions), key=lambda e: e.value("v")),
        )

    def run(
        self,
        scenario_id: str,
        step: float,
        start: Mapping[str, float] | None = None,
        held: bool = False,
    ) -> RunData:
        """The results of built-in scenario ``scenario_id`` at the communication step
        ``step`` (s) with the start values ``start`` added, run once; ``held``: the
        exchanged values held over each step (extrapolation none), not extrapolated as
        the scenario ships."""
        if self.runner is None:
            raise NotRunError("scenarios skipped")
        runner, values = self.runner, dict(start or {})
        key = ("run", scenario_id, step, tuple(sorted(values.items())), held)
        return self.memo(key, lambda: runner(scenario_id, step, values, held))


def uvr(eq: Equilibrium) -> tuple[float, float, float]:
    """[u, v, r] of an equilibrium."""
    return eq.value("u"), eq.value("v"), eq.value("r")


def stability(eq: Equilibrium) -> str:
    """ "stable" or "unstable"."""
    return "stable" if eq.stable else "unstable"
