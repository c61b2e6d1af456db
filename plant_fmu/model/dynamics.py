"""Equations of motion of the REMUS 100 with internal actuators: the one source of truth.

Everything that moves the vehicle is here or in the modules it draws on: rigid body
(2.3.11, 2.3.13), added mass and its Coriolis terms (A.62), the current's terms
(:mod:`plant_fmu.model.currents`: (3.4.12), (3.4.20), (5.2.10), (5.3.1)), viscous cross-flow and
lift (4.2.6-4.2.9), hydrostatics (3.5.3), propeller, tunnel thruster (6.3.79), stern planes
(Table 6.1) and the internal moving mass with its servo (:mod:`plant_fmu.model.moving_mass`:
(6.3.11)-(6.3.13), or the full two-body equations 6.2.28). The equation numbers refer to
B. Li, *Dynamics and Control of Autonomous Underwater Vehicles with Internal Actuators*,
FAU 2016; ``docs/model.md`` restates them. Kinematics live in
:mod:`plant_fmu.model.kinematics`, the mass matrices in :mod:`plant_fmu.model.inertia`.

The full 6-DOF variant integrates the full form (3.6.2 with viscous terms, 4.3.1), on the
velocity over ground nu and the relative velocity nu_r = nu - nu_c::

    (M_RB + M_A) nu_dot = tau - C_RB(nu) nu - C_A*(nu_r) nu_r - D(nu_r) nu_r + g(eta)
                          + (Mbar + M_A) nuc_dot + Cbar(nu) nu_c

(here g(eta) is the restoring force on the right-hand side). C_RB uses the
linear-velocity-independent parametrisation, which makes this reduce exactly to the
relative form (3.6.10) in a steady, uniform current. The lateral and horizontal variants
integrate the relative form itself (their frozen attitude breaks that reduction: see
:mod:`plant_fmu.model.currents`)::

    (M_RB + M_A) nur_dot = tau - C_RB(nu_r) nu_r - C_A(nu_r) nu_r - D(nu_r) nu_r + g(eta)
    nu_dot = nur_dot + [dU/dt; 0],   eta1_dot = R nu_r + V_c

with U the horizontal current turned by the yaw only (5.2.10). The state always holds the
velocity over ground, nu = nu_r + [U; 0].

The state and input vectors are laid out in :mod:`plant_fmu.model.state_layout`.

Attitude: :meth:`PlantModel.derivative` writes the state with Euler angles and their
rates T(eta2) omega (2.2.15), the form the dissertation linearises and every analysis tool
(equilibria, continuation, the controllers' linearisations) differentiates: near their
operating points T is regular and the gains they get are the dissertation's. T is singular
at pitch +-90 deg, so beyond 70 deg of pitch the stepping (:mod:`plant_fmu.model.stepping`)
integrates the full variant's attitude as a unit quaternion instead
(:meth:`PlantModel.step_derivative`, the same forces from the same rotation matrix) and
refreshes the Euler angles from it after every sub-step (below 70 deg it integrates the
Euler angles, as the lateral and horizontal variants always do:
:meth:`PlantModel.uses_quaternion` says why).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from enum import IntEnum
from functools import cached_property

import numpy as np

from plant_fmu.model.currents import (
    full_form_current_force,
    planar_current,
    relative_form_shear_force,
)
from plant_fmu.model.inertia import (
    added_mass_matrix,
    added_mass_matrix_times,
    rigid_body_mass_matrix,
)
from plant_fmu.model.kinematics import (
    cross,
    euler_rate_matrix,
    gravity_direction,
    quaternion_rate,
    quaternion_rotation_matrix,
    rotate,
    rotation_matrix,
)
from plant_fmu.model.moving_mass import (
    MovingMassModel,
    mass_matrix_shift,
    rail_direction,
    servo_motion,
    two_body_force,
    weight_moment,
)
from plant_fmu.model.parameters import VehicleParameters
from plant_fmu.model.state_layout import (
    ANGULAR_VELOCITY,
    CURRENT,
    EULER,
    MASS_COMMAND,
    N_STEP_STATES,
    NU,
    PITCH,
    POSITION,
    QUATERNION,
    QUATERNION_CHART_PITCH,
    STATE,
)
from plant_fmu.model.state_layout import INPUT_INDEX as INPUT_INDEX
from plant_fmu.model.state_layout import INPUT_NAMES as INPUT_NAMES
from plant_fmu.model.state_layout import INPUT_UNITS as INPUT_UNITS
from plant_fmu.model.state_layout import MASS_POSITION as _YV
from plant_fmu.model.state_layout import MASS_VELOCITY as _YVEL
from plant_fmu.model.state_layout import N_INPUTS as N_INPUTS
from plant_fmu.model.state_layout import N_STATES as N_STATES
from plant_fmu.model.state_layout import STATE_INDEX as STATE_INDEX
from plant_fmu.model.state_layout import STATE_NAMES as STATE_NAMES
from plant_fmu.model.state_layout import STATE_UNITS as STATE_UNITS


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
        moving_mass_model: the dissertation's equations (0, default) or the full two-body
            dynamics of hull and moving mass (1); see :class:`MovingMassModel`.
        servo_reaction: the servo's reaction -m_v y'' on the hull (sway, roll, yaw) and a
            stop's impact act (True, default: (6.3.11)-(6.3.13)); False leaves both out, as the
            dissertation's 6-DOF simulation ((6.3.79): only the offset weight m_v g y_v
            cos(phi) in roll) does. Analysis only: the plant FMU always keeps them.
    """

    params: VehicleParameters
    variant: Variant = Variant.FULL
    ideal_fluid: bool = False
    current_shear: float = 0.0
    moving_mass_model: MovingMassModel = MovingMassModel.DISSERTATION
    servo_reaction: bool = True
    mass_matrix: np.ndarray = field(init=False, repr=False)
    _inverse_mass: np.ndarray = field(init=False, repr=False)
    _rigid_mass: np.ndarray = field(init=False, repr=False)
    _free: np.ndarray = field(init=False, repr=False)
    _frozen_pose: list[int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "variant", Variant(self.variant))
        if self.moving_mass_model not in tuple(MovingMassModel):
            raise ValueError(
                f"moving_mass_model = {self.moving_mass_model!r}: expected 0 (the "
                "dissertation's equations) or 1 (two-body dynamics of hull and mass)"
            )
        object.__setattr__(self, "moving_mass_model", MovingMassModel(self.moving_mass_model))
        if not math.isfinite(self.current_shear):
            raise ValueError(f"current_shear = {self.current_shear!r}: expected a finite 1/s")
        rigid = rigid_body_mass_matrix(self.params)
        M = rigid + added_mass_matrix(self.params)
        free = np.array(self.variant.velocities)
        inverse = np.zeros((6, 6))
        inverse[np.ix_(free, free)] = np.linalg.inv(M[np.ix_(free, free)])
        object.__setattr__(self, "mass_matrix", M)
        object.__setattr__(self, "_inverse_mass", inverse)
        object.__setattr__(self, "_rigid_mass", rigid)
        object.__setattr__(self, "_free", free)
        frozen = [i for i in range(6) if i not in self.variant.pose]
        object.__setattr__(self, "_frozen_pose", frozen)

    @property
    def two_body(self) -> bool:
        """True when the moving mass is modelled as a second body (model 1)."""
        return self.moving_mass_model is MovingMassModel.TWO_BODY

    def mass_matrix_at(self, mass_position: float) -> np.ndarray:
        """M_RB + M_A with the moving mass at y_v = ``mass_position`` (m); model 0 keeps it
        at the centre of its rail."""
        if not self.two_body:
            return self.mass_matrix
        shifted: np.ndarray = self.mass_matrix + mass_matrix_shift(self.params, mass_position)
        return shifted

    # The current at the vehicle.

    def current_velocity(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """Earth-frame water velocity at the vehicle, m/s (uniform part plus shear)."""
        v_c = np.array(inputs[CURRENT], dtype=float)
        v_c[0] += self.current_shear * x[1]
        return v_c

    def uses_quaternion(self, z: np.ndarray) -> bool:
        """Whether the stepping integrates the quaternion of the stepping state ``z`` (the
        full variant beyond ``QUATERNION_CHART_PITCH``) rather than its Euler angles. The
        planar variants always keep Euler angles: their pitch is frozen at 0, and their
        frozen attitude does not turn as the body rates say (psi' = r cos phi with theta
        held), which a quaternion could not follow."""
        return self.variant is Variant.FULL and abs(float(z[PITCH])) > QUATERNION_CHART_PITCH

    def rotation(self, x: np.ndarray) -> np.ndarray:
        """Body-to-earth rotation R of a state (Euler angles, (2.2.8)) or of a stepping state,
        from the attitude chart the stepping integrates there: the full variant's
        quaternion beyond ``QUATERNION_CHART_PITCH`` (accurate at pitch +-90 deg)."""
        if len(x) == N_STEP_STATES and self.uses_quaternion(x):
            return quaternion_rotation_matrix(x[QUATERNION])
        return rotation_matrix(x[3], x[4], x[5])

    def current_in_body(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """U, the current in body axes, m/s: R^T V_c in the full variant; in the lateral and
        horizontal variants the horizontal current turned by the yaw only (5.2.10).
        ``x`` is a state or a stepping state (:meth:`rotation`)."""
        v_c = self.current_velocity(x, inputs)
        if self.variant is Variant.FULL:
            return rotate(self.rotation(x), v_c, transpose=True)
        return np.array([*planar_current(x[5], v_c), 0.0])

    def relative_velocity(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """nu_r = nu - [U; 0] (:meth:`current_in_body`), m/s and rad/s."""
        nu_r = np.array(x[NU], dtype=float)
        nu_r[:3] -= self.current_in_body(x, inputs)
        return nu_r

    def kinetic_energy(self, x: np.ndarray, inputs: np.ndarray) -> float:
        """Kinetic energy of the motion relative to the water, J: 1/2 nu_r^T (M_RB + M_A)
        nu_r, Eq. (5.1.1), constant in an ideal fluid (Thm 5.1); with the two-body model, of
        hull, fluid and moving mass together, 1/2 nu_r^T M(y_v) nu_r + m_v y' J.nu_r
        + 1/2 m_v y'^2."""
        nu_r = self.relative_velocity(x, inputs)
        if not self.two_body:
            return 0.5 * float(nu_r @ self.mass_matrix @ nu_r)
        y_v, y_vel, m_v = x[_YV], x[_YVEL], self.params.m_v
        hull = 0.5 * float(nu_r @ self.mass_matrix_at(y_v) @ nu_r)
        energy: float = (
            hull + m_v * y_vel * float(rail_direction(self.params) @ nu_r) + 0.5 * m_v * y_vel**2
        )
        return energy

    # The pieces of the right-hand side, each a generalised force on [X, Y, Z, K, M, N].

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
            [params.m * (a + b) for a, b in zip(w_x_v, w_w_rg)]
            + [params.m * a + b for a, b in zip(rg_w_v, w_I_w)]
        )

    def coriolis_added_mass(self, nu_r: Sequence[float]) -> np.ndarray:
        """C_A(nu_r) nu_r (A.62): with [p_A; pi_A] = M_A nu_r = [A11 u + A12 w; A21 u + A22 w],
        C_A nu_r = [-p_A x w; -p_A x u - pi_A x w]."""
        impulse = added_mass_matrix_times(self.params, nu_r)
        lin, ang = impulse[:3], impulse[3:]
        u, w = nu_r[:3], nu_r[3:]
        return np.array(
            [-a for a in cross(lin, w)] + [-a - b for a, b in zip(cross(lin, u), cross(ang, w))]
        )

    def viscous(self, nu_r: Sequence[float] | np.ndarray) -> np.ndarray:
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
        """Hydrostatic force and moment on the right-hand side, r_b = 0:
        [(W - B) Gamma; r_g x W Gamma], Gamma = R^T [0, 0, 1]; minus the g(eta) of (3.5.3),
        which the dissertation writes on the left-hand side of (4.3.1)."""
        return self.hydrostatics(gravity_direction(phi, theta))

    def hydrostatics(self, gamma: Sequence[float] | np.ndarray) -> np.ndarray:
        """:meth:`restoring` for the earth's down axis in body coordinates, Gamma (the
        third row of R), however the attitude is held."""
        params = self.params
        moment = cross((params.x_g, 0.0, params.z_g), gamma)
        return np.array([(params.W - params.B) * c for c in gamma] + [params.W * c for c in moment])

    def actuators(self, inputs: Sequence[float], u_r: float) -> np.ndarray:
        """Propeller thrust T and torque Q, tunnel thruster F_t at (0, 0, z_t) (6.3.79) and
        stern planes Z_ds s, M_ds s with s = (u_r |u_r| / U_fin^2) delta_s (Table 6.1): the
        fins' lift follows the flow across them, so it reverses when moving astern. Idle
        fins (delta_s = 0) give s = 0, also where (u_r / U_fin)^2 overflows (a tiny U_fin),
        which inf * 0 would turn into nan."""
        params = self.params
        thrust, torque, f_t, delta_s = inputs[0], inputs[1], inputs[2], inputs[3]
        relative = u_r / params.fin_reference_speed
        scale = relative * abs(relative) * delta_s if delta_s != 0.0 else 0.0
        return np.array(
            [thrust, f_t, params.Z_ds * scale, torque - f_t * params.z_t, params.M_ds * scale, 0.0]
        )

    def moving_mass(
        self,
        x: Sequence[float],
        inputs: Sequence[float],
        gamma: Sequence[float] | np.ndarray | None = None,
    ) -> tuple[float, float, np.ndarray]:
        """Servo motion of the moving mass and its reaction on the hull (6.3.11-6.3.13).

        The servo (:func:`~plant_fmu.model.moving_mass.servo_motion`) sets y'' along the
        rail; the reaction F_mm = -m_v y'' acts in sway at (x_v, ., z_g): sway +F_mm, roll
        -z_g F_mm, yaw +x_v F_mm (F_mm = 0 without ``servo_reaction``); the offset weight
        adds r x m_v g Gamma with r = [0, y_v, 0]. The two-body model adds
        :func:`two_body_force` in the form being integrated. ``gamma``: the earth's down
        axis in body coordinates (default: from the Euler angles of x).

        Returns:
            (y' in m/s, y'' in m/s^2, generalised force on the hull [X, Y, Z, K, M, N]).
        """
        params = self.params
        y_vel, accel = servo_motion(params, x[_YV], x[_YVEL], inputs[MASS_COMMAND])
        f_mm = -params.m_v * accel if self.servo_reaction else 0.0
        down = gravity_direction(x[3], x[4]) if gamma is None else gamma
        roll_weight, yaw_weight = weight_moment(params, x[_YV], down)
        roll = -params.z_g * f_mm + roll_weight
        yaw = params.x_v * f_mm + yaw_weight
        return y_vel, accel, np.array([0.0, f_mm, 0.0, roll, 0.0, yaw])

    def derivative(self, x: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """State derivative x_dot = f(x, inputs) of the active variant (frozen states: 0),
        attitude as Euler angles: eta2_dot = T(eta2) omega (2.2.15), singular at pitch
        +-90 deg. The form the analysis tools differentiate; stepping uses
        :meth:`step_derivative`."""
        phi, theta = float(x[3]), float(x[4])
        dx = np.empty(N_STATES)
        dx[EULER] = euler_rate_matrix(phi, theta) @ x[ANGULAR_VELOCITY]
        self._rates(x, inputs, rotation_matrix(phi, theta, float(x[5])), dx)
        if self._frozen_pose:
            dx[self._frozen_pose] = 0.0
        return dx

    def step_derivative(self, z: np.ndarray, inputs: np.ndarray, quaternion: bool) -> np.ndarray:
        """Derivative of a stepping state (``STEP_STATE_NAMES``) in one attitude chart
        (the other chart's entries do not move; the stepping refreshes them). ``quaternion``
        (full variant only): q_dot = 1/2 q (x) [0, omega], the forces from R(q); else
        :meth:`derivative` on the Euler angles."""
        dz = np.zeros(N_STEP_STATES)
        if not quaternion:
            dz[STATE] = self.derivative(z[STATE], inputs)
            return dz
        q = z[QUATERNION]
        self._rates(z, inputs, quaternion_rotation_matrix(q), dz)
        dz[QUATERNION] = quaternion_rate(q, z[ANGULAR_VELOCITY])
        return dz

    def _rates(self, x: np.ndarray, inputs: np.ndarray, R: np.ndarray, dx: np.ndarray) -> None:
        """Everything but the attitude's rate into dx: eta1_dot, nu_dot and the mass's
        motion, with the attitude given as the rotation R (forces need only R; the planar
        variants also read the yaw x[5] and its rate dx[5])."""
        xs, us = x[STATE].tolist(), inputs.tolist()
        gamma = R[2].tolist()  # Gamma = R^T [0, 0, 1]
        mass_velocity, mass_accel, f_mm = self.moving_mass(xs, us, gamma)
        base = (f_mm, self.hydrostatics(gamma))
        v_c = self.current_velocity(x, inputs)
        if self.variant is Variant.FULL:
            dx[NU], dx[POSITION] = self._full_form(xs, us, R, v_c, base, mass_velocity)
        else:
            dx[NU], dx[POSITION] = self._relative_form(xs, us, R, v_c, base, mass_velocity, dx[5])
        dx[_YV] = mass_velocity
        dx[_YVEL] = mass_accel

    def _full_form(
        self,
        xs: list[float],
        us: list[float],
        R: np.ndarray,
        v_c: np.ndarray,
        base: tuple[np.ndarray, np.ndarray],
        y_vel: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(nu_dot, eta1_dot) of the full form (3.6.2, 4.3.1) on the velocity over ground;
        ``v_c`` is the current at the vehicle (earth frame), ``base`` holds the forces that
        depend on no velocity (moving mass, restoring). Python floats throughout, so an
        overflow raises (OverflowError) instead of turning into inf."""
        nu = xs[6:12]
        current_body = rotate(R, v_c, transpose=True).tolist()
        nu_r = [nu[0] - current_body[0], nu[1] - current_body[1], nu[2] - current_body[2], *nu[3:]]
        force = (
            self.actuators(us, nu_r[0])
            + base[0]
            + base[1]
            - self.coriolis_rigid_body(nu)
            - self.coriolis_added_mass(nu_r)
            + full_form_current_force(self.params, self.current_shear, R, current_body, nu, nu_r)
        )
        if not self.ideal_fluid:
            force += self.viscous(nu_r)
        if self.two_body:
            force += two_body_force(self.params, nu, xs[_YV], y_vel)
        return self._accelerate(xs[_YV], force), rotate(R, nu[:3])

    def _relative_form(
        self,
        xs: list[float],
        us: list[float],
        R: np.ndarray,
        v_c: np.ndarray,
        base: tuple[np.ndarray, np.ndarray],
        y_vel: float,
        yaw_rate: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(nu_dot, eta1_dot) of the lateral and horizontal variants: the relative form with
        the current turned by the yaw only (5.2.10), nu_dot = nur_dot + [dU/dt; 0] with
        dU/dt = psi' [U_y, -U_x, 0] + a (a: the water's acceleration along the path).
        Arguments as :meth:`_full_form`, and yaw_rate = psi', rad/s."""
        current = planar_current(xs[5], v_c.tolist())
        nu_r = xs[6:12]
        nu_r[0] -= current[0]
        nu_r[1] -= current[1]
        position_rate = rotate(R, nu_r[:3]) + v_c
        force = (
            self.actuators(us, nu_r[0])
            + base[0]
            + base[1]
            - self.coriolis_rigid_body(nu_r)
            - self.coriolis_added_mass(nu_r)
        )
        if not self.ideal_fluid:
            force += self.viscous(nu_r)
        if self.two_body:
            force += two_body_force(self.params, nu_r, xs[_YV], y_vel)
        water_accel: tuple[float, float] | np.ndarray = (0.0, 0.0)
        if self.current_shear != 0.0:
            rigid = self._rigid_mass
            if self.two_body:
                rigid = rigid + mass_matrix_shift(self.params, xs[_YV])
            shear, water_accel = relative_form_shear_force(
                self.params, self.current_shear, xs[5], position_rate[1], nu_r, rigid
            )
            force += shear
        nu_dot = self._accelerate(xs[_YV], force)
        nu_dot[0] += yaw_rate * current[1] + water_accel[0]
        nu_dot[1] += -yaw_rate * current[0] + water_accel[1]
        return nu_dot, position_rate

    def _accelerate(self, mass_position: float, force: np.ndarray) -> np.ndarray:
        """(M_RB + M_A)^-1 force on the free degrees of freedom (0 on the frozen ones)."""
        if not self.two_body:
            accelerated: np.ndarray = self._inverse_mass @ force
            return accelerated
        free = self._free
        M = self.mass_matrix_at(mass_position)
        accel = np.zeros(6)
        accel[free] = np.linalg.solve(M[np.ix_(free, free)], force[free])
        return accel

    def project(self, x: np.ndarray, collide: bool = False) -> np.ndarray:
        """Enforce the constraints on a state or stepping state in place: frozen DOFs at 0,
        the mass within its stops (resting, y_vel = 0, when pushed against one) and under
        the speed limit.

        Args:
            collide: the state ends an integration step, so a mass that reached a stop with
                speed y_vel hits it: the collision is inelastic and conserves the momentum
                of hull, fluid and mass, (M(stop) + M_A) nu + m_v y_vel J along the free
                degrees of freedom, so the momentum the servo took from the hull while
                accelerating the mass comes back (without it, every arrival at a stop would
                be a spurious kick); and a stepping state's quaternion is normalised. RK4
                stage states pass False.
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
                    x[NU] = self._velocity_after_impact(x[NU], x[_YV], x[_YVEL])
                x[_YVEL] = 0.0
        if params.mass_speed_limit > 0.0:
            x[_YVEL] = min(max(x[_YVEL], -params.mass_speed_limit), params.mass_speed_limit)
        if collide and len(x) == N_STEP_STATES:
            w, a, b, c = x[QUATERNION].tolist()
            x[QUATERNION] /= math.sqrt(w * w + a * a + b * b + c * c)
        return x

    def _velocity_after_impact(
        self, nu: np.ndarray, stop: float, mass_velocity: float
    ) -> np.ndarray:
        """Hull velocity after the mass, sliding at ``mass_velocity`` (m/s), is stopped dead
        at y_v = ``stop``: the stop's impulse m_v y_vel J on the hull (the rail speed is the
        same in every frame) changes its momentum, M(stop) d nu = m_v y_vel J, with M(stop)
        = M_RB + M_A + dM(stop) at the stop (M_RB + M_A with model 0). Relative velocity
        and velocity over ground change alike, so the impact is frame-independent; the
        stepping (:mod:`plant_fmu.model.stepping`) ends the two-body model's step at the
        moment the mass arrives, so no overshoot enters. Without ``servo_reaction`` the hull
        feels no impact: ``nu`` unchanged."""
        if not self.servo_reaction:
            return nu
        impulse = self.params.m_v * mass_velocity * rail_direction(self.params)
        if not self.two_body:
            return nu + self._inverse_mass @ impulse
        after: np.ndarray = nu + self._accelerate(stop, impulse)
        return after

    @cached_property
    def without_stops(self) -> PlantModel:
        """This plant with the rail's stops out of reach: the two-body stepping integrates
        with it up to the moment the mass arrives at a stop (before that, stage states that
        touch the stop must not be held there)."""
        params = self.params.with_stroke(1e9)  # m: a rail no mass reaches the end of
        return replace(self, params=params)

    def current_change_velocity_jump(self, x: np.ndarray, delta_current: np.ndarray) -> np.ndarray:
        """Velocity change of the hull when the uniform current jumps by delta_current (earth,
        m/s) between two steps: the impulse of the (Mbar + M_A) nuc_dot term of (3.6.2),
        (M_RB + M_A) d nu = (Mbar + M_A) [dU; 0], dU the jump in body axes
        (:meth:`current_in_body`); ``x`` a state or a stepping state."""
        d_nuc = np.zeros(6)
        if self.variant is Variant.FULL:
            d_nuc[:3] = self.rotation(x).T @ np.asarray(delta_current, float)
        else:
            d_nuc[:2] = planar_current(x[5], delta_current)
        impulse: np.ndarray = np.array(added_mass_matrix_times(self.params, d_nuc))
        impulse[:3] += self.params.m_bar * d_nuc[:3]
        return self._accelerate(x[_YV], impulse)
