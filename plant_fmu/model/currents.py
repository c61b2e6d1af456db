"""What a moving ocean current does to the hull: the current seen in body axes and the
forces of a sheared current (3.4.12-3.4.20, 5.2.10, 5.3.1).

The full 6-DOF variant integrates the full form on the velocity over ground and takes the
current forcing from :func:`full_form_current_force`. The lateral and horizontal variants
hold some degrees of freedom frozen, so their attitude does not turn as the body rates say
(theta stays 0 while psi' = r cos phi): the full form's Coriolis terms then no longer
cancel the current's, and those variants use the relative form instead (the substitution
nu -> nu_r of (5.2.10)), with the current turned into the body by the yaw only
(:func:`planar_current`) and the shear terms of :func:`relative_form_shear_force`.

Units SI; equation numbers refer to B. Li, FAU 2016.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from plant_fmu.model.inertia import added_mass_matrix_times
from plant_fmu.model.kinematics import cross

if TYPE_CHECKING:
    from plant_fmu.model.parameters import VehicleParameters


def planar_current(psi: float, v_c: Sequence[float] | np.ndarray) -> tuple[float, float]:
    """The horizontal current in the yaw-turned frame, Rz(psi)^T [V_N, V_E], m/s (5.2.10)."""
    cp, sp = math.cos(psi), math.sin(psi)
    return cp * v_c[0] + sp * v_c[1], -sp * v_c[0] + cp * v_c[1]


def full_form_current_force(
    params: VehicleParameters,
    shear: float,
    R: np.ndarray,
    current_body: Sequence[float],
    nu: Sequence[float],
    nu_r: Sequence[float],
) -> np.ndarray:
    """Forces the moving water exerts beyond C_A*(nu_r) nu_r in the full form: (Mbar + M_A)
    nuc_dot + Cbar(nu) nu_c minus the non-uniform term of (3.4.20), [X, Y, Z, K, M, N].

    With r_b = 0 and V_u held constant over a step (3.4.12):
    nuc_dot = [-w x U + Phi u; 0], Mbar nuc_dot + Cbar nu_c = [mbar Phi u; 0], and the
    non-uniform term is -Phi [(A11 + mbar I) u_r + A12 w], Phi = R^T (dV_s/d eta1) R.
    We write Phi u (the chain rule along the path) where the text of (3.4.12) has Phi^T u:
    the two agree for the symmetric gradients of (3.4.13), differ for a sheared current.

    Args:
        shear: d(current_north)/d(east), 1/s.
        R: body-to-earth rotation; current_body: U = R^T V_c; nu, nu_r: velocities.
    """
    w_x_U = cross(nu[3:], current_body)
    nuc_dot = [-w_x_U[0], -w_x_U[1], -w_x_U[2], 0.0, 0.0, 0.0]
    force = np.zeros(6)
    if shear != 0.0:
        gradient = np.zeros((3, 3))
        gradient[0, 1] = shear
        phi_t = R.T @ gradient @ R
        phi_u = phi_t @ np.asarray(nu[:3])
        nuc_dot[:3] = (np.asarray(nuc_dot[:3]) + phi_u).tolist()
        m_bar = params.m_bar
        impulse = added_mass_matrix_times(params, nu_r)
        force[:3] = m_bar * phi_u - phi_t @ (np.asarray(impulse[:3]) + m_bar * np.asarray(nu_r[:3]))
    return force + added_mass_matrix_times(params, nuc_dot)


def relative_form_shear_force(
    params: VehicleParameters,
    shear: float,
    psi: float,
    east_rate: float,
    nu_r: Sequence[float],
    rigid_mass: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The sheared current's force in the relative form of the planar variants, and the
    water's acceleration along the path a = Rz^T (dV/d eta1) eta1_dot (body axes, m/s^2).

    Subtracting (M_RB + M_A) nuc_dot from the full form leaves (5.3.1)
    [mbar a - Phi ((A11 + mbar I) u_r + A12 w); 0] - M_RB [a; 0], Phi = Rz^T (dV/d eta1) Rz:
    the pressure gradient that accelerates the water pushes the hull (mbar a plus the
    added-mass part), while the hull's own inertia lags the accelerating frame (M_RB a).

    Args:
        shear: d(current_north)/d(east), 1/s; psi: yaw, rad; east_rate: d(east)/dt, m/s.
        nu_r: velocity relative to the water; rigid_mass: M_RB (6x6, with the moving mass
            where it is).
    """
    cp, sp = math.cos(psi), math.sin(psi)
    accel = np.array([cp, -sp, 0.0]) * (shear * east_rate)
    impulse = added_mass_matrix_times(params, nu_r)
    m_bar = params.m_bar
    flow = [impulse[i] + m_bar * nu_r[i] for i in range(3)]
    phi_flow = np.array([cp, -sp, 0.0]) * (shear * (sp * flow[0] + cp * flow[1]))
    force = -rigid_mass[:, :3] @ accel
    force[:3] += m_bar * accel - phi_flow
    return force, accel
