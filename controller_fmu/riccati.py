"""Algebraic Riccati equations and the LQR gains from them, in numpy.

Why by hand: the autopilot FMU designs its LQR and sliding-mode gains when it starts, and an
FMU's host Python holds only the standard library and numpy (no scipy, no python-control).
The analysis code in ``cosim`` keeps using scipy and python-control, and
``tests/controller_fmu/test_riccati.py`` compares these solutions with theirs.

Method: the structure-preserving doubling algorithm (SDA; reviewed in F. Poloni, "Iterative
and doubling algorithms for Riccati-type matrix equations: a comparative introduction",
GAMM-Mitteilungen 43(4), 2020; the continuous equation goes through a Cayley transform
first, E. K.-W. Chu, H.-Y. Fan, W.-W. Lin, Linear Algebra Appl. 396, 2005) converges
quadratically to the stabilising solution without inverting A (the discretised servo of the
autopilot's design has an eigenvalue near e^-58, so methods that invert A lose every
digit); then one Newton step (Kleinman's for the continuous equation, Hewer's for the
discrete one, each a linear Lyapunov/Stein equation solved through its Kronecker form, fine
for the autopilot's 7 states) removes the doubling's rounding. On the autopilot's design
the result's residual is at most scipy's.

Equations (G = B R^-1 B^T):
    continuous: A^T X + X A - X B R^-1 B^T X + Q = 0
    discrete:   A^T X A - X - A^T X B (R + B^T X B)^-1 B^T X A + Q = 0
"""

from __future__ import annotations

import contextlib

import numpy as np

_UNIT_CIRCLE_MARGIN = 1e-10  # |z| closer to 1 than this is on the unit circle
_MAX_DOUBLINGS = 100  # each squares the convergence factor; 20 reach 1e-16 from 0.99998


def solve_continuous_are(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray | float
) -> np.ndarray:
    """The stabilising solution X of the continuous-time equation (module docstring).

    Raises:
        ValueError: bad shapes, or no stabilising solution ((A, B) not stabilisable, or
            (Q, A) with an unobservable mode on the imaginary axis).
    """
    A, B, Q, R = _checked(A, B, Q, R)
    n = A.shape[0]
    identity = np.eye(n)
    G = B @ np.linalg.solve(R, B.T)
    # Cayley transform with gamma beyond every eigenvalue of A (|lambda| <= ||A||_1), so
    # A - gamma I is invertible: the stabilising solution of the continuous equation is
    # that of a discrete one in the doubling's form (Chu, Fan, Lin 2005).
    gamma = 2.0 * max(1.0, float(np.linalg.norm(A, 1)))
    shifted_inverse = np.linalg.inv(A - gamma * identity)
    W = (A - gamma * identity).T + Q @ shifted_inverse @ G
    W_inverse = np.linalg.inv(W)
    X = _doubling(
        identity + 2.0 * gamma * W_inverse.T,
        2.0 * gamma * shifted_inverse @ G @ W_inverse,
        2.0 * gamma * W_inverse @ Q @ shifted_inverse,
    )
    X = _kleinman_step(A, B, Q, R, X)
    if not np.all(np.linalg.eigvals(A - G @ X).real < 0.0):
        raise ValueError("the continuous Riccati equation has no stabilising solution")
    return X


def solve_discrete_are(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray | float
) -> np.ndarray:
    """The stabilising solution X of the discrete-time equation (module docstring).

    Raises:
        ValueError: bad shapes, or no stabilising solution.
    """
    A, B, Q, R = _checked(A, B, Q, R)
    G = B @ np.linalg.solve(R, B.T)
    X = _hewer_step(A, B, Q, R, _doubling(A, G, Q))
    if not _stabilises(A, B, R, X):
        # The doubling needs (Q, A) detectable: with an unstable mode Q does not see (Q = 0
        # on an unstable system) it stops at a solution that leaves the mode unstable (from
        # H = Q = 0 it never moves). Hewer's iteration converges to the stabilising
        # solution from any stabilising gain: take one from the equation with Q + eps I.
        eps = 1e-6 * max(1.0, float(np.linalg.norm(Q, 1)))
        with contextlib.suppress(ValueError, np.linalg.LinAlgError):
            X = _hewer_iterations(A, B, Q, R, _doubling(A, G, Q + eps * np.eye(A.shape[0])))
    if not _stabilises(A, B, R, X):
        raise ValueError("the discrete Riccati equation has no stabilising solution")
    return X


def _stabilises(A: np.ndarray, B: np.ndarray, R: np.ndarray, X: np.ndarray) -> bool:
    """The gain of X puts every closed-loop eigenvalue inside the unit circle, by more
    than rounding (a mode on the circle that Q does not see, as the free heading psi with
    no weight, has no stabilising solution: the iterations leave it at |z| = 1 - 1e-16)."""
    closed = A - B @ _discrete_gain(A, B, R, X)
    return bool(np.all(np.abs(np.linalg.eigvals(closed)) < 1.0 - _UNIT_CIRCLE_MARGIN))


def _hewer_iterations(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, X: np.ndarray
) -> np.ndarray:
    """Hewer's steps from X (whose gain stabilises) until they stop improving: each keeps
    the gain stabilising and converges quadratically (G. Hewer, IEEE TAC 16(4), 1971)."""
    change = np.inf
    for _ in range(_MAX_DOUBLINGS):
        X_next = _hewer_step(A, B, Q, R, X)
        step = float(np.linalg.norm(X_next - X, 1)) / max(float(np.linalg.norm(X_next, 1)), 1e-300)
        X = X_next
        if step <= 1e-15 or step >= change:  # converged, or at the rounding floor
            break
        change = step
    return X


def lqr(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, X, poles) of the continuous LQR, as ``control.lqr``: u = -K x minimises
    the integral of x^T Q x + u^T R u; poles are the eigenvalues of A - B K."""
    A, B, Q, R = _checked(A, B, Q, R)
    X = solve_continuous_are(A, B, Q, R)
    K: np.ndarray = np.linalg.solve(R, B.T @ X)
    return K, X, np.linalg.eigvals(A - B @ K)


def dlqr(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(K, X, poles) of the discrete LQR, as ``control.dlqr``: u[k] = -K x[k] minimises
    the sum of x^T Q x + u^T R u; poles are the eigenvalues of A - B K."""
    A, B, Q, R = _checked(A, B, Q, R)
    X = solve_discrete_are(A, B, Q, R)
    K = _discrete_gain(A, B, R, X)
    return K, X, np.linalg.eigvals(A - B @ K)


def _checked(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray | float
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The four matrices as float arrays of fitting shapes (R may be a number)."""
    A = np.atleast_2d(np.asarray(A, dtype=float))
    n = A.shape[0]
    B = np.asarray(B, dtype=float).reshape(n, -1)
    Q = np.atleast_2d(np.asarray(Q, dtype=float))
    R = np.atleast_2d(np.asarray(R, dtype=float))
    m = B.shape[1]
    if A.shape != (n, n) or Q.shape != (n, n) or R.shape != (m, m):
        raise ValueError(
            f"Riccati equation: expected A n x n, B n x m, Q n x n, R m x m; got A {A.shape}, "
            f"B {B.shape}, Q {Q.shape}, R {R.shape}"
        )
    if not all(np.all(np.isfinite(M)) for M in (A, B, Q, R)):
        raise ValueError("Riccati equation: A, B, Q and R must be finite")
    return A, B, 0.5 * (Q + Q.T), 0.5 * (R + R.T)


def _doubling(A: np.ndarray, G: np.ndarray, H: np.ndarray) -> np.ndarray:
    """The SDA's limit of H_k:
    A_k+1 = A_k W^-1 A_k, G_k+1 = G_k + A_k W^-1 G_k A_k^T, H_k+1 = H_k + A_k^T H_k W^-1 A_k
    with W = I + G_k H_k (invertible: G_k, H_k are symmetric positive semi-definite)."""
    identity = np.eye(A.shape[0])
    for _ in range(_MAX_DOUBLINGS):
        with np.errstate(over="ignore", invalid="ignore"):  # a divergence is raised below
            W = identity + G @ H
            W_inverse_A = np.linalg.solve(W, A)
            W_inverse_G = np.linalg.solve(W, G)
            H_next = H + A.T @ H @ W_inverse_A
            G = G + A @ W_inverse_G @ A.T
            A = A @ W_inverse_A
        if not (np.all(np.isfinite(H_next)) and np.all(np.isfinite(G))):
            break
        G, H_next = 0.5 * (G + G.T), 0.5 * (H_next + H_next.T)
        converged = np.linalg.norm(H_next - H, 1) <= 1e-15 * np.linalg.norm(H_next, 1)
        H = H_next
        if converged:
            return H
    raise ValueError("the Riccati equation has no stabilising solution (the doubling diverged)")


def _kleinman_step(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, X: np.ndarray
) -> np.ndarray:
    """One Newton step on the continuous equation: with K = R^-1 B^T X and
    A_c = A - B K, solve A_c^T X' + X' A_c = -(Q + K^T R K)."""
    n = A.shape[0]
    K = np.linalg.solve(R, B.T @ X)
    closed = A - B @ K
    identity = np.eye(n)
    # row-major vec(A_c^T X) = (A_c^T kron I) vec X, vec(X A_c) = (I kron A_c^T) vec X
    operator = np.kron(closed.T, identity) + np.kron(identity, closed.T)
    rhs = -(Q + K.T @ R @ K)
    solution = np.linalg.solve(operator, rhs.reshape(-1)).reshape(n, n)
    return 0.5 * (solution + solution.T)


def _hewer_step(
    A: np.ndarray, B: np.ndarray, Q: np.ndarray, R: np.ndarray, X: np.ndarray
) -> np.ndarray:
    """One Newton step on the discrete equation: with K the gain of X and A_c = A - B K,
    solve X' = A_c^T X' A_c + Q + K^T R K."""
    n = A.shape[0]
    K = _discrete_gain(A, B, R, X)
    closed = A - B @ K
    # row-major vec(A_c^T X A_c) = (A_c^T kron A_c^T) vec X
    operator = np.eye(n * n) - np.kron(closed.T, closed.T)
    rhs = Q + K.T @ R @ K
    solution = np.linalg.solve(operator, rhs.reshape(-1)).reshape(n, n)
    return 0.5 * (solution + solution.T)


def _discrete_gain(A: np.ndarray, B: np.ndarray, R: np.ndarray, X: np.ndarray) -> np.ndarray:
    """K = (R + B^T X B)^-1 B^T X A."""
    K: np.ndarray = np.linalg.solve(R + B.T @ X @ B, B.T @ X @ A)
    return K
