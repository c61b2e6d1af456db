"""Kinematics of a rigid body in the earth frame (Ch. 2 of the dissertation).

Rotation and Euler-rate matrices, the cross-product matrix, and a cross product on plain
Python floats for the hot paths of :mod:`plant_fmu.model.dynamics`. Equation numbers refer
to B. Li, *Dynamics and Control of Autonomous Underwater Vehicles with Internal
Actuators*, FAU 2016. Angles in rad.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def rotation_matrix(phi: float, theta: float, psi: float) -> np.ndarray:
    """Body-to-earth rotation R = Rz(psi) Ry(theta) Rx(phi) (2.2.8)."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, st = math.cos(theta), math.sin(theta)
    cp, sp = math.cos(psi), math.sin(psi)
    return np.array(
        [
            [cp * ct, -sp * cf + cp * st * sf, sp * sf + cp * cf * st],
            [sp * ct, cp * cf + sf * st * sp, -cp * sf + st * sp * cf],
            [-st, ct * sf, ct * cf],
        ]
    )


def euler_rate_matrix(phi: float, theta: float) -> np.ndarray:
    """T(eta2) with eta2_dot = T omega (2.2.15); singular at theta = +-90 deg."""
    cf, sf = math.cos(phi), math.sin(phi)
    ct, tt = math.cos(theta), math.tan(theta)
    return np.array([[1.0, sf * tt, cf * tt], [0.0, cf, -sf], [0.0, sf / ct, cf / ct]])


def skew(a: np.ndarray) -> np.ndarray:
    """Cross-product matrix S(a) with S(a) b = a x b."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def cross(
    a: Sequence[float] | np.ndarray, b: Sequence[float] | np.ndarray
) -> tuple[float, float, float]:
    """a x b of two 3-sequences of floats, as a tuple of Python floats.

    On 3-vectors np.cross costs ~10 us and numpy element access ~0.1 us per element; the
    force terms of the dynamics therefore work on Python floats (one array per term), which
    makes the right-hand side about 4x cheaper. Same product, same rounding.
    """
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def rotate(R: np.ndarray, v: Sequence[float] | np.ndarray, transpose: bool = False) -> np.ndarray:
    """R v (or R^T v) of a 3-vector, summed left to right as the compiled path sums it
    (numpy's BLAS product may round differently, which a closed loop can amplify)."""
    m = R.T if transpose else R
    rows = m.tolist()
    return np.array([r[0] * v[0] + r[1] * v[1] + r[2] * v[2] for r in rows])


def gravity_direction(phi: float, theta: float) -> np.ndarray:
    """Gamma = R^T [0, 0, 1] = [-sin theta, cos theta sin phi, cos theta cos phi] (3.5.3):
    the earth's down axis in body coordinates."""
    ct = math.cos(theta)
    return np.array([-math.sin(theta), ct * math.sin(phi), ct * math.cos(phi)])


# --- The attitude as a unit quaternion ----------------------------------------------------
#
# Written out by hand, not taken from scipy.spatial.transform.Rotation: these run four times
# per RK4 step inside the plant (a Rotation costs ~10 us per call, the whole derivative ~30)
# and the compiled path (plant_fmu.model.compiled) repeats them term by term in numba.
# Quaternions are [w, x, y, z] (Hamilton, scalar first) of the body-to-earth rotation.


def quaternion_from_euler(phi: float, theta: float, psi: float) -> np.ndarray:
    """q = q_z(psi) q_y(theta) q_x(phi), the quaternion of R = Rz(psi) Ry(theta) Rx(phi)
    (2.2.8); scipy's ``Rotation.from_euler("ZYX", [psi, theta, phi])`` up to sign."""
    cr, sr = math.cos(0.5 * phi), math.sin(0.5 * phi)
    cp, sp = math.cos(0.5 * theta), math.sin(0.5 * theta)
    cy, sy = math.cos(0.5 * psi), math.sin(0.5 * psi)
    return np.array(
        [
            cr * cp * cy + sr * sp * sy,
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
        ]
    )


def quaternion_rotation_matrix(q: Sequence[float] | np.ndarray) -> np.ndarray:
    """Body-to-earth rotation R of the quaternion q = [w, x, y, z], normalised on the way
    (s = 2 / |q|^2), so the RK4 stage states, which leave the unit sphere by O(h^2), still
    give a rotation."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    s = 2.0 / (w * w + x * x + y * y + z * z)
    return np.array(
        [
            [1.0 - s * (y * y + z * z), s * (x * y - w * z), s * (x * z + w * y)],
            [s * (x * y + w * z), 1.0 - s * (x * x + z * z), s * (y * z - w * x)],
            [s * (x * z - w * y), s * (y * z + w * x), 1.0 - s * (x * x + y * y)],
        ]
    )


def quaternion_rate(
    q: Sequence[float] | np.ndarray, omega: Sequence[float] | np.ndarray
) -> tuple[float, ...]:
    """q_dot = 1/2 q (x) [0, omega], omega = [p, q, r] the body rates: the kinematics of a
    unit quaternion (Fossen, *Handbook of Marine Craft Hydrodynamics*, 2011, Sec. 2.2.2),
    singular nowhere, unlike T(eta2) of (2.2.15)."""
    w, x, y, z = q[0], q[1], q[2], q[3]
    p, qr, r = omega[0], omega[1], omega[2]
    return (
        0.5 * (-x * p - y * qr - z * r),
        0.5 * (w * p + y * r - z * qr),
        0.5 * (w * qr + z * p - x * r),
        0.5 * (w * r + x * qr - y * p),
    )


def euler_from_quaternion(
    q: Sequence[float] | np.ndarray, previous: Sequence[float] | np.ndarray
) -> tuple[float, ...]:
    """(phi, theta, psi) of the rotation q: the triple with |theta| <= 90 deg, roll and yaw
    continued by whole turns from ``previous``.

    A rotation has two Euler triples, (phi, theta, psi) with |theta| <= 90 deg and
    (phi + pi, pi - theta, psi + pi), each up to whole turns. Which one is output is a rule
    of the attitude alone: always the first, the one the Euler-angle equations (2.2.15)
    follow, since their solution reaches |theta| = 90 deg only by passing exactly through
    the vertical. (Choosing the triple nearest the previous output instead made the choice
    after a pass near the vertical depend on the step: roll and yaw swing by nearly 180 deg
    there, and a coarse step found the other triple nearer.) Only the whole turns of roll
    and yaw come from ``previous``, so yaw runs on past +-180 deg in a turning circle.
    Pitch stays within +-90 deg; over the top of a loop roll and yaw turn by 180 deg.
    At theta = +-90 deg exactly only phi - psi (or phi + psi) is defined; phi then keeps
    its previous value.
    """
    R = quaternion_rotation_matrix(q)
    cos_theta = math.sqrt(R[0, 0] * R[0, 0] + R[1, 0] * R[1, 0])  # not hypot: numba's differs
    theta = math.atan2(-R[2, 0], cos_theta)
    if cos_theta > 1e-12:
        phi, psi = math.atan2(R[2, 1], R[2, 2]), math.atan2(R[1, 0], R[0, 0])
    else:  # R[0, 1:] = [sin, cos] of phi - psi (theta = 90 deg) or -(phi + psi) (-90 deg)
        phi = previous[0]
        turn = math.atan2(R[0, 1], R[0, 2]) if theta > 0 else math.atan2(-R[0, 1], -R[0, 2])
        psi = phi - turn if theta > 0 else turn - phi
    return _nearest_turn(phi, previous[0]), theta, _nearest_turn(psi, previous[2])


def _nearest_turn(angle: float, previous: float) -> float:
    """angle + 2 pi k, with k the whole number of turns that brings it nearest ``previous``;
    a nan stays nan (a sub-step gone unstable: the step's range check names it)."""
    turns = (previous - angle) / (2.0 * math.pi) + 0.5
    if not math.isfinite(turns):
        return angle + turns
    return angle + 2.0 * math.pi * math.floor(turns)
