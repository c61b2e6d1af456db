"""LQR heading autopilot on the moving mass with its servo dynamics (6.3.17)-(6.3.19).

State x = [v, r, p, phi, psi - psi_d, y_v, y_vel], input the servo command y_d, outputs
y = C x = [r, p, phi, psi, y_v, y_vel] (6.3.18), cost weights Q = C^T Q_y C with
Q_y = diag(1, 5e3, 1e2, 1e3, 1e3, 1e6) and R_u = 1 (Sec. 6.3.1).

Why a discrete design. The continuous LQR with these weights (``continuous_gain``, kept for
comparison) closes the servo loop with a pole near -5760 1/s: the huge weight on y_vel asks
for a rail speed that follows y_d within 0.2 ms. A controller that holds its output over a
10 ms communication step cannot realise that pole; the continuous gains sampled at 10 ms
give a closed loop with an eigenvalue of modulus ~57 (violently unstable). So the gain the
autopilot uses is the discrete-time LQR for the zero-order-hold discretisation of the same
plant at the controller's sample time (zero-order hold + discrete LQR, as python-control's
``c2d`` + ``dlqr``, computed in numpy by :mod:`controller_fmu.matrix_exponential` and
:mod:`controller_fmu.riccati`: the FMU's host has no scipy or python-control) with the
same Q and R. Its slow closed-loop poles match the continuous design's (about -0.16 +- 0.16i
1/s at U0 = 1.525 m/s), and it is stable at every sample time from 1 to 50 ms.

The matrices come from linearising the plant's own equations (:mod:`lateral_model`) at
u = design_speed for the current vehicle parameters, at construction; nothing is typed in.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from controller_fmu import riccati
from controller_fmu.lateral_model import CONTROL_STATES, LateralDesignModel
from controller_fmu.lqr_weights import DISSERTATION_Q_Y as DISSERTATION_Q_Y
from controller_fmu.lqr_weights import DISSERTATION_R_U as DISSERTATION_R_U
from controller_fmu.matrix_exponential import expm, zero_order_hold

OUTPUT_STATES: tuple[str, ...] = CONTROL_STATES[1:]
"""y = [r, p, phi, psi, y_v, y_vel]: every state but v (6.3.18)."""


def output_matrix() -> np.ndarray:
    """C of (6.3.18), 6x7: y picks every state of x but v."""
    return np.eye(len(CONTROL_STATES))[1:]


def state_weight(q_y: Sequence[float]) -> np.ndarray:
    """Q = C^T diag(Q_y) C, 7x7, from the weights ``q_y`` on y = [r (rad/s), p (rad/s),
    phi (rad), psi (rad), y_v (m), y_vel (m/s)] of (6.3.18).

    Raises:
        ValueError: q_y is not 6 finite non-negative weights.
    """
    weights = np.asarray(q_y, dtype=float)
    if (
        weights.shape != (len(OUTPUT_STATES),)
        or not np.all(np.isfinite(weights))
        or np.any(weights < 0)
    ):
        raise ValueError(
            f"Q_y = {weights.tolist()!r}: expected {len(OUTPUT_STATES)} finite weights >= 0 on "
            f"{list(OUTPUT_STATES)}"
        )
    C = output_matrix()
    Q: np.ndarray = C.T @ np.diag(weights) @ C
    return Q


def _check_r(r_u: float) -> None:
    if not (np.isfinite(r_u) and r_u > 0.0):
        raise ValueError(f"R_u = {r_u!r}: expected a finite weight > 0")


def continuous_gain(
    A: np.ndarray, B: np.ndarray, q_y: Sequence[float], r_u: float
) -> tuple[np.ndarray, np.ndarray]:
    """The dissertation's continuous LQR (as control.lqr), minimising the cost (6.3.9)
    with Q = C^T Q_y C: gain K (7,) with y_d = -K x
    (y_d in m, so K in m per unit of each state of :data:`CONTROL_STATES`), and the
    closed-loop eigenvalues of A - B K, 1/s."""
    _check_r(r_u)
    K, _, poles = riccati.lqr(A, B, state_weight(q_y), r_u)
    return np.asarray(K).ravel(), np.asarray(poles)


def discrete_gain(
    A: np.ndarray, B: np.ndarray, q_y: Sequence[float], r_u: float, dt: float
) -> tuple[np.ndarray, np.ndarray]:
    """Discrete LQR (zero-order hold + dlqr, as control's c2d + dlqr) of the cost (6.3.9)
    for sample time dt:
    gain K (7,) with y_d[k] = -K x[k] (m per unit of each state of
    :data:`CONTROL_STATES`), and the closed-loop eigenvalues of Ad - Bd K (|z| < 1 when
    stable)."""
    _check_r(r_u)
    Ad, Bd = zero_order_hold(A, B, dt)  # as control.c2d
    Q = state_weight(q_y)
    try:
        K, _, poles = riccati.dlqr(Ad, Bd, Q, r_u)
    except ValueError:
        raise ValueError(no_gain_reason(Ad, Q, CONTROL_STATES, q_y, r_u)) from None
    return np.asarray(K).ravel(), np.asarray(poles)


def delayed_poles(
    A: np.ndarray, B: np.ndarray, gain: np.ndarray, dt: float, delay: float
) -> np.ndarray:
    """The closed-loop poles z of the sampled loop y_d[k] = -K x[k] (held over each
    sample of dt s) on x' = A x + B y_d when each command reaches the plant ``delay`` s
    late (delay >= 0: a coupling that hands it on one communication step late, a delay
    fault of several steps on it); stable when every |z| < 1.

    Exact for the zero-order hold (the modified z-transform, written out in numpy because
    the FMU's host has no python-control): with delay = m dt + f, 0 < f <= dt (m = 0,
    f = 0 for none), over a sample the plant is driven by the command q = m + 1 samples
    old for f s, then by the one m samples old (y_d[k] itself for m = 0), so
    x[k+1] = Ad x[k] + G1 y_d[k-q] + G0 y_d[k-m] with G0 = int_0^(dt-f) e^(A s) ds B and
    G1 = e^(A (dt-f)) int_0^f e^(A s) ds B; the loop's state is x and the q commands
    y_d[k-1] ... y_d[k-q] (a shift register), so it has q poles more than Ad - Bd K.

    Raises:
        ValueError: delay is negative.
    """
    if not delay >= 0.0:
        raise ValueError(f"delay {delay!r} s: expected a delay >= 0 s")
    K = np.asarray(gain, dtype=float).reshape(1, -1)
    n = K.shape[1]
    q = max(1, math.ceil(delay / dt - 1e-9))  # a whole number of samples within rounding
    fraction = min(max(delay - (q - 1) * dt, 0.0), dt)
    Ad, _ = zero_order_hold(A, B, dt)
    g0 = _held(A, B, dt - fraction)
    g1 = expm(A * (dt - fraction)) @ _held(A, B, fraction)
    loop = np.zeros((n + q, n + q))
    loop[:n, :n] = Ad
    loop[:n, n + q - 1 :] = g1  # the oldest command, y_d[k-q]
    if q == 1:
        loop[:n, :n] -= g0 @ K  # the new command, y_d[k] = -K x[k]
    else:
        loop[:n, n + q - 2 : n + q - 1] += g0  # y_d[k-m], m = q - 1
    loop[n : n + 1, :n] = -K  # the register's newest at k + 1: y_d[k]
    loop[n + 1 :, n : n + q - 1] = np.eye(q - 1)  # the others shift on
    poles: np.ndarray = np.linalg.eigvals(loop)
    return poles


def _held(A: np.ndarray, B: np.ndarray, duration: float) -> np.ndarray:
    """int_0^duration e^(A s) ds B, the state a unit input held ``duration`` s adds (zero
    for no time)."""
    if duration <= 0.0:
        return np.zeros((A.shape[0], 1))
    return zero_order_hold(A, B, duration)[1]


def no_gain_reason(
    Ad: np.ndarray, Q: np.ndarray, states: Sequence[str], q_y: Sequence[float], r_u: float
) -> str:
    """Why the discrete LQR on Ad with weights Q found no stabilising gain, in words: an
    open-loop mode on the unit circle that Q does not see (no stabilising solution exists;
    e.g. psi, the free heading, with lqr_q_yaw = 0), named by the weighable
    output it lies most along (``states`` names Ad's states); else the other causes (a
    mode y_d hardly moves, weights too far apart)."""
    eigenvalues, vectors = np.linalg.eig(Ad)
    weights = f"Q_y = {list(map(float, q_y))!r} on {list(OUTPUT_STATES)}, R_u = {r_u!r}"
    positive = [q for q in (*q_y, r_u) if q > 0.0]
    for k, z in enumerate(eigenvalues):
        v = vectors[:, k]
        seen = float(np.real(v.conj() @ Q @ v)) / float(np.real(v.conj() @ v))
        if abs(abs(z) - 1.0) <= 1e-9 and seen <= 1e-12 * min(positive):
            weighable = [i for i, name in enumerate(states) if name in OUTPUT_STATES]
            state = states[weighable[int(np.argmax(np.abs(v[weighable])))]]
            return (
                f"no stabilising LQR gain for {weights}: the open-loop mode z = "
                f"{complex(z):.6g} (on the unit circle, along {state}) has no weight, so the "
                f"cost does not grow while it drifts and no gain stabilises it; expected a "
                f"weight > 0 on {state}"
            )
    return (
        f"no stabilising LQR gain found for {weights} (the positive weights span "
        f"{np.log10(max(positive) / min(positive)):.0f} orders of magnitude): an open-loop "
        "mode with |z| >= 1 that the mass command hardly moves at this design speed, or "
        "weights too far apart (more than about 1e12) for the Riccati equation to resolve"
    )


class LqrHeading:
    """The sampled LQR heading controller, designed at construction.

    Args:
        design: the plant's lateral design model (vehicle and U0).
        sample_time: the sample time the gain is designed for, s.
        q_y, r_u: the weights (default: the dissertation's).
    """

    def __init__(
        self,
        design: LateralDesignModel,
        sample_time: float,
        q_y: Sequence[float] = DISSERTATION_Q_Y,
        r_u: float = DISSERTATION_R_U,
    ) -> None:
        self.A, self.B = design.linearize()
        self.sample_time = float(sample_time)
        try:
            self.gain, self.poles = discrete_gain(self.A, self.B, q_y, r_u, self.sample_time)
        except ValueError as exc:
            raise ValueError(
                f"LQR at design_speed {design.design_speed!r} m/s, sample time "
                f"{sample_time!r} s: {exc}"
            ) from None
        if not np.all(np.abs(self.poles) < 1.0):
            raise ValueError(
                f"the discrete LQR at sample time {sample_time} s is not stable "
                f"(closed-loop |z| max {np.abs(self.poles).max():.6g})"
            )

    def command(self, x: np.ndarray) -> float:
        """y_d = -K x (Sec. 6.3.1's delta u = -K delta z), m (unsaturated), x in
        :data:`CONTROL_STATES` order."""
        return -float(self.gain @ x)
