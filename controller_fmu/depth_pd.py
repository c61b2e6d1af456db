"""Depth autopilot: outer proportional depth loop, inner PD pitch loop (Fig. 6.40, Table 6.2).

    theta_d = gamma (z_d - z),                      |theta_d| <= theta_max if set
    delta_s = -K_p [(theta_d - theta) - tau_d q],   |delta_s| <= delta_max

Table 6.2 (designed by Prestero for U0 = 1.525 m/s): gamma = -0.7720 rad/m, K_p = 10.345,
tau_d = 0.21 s. Signs: z is down, theta nose-up; a positive stern-plane angle gives a
nose-down moment (M_ds < 0, Table 6.1), so a vehicle shallower than its set-point
(z_d - z > 0) asks for nose down (theta_d < 0) and the fins deflect positive.

Fin limit (not given in the dissertation, our choice): delta_max = 25 deg = 0.4363 rad.
Table 6.2's outer gain asks for 44 deg of pitch per metre of depth error, so after a depth
step the inner loop sits on the fin limit for seconds, and the limit decides whether the
saturated loop settles. Fig. 6.43 plots delta_s on a +-20 deg axis that its transient
fills. On our plant (vert-2 in-process, 10 ms) limits of 15 and 20 deg leave a limit cycle
(depth swinging 0.4-1.7 m and more), while 25 deg and above settle near the steady state
Sec. 6.3.4 reports for vert-1 (w = -0.07 m/s, theta = -0.045 rad, mean delta_s = -5 deg),
which our vert-1 gives at the printed digits (docs/reproduction.md, Chapter 6; vert-2, its
mass locked, settles a little further off). 25 deg is the smallest round limit that lets
Table 6.2's design work as published; the linear fin model (Table 6.1) is optimistic that
far beyond the 15 deg where the hull's lift curve stalls (Fig. 4.20), so a user lowering
the limit should lower |gamma| too.

Pitch limit (ours, off by default): the outer loop is linear, so a depth error of
2.03 m already asks for a pitch of 90 deg and a 50 m step for -38.6 rad (-2212 deg), no
attitude at all. The inner loop then holds the fins on their stop until the vehicle
pitches over the vertical: from 1.5 m/s at 1 m, told to go to 51 m, it passed -89 deg
and looped (roll and yaw swung by 170 and 200 deg) within 30 s. ``pitch_limit``
theta_max (rad, at most pi/2: no Euler pitch is larger) holds theta_d within +-theta_max,
so a large step becomes a dive at theta_max: with 0.5 rad the same step dives at about
29 deg, upright, and arrives. The default, 0, keeps the linear law the dissertation
runs; its depth-steps scenario asks for up to 91.5 deg right after its 2 m step.

Gains that cannot hold a depth are refused when the autopilot is designed
(:func:`check_depth_loop`): the loop closed on the plant's own depth plane, linearised at
the straight run at the design speed (as :mod:`controller_fmu.lateral_model` does for the
heading) and sampled every design_step as the autopilot runs it, must have every pole
inside the unit circle. A sign slip (gamma > 0 or K_p < 0 is positive feedback: vert-2 with
gamma = +0.772 rad/m ran to 38 m above the surface), gamma = 0 or K_p = 0 (no depth
control: a pole at z = 1) and tau_d = 0 (Table 6.2's gains without the pitch damping:
poles 0.52 +- 5.9i 1/s at 1.525 m/s) are; so are gains the 10 ms sampling cannot realise
(K_p = 1e4 or tau_d = 100 s: the fins bang between their limits, and with tau_d = 100 s
vert-2 ended 5.8 m deep for a 1 m set-point). Table 6.2's gains are stable at every step
up to 0.2 s, and from about 0.5 m/s up; at 0.1 m/s the fins are too weak for them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from controller_fmu.matrix_exponential import zero_order_hold
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

TABLE_6_2_GAMMA = -0.7720  # rad/m
TABLE_6_2_K_P = 10.345  # 1
TABLE_6_2_TAU_D = 0.21  # s
DEFAULT_FIN_LIMIT = 0.4363323129985824  # rad, 25 deg (module docstring)
# rad: the largest pitch limit, 90 deg, the largest Euler pitch (module docstring)
MAX_PITCH_LIMIT = math.pi / 2


def check_pitch_limit(limit: float, name: str = "pitch_limit") -> None:
    """Refuse a pitch limit (rad) other than 0 (off) or an angle in (0, pi/2].

    Raises:
        ValueError: naming ``name`` (as the caller calls it), ``limit`` and the range.
    """
    if not 0.0 <= limit <= MAX_PITCH_LIMIT:
        raise ValueError(
            f"{name} = {limit!r} rad: expected 0 (no limit) or an angle in (0, "
            f"{MAX_PITCH_LIMIT:.4g}] rad (90 deg: a pitch beyond the vertical is no Euler "
            "pitch)"
        )


@dataclass(frozen=True)
class DepthPd:
    """The depth-plane controller of Fig. 6.40 (stateless).

    Attributes:
        gamma: outer-loop gain, rad of pitch per m of depth error.
        k_p: inner-loop proportional gain, rad of fin per rad of pitch error.
        tau_d: inner-loop derivative time, s.
        fin_limit: |delta_s| limit, rad (> 0).
        pitch_limit: |theta_d| limit, rad, in (0, pi/2]; 0 (the default): no limit.
    """

    gamma: float = TABLE_6_2_GAMMA
    k_p: float = TABLE_6_2_K_P
    tau_d: float = TABLE_6_2_TAU_D
    fin_limit: float = DEFAULT_FIN_LIMIT
    pitch_limit: float = 0.0

    def __post_init__(self) -> None:
        if not self.fin_limit > 0.0:
            raise ValueError(f"fin_limit = {self.fin_limit!r}: expected an angle > 0 rad")
        check_pitch_limit(self.pitch_limit)

    def pitch_setpoint(self, depth_setpoint: float, depth: float) -> float:
        """theta_d = gamma (z_d - z), rad, within +-pitch_limit when one is set: the outer
        depth loop of Fig. 6.40."""
        theta_d = self.gamma * (depth_setpoint - depth)
        if self.pitch_limit == 0.0:
            return theta_d
        return min(max(theta_d, -self.pitch_limit), self.pitch_limit)

    def fin_angle(self, depth_setpoint: float, depth: float, pitch: float, q: float) -> float:
        """delta_s, rad, saturated at +-fin_limit: the inner PD pitch loop of Fig. 6.40.

        Args:
            depth_setpoint, depth: z_d and z, m (down positive).
            pitch: theta, rad; q: pitch rate, rad/s.
        """
        theta_d = self.pitch_setpoint(depth_setpoint, depth)
        delta = -self.k_p * ((theta_d - pitch) - self.tau_d * q)
        return min(max(delta, -self.fin_limit), self.fin_limit)


DEPTH_PLANE_STATES: tuple[str, ...] = ("w", "q", "down", "pitch")
"""The states of the depth plane (6.3.77) the loop is closed on."""


def closed_plane(
    law: DepthPd, params: VehicleParameters, speed: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B) of the plant's depth plane (w, q, z, theta of the full variant), linearised
    at the straight run at u = ``speed`` m/s, and ``law``'s gain over those states with the
    fins inside their limit: delta_s = K_p (tau_d q + gamma z + theta) at z_d = 0."""
    model = PlantModel(params, Variant.FULL)
    A, B = linearize(
        model, state_vector({"u": speed}), input_vector(), DEPTH_PLANE_STATES, ["fin_angle"]
    )
    gain = law.k_p * np.array([0.0, law.tau_d, law.gamma, 1.0])
    return A, B, gain


def loop_poles(law: DepthPd, params: VehicleParameters, speed: float) -> np.ndarray:
    """The poles (1/s) of ``law`` closed on the plant's depth plane at ``speed`` m/s
    (:func:`closed_plane`)."""
    A, B, gain = closed_plane(law, params, speed)
    poles: np.ndarray = np.linalg.eigvals(A + B @ gain[None, :])
    return poles


def sampled_loop_poles(
    law: DepthPd, params: VehicleParameters, speed: float, sample_time: float
) -> np.ndarray:
    """The poles z (dimensionless, |z| < 1 when stable) of :func:`loop_poles`'s loop as the
    autopilot runs it: the fin command computed every ``sample_time`` s and held between
    (zero-order hold of the plane)."""
    A, B, gain = closed_plane(law, params, speed)
    Ad, Bd = zero_order_hold(A, B, sample_time)
    poles: np.ndarray = np.linalg.eigvals(Ad + Bd @ gain[None, :])
    return poles


def check_depth_loop(
    law: DepthPd, params: VehicleParameters, speed: float, sample_time: float
) -> None:
    """Refuse gains whose depth loop, sampled every ``sample_time`` s, is not
    asymptotically stable at ``speed`` (m/s) on vehicle ``params`` (module docstring).

    Raises:
        ValueError: a pole with |z| >= 1, naming the gains and that pole.
    """
    poles = sampled_loop_poles(law, params, speed, sample_time)
    worst = complex(poles[np.argmax(np.abs(poles))])
    if abs(worst) < 1.0 - 1e-9:
        return
    raise ValueError(
        f"depth_gamma = {law.gamma!r} rad/m, depth_k_p = {law.k_p!r}, depth_tau_d = "
        f"{law.tau_d!r} s: the depth loop closed on the depth plane of vehicle "
        f"{params.name!r} at design_speed {speed!r} m/s, sampled every {sample_time!r} s "
        f"(design_step), has the pole z = {worst:.4g} (|z| = {abs(worst):.4g} >= 1), so it "
        f"holds no depth; expected gains with every |z| < 1 (Table 6.2's gamma = "
        f"{TABLE_6_2_GAMMA} rad/m < 0, K_p = {TABLE_6_2_K_P} > 0, tau_d = {TABLE_6_2_TAU_D} s)"
    )
