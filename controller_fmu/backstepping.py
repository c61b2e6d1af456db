"""Backstepping heading autopilot on the moving mass with a Lyapunov-redesigned tunnel
thruster (Sec. 6.3.3, (6.3.53)-(6.3.73)).

The chain (6.3.53), with the plant's own right-hand sides::

    psi'  = r                              (psi_e = psi - psi_d)
    r'    = f1 + g1 v
    v'    = f2 + g2 phi + delta + u~       (u~: tunnel thruster, delta: mass disturbance)
    phi'  = p
    p'    = f3 + g3 y_v

Model terms. g1 = d r'/d v, g2 = d v'/d phi, g3 = d p'/d y_v and eps4' = d v'/d y_v are
Jacobians of the LATERAL plant at the straight run at U0 with the mass held still
(:meth:`LateralDesignModel.static_mass_jacobian`), and f1, f2, f3 are the plant's rates
r', v', p' at the measured (v, r, p, phi) with the mass at the centre, minus the g-terms:
f1 = r' - g1 v, f2 = v' - g2 phi, f3 = p'. So nothing is re-typed, and the terms (6.3.53)
drops for a strict-feedback form (Gamma3' in yaw, the p terms in sway, sin phi ~ phi) are
kept: with filtered derivatives (below) nothing is differentiated analytically, so the
f's may depend on the whole measured state. The mass enters only through g3 y_v and the
disturbance delta = eps4' y_v + (the servo's inertia force), as in (6.3.52)-(6.3.53).

Control law (Steps 1-5 and (6.3.55)-(6.3.64)), gains k0..k4::

    alpha0 = -k0 psi_e,                 z1 = r - alpha0,   alpha0' = -k0 r     (exact)
    alpha1 = (-k1 z1 - psi_e - f1 + alpha0') / g1,          z2 = v - alpha1
    alpha2 = (-k2 z2 - g1 z1 - f2 + alpha1'_c) / g2,        z3 = phi - alpha2
    alpha3 = -k3 z3 - g2 z2 + alpha2'_c,                    z4 = p - alpha3
    y_v    = (-k4 z4 - z3 - f3 + alpha3'_c) / g3            (6.3.64), sent as y_d
    F_t    = -(eta0 + |eps4' y_v|) sat(z2 / Phi) / (d v'/d F_t)      (6.3.72)-(6.3.73)

Derivatives of the virtual controls: alpha0' is exact (psi_d is piecewise constant, so
alpha0' = -k0 r). alpha1', alpha2', alpha3' are COMMAND-FILTERED: each alpha_i passes
through a critically damped second-order filter (:mod:`command_filter`, omega_f) whose rate
output replaces alpha_i' (the dynamic-surface form of command-filtered backstepping; the
alternative Sec. 6.3.3 names). Why not exact:
* the plant's terms contain v|v|, r|r|, p|p|: alpha3' needs third derivatives of f1, which
  do not exist at v = 0 or r = 0, and the f's are evaluated numerically from the plant, so
  exact derivatives would need nested finite differences of a non-smooth function;
* the exact design assumes y_v is set instantly, but our plant moves the mass through its
  servo (omega_n = 2.4 rad/s: 130 deg of lag at the 5 rad/s roll frequency whose spring
  the law cancels), so the faster alpha3' follows the roll, the harder y_d bangs between
  the stops. The filter bandwidth omega_f = 10 rad/s (zeta = 1) sits above the designed
  error dynamics (|eigenvalues| of -Lambda + S up to 5.8 rad/s) yet keeps the command
  smooth. Measured on bs-3 (60 s, 10 ms): omega_f = 6-10 rad/s gives a total variation
  of y_d of 0.3-0.45 m, 15 rad/s 2.0 m, 20 rad/s 22.5 m (bang-bang between the stops, the
  thruster chattering too); every one of them settles within 5 s.
Farrell's compensating signals are left out on purpose: they integrate the difference
between the saturated and the wanted commands and wound up in our trials whenever the
mass sat on a stop (bs-3 then never settled).

Thruster (Lyapunov redesign, (6.3.67)-(6.3.73)). The thruster's acceleration u~ enters the
sway equation: with d v'/d F_t taken from the plant (1/64.1 kg for REMUS 100; (6.3.71)
writes 1/(m + a22) = 1/66 kg, the difference being the sway-roll-yaw coupling of the mass
matrix), F_t = u~ / (d v'/d F_t). The parameters the dissertation leaves open, our choices:
* eta0 = 0.08 m/s^2 (5.1 N): the margin over |delta| must also cover what (6.3.72) drops,
  the mass's inertia force (up to k_v * 12 cm = 3.5 N plus damping, i.e. 0.05-0.1 m/s^2),
  and the sampled-data error. Measured settling (|psi| < 1 deg) of bs-3: eta0 = 0 never
  (a limit cycle of +-6 deg), 0.02 m/s^2 13 s (with a residual wobble), 0.03 8.3 s,
  0.05 5.3 s, 0.08 3.2 s, 0.15 3.0 s: 0.08 is where the gain flattens out.
* boundary layer Phi = 0.01 m/s on z2 (a sway-velocity error): the thruster's gain inside
  the layer, (eta0 + |eps4' y_v|) / Phi <= 20 1/s, keeps the 10 ms sampled loop far from
  its stability limit 2/h = 200 1/s and removes the chattering of sgn (6.3.73), while the
  layer is small against the scenarios' sway velocities (0.05-0.2 m/s).
* F_t limit 10 N (applied by the autopilot): the largest force in the dissertation's
  thruster plots (Figs. 6.21, 6.24); (6.3.72) asks at most 64.1 (0.08 + 1.88 * 0.06) = 12.4 N.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from controller_fmu import compiled_backstepping as fast
from controller_fmu.command_filter import CommandFilterBank
from controller_fmu.lateral_model import LateralDesignModel


@dataclass(frozen=True)
class BacksteppingGains:
    """Gains of (6.3.55)-(6.3.64) and of the thruster (6.3.72)-(6.3.73).

    Defaults: Sec. 6.3.3 (k0 = 0.5, k1..k4 = 1); for currents and low speed the
    dissertation uses k0 = 0.3, k1 = 0.8. eta0, Phi and the filter frequency: module
    docstring.
    """

    k0: float = 0.5
    k1: float = 1.0
    k2: float = 1.0
    k3: float = 1.0
    k4: float = 1.0
    eta0: float = 0.08  # m/s^2
    boundary_layer: float = 0.01  # m/s
    filter_frequency: float = 10.0  # rad/s

    def __post_init__(self) -> None:
        for name in ("k0", "k1", "k2", "k3", "k4", "boundary_layer", "filter_frequency"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0.0):
                raise ValueError(f"backstepping {name} = {value!r}: expected a number > 0")
        if not (math.isfinite(self.eta0) and self.eta0 >= 0.0):
            raise ValueError(f"backstepping eta0 = {self.eta0!r}: expected a number >= 0 m/s^2")


@dataclass(frozen=True)
class BacksteppingOutput:
    """Unsaturated commands and the error coordinates of one evaluation."""

    mass_position: float  # y_v of (6.3.64), m
    tunnel_force: float  # F_t of (6.3.72)-(6.3.73), N
    errors: tuple[float, float, float, float, float]  # psi_e, z1, z2, z3, z4


@dataclass(frozen=True)
class BacksteppingSnapshot:
    """The state of a :class:`BacksteppingHeading` between two samples."""

    last_time: float | None  # s, the previous sample's time (None before the first)
    last_alphas: np.ndarray  # alpha1..3 of the previous sample, held into the filters
    filter_value: np.ndarray  # the command filters' outputs a_c
    filter_rate: np.ndarray  # and their rates a_c' (the alpha_i' estimates)

    def to_json(self) -> dict[str, Any]:
        """A JSON-serialisable form."""
        return {
            "last_time": self.last_time,
            "last_alphas": self.last_alphas.tolist(),
            "filter_value": self.filter_value.tolist(),
            "filter_rate": self.filter_rate.tolist(),
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> BacksteppingSnapshot:
        """The snapshot :meth:`to_json` wrote."""
        return cls(
            last_time=data["last_time"],
            last_alphas=np.array(data["last_alphas"], dtype=float),
            filter_value=np.array(data["filter_value"], dtype=float),
            filter_rate=np.array(data["filter_rate"], dtype=float),
        )


class BacksteppingHeading:
    """The sampled backstepping controller; its filters are its only state.

    Args:
        design: the plant's lateral design model (vehicle and U0).
        gains: :class:`BacksteppingGains`.

    Raises:
        ValueError: a model gain g1, g2 or g3 is zero (the chain is not controllable).
    """

    def __init__(self, design: LateralDesignModel, gains: BacksteppingGains) -> None:
        self.design = design
        self.gains = gains
        jac = design.static_mass_jacobian()
        self.g1, self.g2, self.g3 = jac["r/v"], jac["v/roll"], jac["p/mass_position"]
        self.eps4 = jac["v/mass_position"]
        self.thruster_gain = jac["v/tunnel_force"]  # m/s^2 per N
        for name in ("g1", "g2", "g3", "thruster_gain"):
            if abs(getattr(self, name)) < 1e-9:
                raise ValueError(f"backstepping model gain {name} is 0 for this vehicle/U0")
        # All state in one flat array (compiled_backstepping's layout), which the compiled
        # law updates in place and the reference reads through views.
        self._state = np.zeros(fast.STATE_SIZE)
        self._last_alphas = self._state[fast.ALPHAS : fast.VALUES]
        self.filters = CommandFilterBank(
            3, gains.filter_frequency, storage=self._state[fast.VALUES : fast.STATE_SIZE]
        )
        self._law = None if design.compiled_plant is None else self._flat_law()
        self._next_slot = 0  # the law's interval slot the next new interval takes
        self.reset()
        if self._law is not None:  # compile (or load) the law now, not in the first doStep
            params = design.compiled_plant.parameters
            fast.command(params, self._law.copy(), self._state.copy(), 0.0, *[0.0] * 6)

    def _flat_law(self) -> np.ndarray:
        """The compiled law's constants (:mod:`compiled_backstepping`'s ``law`` layout)."""
        k = self.gains
        law = np.full(fast.LAW_SIZE, np.nan)
        gains = (k.k0, k.k1, k.k2, k.k3, k.k4, k.eta0, k.boundary_layer)
        law[: fast.DESIGN_STATE] = (
            *gains,
            self.g1,
            self.g2,
            self.g3,
            self.eps4,
            self.thruster_gain,
        )
        law[fast.DESIGN_STATE : fast.DESIGN_INPUTS] = self.design.design_state
        law[fast.DESIGN_INPUTS : fast.INTERVALS] = self.design.design_inputs
        return law

    @property
    def _last_time(self) -> float | None:
        """The previous sample's time, s (None before the first)."""
        return float(self._state[fast.LAST_TIME]) if self._state[fast.STARTED] else None

    def reset(self) -> None:
        """Forget the filters; the next call starts them on its own virtual controls."""
        self._state[:] = 0.0

    def snapshot(self) -> BacksteppingSnapshot:
        """The internal state, to restore with :meth:`restore`."""
        return BacksteppingSnapshot(
            last_time=self._last_time,
            last_alphas=self._last_alphas.copy(),
            filter_value=self.filters.value.copy(),
            filter_rate=self.filters.rate.copy(),
        )

    def state_values(self) -> np.ndarray:
        """A copy of the flat state (cheaper than :meth:`snapshot`, for a rollback)."""
        return self._state.copy()

    def load_state_values(self, values: np.ndarray) -> None:
        """Back to the flat state :meth:`state_values` returned."""
        self._state[:] = values

    def restore(self, snapshot: BacksteppingSnapshot) -> None:
        """Back to the state :meth:`snapshot` returned (the snapshot is not shared)."""
        started = snapshot.last_time is not None
        self._state[fast.STARTED] = 1.0 if started else 0.0
        self._state[fast.LAST_TIME] = snapshot.last_time if started else 0.0
        self._last_alphas[:] = snapshot.last_alphas
        self.filters.value[:] = snapshot.filter_value
        self.filters.rate[:] = snapshot.filter_rate

    def command_values(
        self, time: float, v: float, r: float, p: float, phi: float, psi_e: float, y_v: float
    ) -> tuple[float, float]:
        """(y_v command m, F_t N) of :meth:`command`, from the compiled law when numba is
        usable (:mod:`controller_fmu.compiled_backstepping`), else from the reference."""
        if self._law is None:
            out = self.command(time, v, r, p, phi, psi_e, y_v)
            return out.mass_position, out.tunnel_force
        return self._compiled(time, v, r, p, phi, psi_e, y_v)[1:3]

    def _compiled(
        self, time: float, v: float, r: float, p: float, phi: float, psi_e: float, y_v: float
    ) -> tuple[float, ...]:
        """The compiled law's 7 values; writes the filter transition it asks for first."""
        params, law, state = self.design.compiled_plant.parameters, self._law, self._state
        out = fast.command(params, law, state, time, v, r, p, phi, psi_e, y_v)
        if out[0]:  # a new interval: its exact transition (scipy's expm, cached)
            interval = time - float(state[fast.LAST_TIME])
            transition, gamma = self.filters.transition(interval)
            slot = fast.INTERVALS + 7 * self._next_slot
            law[slot : slot + 7] = (interval, *transition.ravel().tolist(), *gamma.tolist())
            self._next_slot = (self._next_slot + 1) % fast.N_INTERVALS
            out = fast.command(params, law, state, time, v, r, p, phi, psi_e, y_v)
        return out

    def command(
        self, time: float, v: float, r: float, p: float, phi: float, psi_e: float, y_v: float
    ) -> BacksteppingOutput:
        """Commands at ``time`` (s) from the measured relative sway velocity v (m/s), rates
        r, p (rad/s), roll phi, heading error psi_e = psi - psi_d (rad) and mass position
        y_v (m). Advances the filters from the previous call with its alphas held. The
        reference law, in Python; :meth:`command_values` steps the compiled one."""
        k = self.gains
        # The filters are at rest (rate 0) until the first sample has started them.
        if self._last_time is not None:
            self.filters.advance(self._last_alphas, time - self._last_time)
        v_dot, r_dot, p_dot = self.design.static_mass_rates(v, r, p, phi, 0.0)
        rate = self.filters.rate.tolist()  # Python floats: numpy scalars cost ~10x
        f1 = r_dot - self.g1 * v
        f2 = v_dot - self.g2 * phi
        f3 = p_dot

        alpha0 = -k.k0 * psi_e
        z1 = r - alpha0
        alpha0_dot = -k.k0 * r
        alpha1 = (-k.k1 * z1 - psi_e - f1 + alpha0_dot) / self.g1
        z2 = v - alpha1
        alpha2 = (-k.k2 * z2 - self.g1 * z1 - f2 + rate[0]) / self.g2
        z3 = phi - alpha2
        alpha3 = -k.k3 * z3 - self.g2 * z2 + rate[1]
        z4 = p - alpha3
        mass = (-k.k4 * z4 - z3 - f3 + rate[2]) / self.g3

        bound = k.eta0 + abs(self.eps4 * y_v)
        saturated = min(max(z2 / k.boundary_layer, -1.0), 1.0)
        force = -bound * saturated / self.thruster_gain

        alphas = (alpha1, alpha2, alpha3)
        if self._last_time is None:  # first sample: filters start at rest on the alphas
            self.filters.start(alphas)
        self._state[fast.STARTED], self._state[fast.LAST_TIME] = 1.0, time
        self._last_alphas[:] = alphas
        return BacksteppingOutput(mass, force, (psi_e, z1, z2, z3, z4))
