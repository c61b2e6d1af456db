"""The internal moving mass: its servo, its stops, and its two models of coupling to the hull.

The mass m_v slides on a rail along body y at (x_v, y_v, z_g) (Fig. 6.2). Its servo sets
the motion along the rail, m_v y'' + d_v y' + k_v y = k_v y_d (6.3.12): the drive (a
screw, not back-drivable) imposes this relative motion and the force it takes to do so is
the internal force between hull and mass. Two models of what that motion does to the hull:

* ``DISSERTATION`` (0): (6.3.11)/(6.3.13). The mass counts in M_RB at y_v = 0; the hull
  feels the reaction -m_v y'' along the rail and the offset weight m_v g y_v. The mass's
  own Coriolis and centripetal terms (m_v omega x y', m_v omega x (omega x r_v)) and the
  change of the inertia with y_v are left out, as in the dissertation.
* ``TWO_BODY`` (1): hull + fluid + point mass as one system (the full equations (6.2.28),
  as in the moving-mass literature after Woolsey and Leonard). The generalised momentum
  of the system is (M + dM(y_v)) nu + m_v y' J, with J the rail direction
  [e_y; r_v x e_y] = [0, 1, 0, -z_g, 0, x_v]; Kirchhoff's equations for it give the
  hull's acceleration with every coupling term kept. A stop is an inelastic impact that
  conserves this momentum.

Units SI; equation numbers refer to B. Li, FAU 2016; docs/model.md#gravity-and-the-moving-mass
derives model 1 and says what its tests check.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum
from typing import TYPE_CHECKING

import numpy as np

from plant_fmu.model.kinematics import cross

if TYPE_CHECKING:
    from plant_fmu.model.parameters import VehicleParameters

_E_Y = (0.0, 1.0, 0.0)


class MovingMassModel(IntEnum):
    """How the moving mass acts on the hull (the plant's ``moving_mass_model`` parameter)."""

    DISSERTATION = 0  # reaction -m_v y'' and offset weight only (6.3.11)-(6.3.13)
    TWO_BODY = 1  # full hull + point-mass dynamics (6.2.28) with every coupling term


def rail_direction(params: VehicleParameters) -> np.ndarray:
    """J = [e_y; r_v x e_y] = [0, 1, 0, -z_g, 0, x_v]: the generalised direction along which a
    force on the rail acts on the hull (independent of y_v): a rail force F (N) is the
    generalised force F J, N in the force rows and N m in the moment rows (J's entries
    there are lever arms, m)."""
    return np.array([0.0, 1.0, 0.0, -params.z_g, 0.0, params.x_v])


def servo_motion(
    params: VehicleParameters, y_v: float, y_vel: float, y_cmd: float
) -> tuple[float, float]:
    """(y' in m/s, y'' in m/s^2) of the mass on its rail under the servo (6.3.12).

    The servo follows the command as given: the stops, not the command, bound the motion
    (Sec. 6.3.1 constrains y_v and y_vel only, and the dissertation's LQR runs drive the
    mass at tens of cm/s, Fig. 6.14's y_vel axis spanning +-50 cm/s, which a command
    saturated at the stroke cannot).
    Against a stop (or at the rail-speed limit) the mass does not accelerate outwards.
    """
    accel = (params.k_v * (y_cmd - y_v) - params.d_v * y_vel) / params.m_v
    if _against_stop(y_v, y_vel, accel, params.mass_stroke):
        return 0.0, 0.0
    limit = params.mass_speed_limit
    if limit > 0.0 and abs(y_vel) >= limit and accel * y_vel > 0:
        accel = 0.0
    return y_vel, accel


def weight_moment(
    params: VehicleParameters, y_v: float, gamma: Sequence[float] | np.ndarray
) -> tuple[float, float]:
    """Roll and yaw moments of the offset weight, r x m_v g Gamma with r = [0, y_v, 0] and
    Gamma = R^T [0, 0, 1] = [-sin theta, cos theta sin phi, cos theta cos phi] (3.5.3):
    (m_v g y_v cos theta cos phi, m_v g y_v sin theta), N m."""
    weight = params.m_v * params.g * y_v
    return weight * gamma[2], weight * -gamma[0]


def mass_matrix_shift(params: VehicleParameters, y_v: float) -> np.ndarray:
    """dM(y_v) = M_p(r_v) - M_p(r_v0): how the rigid-body mass matrix changes when the mass
    leaves the centre of its rail (r_v0 = [x_v, 0, z_g]), with the point-mass matrix
    M_p(r) = m_v [[I, -S(r)], [S(r), |r|^2 I - r r^T]] (2.3.11 for a point). Written out:
    S(r_v) - S(r_v0) = y_v S(e_y), and the inertia changes by
    m_v [[y^2, -x_v y, 0], [-x_v y, 0, -z_g y], [0, -z_g y, y^2]]. y_v in m; dM in the
    units of M_RB (kg, kg m, kg m^2)."""
    m_y = params.m_v * y_v
    m_xy, m_zy, m_yy = params.x_v * m_y, params.z_g * m_y, y_v * m_y
    return np.array(
        [
            [0.0, 0.0, 0.0, 0.0, 0.0, -m_y],
            [0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [0.0, 0.0, 0.0, m_y, 0.0, 0.0],
            [0.0, 0.0, m_y, m_yy, -m_xy, 0.0],
            [0.0, 0.0, 0.0, -m_xy, 0.0, -m_zy],
            [-m_y, 0.0, 0.0, 0.0, -m_zy, m_yy],
        ]
    )


def two_body_force(
    params: VehicleParameters, nu: Sequence[float], y_v: float, y_vel: float
) -> np.ndarray:
    """What the two-body model adds to the hull's generalised force, beyond the reaction
    -m_v y'' J, [X, Y, Z, K, M, N].

    With D = [Dp; Dpi] the mass's momentum beyond what M_RB nu counts (Dp = m_v (omega x
    y_v e_y + y' e_y), Dpi = r_v x p_m - r_v0 x p_m0, p_m = m_v (v + omega x r_v + y' e_y)
    the mass's momentum, p_m0 the same at r_v0 and at rest on the rail), Kirchhoff's
    equations d/dt P + [omega x P; omega x Pi + v x P] = F for the whole system give
    -[m_v y' omega x e_y; y' e_y x p_m + m_v y' r_v x (omega x e_y)]
    - [omega x Dp; omega x Dpi + v x Dp]: the Coriolis (2 m_v omega x y'), centripetal
    (m_v omega x (omega x r_v)) and inertia-rate terms (6.2.28)-(6.2.30).

    Args:
        nu: [u, v, w, p, q, r], over ground (full form) or relative to the water
            (relative form): the rigid-body terms are Galilean-invariant.
    """
    m_v = params.m_v
    v, w = nu[:3], nu[3:]
    r_v = (params.x_v, y_v, params.z_g)
    r_0 = (params.x_v, 0.0, params.z_g)
    w_x_ey = cross(w, _E_Y)
    w_x_rv, w_x_r0 = cross(w, r_v), cross(w, r_0)
    p_m = [m_v * (v[i] + w_x_rv[i] + y_vel * _E_Y[i]) for i in range(3)]
    p_0 = [m_v * (v[i] + w_x_r0[i]) for i in range(3)]
    d_p = [m_v * (y_v * w_x_ey[i] + y_vel * _E_Y[i]) for i in range(3)]
    rv_x_pm, r0_x_p0 = cross(r_v, p_m), cross(r_0, p_0)
    d_pi = [rv_x_pm[i] - r0_x_p0[i] for i in range(3)]
    w_x_dp, w_x_dpi, v_x_dp = cross(w, d_p), cross(w, d_pi), cross(v, d_p)
    ey_x_pm, rv_x_w_x_ey = cross(_E_Y, p_m), cross(r_v, w_x_ey)
    linear = [-m_v * y_vel * w_x_ey[i] - w_x_dp[i] for i in range(3)]
    angular = [
        -y_vel * ey_x_pm[i] - m_v * y_vel * rv_x_w_x_ey[i] - w_x_dpi[i] - v_x_dp[i]
        for i in range(3)
    ]
    return np.array(linear + angular)


def _against_stop(y_v: float, y_vel: float, accel: float, stroke: float) -> bool:
    """True when the mass is at a stop and neither moves nor is pushed away from it."""
    if y_v >= stroke:
        return y_vel >= 0.0 and accel >= 0.0
    if y_v <= -stroke:
        return y_vel <= 0.0 and accel <= 0.0
    return False
