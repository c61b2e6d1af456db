"""Equilibria of the plant: steady states of its reduced (non-cyclic) dynamics.

Examples 5.1-5.3 of the dissertation are equilibria found here, on the plant's own
equations (:class:`plant_fmu.model.dynamics.PlantModel`), with their Jacobian eigenvalues
from :func:`plant_fmu.model.linearization.linearize`.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from plant_fmu.model.dynamics import STATE_INDEX, PlantModel
from plant_fmu.model.linearization import input_vector, linearize, state_vector

# Position and heading never enter the force balance (cyclic coordinates), so an
# equilibrium fixes only the rest: a steady turn is an equilibrium of the reduced system.
CYCLIC_STATES = ("north", "east", "down", "yaw")


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
