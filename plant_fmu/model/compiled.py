"""The plant's compiled fast path: the derivative, the projection and the RK4 step of
:mod:`plant_fmu.model.dynamics` and :mod:`plant_fmu.model.stepping`, flat and
allocation-free, compiled with numba (``njit(cache=True)``, no fastmath).

Why by hand: no library compiles a numpy model like ours; the reference
(:class:`~plant_fmu.model.dynamics.PlantModel`) stays the readable source of truth, and
this module writes the same equations term by term in the same order of operations, on a
flat float64 parameter array built once from the model (:func:`flat_parameters`, which
takes every coefficient and matrix from the model itself: nothing is re-typed). The test
``tests/plant_fmu/model/test_compiled.py`` holds the two to 1e-12 over whole scenarios
(the two differ only in the rounding of the matrix products, which numpy hands to BLAS).

The step works on the stepping state of :mod:`plant_fmu.model.state_layout` (the state
and the attitude quaternion, 18 values), each sub-step in the attitude chart that
``PlantModel.uses_quaternion`` picks (:func:`_quaternion_chart`), with
``PlantModel.step_derivative``;
:func:`derivative_into` is ``PlantModel.derivative`` (Euler angles) for the analysis tools.

Covered: the three variants, ideal fluid, current shear, and the dissertation's moving
mass (``moving_mass_model = 0``), with its servo's reaction on the hull or without
(``servo_reaction``). Not covered: the two-body moving mass (model 1), whose
mass matrix depends on y_v; :func:`supports` says so and the plant FMU then steps the
reference. Equation numbers: B. Li, FAU 2016; units SI.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

# Relative imports: the build renames the absolute imports of the project's packages
# (cosim/fmus/staging.py), which would make this file's text differ between the source
# tree and every build.
from .dynamics import PlantModel
from .jit import load_numba, njit, numba_fix
from .state_layout import (
    ANGULAR_VELOCITY,
    CURRENT,
    LINEAR_VELOCITY,
    MAX_SPEED,
    MAX_TURN_RATE,
    N_INPUTS,
    N_STATES,
    N_STEP_STATES,
    QUATERNION_CHART_PITCH,
)

_U, _P = LINEAR_VELOCITY.start, ANGULAR_VELOCITY.start  # u and p in the stepping state
_CURRENT_START, _CURRENT_STOP = CURRENT.start, CURRENT.stop  # the currents in the inputs
numba, NO_JIT_REASON = load_numba()
NO_JIT_FIX = numba_fix(NO_JIT_REASON) if numba is None else ""  # what would turn it on
AVAILABLE = numba is not None
_F = TypeVar("_F", bound=Callable[..., Any])


def _jit(func: _F) -> _F:
    """numba's compiled ``func`` (:func:`njit`: cached where it can be) when numba is usable,
    else the Python function unchanged."""
    if numba is None:
        return func
    return njit(numba, func)


# Layout of the flat parameter array (indices are compile-time constants in numba).
_SCALARS = (
    "m", "W", "B", "g", "I_xx", "I_yy", "I_zz", "x_g", "z_g",
    "a11", "a22", "a33", "a44", "a55", "a66", "a26", "a35",
    "X_uu", "Y_vv", "Y_rr", "Y_uv", "Y_ur", "N_vv", "N_rr", "N_uv", "N_ur", "K_p", "K_pp",
    "Z_ww", "Z_qq", "Z_uw", "Z_uq", "M_ww", "M_qq", "M_uw", "M_uq",
    "Z_ds", "M_ds", "fin_reference_speed", "m_v", "x_v", "mass_stroke", "mass_speed_limit",
    "z_t", "k_v", "d_v", "m_bar",
)  # fmt: skip
(M, W, B, G, IXX, IYY, IZZ, XG, ZG, A11, A22, A33, A44, A55, A66, A26, A35,
 XUU, YVV, YRR, YUV, YUR, NVV, NRR, NUV, NUR, KP, KPP,
 ZWW, ZQQ, ZUW, ZUQ, MWW, MQQ, MUW, MUQ,
 ZDS, MDS, FINREF, MV, XV, STROKE, SPEEDLIM, ZT, KV, DV, MBAR) = range(len(_SCALARS))  # fmt: skip
VARIANT = len(_SCALARS)
IDEAL = VARIANT + 1
SHEAR = VARIANT + 2
REACTION = VARIANT + 3  # 1: the servo's reaction and the stops' impacts act; 0: left out
INV = VARIANT + 4  # (M_RB + M_A)^-1 on the free DOFs, 36 values row by row
RIGID = INV + 36  # M_RB, 36 values row by row
MASS = RIGID + 36  # M_RB + M_A, 36 values row by row
N_PARAMETERS = MASS + 36


def supports(model: PlantModel) -> str:
    """ "" when the compiled path covers ``model``, else why not."""
    if not AVAILABLE:
        return NO_JIT_REASON
    if model.two_body:
        return "moving_mass_model = 1 (two bodies) has no compiled path"
    return ""


def flat_parameters(model: PlantModel) -> np.ndarray:
    """The flat float64 parameter array of ``model`` (built once per model)."""
    params = model.params
    p = np.empty(N_PARAMETERS)
    p[:VARIANT] = [float(getattr(params, name)) for name in _SCALARS]
    p[VARIANT] = int(model.variant)
    p[IDEAL] = 1.0 if model.ideal_fluid else 0.0
    p[SHEAR] = model.current_shear
    p[REACTION] = 1.0 if model.servo_reaction else 0.0
    p[INV:RIGID] = model._inverse_mass.ravel()
    p[RIGID:MASS] = model._rigid_mass.ravel()
    p[MASS:] = model.mass_matrix.ravel()
    return p


@_jit
def _cross(
    a0: float, a1: float, a2: float, b0: float, b1: float, b2: float
) -> tuple[float, float, float]:
    """a x b on scalars (the reference's ``kinematics.cross``, same rounding)."""
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@_jit
def _mat_vec(p: np.ndarray, start: int, v: np.ndarray, out: np.ndarray) -> None:
    """out = A v with A the 6x6 block of p at ``start`` (row by row, left to right)."""
    for i in range(6):
        acc = 0.0
        for j in range(6):
            acc += p[start + 6 * i + j] * v[j]
        out[i] = acc


@_jit
def _coriolis(p: np.ndarray, nu: np.ndarray, nu_r: np.ndarray, f: np.ndarray) -> None:
    """f -= C_RB(nu) nu (2.3.13) + C_A(nu_r) nu_r (A.62), as the reference writes them."""
    m, xg, zg = p[M], p[XG], p[ZG]
    v0, v1, v2, w0, w1, w2 = nu[0], nu[1], nu[2], nu[3], nu[4], nu[5]
    a0, a1, a2 = _cross(w0, w1, w2, v0, v1, v2)
    c0, c1, c2 = _cross(w0, w1, w2, xg, 0.0, zg)
    b0, b1, b2 = _cross(w0, w1, w2, c0, c1, c2)
    d0, d1, d2 = _cross(xg, 0.0, zg, a0, a1, a2)
    e0, e1, e2 = _cross(w0, w1, w2, p[IXX] * w0, p[IYY] * w1, p[IZZ] * w2)
    crb = (m * (a0 + b0), m * (a1 + b1), m * (a2 + b2), m * d0 + e0, m * d1 + e1, m * d2 + e2)
    u, v, w, pr, q, r = nu_r[0], nu_r[1], nu_r[2], nu_r[3], nu_r[4], nu_r[5]
    l0, l1, l2 = p[A11] * u, p[A22] * v + p[A26] * r, p[A33] * w + p[A35] * q
    g0, g1, g2 = p[A44] * pr, p[A55] * q + p[A35] * w, p[A66] * r + p[A26] * v
    h0, h1, h2 = _cross(l0, l1, l2, pr, q, r)
    i0, i1, i2 = _cross(l0, l1, l2, u, v, w)
    j0, j1, j2 = _cross(g0, g1, g2, pr, q, r)
    ca = (-h0, -h1, -h2, -i0 - j0, -i1 - j1, -i2 - j2)
    for k in range(6):
        f[k] = f[k] - crb[k] - ca[k]


@_jit
def _viscous(p: np.ndarray, nu_r: np.ndarray, f: np.ndarray) -> None:
    """f += the viscous cross-flow and lift forces (4.2.6)-(4.2.9)."""
    u, v, w, pr, q, r = nu_r[0], nu_r[1], nu_r[2], nu_r[3], nu_r[4], nu_r[5]
    f[0] += p[XUU] * u * abs(u)
    f[1] += p[YVV] * v * abs(v) + p[YRR] * r * abs(r) + p[YUV] * u * v + p[YUR] * u * r
    f[2] += p[ZWW] * w * abs(w) + p[ZQQ] * q * abs(q) + p[ZUW] * u * w + p[ZUQ] * u * q
    f[3] += p[KP] * pr + p[KPP] * pr * abs(pr)
    f[4] += p[MWW] * w * abs(w) + p[MQQ] * q * abs(q) + p[MUW] * u * w + p[MUQ] * u * q
    f[5] += p[NVV] * v * abs(v) + p[NRR] * r * abs(r) + p[NUV] * u * v + p[NUR] * u * r


@_jit
def _base_force(
    p: np.ndarray, x: np.ndarray, inputs: np.ndarray, u_r: float, R: np.ndarray, f: np.ndarray
) -> tuple[float, float]:
    """f = actuators (6.3.79, Table 6.1) + moving-mass reaction and offset weight
    (6.3.11-6.3.13; no reaction without ``servo_reaction``) + restoring (3.5.3), with
    Gamma = R^T [0, 0, 1] the third row of R; returns (y', y'') of the mass (6.3.12)."""
    y_v, y_vel = x[12], x[13]
    accel = (p[KV] * (inputs[4] - y_v) - p[DV] * y_vel) / p[MV]
    stroke, limit = p[STROKE], p[SPEEDLIM]
    if (y_v >= stroke and y_vel >= 0.0 and accel >= 0.0) or (
        y_v <= -stroke and y_vel <= 0.0 and accel <= 0.0
    ):
        y_vel, accel = 0.0, 0.0
    elif limit > 0.0 and abs(y_vel) >= limit and accel * y_vel > 0:
        accel = 0.0
    f_mm = -p[MV] * accel if p[REACTION] != 0.0 else 0.0
    g0, g1, g2 = R[2, 0], R[2, 1], R[2, 2]
    weight = p[MV] * p[G] * y_v
    roll = -p[ZG] * f_mm + weight * g2
    yaw = p[XV] * f_mm + weight * -g0
    m0, m1, m2 = _cross(p[XG], 0.0, p[ZG], g0, g1, g2)
    wb = p[W] - p[B]
    thrust, f_t, delta_s = inputs[0], inputs[2], inputs[3]
    relative = u_r / p[FINREF]
    scale = 0.0  # idle fins: no force, even where relative^2 overflows (PlantModel.actuators)
    if delta_s != 0.0:
        scale = relative * abs(relative) * delta_s  # lift reverses astern
    f[0] = thrust + 0.0 + wb * g0
    f[1] = f_t + f_mm + wb * g1
    f[2] = p[ZDS] * scale + 0.0 + wb * g2
    f[3] = inputs[1] - f_t * p[ZT] + roll + p[W] * m0
    f[4] = p[MDS] * scale + 0.0 + p[W] * m1
    f[5] = 0.0 + yaw + p[W] * m2
    return y_vel, accel


@_jit
def _rotation(phi: float, theta: float, psi: float, R: np.ndarray) -> None:
    """R = Rz(psi) Ry(theta) Rx(phi) (2.2.8) into the 3x3 array R."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    R[0, 0], R[0, 1], R[0, 2] = cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st
    R[1, 0], R[1, 1], R[1, 2] = sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf
    R[2, 0], R[2, 1], R[2, 2] = -st, ct * sf, ct * cf


@_jit
def _quaternion_rotation(z: np.ndarray, R: np.ndarray) -> None:
    """R of the quaternion z[14:18] = [w, x, y, z], normalised on the way
    (``kinematics.quaternion_rotation_matrix``)."""
    w, x, y, c = z[14], z[15], z[16], z[17]
    s = 2.0 / (w * w + x * x + y * y + c * c)
    R[0, 0], R[0, 1], R[0, 2] = 1.0 - s * (y * y + c * c), s * (x * y - w * c), s * (x * c + w * y)
    R[1, 0], R[1, 1], R[1, 2] = s * (x * y + w * c), 1.0 - s * (x * x + c * c), s * (y * c - w * x)
    R[2, 0], R[2, 1], R[2, 2] = s * (x * c - w * y), s * (y * c + w * x), 1.0 - s * (x * x + y * y)


@_jit
def _added_mass_times(
    p: np.ndarray, n0: float, n1: float, n2: float, n3: float, n4: float, n5: float
) -> tuple[float, float, float, float, float, float]:
    """M_A n (the reference's ``added_mass_matrix_times``)."""
    return (
        p[A11] * n0,
        p[A22] * n1 + p[A26] * n5,
        p[A33] * n2 + p[A35] * n4,
        p[A44] * n3,
        p[A55] * n4 + p[A35] * n2,
        p[A66] * n5 + p[A26] * n1,
    )


@_jit
def _phi_row(a: float, R: np.ndarray, v0: float, v1: float, v2: float) -> float:
    """Row i of Phi = R^T (dV/d eta1) R times v, with a = R[0, i] * shear (the only
    non-zero gradient is d(current_north)/d(east)): Phi[i, j] = a R[1, j]."""
    row: float = (a * R[1, 0]) * v0 + (a * R[1, 1]) * v1 + (a * R[1, 2]) * v2
    return row


@_jit
def _full_form(
    p: np.ndarray,
    x: np.ndarray,
    inputs: np.ndarray,
    R: np.ndarray,
    work: np.ndarray,
    dx: np.ndarray,
) -> tuple[float, float]:
    """nu_dot and eta1_dot of the full form (3.6.2, 4.3.1) into dx, with the current's
    forces (3.4.12-3.4.20: ``currents.full_form_current_force``)."""
    nu, nu_r, f, cur = work[0], work[1], work[2], work[3]
    for i in range(6):
        nu[i] = x[6 + i]
        nu_r[i] = x[6 + i]
    v0, v1, v2 = inputs[5] + p[SHEAR] * x[1], inputs[6], inputs[7]
    cb0 = R[0, 0] * v0 + R[1, 0] * v1 + R[2, 0] * v2
    cb1 = R[0, 1] * v0 + R[1, 1] * v1 + R[2, 1] * v2
    cb2 = R[0, 2] * v0 + R[1, 2] * v1 + R[2, 2] * v2
    nu_r[0], nu_r[1], nu_r[2] = nu[0] - cb0, nu[1] - cb1, nu[2] - cb2
    y_vel, accel = _base_force(p, x, inputs, nu_r[0], R, f)
    _coriolis(p, nu, nu_r, f)
    a0, a1, a2 = _cross(nu[3], nu[4], nu[5], cb0, cb1, cb2)
    d0, d1, d2 = -a0, -a1, -a2
    for i in range(6):
        cur[i] = 0.0
    shear = p[SHEAR]
    if shear != 0.0:
        a0, a1, a2 = R[0, 0] * shear, R[0, 1] * shear, R[0, 2] * shear  # rows of Phi
        pu0 = _phi_row(a0, R, nu[0], nu[1], nu[2])
        pu1 = _phi_row(a1, R, nu[0], nu[1], nu[2])
        pu2 = _phi_row(a2, R, nu[0], nu[1], nu[2])
        d0, d1, d2 = d0 + pu0, d1 + pu1, d2 + pu2
        mb = p[MBAR]
        im = _added_mass_times(p, nu_r[0], nu_r[1], nu_r[2], nu_r[3], nu_r[4], nu_r[5])
        s0, s1, s2 = im[0] + mb * nu_r[0], im[1] + mb * nu_r[1], im[2] + mb * nu_r[2]
        cur[0] = mb * pu0 - _phi_row(a0, R, s0, s1, s2)
        cur[1] = mb * pu1 - _phi_row(a1, R, s0, s1, s2)
        cur[2] = mb * pu2 - _phi_row(a2, R, s0, s1, s2)
    md = _added_mass_times(p, d0, d1, d2, 0.0, 0.0, 0.0)
    for i in range(6):
        f[i] = f[i] + (cur[i] + md[i])
    if p[IDEAL] == 0.0:
        _viscous(p, nu_r, f)
    _mat_vec(p, INV, f, work[4])
    for i in range(6):
        dx[6 + i] = work[4][i]
    for i in range(3):
        dx[i] = R[i, 0] * nu[0] + R[i, 1] * nu[1] + R[i, 2] * nu[2]
    return y_vel, accel


@_jit
def _relative_form(
    p: np.ndarray,
    x: np.ndarray,
    inputs: np.ndarray,
    R: np.ndarray,
    work: np.ndarray,
    dx: np.ndarray,
) -> tuple[float, float]:
    """nu_dot and eta1_dot of the lateral and horizontal variants (the relative form with
    the yaw-turned current, (5.2.10); the sheared current's terms, (5.3.1)) into dx."""
    nu_r, f = work[1], work[2]
    v0, v1, v2 = inputs[5] + p[SHEAR] * x[1], inputs[6], inputs[7]
    cp, sp = math.cos(x[5]), math.sin(x[5])
    c0, c1 = cp * v0 + sp * v1, -sp * v0 + cp * v1
    for i in range(6):
        nu_r[i] = x[6 + i]
    nu_r[0] -= c0
    nu_r[1] -= c1
    for i in range(3):
        dx[i] = (R[i, 0] * nu_r[0] + R[i, 1] * nu_r[1] + R[i, 2] * nu_r[2]) + (v0, v1, v2)[i]
    y_vel, accel = _base_force(p, x, inputs, nu_r[0], R, f)
    _coriolis(p, nu_r, nu_r, f)
    if p[IDEAL] == 0.0:
        _viscous(p, nu_r, f)
    shear, wa0, wa1 = p[SHEAR], 0.0, 0.0
    if shear != 0.0:
        k = shear * dx[1]
        wa0, wa1 = cp * k, -sp * k
        im = _added_mass_times(p, nu_r[0], nu_r[1], nu_r[2], nu_r[3], nu_r[4], nu_r[5])
        mb = p[MBAR]
        s = shear * (sp * (im[0] + mb * nu_r[0]) + cp * (im[1] + mb * nu_r[1]))
        pf0, pf1 = cp * s, -sp * s
        for i in range(6):
            r = RIGID + 6 * i
            sf = -p[r] * wa0 + -p[r + 1] * wa1 + -p[r + 2] * 0.0
            if i == 0:
                sf += mb * wa0 - pf0
            elif i == 1:
                sf += mb * wa1 - pf1
            elif i == 2:
                sf += mb * 0.0 - 0.0 * s
            f[i] += sf
    _mat_vec(p, INV, f, work[4])
    for i in range(6):
        dx[6 + i] = work[4][i]
    dx[6] += dx[5] * c1 + wa0
    dx[7] += -dx[5] * c0 + wa1
    return y_vel, accel


@_jit
def derivative_into(
    p: np.ndarray,
    x: np.ndarray,
    inputs: np.ndarray,
    R: np.ndarray,
    work: np.ndarray,
    dx: np.ndarray,
) -> None:
    """x_dot = f(x, inputs) into dx (``PlantModel.derivative``); R (3x3) and work (5x6)
    are scratch arrays."""
    phi, theta = x[3], x[4]
    _rotation(phi, theta, x[5], R)
    cf, sf, ct, tt = math.cos(phi), math.sin(phi), math.cos(theta), math.tan(theta)
    pr, q, r = x[9], x[10], x[11]
    dx[3] = 1.0 * pr + sf * tt * q + cf * tt * r
    dx[4] = 0.0 * pr + cf * q + -sf * r
    dx[5] = 0.0 * pr + sf / ct * q + cf / ct * r
    _rates(p, x, inputs, R, work, dx)
    variant = p[VARIANT]
    if variant != 0.0:
        dx[2], dx[4] = 0.0, 0.0
        if variant == 2.0:
            dx[3] = 0.0


@_jit
def _rates(
    p: np.ndarray,
    x: np.ndarray,
    inputs: np.ndarray,
    R: np.ndarray,
    work: np.ndarray,
    dx: np.ndarray,
) -> None:
    """Everything but the attitude's rate into dx, the attitude given as R
    (``PlantModel._rates``)."""
    if p[VARIANT] == 0.0:
        y_vel, accel = _full_form(p, x, inputs, R, work, dx)
    else:
        y_vel, accel = _relative_form(p, x, inputs, R, work, dx)
    dx[12], dx[13] = y_vel, accel


@_jit
def step_derivative_into(
    p: np.ndarray,
    z: np.ndarray,
    inputs: np.ndarray,
    R: np.ndarray,
    work: np.ndarray,
    dz: np.ndarray,
    quaternion: bool,
) -> None:
    """The stepping state's derivative into dz in one attitude chart
    (``PlantModel.step_derivative``): with ``quaternion`` (full variant) q_dot =
    1/2 q (x) [0, omega], Euler entries still; else :func:`derivative_into`, quaternion
    still."""
    if not quaternion:
        derivative_into(p, z, inputs, R, work, dz)
        for i in range(14, 18):
            dz[i] = 0.0
        return
    _quaternion_rotation(z, R)
    _rates(p, z, inputs, R, work, dz)
    dz[3], dz[4], dz[5] = 0.0, 0.0, 0.0
    w, x, y, c = z[14], z[15], z[16], z[17]
    pr, q, r = z[9], z[10], z[11]
    dz[14] = 0.5 * (-x * pr - y * q - c * r)
    dz[15] = 0.5 * (w * pr + y * r - c * q)
    dz[16] = 0.5 * (w * q + c * pr - x * r)
    dz[17] = 0.5 * (w * r + x * q - y * pr)


@_jit
def project(p: np.ndarray, x: np.ndarray, collide: bool) -> None:
    """``PlantModel.project`` in place: frozen DOFs at 0, the mass within its stops (an
    arrival at a stop with ``collide`` hands its momentum m_v y' J to the hull, unless
    ``servo_reaction`` is off) and under the speed limit. Model 0 only
    (J = [0, 1, 0, -z_g, 0, x_v])."""
    variant = p[VARIANT]
    if variant != 0.0:
        x[8], x[10], x[2], x[4] = 0.0, 0.0, 0.0, 0.0
        if variant == 2.0:
            x[9], x[3] = 0.0, 0.0
    stroke = p[STROKE]
    if abs(x[12]) >= stroke:
        x[12] = math.copysign(stroke, x[12])
        if x[13] * x[12] > 0.0:
            if collide and p[REACTION] != 0.0:
                k = p[MV] * x[13]
                j0, j1, j2, j3, j4, j5 = k * 0.0, k * 1.0, k * 0.0, k * -p[ZG], k * 0.0, k * p[XV]
                for i in range(6):
                    r = INV + 6 * i
                    x[6 + i] = x[6 + i] + (
                        p[r] * j0
                        + p[r + 1] * j1
                        + p[r + 2] * j2
                        + p[r + 3] * j3
                        + p[r + 4] * j4
                        + p[r + 5] * j5
                    )
            x[13] = 0.0
    limit = p[SPEEDLIM]
    if limit > 0.0:
        x[13] = min(max(x[13], -limit), limit)
    if collide and x.size == 18:
        norm = math.sqrt(x[14] * x[14] + x[15] * x[15] + x[16] * x[16] + x[17] * x[17])
        for i in range(14, 18):
            x[i] = x[i] / norm


@_jit
def _quaternion_from_euler(phi: float, theta: float, psi: float, z: np.ndarray) -> None:
    """z[14:18] = the quaternion of R = Rz(psi) Ry(theta) Rx(phi)
    (``kinematics.quaternion_from_euler``)."""
    cr, sr = math.cos(0.5 * phi), math.sin(0.5 * phi)
    cp, sp = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cy, sy = math.cos(0.5 * psi), math.sin(0.5 * psi)
    z[14] = cr * cp * cy + sr * sp * sy
    z[15] = sr * cp * cy - cr * sp * sy
    z[16] = cr * sp * cy + sr * cp * sy
    z[17] = cr * cp * sy - sr * sp * cy


@_jit
def _nearest_turn(angle: float, previous: float) -> float:
    """angle + 2 pi k nearest ``previous`` (``kinematics._nearest_turn``; a nan stays nan)."""
    turns = (previous - angle) / (2.0 * math.pi) + 0.5
    if not math.isfinite(turns):
        return angle + turns
    return angle + 2.0 * math.pi * math.floor(turns)


@_jit
def _euler_from_quaternion(z: np.ndarray, R: np.ndarray, a0: float, a2: float) -> None:
    """z[3:6] = the Euler angles of z's quaternion with |theta| <= 90 deg, roll and yaw
    continued by whole turns from a0 and a2 (``kinematics.euler_from_quaternion``, which
    says why)."""
    _quaternion_rotation(z, R)
    cos_theta = math.sqrt(R[0, 0] * R[0, 0] + R[1, 0] * R[1, 0])  # not hypot: numba's differs
    theta = math.atan2(-R[2, 0], cos_theta)
    if cos_theta > 1e-12:
        phi, psi = math.atan2(R[2, 1], R[2, 2]), math.atan2(R[1, 0], R[0, 0])
    else:
        phi = a0
        if theta > 0:
            psi = phi - math.atan2(R[0, 1], R[0, 2])
        else:
            psi = math.atan2(-R[0, 1], -R[0, 2]) - phi
    z[3], z[4], z[5] = _nearest_turn(phi, a0), theta, _nearest_turn(psi, a2)


@_jit
def _start(x: np.ndarray, z: np.ndarray) -> bool:
    """z = the stepping state of x (``stepping.stepping_state``): False for a zero
    quaternion."""
    for i in range(14):
        z[i] = x[i]
    if x.size == 14:
        _quaternion_from_euler(x[3], x[4], x[5], z)
        return True
    w, a, b, c = x[14], x[15], x[16], x[17]
    norm = math.sqrt(w * w + a * a + b * b + c * c)
    if not norm > 0.0:
        return False
    for i in range(14, 18):
        z[i] = x[i] / norm
    return True


@_jit
def _quaternion_chart(p: np.ndarray, z: np.ndarray) -> bool:
    """``PlantModel.uses_quaternion``: the full variant beyond ``QUATERNION_CHART_PITCH``."""
    chart: bool = p[VARIANT] == 0.0 and abs(z[4]) > QUATERNION_CHART_PITCH
    return chart


@_jit
def _stage(
    p: np.ndarray,
    z: np.ndarray,
    k: np.ndarray,
    scale: float,
    inputs: np.ndarray,
    scratch: tuple[np.ndarray, np.ndarray, np.ndarray],
    out: np.ndarray,
    quaternion: bool,
) -> None:
    """An RK4 stage: out = the derivative at z + scale k, projected; ``scratch`` holds R
    (3x3), work (5x6) and the stage state (18)."""
    R, work, y = scratch
    for i in range(18):
        y[i] = z[i] + scale * k[i]
    project(p, y, False)
    step_derivative_into(p, y, inputs, R, work, out, quaternion)


# The scratch array of :func:`advance_into` and :func:`step_into` (float64): R (3x3), work
# (5x6), the stage state (18), the RK4 slopes k1..k4 (4x18), the new stepping state (18),
# the inputs at a sub-step's start, middle and end when they vary (3 x inputs).
_SCRATCH_R, _SCRATCH_WORK, _SCRATCH_Y, _SCRATCH_K, _SCRATCH_Z, _SCRATCH_U = 0, 9, 39, 57, 129, 147
STEP_SCRATCH = _SCRATCH_U + 3 * N_INPUTS
CURRENT_CHANGED = 4  # step_into: the currents changed since the last step, nothing done
LEFT_THE_RANGE = 3  # advance_into: the state became non-finite or left the model's range


@_jit
def _substep(
    p: np.ndarray,
    z: np.ndarray,
    u0: np.ndarray,
    u1: np.ndarray,
    u2: np.ndarray,
    dt: float,
    scratch: tuple[np.ndarray, np.ndarray, np.ndarray],
    stages: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """One RK4 sub-step of dt s on z in place, the inputs u0 at its start, u1 at its
    middle and u2 at its end (all three the same when held), projected, the attitude chart
    it did not integrate refreshed (``stepping._substep``)."""
    R, work, _ = scratch
    k1, k2, k3, k4 = stages
    half, sixth = 0.5 * dt, dt / 6.0
    quaternion = _quaternion_chart(p, z)
    a0, a2 = z[3], z[5]
    step_derivative_into(p, z, u0, R, work, k1, quaternion)
    _stage(p, z, k1, half, u1, scratch, k2, quaternion)
    _stage(p, z, k2, half, u1, scratch, k3, quaternion)
    _stage(p, z, k3, dt, u2, scratch, k4, quaternion)
    for i in range(18):
        z[i] = z[i] + sixth * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i])
    project(p, z, True)
    if quaternion:
        _euler_from_quaternion(z, R, a0, a2)
    else:
        _quaternion_from_euler(z[3], z[4], z[5], z)


@_jit
def _inputs_at(inputs: np.ndarray, rates: np.ndarray, tau: float, out: np.ndarray) -> None:
    """out = the inputs tau seconds into the step: u + tau u' + tau^2 / 2 u''."""
    for i in range(inputs.size):
        out[i] = inputs[i] + tau * rates[0, i] + 0.5 * tau * tau * rates[1, i]


@_jit
def varies(rates: np.ndarray) -> bool:
    """True if some input has a first or second time derivative other than 0 in ``rates``
    (2 x inputs): the step then follows them, else it holds every input (a second
    derivative alone, as at the turning point of a quadratic extrapolation, counts)."""
    varying = False  # (a loop, not any(): numba compiles no generator into this)
    for i in range(rates.shape[1]):
        if rates[0, i] != 0.0 or rates[1, i] != 0.0:
            varying = True
    return varying


@_jit
def advance_into(
    p: np.ndarray,
    x: np.ndarray,
    z: np.ndarray,
    inputs: np.ndarray,
    rates: np.ndarray,
    varying: bool,
    n: int,
    dt: float,
    scratch: np.ndarray,
) -> int:
    """z = the stepping state n RK4 steps of dt seconds after x (a state or a stepping
    state), projected after each stage, each sub-step in the attitude chart its start
    picks and the other chart refreshed at its end, like ``stepping.advance``: the inputs
    held, or (``varying``) following ``rates`` (2 x inputs: their first and second time
    derivatives at the step's start), each RK4 stage taking the inputs at its own time.
    Its working arrays are slices of ``scratch`` (:data:`STEP_SCRATCH` values), so it
    allocates nothing. Returns 0, or 1 for a non-finite input or rate or a current beyond
    MAX_SPEED (an input, or the sheared current at the vehicle: ``stepping.check_current``),
    2 for a non-finite state or a zero quaternion, 3 for a state that became non-finite or
    left the model's range."""
    for i in range(inputs.size):
        if not math.isfinite(inputs[i]):
            return 1
        if _CURRENT_START <= i < _CURRENT_STOP and not abs(inputs[i]) <= MAX_SPEED:
            return 1
        if varying and not (math.isfinite(rates[0, i]) and math.isfinite(rates[1, i])):
            return 1
    for i in range(x.size):
        if not math.isfinite(x[i]):
            return 2
    if not abs(inputs[_CURRENT_START] + p[SHEAR] * x[1]) <= MAX_SPEED:  # at the vehicle
        return 1
    if not _start(x, z):
        return 2
    R = scratch[_SCRATCH_R:_SCRATCH_WORK].reshape((3, 3))
    work = scratch[_SCRATCH_WORK:_SCRATCH_Y].reshape((5, 6))
    y = scratch[_SCRATCH_Y:_SCRATCH_K]
    slopes = scratch[_SCRATCH_K:_SCRATCH_Z].reshape((4, 18))
    stages = (slopes[0], slopes[1], slopes[2], slopes[3])
    m = inputs.size
    u0 = scratch[_SCRATCH_U : _SCRATCH_U + m]
    u1 = scratch[_SCRATCH_U + m : _SCRATCH_U + 2 * m]
    u2 = scratch[_SCRATCH_U + 2 * m : _SCRATCH_U + 3 * m]
    project(p, z, False)
    for j in range(n):
        if varying:
            _inputs_at(inputs, rates, j * dt, u0)
            _inputs_at(inputs, rates, j * dt + 0.5 * dt, u1)
            _inputs_at(inputs, rates, (j + 1) * dt, u2)
            _substep(p, z, u0, u1, u2, dt, (R, work, y), stages)
        else:
            _substep(p, z, inputs, inputs, inputs, dt, (R, work, y), stages)
    for i in range(18):
        if not math.isfinite(z[i]):
            return LEFT_THE_RANGE
    for i in range(3):  # the model's range (state_layout.MAX_SPEED, MAX_TURN_RATE)
        if abs(z[_U + i]) > MAX_SPEED or abs(z[_P + i]) > MAX_TURN_RATE:
            return LEFT_THE_RANGE
    return 0


@_jit
def outputs_into(
    p: np.ndarray, z: np.ndarray, inputs: np.ndarray, R: np.ndarray, out: np.ndarray
) -> None:
    """The plant FMU's derived outputs into out from the stepping state z: u_rel, v_rel,
    w_rel (nu - U, ``PlantModel.relative_velocity``) and the kinetic energy
    1/2 nu_r^T (M_RB + M_A) nu_r (``PlantModel.kinetic_energy``, model 0), J."""
    v0, v1, v2 = inputs[5] + p[SHEAR] * z[1], inputs[6], inputs[7]
    if p[VARIANT] == 0.0:
        if _quaternion_chart(p, z):  # the rotation of the chart the stepping integrates
            _quaternion_rotation(z, R)
        else:
            _rotation(z[3], z[4], z[5], R)
        c0 = R[0, 0] * v0 + R[1, 0] * v1 + R[2, 0] * v2
        c1 = R[0, 1] * v0 + R[1, 1] * v1 + R[2, 1] * v2
        c2 = R[0, 2] * v0 + R[1, 2] * v1 + R[2, 2] * v2
    else:
        cp, sp = math.cos(z[5]), math.sin(z[5])
        c0, c1, c2 = cp * v0 + sp * v1, -sp * v0 + cp * v1, 0.0
    nu_r = (z[6] - c0, z[7] - c1, z[8] - c2, z[9], z[10], z[11])
    energy = 0.0
    for j in range(6):
        column = 0.0
        for i in range(6):
            column += nu_r[i] * p[MASS + 6 * i + j]
        energy += column * nu_r[j]
    out[0], out[1], out[2], out[3] = nu_r[0], nu_r[1], nu_r[2], 0.5 * energy


@_jit
def step_into(
    p: np.ndarray,
    inputs: np.ndarray,
    rates: np.ndarray,
    x: np.ndarray,
    derived: np.ndarray,
    last_current: np.ndarray,
    scratch: np.ndarray,
    n: int,
    dt: float,
) -> int:
    """One communication step of the plant FMU, in place: the stepping state x (18) n RK4
    steps of dt seconds on (:func:`advance_into`), then its derived outputs into
    ``derived`` (:func:`outputs_into`). ``rates`` (2 x inputs) are the input derivatives
    the importer set for this step: the currents' are set to 0 here (the currents are held
    over a step), and the step follows the others when one of their derivatives is not 0
    (:func:`varies`), else holds every input. Nothing is allocated: the FMU passes
    views of its value buffers and a preallocated ``scratch`` (:data:`STEP_SCRATCH`).
    Returns 0; or, with nothing changed, :data:`CURRENT_CHANGED` when the current inputs
    differ from ``last_current`` (the velocity jump of a current change is computed by the
    reference, ``PlantModel.current_change_velocity_jump``), or :func:`advance_into`'s
    code of a non-finite input, rate or state."""
    for i in range(3):
        if inputs[_CURRENT_START + i] != last_current[i]:
            return CURRENT_CHANGED
    for i in range(3):
        rates[0, _CURRENT_START + i] = 0.0
        rates[1, _CURRENT_START + i] = 0.0
    z = scratch[_SCRATCH_Z:_SCRATCH_U]
    status = advance_into(p, x, z, inputs, rates, varies(rates), n, dt, scratch)
    if status != 0:
        return status
    for i in range(18):
        x[i] = z[i]
    outputs_into(p, x, inputs, scratch[_SCRATCH_R:_SCRATCH_WORK].reshape((3, 3)), derived)
    return 0


class CompiledPlant:
    """The compiled derivative and step of one :class:`PlantModel` (see :func:`supports`)."""

    def __init__(self, model: PlantModel) -> None:
        reason = supports(model)
        if reason:
            raise ValueError(f"no compiled path for this plant: {reason}")
        self.model = model
        self.parameters = flat_parameters(model)
        self._R, self._work = np.empty((3, 3)), np.empty((5, 6))
        self._scratch = np.empty(STEP_SCRATCH)
        self._no_rates = np.zeros((2, N_INPUTS))  # (not read when the inputs are held)

    def derivative(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """``PlantModel.derivative`` (a new array)."""
        dx = np.empty(N_STATES)
        derivative_into(self.parameters, x, inputs, self._R, self._work, dx)
        return dx

    def step_derivative(self, z: np.ndarray, inputs: np.ndarray, quaternion: bool) -> np.ndarray:
        """``PlantModel.step_derivative`` (a new array)."""
        dz = np.empty(N_STEP_STATES)
        step_derivative_into(self.parameters, z, inputs, self._R, self._work, dz, quaternion)
        return dz

    def outputs(self, z: np.ndarray, inputs: np.ndarray) -> list[float]:
        """[u_rel, v_rel, w_rel (m/s), kinetic_energy (J)] of a stepping state (see
        :func:`outputs_into`)."""
        out = np.empty(4)
        outputs_into(self.parameters, z, inputs, self._R, out)
        return out.tolist()

    def advance(
        self,
        x: np.ndarray,
        z: np.ndarray,
        inputs: np.ndarray,
        n: int,
        dt: float,
        rates: np.ndarray | None = None,
    ) -> int:
        """z (a float64 stepping state) = n RK4 steps of dt s after x (a state or a
        stepping state); :func:`advance_into`'s code, the inputs held, or following
        ``rates`` (the inputs' derivatives, 2 x inputs) when given."""
        varying = rates is not None
        held = self._no_rates if rates is None else rates
        try:
            return advance_into(self.parameters, x, z, inputs, held, varying, n, dt, self._scratch)
        except ArithmeticError:  # numba's division by zero: a state thrown out of the range
            return LEFT_THE_RANGE

    def warm_up(self, x: np.ndarray, inputs: np.ndarray, rates: np.ndarray | None = None) -> None:
        """Compile (or load from numba's cache) every function a step calls, by one RK4
        step of 1 ms on copies of ``x``, ``inputs`` and ``rates`` (the FMU's input
        derivatives, 2 x inputs, of the array type the FMU steps with), held and with
        input derivatives: numba compiles on a function's first call, which would
        otherwise be the first doStep (seconds on a first run, ~0.5 s of cache loading
        later), counted as stepping time."""
        z = np.empty(N_STEP_STATES)
        x, inputs = np.array(x, dtype=float), np.array(inputs, dtype=float)
        self.advance(x, z, inputs, 1, 1e-3)
        self.advance(x, z, inputs, 1, 1e-3, np.zeros((2, inputs.size)))  # input derivatives
        if len(x) == N_STEP_STATES and rates is not None:  # and the FMU's step, same types
            last_current = inputs[CURRENT].copy()
            scratch = np.empty(STEP_SCRATCH)
            rates = rates.copy() if rates.flags.c_contiguous else _strided_zeros(rates.shape)
            step_into(self.parameters, inputs, rates, x, np.empty(4), last_current, scratch, 1,
                      1e-3)  # fmt: skip


def _strided_zeros(shape: tuple[int, ...]) -> np.ndarray:
    """Zeros of ``shape`` (2, m) in a non-contiguous array, as numba types a view of some
    of the FMU's derivative buffer's columns."""
    return np.zeros((shape[0], shape[1] + 1))[:, : shape[1]]
