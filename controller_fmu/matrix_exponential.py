"""The matrix exponential and the zero-order-hold discretisation the controllers' design
uses, in numpy.

Why by hand: the FMUs ship these designs, and an FMU's host Python holds only the
standard library and numpy (no scipy, no python-control). :func:`expm` is the scaling and
squaring method with Pade approximants of N. J. Higham, "The scaling and squaring method
for the matrix exponential revisited", SIAM J. Matrix Anal. Appl. 26(4), 2005 (its
Algorithm 2.3; scipy's ``scipy.linalg.expm`` refines the same method), and
:func:`zero_order_hold` the exponential of the augmented matrix, as
``control.c2d(..., "zoh")`` computes it. ``tests/controller_fmu/test_matrix_exponential.py``
compares both with scipy's and python-control's.
"""

from __future__ import annotations

import math

import numpy as np

# Pade coefficients b_0..b_m (Higham 2005, Table 2.3 and (2.7)) and the largest 1-norm
# theta_m for which each degree m keeps the backward error below the unit roundoff.
_PADE: dict[int, tuple[float, ...]] = {
    3: (120.0, 60.0, 12.0, 1.0),
    5: (30240.0, 15120.0, 3360.0, 420.0, 30.0, 1.0),
    7: (17297280.0, 8648640.0, 1995840.0, 277200.0, 25200.0, 1512.0, 56.0, 1.0),
    9: (
        17643225600.0, 8821612800.0, 2075673600.0, 302702400.0, 30270240.0,
        2162160.0, 110880.0, 3960.0, 90.0, 1.0,
    ),
    13: (
        64764752532480000.0, 32382376266240000.0, 7771770303897600.0, 1187353796428800.0,
        129060195264000.0, 10559470521600.0, 670442572800.0, 33522128640.0, 1323241920.0,
        40840800.0, 960960.0, 16380.0, 182.0, 1.0,
    ),
}  # fmt: skip
_THETA: dict[int, float] = {
    3: 1.495585217958292e-2,
    5: 2.539398330063230e-1,
    7: 9.504178996162932e-1,
    9: 2.097847961257068e0,
    13: 5.371920351148152e0,
}


def expm(matrix: np.ndarray) -> np.ndarray:
    """exp(matrix) of a square real matrix (Higham 2005, Algorithm 2.3).

    Raises:
        ValueError: the matrix is not square or not finite.
    """
    a = np.asarray(matrix, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or not np.all(np.isfinite(a)):
        raise ValueError(f"expm: expected a finite square matrix, got shape {a.shape}")
    norm = float(np.linalg.norm(a, 1)) if a.size else 0.0
    for degree in (3, 5, 7, 9):
        if norm <= _THETA[degree]:
            return _pade_quotient(*_pade_low(a, degree))
    squarings = max(0, math.ceil(math.log2(norm / _THETA[13])))
    result = _pade_quotient(*_pade_13(a / 2.0**squarings))
    for _ in range(squarings):
        result = result @ result
    return result


def _pade_low(a: np.ndarray, degree: int) -> tuple[np.ndarray, np.ndarray]:
    """(U, V) of the [m/m] Pade approximant, m = 3, 5, 7 or 9: U the odd part, V the even."""
    b = _PADE[degree]
    identity = np.eye(a.shape[0])
    a2 = a @ a
    power = identity  # A^(2k)
    odd = b[1] * identity
    even = b[0] * identity
    for k in range(1, degree // 2 + 1):
        power = power @ a2
        odd = odd + b[2 * k + 1] * power
        even = even + b[2 * k] * power
    return a @ odd, even


def _pade_13(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(U, V) of the [13/13] Pade approximant, evaluated as Higham's (2.11)."""
    b = _PADE[13]
    identity = np.eye(a.shape[0])
    a2 = a @ a
    a4 = a2 @ a2
    a6 = a4 @ a2
    u = a @ (
        a6 @ (b[13] * a6 + b[11] * a4 + b[9] * a2)
        + b[7] * a6 + b[5] * a4 + b[3] * a2 + b[1] * identity
    )  # fmt: skip
    v = (
        a6 @ (b[12] * a6 + b[10] * a4 + b[8] * a2)
        + b[6] * a6 + b[4] * a4 + b[2] * a2 + b[0] * identity
    )  # fmt: skip
    return u, v


def _pade_quotient(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """r = (V - U)^-1 (V + U)."""
    result: np.ndarray = np.linalg.solve(v - u, v + u)
    return result


def zero_order_hold(A: np.ndarray, B: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(Ad, Bd) of x' = A x + B u with u held over each sample of dt s: the blocks of
    exp([[A, B], [0, 0]] dt).

    Raises:
        ValueError: dt is not a finite time > 0, or A, B do not fit.
    """
    if not (math.isfinite(dt) and dt > 0.0):
        raise ValueError(f"sample time {dt!r}: expected a finite time > 0 s")
    A = np.atleast_2d(np.asarray(A, dtype=float))
    B = np.asarray(B, dtype=float).reshape(A.shape[0], -1)
    n, m = B.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n] = A
    augmented[:n, n:] = B
    exp = expm(augmented * dt)
    return exp[:n, :n].copy(), exp[:n, n:].copy()
