"""The backstepping heading law's compiled fast path: one sample of
:meth:`controller_fmu.backstepping.BacksteppingHeading.command` (Steps 1-5, (6.3.55)-(6.3.64),
and the thruster (6.3.72)-(6.3.73)) in one numba call, on flat float64 arrays.

Why by hand: the Python law costs ~10 us per sample, most of it interpreter overhead
around a few dozen multiplications; no library compiles it for us. The reference stays
:meth:`BacksteppingHeading.command` (used when numba is off), and this kernel writes the
same operations in the same order, so the two agree to the last bit but for the matrix
products of the plant derivative and of the filters (Phi @ state, which numpy hands to
BLAS, possibly with fused multiply-adds): ``tests/controller_fmu/test_compiled_backstepping.py``
holds them to 1e-12. Nothing is re-typed: the model terms f1, f2, f3 come from the plant's compiled
derivative (:func:`plant_fmu.model.compiled.derivative_into`) on the design model's flat
parameters, and g1, g2, g3, eps4', d v'/d F_t, the gains and the command filters'
zero-order-hold transition (the expm of :mod:`controller_fmu.matrix_exponential`) are handed
in by :class:`BacksteppingHeading`.

Layouts (float64, SI):

* ``law``: the constants, :data:`LAW_SIZE` values: k0..k4, eta0, Phi, g1, g2, g3, eps4',
  d v'/d F_t; the design model's plant state (14) and inputs (8) at the straight run;
  then :data:`N_INTERVALS` slots of 9: a filter interval (s, NaN: free), its
  transition Phi00, Phi01, Phi10, Phi11, Gamma0, Gamma1 and the first-order hold's ramp
  terms Ramp0, Ramp1 (:meth:`CommandFilterBank.ramp`). Sample times n h give a handful
  of intervals that differ in the last bits (14 in 60 s at 10 ms, 20 in an hour).
* ``state``: :data:`STATE_SIZE` values: started (1.0 once a sample was taken), the last
  sample's time (s), its alpha1..3, the filters' outputs a_c (3) and rates a_c' (3).
* ``scratch``: :data:`SCRATCH_SIZE` values the sample works in (the design state and
  inputs with the measurements in, the derivative, R, work): nothing is allocated.

The plant's kernels are imported absolutely: ``plant_fmu`` is a sibling top-level package
in the source tree, where no relative import reaches it.
"""

from __future__ import annotations

import numpy as np

from plant_fmu.model.compiled import _jit as _jit  # (also compiled_autopilot's)
from plant_fmu.model.compiled import derivative_into

# law
K0, K1, K2, K3, K4, ETA0, PHI, G1, G2, G3, EPS4, THRUSTER = range(12)
DESIGN_STATE = 12  # 14 plant states at the straight run
DESIGN_INPUTS = DESIGN_STATE + 14  # 8 plant inputs
INTERVALS = DESIGN_INPUTS + 8  # slots: interval s, Phi00..Phi11, Gamma0, Gamma1, Ramp0, Ramp1
SLOT = 9  # values per slot
N_INTERVALS = 16
LAW_SIZE = INTERVALS + SLOT * N_INTERVALS
# state
STARTED, LAST_TIME, ALPHAS, VALUES, RATES = 0, 1, 2, 5, 8
STATE_SIZE = 11
# scratch
_SCRATCH_X, _SCRATCH_INPUTS, _SCRATCH_DX, _SCRATCH_R, _SCRATCH_WORK = 0, 14, 22, 36, 45
SCRATCH_SIZE = _SCRATCH_WORK + 30
# plant state and input indices the law reads and writes (plant_fmu.model.dynamics order)
_V, _P, _R, _ROLL, _YV, _Y_D = 7, 9, 11, 3, 12, 4


# (needs_transition, y_v command m, F_t N, z1, z2, z3, z4): see :func:`command`
Sample = tuple[float, float, float, float, float, float, float]


@_jit
def _ramp(state: np.ndarray, i: int, new: float, law: np.ndarray, slot: int) -> None:
    """Advance filter i over the interval of ``slot`` with its input going linearly from
    the held alpha to ``new`` (first-order hold)."""
    value, rate, held = state[VALUES + i], state[RATES + i], state[ALPHAS + i]
    change = new - held
    state[VALUES + i] = (
        law[slot] * value + law[slot + 1] * rate + law[slot + 4] * held + law[slot + 6] * change
    )
    state[RATES + i] = (
        law[slot + 2] * value + law[slot + 3] * rate + law[slot + 5] * held + law[slot + 7] * change
    )


@_jit
def _design_point(law: np.ndarray, scratch: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The design model's plant state (14) and inputs (8) at the straight run, copied
    into ``scratch`` (views of it, for the sample to fill in its measurements)."""
    x = scratch[_SCRATCH_X:_SCRATCH_INPUTS]
    inputs = scratch[_SCRATCH_INPUTS:_SCRATCH_DX]
    for i in range(14):
        x[i] = law[DESIGN_STATE + i]
    for i in range(8):
        inputs[i] = law[DESIGN_INPUTS + i]
    return x, inputs


@_jit
def command(
    p: np.ndarray,
    law: np.ndarray,
    state: np.ndarray,
    scratch: np.ndarray,
    time: float,
    v: float,
    r: float,
    pp: float,
    phi: float,
    psi_e: float,
    y_v: float,
    ramp: bool,
) -> Sample:
    """One sample: (needs_transition, y_v command m, F_t N, z1, z2, z3, z4), the state
    advanced in place, ``scratch`` (:data:`SCRATCH_SIZE`) worked in. ``needs_transition``
    = 1.0 (nothing changed) when the filters must advance over an interval whose
    transition ``law`` does not hold yet: the caller writes it into a slot and calls
    again. ``ramp``: the filters' inputs went linearly from the last sample's alphas to
    these (a first-order hold, each filter advanced once the alpha it follows is known),
    else they were held."""
    started = state[STARTED] != 0.0
    slot = -1
    if started:
        interval = time - state[LAST_TIME]
        for i in range(N_INTERVALS):
            if law[INTERVALS + SLOT * i] == interval:
                slot = INTERVALS + SLOT * i + 1
                break
        if slot < 0:
            return 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        p00, p01, p10, p11 = law[slot], law[slot + 1], law[slot + 2], law[slot + 3]
        g0, g1 = law[slot + 4], law[slot + 5]
        if not ramp:  # held: every filter advances before the law (they need no alpha)
            for i in range(3):
                value, rate, held = state[VALUES + i], state[RATES + i], state[ALPHAS + i]
                state[VALUES + i] = p00 * value + p01 * rate + g0 * held
                state[RATES + i] = p10 * value + p11 * rate + g1 * held
    step = started and ramp
    x, inputs = _design_point(law, scratch)
    x[_V], x[_R], x[_P], x[_ROLL], x[_YV] = v, r, pp, phi, 0.0
    inputs[_Y_D] = 0.0
    dx = scratch[_SCRATCH_DX:_SCRATCH_R]
    R = scratch[_SCRATCH_R:_SCRATCH_WORK].reshape((3, 3))
    work = scratch[_SCRATCH_WORK:SCRATCH_SIZE].reshape((5, 6))
    derivative_into(p, x, inputs, R, work, dx)
    f1 = dx[_R] - law[G1] * v
    f2 = dx[_V] - law[G2] * phi
    f3 = dx[_P]

    alpha0 = -law[K0] * psi_e
    z1 = r - alpha0
    alpha0_dot = -law[K0] * r
    alpha1 = (-law[K1] * z1 - psi_e - f1 + alpha0_dot) / law[G1]
    if step:
        _ramp(state, 0, alpha1, law, slot)
    z2 = v - alpha1
    alpha2 = (-law[K2] * z2 - law[G1] * z1 - f2 + state[RATES]) / law[G2]
    if step:
        _ramp(state, 1, alpha2, law, slot)
    z3 = phi - alpha2
    alpha3 = -law[K3] * z3 - law[G2] * z2 + state[RATES + 1]
    if step:
        _ramp(state, 2, alpha3, law, slot)
    z4 = pp - alpha3
    mass = (-law[K4] * z4 - z3 - f3 + state[RATES + 2]) / law[G3]

    bound = law[ETA0] + abs(law[EPS4] * y_v)
    saturated = min(max(z2 / law[PHI], -1.0), 1.0)
    force = -bound * saturated / law[THRUSTER]

    if not started:  # first sample: the filters start at rest on the alphas
        state[VALUES], state[VALUES + 1], state[VALUES + 2] = alpha1, alpha2, alpha3
        state[RATES], state[RATES + 1], state[RATES + 2] = 0.0, 0.0, 0.0
    state[STARTED], state[LAST_TIME] = 1.0, time
    state[ALPHAS], state[ALPHAS + 1], state[ALPHAS + 2] = alpha1, alpha2, alpha3
    return 0.0, mass, force, z1, z2, z3, z4
