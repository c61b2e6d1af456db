"""A bank of second-order command filters, discretised exactly for any sample interval.

Each filter follows its input a (held constant between samples) with

    a_c'' = -2 zeta omega a_c' - omega^2 (a_c - a)

and supplies a_c' as the estimate of the input's time derivative: the standard
"command filter" of command-filtered backstepping (Farrell et al., IEEE TAC 54(6), 2009;
Sec. 6.3.3's remark). Because the filter is linear and its input is held, its state is
advanced by the exact zero-order-hold transition matrix
(:func:`controller_fmu.matrix_exponential.expm`, numpy only: an FMU's host has no scipy),
which is cached per interval length, so the result does not depend on any inner
integration step.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from controller_fmu.matrix_exponential import expm

_MAX_CACHED_INTERVALS = 16


class CommandFilterBank:
    """n independent filters with the same natural frequency and damping.

    Args:
        n: number of filters.
        frequency: omega, rad/s (> 0).
        damping: zeta (> 0).
        storage: optional float64 array of 2 n values the filters keep their outputs a_c
            (first n) and rates a_c' (last n) in, updated in place (a caller's flat state).
    """

    def __init__(
        self, n: int, frequency: float, damping: float = 1.0, storage: np.ndarray | None = None
    ) -> None:
        if not (math.isfinite(frequency) and frequency > 0.0):
            raise ValueError(f"command filter frequency {frequency!r}: expected > 0 rad/s")
        if not (math.isfinite(damping) and damping > 0.0):
            raise ValueError(f"command filter damping {damping!r}: expected > 0")
        self.n = n
        self.frequency = float(frequency)
        self.damping = float(damping)
        self._cache: dict[float, tuple[np.ndarray, np.ndarray]] = {}
        storage = np.zeros(2 * n) if storage is None else storage
        self.value = storage[:n]  # a_c (views: every update is in place)
        self.rate = storage[n : 2 * n]  # a_c'

    def start(self, inputs: Sequence[float] | np.ndarray) -> None:
        """Start at rest on the given inputs (a_c = a, a_c' = 0)."""
        self.value[:] = inputs
        self.rate[:] = 0.0

    def advance(self, inputs: np.ndarray, interval: float) -> None:
        """Advance by ``interval`` seconds with ``inputs`` held."""
        Phi, Gamma = self.transition(interval)
        state = np.stack([self.value, self.rate])  # 2 x n
        new = Phi @ state + np.outer(Gamma, inputs)
        self.value[:], self.rate[:] = new[0], new[1]

    def transition(self, interval: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi 2x2, Gamma 2) of the exact zero-order-hold discretisation over ``interval``
        s (cached; not to be modified)."""
        cached = self._cache.get(interval)
        if cached is None:
            w, z = self.frequency, self.damping
            augmented = np.zeros((3, 3))
            augmented[0, 1] = 1.0
            augmented[1, :] = (-(w**2), -2.0 * z * w, w**2)
            exp = expm(augmented * interval)
            cached = (exp[:2, :2].copy(), exp[:2, 2].copy())
            if len(self._cache) >= _MAX_CACHED_INTERVALS:
                self._cache.clear()
            self._cache[interval] = cached
        return cached
