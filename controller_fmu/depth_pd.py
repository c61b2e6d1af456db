"""Depth autopilot: outer proportional depth loop, inner PD pitch loop (Fig. 6.40, Table 6.2).

    theta_d = gamma (z_d - z)
    delta_s = -K_p [(theta_d - theta) - tau_d q],   |delta_s| <= delta_max

Table 6.2 (designed by Prestero for U0 = 1.525 m/s): gamma = -0.7720 rad/m, K_p = 10.345,
tau_d = 0.21 s. Signs: z is down, theta nose-up; a positive stern-plane angle gives a
nose-down moment (M_ds < 0, Table 6.1), so a depth below the set-point (z_d - z > 0) asks
for nose down (theta_d < 0) and the fins deflect positive.

Fin limit (not given in the dissertation, our choice): delta_max = 25 deg = 0.4363 rad.
Table 6.2's outer gain asks for 44 deg of pitch per metre of depth error, so after a depth
step the inner loop sits on the fin limit for seconds, and the limit decides whether the
saturated loop settles. Fig. 6.43 plots delta_s on a +-20 deg axis that its transient
fills. On our plant (vert-2 in-process, 10 ms) limits of 15 and 20 deg leave a limit cycle
(depth swinging 0.4-1.7 m and more), while 25 deg and above settle to the steady state the
dissertation reports: w = -0.075 m/s, theta = -0.050 rad, mean delta_s = -5.2 deg
(Sec. 6.3.4: -0.07 m/s, -0.045 rad, -5 deg). 25 deg is the smallest round limit that lets
Table 6.2's design work as published; the linear fin model (Table 6.1) is optimistic that
far beyond the 15 deg where the hull's lift curve stalls (Fig. 4.20), so a user lowering
the limit should lower |gamma| too.
"""

from __future__ import annotations

from dataclasses import dataclass

TABLE_6_2_GAMMA = -0.7720  # rad/m
TABLE_6_2_K_P = 10.345  # 1
TABLE_6_2_TAU_D = 0.21  # s
DEFAULT_FIN_LIMIT = 0.4363323129985824  # rad, 25 deg (module docstring)


@dataclass(frozen=True)
class DepthPd:
    """The depth-plane controller of Fig. 6.40 (stateless).

    Attributes:
        gamma: outer-loop gain, rad of pitch per m of depth error.
        k_p: inner-loop proportional gain, rad of fin per rad of pitch error.
        tau_d: inner-loop derivative time, s.
        fin_limit: |delta_s| limit, rad (> 0).
    """

    gamma: float = TABLE_6_2_GAMMA
    k_p: float = TABLE_6_2_K_P
    tau_d: float = TABLE_6_2_TAU_D
    fin_limit: float = DEFAULT_FIN_LIMIT

    def __post_init__(self) -> None:
        if not self.fin_limit > 0.0:
            raise ValueError(f"fin_limit = {self.fin_limit!r}: expected an angle > 0 rad")

    def pitch_setpoint(self, depth_setpoint: float, depth: float) -> float:
        """theta_d = gamma (z_d - z), rad."""
        return self.gamma * (depth_setpoint - depth)

    def fin_angle(self, depth_setpoint: float, depth: float, pitch: float, q: float) -> float:
        """delta_s, rad, saturated at +-fin_limit.

        Args:
            depth_setpoint, depth: z_d and z, m (down positive).
            pitch: theta, rad; q: pitch rate, rad/s.
        """
        theta_d = self.pitch_setpoint(depth_setpoint, depth)
        delta = -self.k_p * ((theta_d - pitch) - self.tau_d * q)
        return min(max(delta, -self.fin_limit), self.fin_limit)
