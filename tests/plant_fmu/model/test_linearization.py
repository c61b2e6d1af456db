"""The plant's Jacobians (``linearize``, the controllers' design matrices) at operating
points away from the design's straight run: other speeds, the mass off-centre, heeled,
turning, pitched, in a current, in the lateral and the full variant; each checked against
scipy's adaptive finite differences and against the nonlinear derivative itself (the
first-order Taylor remainder shrinks as the square of the perturbation)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from scipy.differentiate import jacobian

from plant_fmu.model.dynamics import INPUT_NAMES, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

OPERATING_POINTS = {  # (states, inputs), SI units
    "design": ({"u": 1.525}, {"thrust": 9.0}),
    "slow heeled turn": (
        {"u": 0.5, "v": 0.05, "r": -0.1, "p": 0.2, "roll": 0.3,
         "mass_position": 0.03, "mass_velocity": 0.01},
        {"thrust": 2.0, "mass_position_cmd": 0.04, "tunnel_force": 3.0},
    ),
    "fast pitched dive in a current": (
        {"u": 2.2, "v": -0.1, "r": 0.2, "p": -0.3, "roll": -0.6, "yaw": 2.0, "w": 0.05,
         "q": 0.1, "pitch": 0.3, "down": 5.0, "mass_position": -0.05},
        {"thrust": 20.0, "fin_angle": 0.1, "current_north": -0.1, "current_east": 0.2},
    ),
}  # fmt: skip


def _point(variant: Variant, name: str) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(x0, u0, the variant's free states) at the named operating point."""
    states, inputs = OPERATING_POINTS[name]
    free = list(variant.states)
    return state_vector({k: v for k, v in states.items() if k in free}), input_vector(inputs), free


def _vectorised(
    evaluate: Callable[[np.ndarray], np.ndarray], rows: list[int]
) -> Callable[[np.ndarray], np.ndarray]:
    """``evaluate(point)`` over the trailing axes scipy's differentiation hands in."""

    def f(points: np.ndarray) -> np.ndarray:
        out = np.empty((len(rows), *points.shape[1:]))
        for at in np.ndindex(points.shape[1:]):
            out[(slice(None), *at)] = evaluate(points[(slice(None), *at)])[rows]
        return out

    return f


@pytest.mark.parametrize("variant", [Variant.LATERAL, Variant.FULL])
@pytest.mark.parametrize("name", list(OPERATING_POINTS))
def test_jacobians_are_scipys_adaptive_differences(
    remus: VehicleParameters, variant: Variant, name: str
) -> None:
    """A and B of every free state and every input agree with scipy.differentiate's
    adaptive-order central differences to 1e-7 of the largest entry."""
    model = PlantModel(remus, variant=variant)
    x0, u0, free = _point(variant, name)
    rows = [STATE_INDEX[s] for s in free]
    A, B = linearize(model, x0, u0, free, INPUT_NAMES)

    def in_states(z: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[rows] = z
        return model.derivative(x, u0)

    A_ref = jacobian(_vectorised(in_states, rows), x0[rows], initial_step=1e-3).df
    B_ref = jacobian(_vectorised(lambda u: model.derivative(x0, u), rows), u0, initial_step=1e-3).df
    scale = max(np.abs(A_ref).max(), np.abs(B_ref).max())
    np.testing.assert_allclose(A, A_ref, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(B, B_ref, rtol=0, atol=1e-7 * scale)


@pytest.mark.parametrize("variant", [Variant.LATERAL, Variant.FULL])
@pytest.mark.parametrize("name", list(OPERATING_POINTS))
def test_the_linear_model_predicts_the_derivative_to_second_order(
    remus: VehicleParameters, variant: Variant, name: str
) -> None:
    """f(x0 + e dx, u0 + e du) - f(x0, u0) - e (A dx + B du) shrinks four-fold as e
    halves (a Jacobian off in any entry would leave a remainder linear in e), for a
    random direction through every free state and input."""
    model = PlantModel(remus, variant=variant)
    x0, u0, free = _point(variant, name)
    rows = [STATE_INDEX[s] for s in free]
    A, B = linearize(model, x0, u0, free, INPUT_NAMES)
    rng = np.random.default_rng(7)
    dx, du = np.zeros_like(x0), rng.normal(size=u0.size) * np.abs(u0).clip(0.1)
    dx[rows] = rng.normal(size=len(rows)) * np.abs(x0[rows]).clip(0.05)

    def remainder(e: float) -> float:
        change = model.derivative(x0 + e * dx, u0 + e * du) - model.derivative(x0, u0)
        return float(np.linalg.norm(change[rows] - e * (A @ dx[rows] + B @ du)))

    ratios = [remainder(e) / remainder(e / 2) for e in (0.04, 0.02, 0.01)]
    np.testing.assert_allclose(ratios, 4.0, rtol=0.1)
