"""Linearisation of the plant, evaluated on its own equations.

Controllers (LQR, sliding mode) take their A and B matrices from :func:`linearize`, so no
coefficient formula of the dissertation is typed twice. Equilibrium search, which only
offline analysis needs, lives in :mod:`cosim.analysis.equilibria`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np

from plant_fmu.model.dynamics import (
    INPUT_INDEX,
    N_INPUTS,
    N_STATES,
    STATE_INDEX,
    PlantModel,
)


def state_vector(values: Mapping[str, float] | None = None) -> np.ndarray:
    """A full state vector from ``{name: value}``; unnamed states are 0."""
    return _vector(values, STATE_INDEX, N_STATES, "state")


def input_vector(values: Mapping[str, float] | None = None, thrust: float = 0.0) -> np.ndarray:
    """A full input vector from ``{name: value}``; unnamed inputs are 0 except ``thrust``."""
    vector = _vector(values, INPUT_INDEX, N_INPUTS, "input")
    if values is None or "thrust" not in values:
        vector[INPUT_INDEX["thrust"]] = thrust
    return vector


def _vector(
    values: Mapping[str, float] | None, index: Mapping[str, int], n: int, what: str
) -> np.ndarray:
    vector = np.zeros(n)
    for name, value in (values or {}).items():
        if name not in index:
            raise ValueError(f"unknown {what} {name!r}: expected one of {list(index)}")
        vector[index[name]] = value
    return vector


def linearize(
    model: PlantModel,
    x0: np.ndarray,
    u0: np.ndarray,
    states: Sequence[str],
    inputs: Sequence[str] = (),
    rel_step: float = 1e-6,
) -> tuple[np.ndarray, np.ndarray]:
    """Jacobians A = d(xdot_S)/d(x_S), B = d(xdot_S)/d(u_I) about (x0, u0) by central
    differences, for the named subset S of states and I of inputs; the other states and
    inputs stay at x0, u0 (e.g. u held at U0 as in (6.3.17)).

    Central differences (written out here because scipy offers no vector-valued
    finite-difference Jacobian for a non-vectorised function) have truncation error
    O(step^2) ~ 1e-12 with step = rel_step * max(1, |x|).
    """
    s_idx = [_index(name, STATE_INDEX, "state") for name in states]
    i_idx = [_index(name, INPUT_INDEX, "input") for name in inputs]
    x0 = np.asarray(x0, dtype=float)
    u0 = np.asarray(u0, dtype=float)

    def column(
        vector: np.ndarray, k: int, evaluate: Callable[[np.ndarray], np.ndarray]
    ) -> np.ndarray:
        step = rel_step * max(1.0, abs(vector[k]))
        plus, minus = vector.copy(), vector.copy()
        plus[k] += step
        minus[k] -= step
        difference: np.ndarray = (evaluate(plus)[s_idx] - evaluate(minus)[s_idx]) / (2.0 * step)
        return difference

    A = np.column_stack([column(x0, k, lambda x: model.derivative(x, u0)) for k in s_idx])
    B = (
        np.column_stack([column(u0, k, lambda u: model.derivative(x0, u)) for k in i_idx])
        if i_idx
        else np.zeros((len(s_idx), 0))
    )
    return A, B


def _index(name: str, index: Mapping[str, int], what: str) -> int:
    if name not in index:
        raise ValueError(f"unknown {what} {name!r}: expected one of {list(index)}")
    return index[name]
