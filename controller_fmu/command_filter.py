"""A bank of second-order command filters, discretised exactly for any sample interval.

Each filter follows its input a (held constant between samples) with

    a_c'' = -2 zeta omega a_c' - omega^2 (a_c - a)

and supplies a_c' as the estimate of the input's time derivative: the standard
"command filter" of command-filtered backstepping (Farrell et al., IEEE TAC 54(6), 2009;
Sec. 6.3.3's remark). Because the filter is linear and its input is held, its state is
advanced by the exact zero-order-hold transition matrix
(:func:`controller_fmu.matrix_exponential.expm`, numpy only: an FMU's host has no scipy),
which is cached per interval length (the exact float: :data:`CACHED_INTERVALS`), so the
result does not depend on any inner integration step. When the input is taken as going
linearly from one sample to the next (a first-order hold: the continuous-time law between
samples, second-order accurate in the interval), :meth:`CommandFilterBank.ramp` adds the
exact response to that ramp.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence

import numpy as np

from controller_fmu.matrix_exponential import expm

# Intervals whose transitions are kept, the least recently used let go first. A fixed
# step's sample times n h give a handful of intervals that differ in the last bits (14 in
# 60 s at 10 ms); an adaptive run's many: vert-1 (60 s, --algorithm adaptive) asked for
# 4171 transitions of 2294 distinct intervals, 1237 distinct in its grid units (its step /
# 2^10). Emptied each time 16 had gathered, the cache computed all 4171; 2048 computes each
# distinct interval once. The key stays the exact float: two floats of one interval in grid
# units (3 * 0.001 and 0.003) have transitions that differ in the last bits (all 656 such
# pairs of that run, by up to 6e-13 of their largest value), and a fixed-step run, whose 14
# intervals are one in grid units, would then not give the same results to the last bit.
CACHED_INTERVALS = 2048


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
        # per bank (its own frequency and damping); functools' LRU cache, not a dict of our
        # own. Of module functions, not of bound methods: a cache holding self would make a
        # reference cycle, and a bank let go would keep its 2 x 2048 transitions until the
        # garbage collector ran
        cached = functools.lru_cache(maxsize=CACHED_INTERVALS)
        self._transitions = cached(functools.partial(_transition, self.frequency, self.damping))
        self._ramps = cached(functools.partial(_ramp, self.frequency, self.damping))
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

    def advance_ramp(self, i: int, held: float, new: float, interval: float) -> None:
        """Advance filter i by ``interval`` seconds with its input going linearly from
        ``held`` to ``new`` (first-order hold)."""
        Phi, Gamma = self.transition(interval)
        ramp = self.ramp(interval)
        value, rate = float(self.value[i]), float(self.rate[i])
        change = new - held
        self.value[i] = Phi[0, 0] * value + Phi[0, 1] * rate + Gamma[0] * held + ramp[0] * change
        self.rate[i] = Phi[1, 0] * value + Phi[1, 1] * rate + Gamma[1] * held + ramp[1] * change

    def ramp(self, interval: float) -> np.ndarray:
        """The state ``interval`` s after rest under an input going linearly from 0 to 1
        (2 values, cached: :data:`CACHED_INTERVALS`; not to be modified): the first-order
        hold's term, added to :meth:`transition`'s for an input from a to a + 1."""
        return self._ramps(interval)

    def transition(self, interval: float) -> tuple[np.ndarray, np.ndarray]:
        """(Phi 2x2, Gamma 2) of the exact zero-order-hold discretisation over ``interval``
        s (cached: :data:`CACHED_INTERVALS`; not to be modified)."""
        return self._transitions(interval)


def _ramp(w: float, z: float, interval: float) -> np.ndarray:
    """:meth:`CommandFilterBank.ramp` of a filter of frequency ``w`` (rad/s) and damping
    ``z``, computed."""
    augmented = np.zeros((4, 4))  # [a_c, a_c', a, a's rate times the interval]
    augmented[0, 1] = interval
    augmented[1, :3] = (-(w**2) * interval, -2.0 * z * w * interval, w**2 * interval)
    augmented[2, 3] = 1.0
    return expm(augmented)[:2, 3].copy()


def _transition(w: float, z: float, interval: float) -> tuple[np.ndarray, np.ndarray]:
    """:meth:`CommandFilterBank.transition` of a filter of frequency ``w`` (rad/s) and
    damping ``z``, computed."""
    augmented = np.zeros((3, 3))
    augmented[0, 1] = 1.0
    augmented[1, :] = (-(w**2), -2.0 * z * w, w**2)
    exp = expm(augmented * interval)
    return exp[:2, :2].copy(), exp[:2, 2].copy()
