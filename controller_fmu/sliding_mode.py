"""Sliding-mode heading autopilot on the moving mass (6.3.31)-(6.3.45), sampled.

The dissertation's design: write x' = A x + f*(x) + g y_d (6.3.31) with f* = f - A x
(6.3.32); take y_d = -k^T x + y*_d with k_psi = 0 (6.3.40), so A_c = A - g k^T keeps a
zero eigenvalue in psi while k stabilises the rest (computed by LQR on the reduced system
without psi, (6.3.46)-(6.3.47)); the sliding variable is s = w^T x with w the left
eigenvector of A_c for that eigenvalue; and

    y_d = -k^T x + (-w^T f*_hat(x) - eta sgn(s)) / (w^T g)                   (6.3.45)

makes s' = -eta sgn(s) (6.3.39), after which x slides to the origin on s = 0.

Sampled version (why and how). As for the LQR (:mod:`lqr`), the reduced LQR with the
dissertation's weights has a servo pole near -100..-5800 1/s that a 10 ms zero-order hold
cannot realise, so:
* k is the discrete LQR (zero-order hold + dlqr, :mod:`controller_fmu.riccati`) of the
  reduced system at the sample time h, with the LQR weights minus the psi entry;
* A_c becomes the discrete closed loop Ad - Bd k^T; it keeps an eigenvalue 1 in psi (psi
  is cyclic, k_psi = 0), and w is its left eigenvector, scaled so w_psi = 1 (s in rad);
* with one Euler step for the nonlinear remainder, s[k+1] = s[k] + w^T Bd y*_d
  + h w^T f*(x[k]), so y*_d = (-h w^T f*_hat - h eta sat(s/Phi)) / (w^T Bd) gives
  s[k+1] = s[k] - h eta sat(s[k]/Phi). As h -> 0, w^T Bd -> h w^T g and this is (6.3.45).
f*_hat(x) = f(x) - A x with f(x) the plant's own lateral right-hand side at y_d = 0
(:meth:`LateralDesignModel.derivative`), A its Jacobian. A boundary layer Phi replaces
sgn (6.3.73).

Choices (not in the dissertation): eta = 1 rad/s and Phi = 0.5 rad. s = w^T x is
dominated by its sway term (w_v is about -80 rad per m/s at U0 = 1.525 m/s), so lqr-1's
initial state already has s = 0.8 rad: eta = 1 rad/s reaches the layer within a second,
and inside it s decays at eta/Phi = 2 1/s, near the bandwidth of the roll/servo loop, so
the reaching law asks no more than the 6 cm stroke gives (lqr-1 then settles in about
19 s; eta/Phi = 1 1/s takes 25 s, 5 1/s gains little and doubles the command's activity);
h eta/Phi = 0.02 keeps the sampled reaching law far from its stability limit 2 (an eta or
Phi that reaches it is refused: inside the layer s[k+1] = (1 - h eta/Phi) s[k] would grow,
and s would chatter across the layer the boundary layer is there to remove). The
dissertation notes the design is only locally stable (the remainder f* can dominate); it
stabilises lqr-1's initial state (tests/controller_fmu/test_sliding_mode.py).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from controller_fmu import riccati
from controller_fmu.lateral_model import CONTROL_STATES, LateralDesignModel
from controller_fmu.lqr import DISSERTATION_Q_Y, DISSERTATION_R_U, no_gain_reason
from controller_fmu.matrix_exponential import zero_order_hold

_PSI = CONTROL_STATES.index("yaw")
_REACHING_LIMIT = 2.0  # h eta / Phi: the sampled reaching law's stability limit inside Phi
_REDUCED = [i for i in range(len(CONTROL_STATES)) if i != _PSI]


class SlidingModeHeading:
    """The sampled sliding-mode controller (stateless between samples).

    Args:
        design: the plant's lateral design model (vehicle and U0).
        sample_time: h, s.
        eta: reaching rate, rad/s (> 0).
        boundary_layer: Phi, rad (> 0).
        q_y, r_u: the LQR weights on y = [r, p, phi, psi, y_v, y_vel] and y_d; the psi
            weight is dropped for the reduced design (6.3.47).

    Raises:
        ValueError: bad eta/Phi (h eta / Phi >= 2 included: the sampled reaching law is
            unstable inside the boundary layer), or the reduced design leaves w^T Bd = 0.
    """

    def __init__(
        self,
        design: LateralDesignModel,
        sample_time: float,
        eta: float = 1.0,
        boundary_layer: float = 0.5,
        q_y: Sequence[float] = DISSERTATION_Q_Y,
        r_u: float = DISSERTATION_R_U,
    ) -> None:
        if not (math.isfinite(eta) and eta > 0.0):
            raise ValueError(f"sliding-mode eta = {eta!r}: expected a rate > 0 rad/s")
        if not (math.isfinite(boundary_layer) and boundary_layer > 0.0):
            raise ValueError(f"sliding-mode boundary layer = {boundary_layer!r}: expected > 0 rad")
        if not sample_time * eta / boundary_layer < _REACHING_LIMIT:
            raise ValueError(
                f"sliding-mode eta = {eta!r} rad/s with boundary layer {boundary_layer!r} rad "
                f"at sample time {sample_time!r} s: h eta / Phi = "
                f"{sample_time * eta / boundary_layer:.6g}, so inside the layer "
                "s[k+1] = (1 - h eta / Phi) s[k] grows and s chatters across it; expected "
                f"eta / Phi < {_REACHING_LIMIT:g} / h = {_REACHING_LIMIT / sample_time:.6g} 1/s"
            )
        self.design = design
        self.sample_time = float(sample_time)
        self.eta = float(eta)
        self.boundary_layer = float(boundary_layer)
        self.A, self.B = design.linearize()
        Ad, Bd = zero_order_hold(self.A, self.B, self.sample_time)

        # Reduced design without psi (6.3.46)-(6.3.47): y = [r, p, phi, y_v, y_vel].
        q_reduced = [q for i, q in enumerate(q_y) if i != _PSI - 1]
        C = np.eye(len(_REDUCED))[1:]
        Q = C.T @ np.diag(q_reduced) @ C
        reduced = Ad[np.ix_(_REDUCED, _REDUCED)]
        try:
            k_reduced, _, _ = riccati.dlqr(reduced, Bd[_REDUCED], Q, r_u)
        except ValueError:
            names = [CONTROL_STATES[i] for i in _REDUCED]
            raise ValueError(
                f"sliding mode at design_speed {design.design_speed!r} m/s, sample time "
                f"{sample_time!r} s: its LQR without psi (the psi weight is not used): "
                + no_gain_reason(reduced, Q, names, q_y, r_u)
            ) from None
        self.k = np.zeros(len(CONTROL_STATES))
        self.k[_REDUCED] = np.asarray(k_reduced).ravel()

        closed = Ad - Bd @ self.k[None, :]
        eigenvalues, left = np.linalg.eig(closed.T)
        unit = int(np.argmin(np.abs(eigenvalues - 1.0)))
        w = np.real(left[:, unit])
        self.w = w / w[_PSI]
        self.w_bd = float(self.w @ Bd[:, 0])
        if abs(self.w_bd) < 1e-12:
            raise ValueError("sliding surface has w^T Bd = 0: y_d cannot move s")

    def sliding_variable(self, x: np.ndarray) -> float:
        """s = w^T x (6.3.36), rad, x in :data:`CONTROL_STATES` order."""
        return float(self.w @ x)

    def command(self, x: np.ndarray) -> float:
        """y_d of (6.3.45), sampled (module docstring), m (unsaturated), from x in
        :data:`CONTROL_STATES` order (psi as psi - psi_d)."""
        h = self.sample_time
        remainder = self.design.derivative(x, 0.0) - self.A @ x  # f*_hat(x), (6.3.32)
        s = self.sliding_variable(x)
        reaching = self.eta * min(max(s / self.boundary_layer, -1.0), 1.0)
        return -float(self.k @ x) + (-h * float(self.w @ remainder) - h * reaching) / self.w_bd
