"""One sample of the autopilot (:meth:`controller_fmu.autopilot.Autopilot.step`) in one
numba call that allocates nothing: from the FMU's input buffer to its output buffer, for
the heading laws "off" and backstepping + tunnel thruster with the depth PD on or off.

Why by hand: the Python step costs ~7 us, most of it interpreter overhead around a few
dozen operations (a dict of the measurements, named tuples, the law's call chain), and
allocates on every sample; the FMU steps it every communication step. The reference stays
:meth:`Autopilot.step` (used for the LQR and the sliding mode, when numba is off, and to
raise the error a refused sample gets), and this kernel does the same operations in the
same order, so the two agree to the last bit (``tests/controller_fmu/test_compiled_autopilot.py``):
the heading set-point and its current compensation (6.3.74), the heading error, the
backstepping law (:func:`controller_fmu.compiled_backstepping.command`, Steps 1-5 and the
thruster, (6.3.55)-(6.3.73)), the mass lock (Sec. 6.3.4), the depth PD (Fig. 6.40, Table
6.2) and the actuator limits. ``wrap_angle`` and ``mass_locked`` are
:mod:`controller_fmu.setpoint_shaping`'s own functions, compiled; the two lines of
``crab_angle`` and of ``DepthPd.fin_angle`` are repeated here (their Python versions raise
with formatted messages, which numba cannot compile). Python's ``min``/``max`` are
spelled out as CPython defines them (:func:`_python_min`, :func:`_python_max`: the first
argument unless the second is strictly smaller/larger), so a signed zero or a NaN comes
out as in Python whatever numba's builtins do.

Layout of ``work`` (float64, :data:`WORK_SIZE`): the configuration (:data:`CONFIG_SIZE`
values from :data:`HEADING` to :data:`PITCH_LIMIT`, written by the autopilot when it takes a
configuration), the published values (:data:`PUBLISHED`: psi_d, rad, then the four
commands), the backstepping state saved for a rollback, and the backstepping law's
scratch. ``inputs`` is the FMU's 16 measurements in ``MEASUREMENT_NAMES`` order,
``outputs`` its 4 commands in ``COMMAND_NAMES`` order.
"""

from __future__ import annotations

import math

import numpy as np

from .compiled_backstepping import SCRATCH_SIZE, STATE_SIZE, _jit, command
from .setpoint_shaping import mass_locked, wrap_angle

# configuration
HEADING, COMPENSATE, DESIGN_SPEED, LOCK_TIME, DEPTH = 0, 1, 2, 3, 4
GAMMA, K_P, TAU_D, FIN_LIMIT, MASS_LIMIT, TUNNEL_LIMIT, THRUST = 5, 6, 7, 8, 9, 10, 11
PITCH_LIMIT = 12
CONFIG_SIZE = 13
PUBLISHED = CONFIG_SIZE  # psi_d, mass_position_cmd, tunnel_force, fin_angle, thrust
_SAVED = PUBLISHED + 5
_SCRATCH = _SAVED + STATE_SIZE
WORK_SIZE = _SCRATCH + SCRATCH_SIZE
# sample's answers (nothing changed unless OK)
OK, NEEDS_TRANSITION, REFUSED = 0, 1, 2
# MEASUREMENT_NAMES indices
(_YAW, _R, _P, _ROLL, _V_REL, _U_REL, _DOWN, _PITCH, _Q, _W_REL, _Y_V, _Y_VEL,
 _CURRENT_NORTH, _CURRENT_EAST, _YAW_SETPOINT, _DEPTH_SETPOINT) = range(16)  # fmt: skip

_wrap = _jit(wrap_angle)
_locked = _jit(mass_locked)


@_jit
def _python_max(a: float, b: float) -> float:
    """Python's ``max(a, b)``: ``a`` unless ``b > a``."""
    return b if b > a else a


@_jit
def _python_min(a: float, b: float) -> float:
    """Python's ``min(a, b)``: ``a`` unless ``b < a``."""
    return b if b < a else a


@_jit
def _clip(value: float, limit: float) -> float:
    """``autopilot._clip``: ``min(max(value, -limit), limit)``."""
    return _python_min(_python_max(value, -limit), limit)


@_jit
def _heading_setpoint(work: np.ndarray, inputs: np.ndarray) -> float:
    """psi_d, rad (``setpoint_shaping.desired_heading``), or NaN when the cross-current
    is not slower than the design speed (``crab_angle`` refuses it, (6.3.74))."""
    course = inputs[_YAW_SETPOINT]
    if work[COMPENSATE] == 0.0:
        return _wrap(course)
    speed = work[DESIGN_SPEED]
    cross = -inputs[_CURRENT_NORTH] * math.sin(course) + inputs[_CURRENT_EAST] * math.cos(course)
    if abs(cross) >= speed:
        return math.nan
    return _wrap(course - math.asin(cross / speed))


@_jit
def _fin_angle(work: np.ndarray, inputs: np.ndarray) -> float:
    """delta_s, rad (``DepthPd.fin_angle``, Fig. 6.40): theta_d = gamma (z_d - z),
    within +-PITCH_LIMIT unless 0, delta_s = -K_p [(theta_d - theta) - tau_d q],
    saturated; 0 with the depth PD off."""
    if work[DEPTH] == 0.0:
        return 0.0
    theta_d = work[GAMMA] * (inputs[_DEPTH_SETPOINT] - inputs[_DOWN])
    if work[PITCH_LIMIT] != 0.0:
        theta_d = _clip(theta_d, work[PITCH_LIMIT])
    delta = -work[K_P] * ((theta_d - inputs[_PITCH]) - work[TAU_D] * inputs[_Q])
    return _python_min(_python_max(delta, -work[FIN_LIMIT]), work[FIN_LIMIT])


@_jit
def sample(
    p: np.ndarray,
    law: np.ndarray,
    state: np.ndarray,
    work: np.ndarray,
    inputs: np.ndarray,
    rates: np.ndarray,
    outputs: np.ndarray,
    time: float,
) -> int:
    """One sample at ``time`` (s): the commands into ``outputs`` and ``work``'s published
    values. ``rates``: the inputs' first time derivatives the importer set; when one is
    not 0 the inputs went linearly from the last sample's to these, and the backstepping's
    filters follow them so (``Autopilot.step``'s ``varying``). Returns :data:`OK`; or,
    with nothing changed, :data:`NEEDS_TRANSITION` (the backstepping filters need the
    transition of a new interval: the caller adds it to ``law`` and calls again) or
    :data:`REFUSED` (a non-finite time or measurement, a depth set-point above the
    surface with the depth loop on, a cross-current the compensation cannot hold, a
    non-finite command: the reference says which). ``p``, ``law`` and
    ``state`` are the backstepping law's (its design plant's parameters, constants and
    state; unused with the heading law off)."""
    if not math.isfinite(time):
        return REFUSED
    for i in range(inputs.size):
        if not math.isfinite(inputs[i]):
            return REFUSED
    if work[DEPTH] != 0.0 and inputs[_DEPTH_SETPOINT] < 0.0:
        return REFUSED
    psi_d = _heading_setpoint(work, inputs)
    if math.isnan(psi_d):
        return REFUSED
    psi_e = _wrap(inputs[_YAW] - psi_d)
    mass, tunnel = 0.0, 0.0
    backstepping = work[HEADING] != 0.0
    saved = work[_SAVED:_SCRATCH]
    if backstepping:
        for i in range(STATE_SIZE):
            saved[i] = state[i]
        ramp = False
        for i in range(rates.size):
            if rates[i] != 0.0:
                ramp = True
        out = command(p, law, state, work[_SCRATCH:WORK_SIZE], time, inputs[_V_REL],
                      inputs[_R], inputs[_P], inputs[_ROLL], psi_e, inputs[_Y_V],
                      ramp)  # fmt: skip
        if out[0] != 0.0:
            return NEEDS_TRANSITION
        mass, tunnel = out[1], out[2]
    if _locked(time, work[LOCK_TIME]):
        mass = 0.0
    fin = _fin_angle(work, inputs)
    mass = _clip(mass, work[MASS_LIMIT])
    tunnel = _clip(tunnel, work[TUNNEL_LIMIT])
    if not (math.isfinite(mass) and math.isfinite(tunnel) and math.isfinite(fin)):
        if backstepping:
            for i in range(STATE_SIZE):
                state[i] = saved[i]
        return REFUSED
    outputs[0], outputs[1], outputs[2], outputs[3] = mass, tunnel, fin, work[THRUST]
    work[PUBLISHED] = psi_d
    for i in range(4):
        work[PUBLISHED + 1 + i] = outputs[i]
    return OK
