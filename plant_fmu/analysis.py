"""Linearisation and equilibria of the plant, evaluated on its own equations.

Controllers (LQR, sliding mode) take their A and B matrices from :func:`linearize`, and the
equilibrium commands (Examples 5.1-5.3) from :func:`find_equilibrium`, so no coefficient
formula of the dissertation is typed twice.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from plant_fmu.dynamics import (
    INPUT_INDEX,
    N_INPUTS,
    N_STATES,
    STATE_INDEX,
    PlantModel,
)

# Position and heading never enter the force balance (cyclic coordinates), so an
# equilibrium fixes only the rest: a steady turn is an equilibrium of the reduced system.
CYCLIC_STATES = ("north", "east", "down", "yaw")


def state_vector(values: Mapping[str, float] | None = None) -> np.ndarray:
    """A full state vector from ``{name: value}``; unnamed states are 0."""
    return _vector(values, STATE_INDEX, N_STATES, "state")


def input_vector(values: Mapping[str, float] | None = None, thrust: float = 0.0) -> np.ndarray:
    """A full input vector from ``{name: value}``; unnamed inputs are 0 except ``thrust``."""
    vector = _vector(values, INPUT_INDEX, N_INPUTS, "input")
    if values is None or "thrust" not in values:
        vector[INPUT_INDEX["thrust"]] = thrust
    return vector


def _vector(values: Mapping[str, float] | None, index: dict, n: int, what: str) -> np.ndarray:
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

    def column(vector: np.ndarray, k: int, evaluate) -> np.ndarray:
        step = rel_step * max(1.0, abs(vector[k]))
        plus, minus = vector.copy(), vector.copy()
        plus[k] += step
        minus[k] -= step
        return (evaluate(plus)[s_idx] - evaluate(minus)[s_idx]) / (2.0 * step)

    A = np.column_stack([column(x0, k, lambda x: model.derivative(x, u0)) for k in s_idx])
    B = (
        np.column_stack([column(u0, k, lambda u: model.derivative(x0, u)) for k in i_idx])
        if i_idx
        else np.zeros((len(s_idx), 0))
    )
    return A, B


def _index(name: str, index: dict, what: str) -> int:
    if name not in index:
        raise ValueError(f"unknown {what} {name!r}: expected one of {list(index)}")
    return index[name]


@dataclass(frozen=True)
class Equilibrium:
    """A steady state of the reduced (non-cyclic) dynamics."""

    state: np.ndarray  # full state vector (cyclic states as in the guess)
    free_states: tuple[str, ...]  # names of the states solved for
    jacobian: np.ndarray  # d(xdot)/dx over free_states
    eigenvalues: np.ndarray

    @property
    def stable(self) -> bool:
        """All eigenvalues strictly in the left half-plane (to 1e-9)."""
        return bool(np.all(self.eigenvalues.real < -1e-9))

    def value(self, name: str) -> float:
        return float(self.state[STATE_INDEX[name]])


def free_states(model: PlantModel, exclude: Sequence[str] = ()) -> tuple[str, ...]:
    """The variant's evolving states minus the cyclic ones and ``exclude``."""
    return tuple(s for s in model.variant.states if s not in CYCLIC_STATES and s not in exclude)


def find_equilibrium(
    model: PlantModel,
    guess: Mapping[str, float],
    inputs: Mapping[str, float] | np.ndarray,
    exclude: Sequence[str] = ("mass_position", "mass_velocity"),
    tol: float = 1e-12,
) -> Equilibrium:
    """Solve xdot = 0 over the variant's non-cyclic states (scipy.optimize.root, hybr).

    Args:
        model: the plant.
        guess: starting values by state name (others 0).
        inputs: by input name, or a full input vector.
        exclude: states held at their guess (by default the moving mass, whose equilibrium
            is simply y_v = y_d, y_vel = 0).

    Raises:
        RuntimeError: the solver did not converge.
    """
    u0 = inputs if isinstance(inputs, np.ndarray) else input_vector(inputs)
    names = free_states(model, exclude)
    idx = [STATE_INDEX[n] for n in names]
    x0 = state_vector(guess)

    def residual(z: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[idx] = z
        return model.derivative(x, u0)[idx]

    solution = root(residual, x0[idx], method="hybr", tol=tol)
    if not solution.success or np.max(np.abs(residual(solution.x))) > 1e-8:
        raise RuntimeError(f"equilibrium not found from {dict(guess)}: {solution.message}")
    x_eq = x0.copy()
    x_eq[idx] = solution.x
    A, _ = linearize(model, x_eq, u0, names)
    return Equilibrium(x_eq, names, A, np.linalg.eigvals(A))
