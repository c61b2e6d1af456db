"""Richardson extrapolation: the error of a result from the same result at smaller steps.

A figure f computed with step h converges as f(h) = f0 + C h^p + ... With the runs at h,
h / 2 and h / 4 (f1, f2, f4) the observed order is p = log2((f1 - f2) / (f2 - f4)), the
continuous-time limit f0 ~ f2 + (f2 - f1) / (2^p - 1) and the error of the run at h
f1 - f0 = (f1 - f2) 2^p / (2^p - 1) (L. F. Richardson, Phil. Trans. R. Soc. A 210, 1911;
the "observed order" of Roache's grid-convergence studies). A figure whose three values
do not converge monotonically (differences of opposite signs, or not shrinking) has no
order of its own: it takes the order observed on the run as a whole (:func:`run_order`),
else the coupling's nominal one.

Why by hand: three lines of arithmetic; no library states it for a co-simulation's
figures.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

MIN_ORDER, MAX_ORDER = 0.5, 6.0  # orders observed outside this range are not believed


@dataclass(frozen=True)
class Estimate:
    """The error of one figure of the run at h (same unit as the figure)."""

    value: float  # f(h)
    half: float  # f(h / 2)
    quarter: float  # f(h / 4)
    order: float  # p used
    observed: bool  # p observed on this figure's three values (else the run's)

    @property
    def limit(self) -> float:
        """f0, the continuous-time limit estimated from the two smaller steps."""
        return self.quarter + (self.quarter - self.half) / (2.0**self.order - 1.0)

    @property
    def error(self) -> float:
        """f(h) - f0: how far the run at h is from the limit."""
        return self.value - self.limit

    def as_dict(self) -> dict[str, float | bool | None]:
        """summary.json's entry: the three values, the order, the limit, the error (and
        relative to the limit, None when the limit is 0)."""
        relative = self.error / abs(self.limit) if self.limit else None
        return {
            "value": self.value,
            "half_step": self.half,
            "quarter_step": self.quarter,
            "order": self.order,
            "order_observed": self.observed,
            "limit": self.limit,
            "error": self.error,
            "relative_error": relative,
        }


def observed_order(f1: float, f2: float, f4: float) -> float | None:
    """p of three values at h, h / 2, h / 4 that converge monotonically, else None."""
    d1, d2 = f1 - f2, f2 - f4
    if d1 == 0.0 or d2 == 0.0 or (d1 > 0.0) != (d2 > 0.0) or abs(d2) >= abs(d1):
        return None
    p = math.log2(d1 / d2)
    return p if MIN_ORDER <= p <= MAX_ORDER else None


def run_order(runs: Sequence[Sequence[float]]) -> float | None:
    """The order observed on whole runs: ``runs`` = the same finite values (final values,
    figures) at h, h / 2, h / 4; p from the largest differences, None if undefined."""
    f1, f2, f4 = runs
    d1 = max((abs(a - b) for a, b in zip(f1, f2, strict=True)), default=0.0)
    d2 = max((abs(a - b) for a, b in zip(f2, f4, strict=True)), default=0.0)
    if d1 == 0.0 or d2 == 0.0 or d2 >= d1:
        return None
    p = math.log2(d1 / d2)
    return p if MIN_ORDER <= p <= MAX_ORDER else None


def estimate(
    values: Sequence[Mapping[str, float | None]], fallback: float
) -> tuple[dict[str, Estimate], float]:
    """Estimates of every figure finite in all three ``values`` (at h, h / 2, h / 4), and
    the run's order (observed on all of them together, else ``fallback``)."""
    triples: dict[str, tuple[float, float, float]] = {}
    for name in values[0]:
        row = [r.get(name) for r in values]
        numbers = [float(v) for v in row if isinstance(v, int | float) and math.isfinite(v)]
        if len(numbers) == 3:
            triples[name] = (numbers[0], numbers[1], numbers[2])
    overall = run_order([[t[i] for t in triples.values()] for i in range(3)]) or fallback
    result = {}
    for name, (f1, f2, f4) in triples.items():
        own = observed_order(f1, f2, f4)
        result[name] = Estimate(f1, f2, f4, own or overall, own is not None)
    return result, overall
