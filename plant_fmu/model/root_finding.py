"""Brent's method for a root of a scalar function in a bracket, in plain Python.

Why by hand: the plant FMU locates the moving mass's arrival at a rail stop with it
(:mod:`plant_fmu.model.stepping`), and an FMU's host Python holds only the standard library
and numpy (no scipy). The algorithm is Brent's (R. P. Brent, *Algorithms for Minimization
without Derivatives*, Prentice-Hall 1973, Ch. 4) in the form of ``scipy.optimize.brentq``
(inverse quadratic interpolation or secant steps, bisection when they do not shrink the
bracket fast enough), with its stopping rule: the bracket's half-width below
(xtol + rtol |x|) / 2. ``tests/plant_fmu/model/test_root_finding.py`` compares the roots
with scipy's.
"""

from __future__ import annotations

import math
from collections.abc import Callable


def brent_root(
    f: Callable[[float], float],
    a: float,
    b: float,
    xtol: float = 2e-12,
    rtol: float = 4 * 2.220446049250313e-16,
    max_iterations: int = 100,
) -> float:
    """A root of ``f`` in [a, b], within xtol + rtol |root| of a sign change of ``f``.

    Raises:
        ValueError: f(a) and f(b) have the same sign (no bracket), a value is not finite,
            or no convergence within ``max_iterations``.
    """
    previous, current = float(a), float(b)
    f_previous, f_current = f(previous), f(current)
    if not (math.isfinite(f_previous) and math.isfinite(f_current)):
        raise ValueError(f"brent_root: f(a) = {f_previous!r}, f(b) = {f_current!r}")
    if f_previous == 0.0:
        return previous
    if f_current == 0.0:
        return current
    if (f_previous < 0.0) == (f_current < 0.0):  # signs, not the product: it may underflow
        raise ValueError(
            f"brent_root: f({a!r}) = {f_previous!r} and f({b!r}) = {f_current!r} have the "
            "same sign; expected a bracket"
        )
    block, f_block = previous, f_previous  # the other end of the bracket
    step = step_before = 0.0
    for _ in range(max_iterations):
        if (f_previous < 0.0) != (f_current < 0.0):  # the bracket is [previous, current]
            block, f_block = previous, f_previous
            step = step_before = current - previous
        if abs(f_block) < abs(f_current):  # keep the best estimate in `current`
            previous, current, block = current, block, current
            f_previous, f_current, f_block = f_current, f_block, f_current
        tolerance = 0.5 * (xtol + rtol * abs(current))
        bisection = 0.5 * (block - current)
        if f_current == 0.0 or abs(bisection) < tolerance:
            return current
        if abs(step_before) > tolerance and abs(f_current) < abs(f_previous):
            trial = _interpolation_step(previous, current, block, f_previous, f_current, f_block)
            if 2.0 * abs(trial) < min(abs(step_before), 3.0 * abs(bisection) - tolerance):
                step_before, step = step, trial  # a short step: accept it
            else:
                step_before = step = bisection
        else:
            step_before = step = bisection
        previous, f_previous = current, f_current
        current += step if abs(step) > tolerance else math.copysign(tolerance, bisection)
        f_current = f(current)
        if not math.isfinite(f_current):
            raise ValueError(f"brent_root: f({current!r}) = {f_current!r}")
    raise ValueError(f"brent_root: no convergence in {max_iterations} iterations")


def _interpolation_step(
    previous: float, current: float, block: float, f_previous: float, f_current: float,
    f_block: float,
) -> float:  # fmt: skip
    """The secant step (two distinct points) or the inverse quadratic one (three)."""
    if previous == block:
        return -f_current * (current - previous) / (f_current - f_previous)
    slope_previous = (f_previous - f_current) / (previous - current)
    slope_block = (f_block - f_current) / (block - current)
    return (
        -f_current
        * (f_block * slope_block - f_previous * slope_previous)
        / (slope_block * slope_previous * (f_block - f_previous))
    )
