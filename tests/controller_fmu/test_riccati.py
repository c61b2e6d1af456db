"""Riccati equations without scipy: scipy's and python-control's solutions, or better."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from controller_fmu import riccati
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.lqr import DISSERTATION_Q_Y, DISSERTATION_R_U, state_weight
from controller_fmu.matrix_exponential import zero_order_hold
from plant_fmu.model.parameters import load_vehicle

R = np.array([[DISSERTATION_R_U]])


@pytest.fixture(scope="module")
def design() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The LQR autopilot's design: A, B at U0 = 1.525 m/s and Q = C^T Q_y C."""
    A, B = LateralDesignModel(load_vehicle("remus100"), 1.525).linearize()
    return A, B, state_weight(DISSERTATION_Q_Y)


def _relative(X: np.ndarray, reference: np.ndarray) -> float:
    return float(np.linalg.norm(X - reference) / np.linalg.norm(reference))


def _discrete_residual(A, B, Q, X, weight=R) -> float:
    gain = np.linalg.solve(weight + B.T @ X @ B, B.T @ X @ A)
    residual = A.T @ X @ A - X - A.T @ X @ B @ gain + Q
    return float(np.linalg.norm(residual) / np.linalg.norm(Q))


def _continuous_residual(A, B, Q, weight, X) -> float:
    """The continuous equation's residual relative to its largest term."""
    quadratic = X @ B @ np.linalg.solve(weight, B.T) @ X
    residual = A.T @ X + X @ A - quadratic + Q
    terms = max(np.linalg.norm(A.T @ X), np.linalg.norm(quadratic), np.linalg.norm(Q))
    return float(np.linalg.norm(residual) / terms)


def test_continuous_solution_agrees_with_scipy(design):
    """The dissertation's continuous LQR (servo pole near -5760 1/s)."""
    A, B, Q = design
    X = riccati.solve_continuous_are(A, B, Q, R)
    assert _relative(X, scipy.linalg.solve_continuous_are(A, B, Q, R)) <= 1e-10
    K, _, poles = riccati.lqr(A, B, Q, R)
    K_control, _, poles_control = control.lqr(A, B, Q, R)
    assert _relative(K, np.asarray(K_control)) <= 1e-10
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(poles_control), rtol=1e-8)


@pytest.mark.parametrize("dt", [0.001, 0.01, 0.05])
def test_discrete_solution_agrees_with_scipy_refined_and_has_a_smaller_residual(design, dt):
    """scipy's discrete solution of this stiff design has a residual of 1e-8..1e-6 of Q
    (its X differs from ours by up to 1.5e-8); one Newton step with scipy's own Stein
    solver brings it to ours within 1e-10."""
    A, B, Q = design
    Ad, Bd = zero_order_hold(A, B, dt)
    X = riccati.solve_discrete_are(Ad, Bd, Q, R)
    theirs = scipy.linalg.solve_discrete_are(Ad, Bd, Q, R)
    assert _discrete_residual(Ad, Bd, Q, X) <= _discrete_residual(Ad, Bd, Q, theirs)
    assert _discrete_residual(Ad, Bd, Q, X) <= 1e-11
    gain = np.linalg.solve(R + Bd.T @ theirs @ Bd, Bd.T @ theirs @ Ad)
    closed = Ad - Bd @ gain
    refined = scipy.linalg.solve_discrete_lyapunov(closed.T, Q + gain.T @ R @ gain)
    assert _relative(X, refined) <= 1e-10
    K, _, poles = riccati.dlqr(Ad, Bd, Q, R)
    K_control, _, poles_control = control.dlqr(Ad, Bd, Q, R)
    assert _relative(K, np.asarray(K_control)) <= 1e-7  # scipy's X, as above
    np.testing.assert_allclose(np.sort_complex(poles), np.sort_complex(poles_control), atol=1e-7)
    assert np.abs(poles).max() < 1.0


SYSTEMS = st.integers(1, 5).flatmap(
    lambda n: st.tuples(
        arrays(float, (n, n), elements=st.floats(-2.0, 2.0)),
        arrays(float, (n, 2), elements=st.floats(-2.0, 2.0)),
        arrays(float, (n, n), elements=st.floats(-1.0, 1.0)),
    )
)


@settings(max_examples=30, deadline=None)  # the fast tier's minute
@given(system=SYSTEMS, weight=st.sampled_from([1e-2, 1.0, 1e2]))
def test_solutions_of_random_controllable_systems_agree_with_scipy(system, weight):
    """Each solution satisfies its equation at least as well as scipy's (relative residual
    within twice scipy's, or 1e-12) and equals scipy's to what the problem's conditioning
    allows: a nearly uncontrollable system (smallest controllability singular value 0.03,
    R = 0.01) moves scipy's own solution by 9e-9 under one Newton step, so agreement is
    asked to 1e-6, far below what a wrong (non-stabilising) solution differs by."""
    A, B, C = system
    n = A.shape[0]
    controllability = np.hstack([np.linalg.matrix_power(A, k) @ B for k in range(n)])
    if np.linalg.svd(controllability, compute_uv=False).min() < 1e-2:
        return  # (nearly) not stabilisable: no well-posed reference
    Q = C.T @ C + 1e-2 * np.eye(n)
    Rw = weight * np.eye(2)
    continuous = scipy.linalg.solve_continuous_are(A, B, Q, Rw)
    ours = riccati.solve_continuous_are(A, B, Q, Rw)
    residual = _continuous_residual(A, B, Q, Rw, ours)
    assert residual <= max(2.0 * _continuous_residual(A, B, Q, Rw, continuous), 1e-12)
    assert _relative(ours, continuous) <= 1e-6
    Ad = A / max(1.0, float(np.abs(np.linalg.eigvals(A)).max()))
    discrete = scipy.linalg.solve_discrete_are(Ad, B, Q, Rw)
    ours = riccati.solve_discrete_are(Ad, B, Q, Rw)
    residual = _discrete_residual(Ad, B, Q, ours, Rw)
    assert residual <= max(2.0 * _discrete_residual(Ad, B, Q, discrete, Rw), 1e-12)
    assert _relative(ours, discrete) <= 1e-6


def test_an_unstabilisable_system_is_refused():
    A, B, Q = np.array([[1.0]]), np.array([[0.0]]), np.array([[1.0]])
    with pytest.raises(ValueError, match="no stabilising solution"):
        riccati.solve_continuous_are(A, B, Q, 1.0)
    with pytest.raises(ValueError, match="no stabilising solution"):
        riccati.solve_discrete_are(2.0 * A, B, Q, 1.0)


def test_matrices_that_do_not_fit_are_refused():
    with pytest.raises(ValueError, match=r"got A \(2, 2\), B \(2, 1\), Q \(3, 3\), R \(1, 1\)"):
        riccati.dlqr(np.eye(2), np.ones((2, 1)), np.eye(3), 1.0)
    with pytest.raises(ValueError, match="must be finite"):
        riccati.lqr(np.eye(2), np.ones((2, 1)), np.eye(2) * np.nan, 1.0)


@pytest.mark.parametrize("weights", [(0.0,) * 6, (0.0, 1.0, 0.0, 0.0, 0.0, 0.0)])
def test_an_unstable_mode_the_weights_do_not_see_is_still_stabilised_as_scipy_does(design, weights):
    """The sliding mode's reduced design (no psi) with zero weights, or a weight on p
    alone: the open-loop sway-yaw mode (z = 1.0104 at 10 ms) is unstable and Q does not
    see it. A stabilising solution exists (scipy's and control.dlqr's, which move that
    pole to its mirror image); the doubling alone, started from H = Q = 0, stayed at
    X = 0 and the design was refused as having none."""
    A, B, _ = design
    Ad, Bd = zero_order_hold(A, B, 0.01)
    keep = [0, 1, 2, 3, 5, 6]  # every state but psi
    Ar, Br = Ad[np.ix_(keep, keep)], Bd[keep]
    Q = np.diag([0.0, *weights[:3], *weights[4:]])
    reference = scipy.linalg.solve_discrete_are(Ar, Br, Q, R)
    K, X, poles = riccati.dlqr(Ar, Br, Q, R)
    assert _relative(X, reference) < 1e-9
    assert np.abs(poles).max() < 1.0
    K_control, _, _ = control.dlqr(Ar, Br, Q, R)
    np.testing.assert_allclose(K, K_control, rtol=1e-8)


def test_a_mode_on_the_unit_circle_the_weights_do_not_see_is_refused(design):
    """psi (z = 1) with no weight: no stabilising solution exists (control.dlqr refuses
    too); the iterations must not return a gain that leaves |z| = 1 - 1e-16."""
    A, B, _ = design
    Ad, Bd = zero_order_hold(A, B, 0.01)
    with pytest.raises(ValueError, match="no stabilising solution"):
        riccati.solve_discrete_are(Ad, Bd, state_weight((1.0, 5e3, 1e2, 0.0, 1e3, 1e6)), R)
