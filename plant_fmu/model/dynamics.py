"""Equations of motion of the REMUS 100 with internal actuators: the one source of truth.

Everything that moves the vehicle is here: rigid body (2.3.11, 2.3.13), added mass and its
Coriolis terms (A.62), the non-uniform-current terms (3.4.12, 3.4.20), viscous cross-flow
and lift (4.2.6-4.2.9), hydrostatics (3.5.3), propeller, tunnel thruster (6.3.79), stern
planes (Table 6.1) and the internal moving mass with its servo (6.3.12-6.3.13). The
equation numbers refer to B. Li, *Dynamics and Control of Autonomous Underwater Vehicles
with Internal Actuators*, FAU 2016; ``docs/model.md`` restates them. Kinematics live in
:mod:`plant_fmu.model.kinematics`, the mass matrices in :mod:`plant_fmu.model.inertia`.

The equation integrated is the full form (3.6.2 with viscous terms, 4.3.1), on the velocity
over ground nu and the relative velocity nu_r = nu - nu_c::

    (M_RB + M_A) nu_dot = tau - C_RB(nu) nu - C_A*(nu_r) nu_r - D(nu_r) nu_r + g(eta)
                          + (Mbar + M_A) nuc_dot + Cbar(nu) nu_c

(here g(eta) is the restoring force on the right-hand side). C_RB uses the
linear-velocity-independent parametrisation, which makes this reduce exactly to the
relative form (3.6.10) in a steady, uniform current.

State vector (``STATE_NAMES``, SI, angles in rad)::

    [north, east, down, roll, pitch, yaw, u, v, w, p, q, r, mass_position, mass_velocity]

Input vector (``INPUT_NAMES``), held constant over a step::

    [thrust, roll_torque, tunnel_force, fin_angle, mass_position_cmd,
     current_north, current_east, current_down]
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np

from plant_fmu.model.inertia import (
    added_mass_matrix,
    added_mass_matrix_times,
    rigid_body_mass_matrix,
)
from plant_fmu.model.kinematics import cross, euler_rate_matrix, gravity_direction, rotation_matrix
from plant_fmu.model.parameters import VehicleParameters

STATE_NAMES: tuple[str, ...] = (
    "north", "east", "down", "roll", "pitch", "yaw",
    "u", "v", "w", "p", "q", "r",
    "mass_position", "mass_velocity",
)  # fmt: skip
STATE_UNITS: tuple[str, ...] = (
    "m", "m", "m", "rad", "rad", "rad",
    "m/s", "m/s", "m/s", "rad/s", "rad/s", "rad/s",
    "m", "m/s",
)  # fmt: skip
INPUT_NAMES: tuple[str, ...] = (
    "thrust", "roll_torque", "tunnel_force", "fin_angle", "mass_position_cmd",
    "current_north", "current_east", "current_down",
)  # fmt: skip
INPUT_UNITS: tuple[str, ...] = ("N", "N.m", "N", "rad", "m", "m/s", "m/s", "m/s")

STATE_INDEX = {name: i for i, name in enumerate(STATE_NAMES)}
INPUT_INDEX = {name: i for i, name in enumerate(INPUT_NAMES)}
N_STATES = len(STATE_NAMES)
N_INPUTS = len(INPUT_NAMES)
_POSE = slice(0, 6)
_NU = slice(6, 12)
_YV, _YVEL = 12, 13


class Variant(IntEnum):
    """Which degrees of freedom move (the plant FMU's ``variant`` codes, docs/model.md#variants)."""

    FULL = 0  # 6-DOF with moving mass, thruster and fins (6.3.78)-(6.3.79)
    LATERAL = 1  # u, v, r, p, phi, psi with the moving mass (6.3.13); w = q = theta = 0
    HORIZONTAL = 2  # u, v, r, psi (5.1.30); w = q = p = theta = phi = 0

    @property
    def velocities(self) -> tuple[int, ...]:
        """Indices into nu = [u, v, w, p, q, r] that are free."""
        return {0: (0, 1, 2, 3, 4, 5), 1: (0, 1, 3, 5), 2: (0, 1, 5)}[self.value]

    @property
    def pose(self) -> tuple[int, ...]:
        """Indices into eta = [north, east, down, roll, pitch, yaw] that are free."""
        return {0: (0, 1, 2, 3, 4, 5), 1: (0, 1, 3, 5), 2: (0, 1, 5)}[self.value]

    @property
    def states(self) -> tuple[str, ...]:
        """Names of the states that evolve in this variant."""
        free = [STATE_NAMES[i] for i in self.pose] + [STATE_NAMES[6 + i] for i in self.velocities]
        return (*free, "mass_position", "mass_velocity")


# --- The model -----------------------------------------------------------------------------


@dataclass(frozen=True)
class PlantModel:
    """The vehicle-plus-fluid plant: parameters, the free DOFs and the fluid options.

    Args:
        params: the vehicle parameter set.
        variant: which degrees of freedom move (:class:`Variant`).
        ideal_fluid: drop the viscous terms D(nu_r) nu_r (Sec. 5.1, Thm 5.1).
        current_shear: linear horizontal shear d(current_north)/d(east), 1/s. The current
            at the vehicle is V_c = [current_north + shear * east, current_east, current_down].
    """

    params: VehicleParameters
    variant: Variant = Variant.FULL
    ideal_fluid: bool = False
    current_shear: float = 0.0
    mass_matrix: np.ndarray = field(init=False, repr=False)
    _inverse_mass: np.ndarray = field(init=False, repr=False)
    _frozen_pose: list[int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "variant", Variant(self.variant))
        if not math.isfinite(self.current_shear):
            raise ValueError(f"current_shear = {self.current_shear!r}: expected a finite 1/s")
        M = rigid_body_mass_matrix(self.params) + added_mass_matrix(self.params)
        free = np.array(self.variant.velocities)
        inverse = np.zeros((6, 6))
        inverse[np.ix_(free, free)] = np.linalg.inv(M[np.ix_(free, free)])
        object.__setattr__(self, "mass_matrix", M)
        object.__setattr__(self, "_inverse_mass", inverse)
        frozen = [i for i in range(6) if i not in self.variant.pose]
        object.__setattr__(self, "_frozen_pose", frozen)

    # The pieces of the right-hand side, each a generalised force on [X, Y, Z, K, M, N].

    def current_velocity(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Earth-frame water velocity at the vehicle, m/s (uniform part plus shear)."""
        v_c = inputs[5:8].copy()
        v_c[0] += self.current_shear * x[1]
        return v_c

    def relative_velocity(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """nu_r = nu - [R^T V_c; 0], m/s and rad/s."""
        R = rotation_matrix(x[3], x[4], x[5])
        nu_r = np.array(x[_NU], dtype=float)
        nu_r[:3] -= R.T @ self.current_velocity(x, inputs)
        return nu_r

    def kinetic_energy(self, x: np.ndarray, inputs: np.ndarray) -> float:
        """1/2 nu_r^T (M_RB + M_A) nu_r, J."""
        nu_r = self.relative_velocity(x, inputs)
        return 0.5 * float(nu_r @ self.mass_matrix @ nu_r)

    def coriolis_rigid_body(self, nu: Sequence[float]) -> np.ndarray:
        """C_RB(nu) nu (2.3.13), linear-velocity-independent form:
        [m (w x v + w x (w x r_g)); m r_g x (w x v) + w x I_o w]."""
        params = self.params
        v, w = nu[:3], nu[3:]
        r_g = (params.x_g, 0.0, params.z_g)
        w_x_v = cross(w, v)
        w_w_rg = cross(w, cross(w, r_g))
        rg_w_v = cross(r_g, w_x_v)
        w_I_w = cross(w, (params.I_xx * w[0], params.I_yy * w[1], params.I_zz * w[2]))
        return np.array(
            [params.m * (a + b) for a, b in zip(w_x_v, w_w_rg, strict=True)]
            + [params.m * a + b for a, b in zip(rg_w_v, w_I_w, strict=True)]
        )

    def coriolis_added_mass(self, nu_r: Sequence[float]) -> np.ndarray:
        """C_A(nu_r) nu_r (A.62): with [p_A; pi_A] = M_A nu_r = [A11 u + A12 w; A21 u + A22 w],
        C_A nu_r = [-p_A x w; -p_A x u - pi_A x w]."""
        impulse = added_mass_matrix_times(self.params, nu_r)
        lin, ang = impulse[:3], impulse[3:]
        u, w = nu_r[:3], nu_r[3:]
        return np.array(
            [-a for a in cross(lin, w)]
            + [-a - b for a, b in zip(cross(lin, u), cross(ang, w), strict=True)]
        )

    def viscous(self, nu_r: np.ndarray) -> np.ndarray:
        """Viscous cross-flow and lift forces on the right-hand side (4.2.6)-(4.2.9)."""
        params = self.params
        u, v, w, roll_rate, q, r = nu_r
        return np.array(
            [
                params.X_uu * u * abs(u),
                params.Y_vv * v * abs(v)
                + params.Y_rr * r * abs(r)
                + params.Y_uv * u * v
                + params.Y_ur * u * r,
                params.Z_ww * w * abs(w)
                + params.Z_qq * q * abs(q)
                + params.Z_uw * u * w
                + params.Z_uq * u * q,
                params.K_p * roll_rate + params.K_pp * roll_rate * abs(roll_rate),
                params.M_ww * w * abs(w)
                + params.M_qq * q * abs(q)
                + params.M_uw * u * w
                + params.M_uq * u * q,
                params.N_vv * v * abs(v)
                + params.N_rr * r * abs(r)
                + params.N_uv * u * v
                + params.N_ur * u * r,
            ]
        )

    def restoring(self, phi: float, theta: float) -> np.ndarray:
        """Hydrostatic force and moment on the right-hand side (3.5.3), r_b = 0:
        [(W - B) Gamma; r_g x W Gamma], Gamma = R^T [0, 0, 1]."""
        params = self.params
        gamma = gravity_direction(phi, theta)
        moment = cross((params.x_g, 0.0, params.z_g), gamma)
        return np.array([(params.W - params.B) * c for c in gamma] + [params.W * c for c in moment])

    def actuators(self, inputs: Sequence[float], u_r: float) -> np.ndarray:
        """Propeller thrust T and torque Q, tunnel thruster F_t at (0, 0, z_t) (6.3.79) and
        stern planes Z_ds (u_r/U0)^2 delta_s, M_ds (u_r/U0)^2 delta_s (Table 6.1)."""
        params = self.params
        thrust, torque, f_t, delta_s = inputs[0], inputs[1], inputs[2], inputs[3]
        scale = (u_r / params.fin_reference_speed) ** 2 * delta_s
        return np.array(
            [thrust, f_t, params.Z_ds * scale, torque - f_t * params.z_t, params.M_ds * scale, 0.0]
        )

    def moving_mass(
        self, x: Sequence[float], inputs: Sequence[float]
    ) -> tuple[float, float, np.ndarray]:
        """Servo motion of the moving mass and its reaction on the hull (6.3.12-6.3.13).

        The servo m_v y'' + d_v y' + k_v y = k_v y_d follows the command as given: the stops,
        not the command, bound the motion (Sec. 6.3.1 constrains y_v and y_vel only, and the
        dissertation's LQR runs drive the mass at up to ~50 cm/s, Fig. 6.14, which a command
        saturated at the stroke cannot). Against a stop (or at the rail-speed limit) the mass
        does not accelerate outwards and exerts no servo reaction. The reaction
        F_mm = -m_v y'' acts in sway at (x_v, ., z_g): sway +F_mm, roll -z_g F_mm,
        yaw +x_v F_mm; the offset weight adds r x m_v g Gamma with r = [0, y_v, 0].

        Returns:
            (y' in m/s, y'' in m/s^2, generalised force on the hull [X, Y, Z, K, M, N]).
        """
        params = self.params
        y_v, y_vel = x[_YV], x[_YVEL]
        accel = (params.k_v * (inputs[4] - y_v) - params.d_v * y_vel) / params.m_v
        if _against_stop(y_v, y_vel, accel, params.mass_stroke):
            y_vel, accel = 0.0, 0.0
        elif (
            params.mass_speed_limit > 0.0
            and abs(y_vel) >= params.mass_speed_limit
            and accel * y_vel > 0
        ):
            accel = 0.0
        f_mm = -params.m_v * accel
        weight = params.m_v * params.g * y_v
        phi, theta = x[3], x[4]
        roll = -params.z_g * f_mm + weight * math.cos(theta) * math.cos(phi)
        yaw = params.x_v * f_mm + weight * math.sin(theta)
        return y_vel, accel, np.array([0.0, f_mm, 0.0, roll, 0.0, yaw])

    def current_forcing(
        self,
        R: np.ndarray,
        current_body: Sequence[float],
        nu: Sequence[float],
        nu_r: Sequence[float],
    ) -> np.ndarray:
        """Forces the moving water exerts beyond C_A*(nu_r) nu_r: (Mbar + M_A) nuc_dot +
        Cbar(nu) nu_c minus the non-uniform term of (3.4.20).

        With r_b = 0 and V_u held constant over a step (3.4.12):
        nuc_dot = [-w x U + Phi u; 0], Mbar nuc_dot + Cbar nu_c = [mbar Phi u; 0], and the
        non-uniform term is -Phi [(A11 + mbar I) u_r + A12 w], Phi = R^T (dV_s/d eta1) R.
        We write Phi u (the chain rule along the path) where the text of (3.4.12) has Phi^T u:
        the two agree for the symmetric gradients of (3.4.13), differ for a sheared current.

        Args:
            R: body-to-earth rotation; current_body: U = R^T V_c; nu, nu_r: velocities.
        """
        w_x_U = cross(nu[3:], current_body)
        nuc_dot = [-w_x_U[0], -w_x_U[1], -w_x_U[2], 0.0, 0.0, 0.0]
        force = np.zeros(6)
        if self.current_shear != 0.0:
            gradient = np.zeros((3, 3))
            gradient[0, 1] = self.current_shear
            phi_t = R.T @ gradient @ R
            phi_u = phi_t @ np.asarray(nu[:3])
            nuc_dot[:3] = (np.asarray(nuc_dot[:3]) + phi_u).tolist()
            m_bar = self.params.m_bar
            impulse = added_mass_matrix_times(self.params, nu_r)
            force[:3] = m_bar * phi_u - phi_t @ (
                np.asarray(impulse[:3]) + m_bar * np.asarray(nu_r[:3])
            )
        return force + added_mass_matrix_times(self.params, nuc_dot)

    def derivative(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """State derivative x_dot = f(x, inputs) of the active variant (frozen states: 0)."""
        xs, us = x.tolist(), inputs.tolist()
        phi, theta, psi = xs[3], xs[4], xs[5]
        nu = xs[6:12]
        R = rotation_matrix(phi, theta, psi)
        current_body = (R.T @ self.current_velocity(x, inputs)).tolist()
        nu_r = [nu[0] - current_body[0], nu[1] - current_body[1], nu[2] - current_body[2], *nu[3:]]
        mass_velocity, mass_accel, f_mm = self.moving_mass(xs, us)
        force = (
            self.actuators(us, nu_r[0])
            + f_mm
            + self.restoring(phi, theta)
            - self.coriolis_rigid_body(nu)
            - self.coriolis_added_mass(nu_r)
            + self.current_forcing(R, current_body, nu, nu_r)
        )
        if not self.ideal_fluid:
            force += self.viscous(nu_r)
        dx = np.empty(N_STATES)
        dx[0:3] = R @ x[6:9]
        dx[3:6] = euler_rate_matrix(phi, theta) @ x[9:12]
        dx[_NU] = self._inverse_mass @ force
        dx[_YV] = mass_velocity
        dx[_YVEL] = mass_accel
        if self._frozen_pose:
            dx[self._frozen_pose] = 0.0
        return dx

    def project(self, x: np.ndarray, collide: bool = False) -> np.ndarray:
        """Enforce the constraints on a state in place: frozen DOFs at 0, the mass within its
        stops (resting, y_vel = 0, when pushed against one) and under the speed limit.

        Args:
            collide: the state ends an integration step, so a mass that reached a stop with
                speed y_vel hits it: the collision is inelastic and its impulse m_v y_vel,
                along the rail at (x_v, ., z_g), goes to the hull, so the momentum the servo
                took from the hull while accelerating the mass comes back (without it, every
                arrival at a stop would be a spurious kick). RK4 stage states pass False.
        """
        params = self.params
        if self.variant is not Variant.FULL:
            frozen_nu = [6 + i for i in range(6) if i not in self.variant.velocities]
            x[frozen_nu] = 0.0
            x[[i for i in (2, 3, 4) if i not in self.variant.pose]] = 0.0
        if abs(x[_YV]) >= params.mass_stroke:
            x[_YV] = math.copysign(params.mass_stroke, x[_YV])
            if x[_YVEL] * x[_YV] > 0.0:  # moving into the stop
                if collide:
                    x[_NU] += self.mass_collision_velocity_change(x[_YVEL])
                x[_YVEL] = 0.0
        if params.mass_speed_limit > 0.0:
            x[_YVEL] = min(max(x[_YVEL], -params.mass_speed_limit), params.mass_speed_limit)
        return x

    def mass_collision_velocity_change(self, mass_velocity: float) -> np.ndarray:
        """Hull velocity change when the moving mass, sliding at ``mass_velocity`` (m/s),
        stops dead against a rail stop: (M_RB + M_A) d nu = m_v y_vel [0, 1, 0, -z_g, 0, x_v]."""
        params = self.params
        impulse = (
            params.m_v * mass_velocity * np.array([0.0, 1.0, 0.0, -params.z_g, 0.0, params.x_v])
        )
        return self._inverse_mass @ impulse

    def current_change_velocity_jump(self, x: np.ndarray, delta_current: np.ndarray) -> np.ndarray:
        """Velocity change of the hull when the uniform current jumps by delta_current (earth,
        m/s) between two steps: the impulse of the (Mbar + M_A) nuc_dot term,
        (M_RB + M_A) d nu = (Mbar + M_A) [R^T dV; 0]."""
        R = rotation_matrix(x[3], x[4], x[5])
        d_nuc = np.zeros(6)
        d_nuc[:3] = R.T @ np.asarray(delta_current, dtype=float)
        impulse = np.array(added_mass_matrix_times(self.params, d_nuc))
        impulse[:3] += self.params.m_bar * d_nuc[:3]
        return self._inverse_mass @ impulse


def _against_stop(y_v: float, y_vel: float, accel: float, stroke: float) -> bool:
    """True when the mass is at a stop and neither moves nor is pushed away from it."""
    if y_v >= stroke:
        return y_vel >= 0.0 and accel >= 0.0
    if y_v <= -stroke:
        return y_vel <= 0.0 and accel <= 0.0
    return False
