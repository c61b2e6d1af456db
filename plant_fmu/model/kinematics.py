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


def gravity_direction(phi: float, theta: float) -> np.ndarray:
    """Gamma = R^T [0, 0, 1] = [-sin theta, cos theta sin phi, cos theta cos phi] (3.5.3):
    the earth's down axis in body coordinates."""
    ct = math.cos(theta)
    return np.array([-math.sin(theta), ct * math.sin(phi), ct * math.cos(phi)])
