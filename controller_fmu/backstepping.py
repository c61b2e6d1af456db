"""Backstepping heading autopilot on the moving mass with a Lyapunov-redesigned tunnel
thruster (Sec. 6.3.3, (6.3.53)-(6.3.73)).

The chain (6.3.53) with the plant's own right-hand sides (g1, g2, g3, eps4' Jacobians of
the lateral plant with the mass held still, :meth:`LateralDesignModel.static_mass_jacobian`;
f1..f3 its rates minus the g terms), the virtual controls (6.3.55)-(6.3.64) with
command-filtered derivatives (:mod:`controller_fmu.command_filter`), and the thruster law
(6.3.72)-(6.3.73): docs/model.md#backstepping states them, with why the derivatives are
filtered and how eta0, Phi and the force limit were chosen.
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

    Defaults: Sec. 6.3.3 (k0 = 0.5, k1..k4 = 1); for heading into a current
    (psi_d = -beta) and at low speed the dissertation uses k0 = 0.3, k1 = 0.8. eta0, Phi
    and the filter frequency: module docstring.
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
    # psi_e (rad) and z1 (rad/s), z2 (m/s), z3 (rad), z4 (rad/s) of (6.3.55)-(6.3.64)
    errors: tuple[float, float, float, float, float]


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
        self.scratch = np.empty(fast.SCRATCH_SIZE)  # what the compiled law works in
        self._next_slot = 0  # the law's interval slot the next new interval takes
        self.reset()
        compiled = design.compiled_plant
        if self._law is not None and compiled is not None:  # compile (or load) it now,
            params = compiled.parameters  # not in the first doStep
            for ramp in (False, True):
                law, state = self._law.copy(), self._state.copy()
                fast.command(params, law, state, self.scratch, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
                             ramp)  # fmt: skip

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
        self,
        time: float,
        v: float,
        r: float,
        p: float,
        phi: float,
        psi_e: float,
        y_v: float,
        ramp: bool = False,
    ) -> tuple[float, float]:
        """(y_v command m, F_t N) of :meth:`command`, from the compiled law when numba is
        usable (:mod:`controller_fmu.compiled_backstepping`), else from the reference."""
        if self._law is None:
            out = self.command(time, v, r, p, phi, psi_e, y_v, ramp)
            return out.mass_position, out.tunnel_force
        return self._compiled(time, v, r, p, phi, psi_e, y_v, ramp)[1:3]

    def _compiled(
        self,
        time: float,
        v: float,
        r: float,
        p: float,
        phi: float,
        psi_e: float,
        y_v: float,
        ramp: bool = False,
    ) -> fast.Sample:
        """The compiled law's 7 values; writes the filter transition it asks for first."""
        plant, law, state = self.design.compiled_plant, self._law, self._state
        assert plant is not None and law is not None, "the compiled law needs numba"
        params, scratch = plant.parameters, self.scratch
        out = fast.command(params, law, state, scratch, time, v, r, p, phi, psi_e, y_v, ramp)
        if out[0]:  # a new interval: its exact transition (expm, cached)
            self.add_transition(time)
            out = fast.command(params, law, state, scratch, time, v, r, p, phi, psi_e, y_v, ramp)
        return out

    @property
    def law(self) -> np.ndarray | None:
        """The compiled law's constants (None when numba is off)."""
        return self._law

    @property
    def state(self) -> np.ndarray:
        """The flat state the compiled law advances in place."""
        return self._state

    def add_transition(self, time: float) -> None:
        """The filters' exact transition over the interval from the last sample to
        ``time`` into the compiled law's next slot (which asked for it)."""
        law = self._law
        assert law is not None, "the compiled law needs numba"
        interval = time - float(self._state[fast.LAST_TIME])
        transition, gamma = self.filters.transition(interval)
        slot = fast.INTERVALS + fast.SLOT * self._next_slot
        law[slot : slot + fast.SLOT] = (
            interval,
            *transition.ravel().tolist(),
            *gamma.tolist(),
            *self.filters.ramp(interval).tolist(),
        )
        self._next_slot = (self._next_slot + 1) % fast.N_INTERVALS

    def command(
        self,
        time: float,
        v: float,
        r: float,
        p: float,
        phi: float,
        psi_e: float,
        y_v: float,
        ramp: bool = False,
    ) -> BacksteppingOutput:
        """Commands at ``time`` (s) from the measured relative sway velocity v (m/s), rates
        r, p (rad/s), roll phi, heading error psi_e = psi - psi_d (rad) and mass position
        y_v (m). Advances the filters from the previous call with its alphas held, or, with
        ``ramp``, going linearly to this call's (each filter once its alpha is known). The
        reference law ((6.3.55)-(6.3.64), the thruster (6.3.72)-(6.3.73)), in Python;
        :meth:`command_values` steps the compiled one."""
        k = self.gains
        # The filters are at rest (rate 0) until the first sample has started them.
        last = self._last_time
        interval = 0.0 if last is None else time - last
        if last is not None and not ramp:
            self.filters.advance(self._last_alphas, interval)
        held = self._last_alphas.tolist()
        ramped = last is not None and ramp
        v_dot, r_dot, p_dot = self.design.static_mass_rates(v, r, p, phi, 0.0)
        rate = self.filters.rate  # read after each filter advanced
        f1 = r_dot - self.g1 * v
        f2 = v_dot - self.g2 * phi
        f3 = p_dot

        alpha0 = -k.k0 * psi_e
        z1 = r - alpha0
        alpha0_dot = -k.k0 * r
        alpha1 = (-k.k1 * z1 - psi_e - f1 + alpha0_dot) / self.g1
        if ramped:
            self.filters.advance_ramp(0, held[0], alpha1, interval)
        z2 = v - alpha1
        alpha2 = (-k.k2 * z2 - self.g1 * z1 - f2 + float(rate[0])) / self.g2
        if ramped:
            self.filters.advance_ramp(1, held[1], alpha2, interval)
        z3 = phi - alpha2
        alpha3 = -k.k3 * z3 - self.g2 * z2 + float(rate[1])
        if ramped:
            self.filters.advance_ramp(2, held[2], alpha3, interval)
        z4 = p - alpha3
        mass = (-k.k4 * z4 - z3 - f3 + float(rate[2])) / self.g3

        bound = k.eta0 + abs(self.eps4 * y_v)
        saturated = min(max(z2 / k.boundary_layer, -1.0), 1.0)
        force = -bound * saturated / self.thruster_gain

        alphas = (alpha1, alpha2, alpha3)
        if self._last_time is None:  # first sample: filters start at rest on the alphas
            self.filters.start(alphas)
        self._state[fast.STARTED], self._state[fast.LAST_TIME] = 1.0, time
        self._last_alphas[:] = alphas
        return BacksteppingOutput(mass, force, (psi_e, z1, z2, z3, z4))
