"""The autopilot's parameters, validated (:class:`AutopilotConfig`): every field is an FMU
parameter of the same name, unit and description.

A module of its own, apart from :mod:`controller_fmu.autopilot` (which imports the
controllers and their compiled code, numba with them): a scenario's autopilot start values
are checked with it as the scenario loads, which must not cost a run or a study's client
the ~0.3 s of those imports.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import Any

from controller_fmu.depth_pd import (
    DEFAULT_FIN_LIMIT,
    TABLE_6_2_GAMMA,
    TABLE_6_2_K_P,
    TABLE_6_2_TAU_D,
    check_pitch_limit,
)
from controller_fmu.lqr_weights import DISSERTATION_Q_Y, DISSERTATION_R_U
from controller_fmu.modes import DepthMode, HeadingMode, choices
from plant_fmu.model.validated import ANGULAR_FREQUENCY, CheckedRecord, checked_field

# smc_eta's quantity: the rate (rad/s) at which the sliding variable s reaches its layer
# (6.3.38), a gain, no turn rate of the vehicle (FMI 2.0's quantity is free text)
REACHING_RATE = "ReachingRate"


class AutopilotConfigError(ValueError):
    """An autopilot parameter is out of range (the message names it and what is allowed)."""


def _pitch_limit(value: float) -> None:
    """``depth_pitch_limit``'s check (:func:`controller_fmu.depth_pd.check_pitch_limit`)."""
    check_pitch_limit(value, "depth_pitch_limit")


def _known_mode(mode: type[IntEnum]) -> Callable[[int], None]:
    """A check that a value is one of ``mode``'s (a ValueError listing them if not)."""

    def check(value: int) -> None:
        try:
            mode(value)
        except ValueError:
            raise ValueError(f"expected one of {choices(mode)}") from None

    return check


@dataclass(frozen=True)
class AutopilotConfig(CheckedRecord):
    """Every parameter of the autopilot (SI). Field names are the FMU parameter names.

    Validated and immutable (:class:`plant_fmu.model.validated.CheckedRecord`)."""

    error_type = AutopilotConfigError
    unknown_key = "unknown autopilot parameter {name!r}"

    heading_mode: int = checked_field(
        default=0,
        description="heading controller: 0 off, 1 lqr (6.3.17), 2 sliding_mode (6.3.45), "
        "3 backstepping + tunnel thruster (6.3.64, 6.3.72)",
        check=_known_mode(HeadingMode),
    )
    depth_mode: int = checked_field(
        default=0,
        description="depth controller: 0 off, 1 pd: PD pitch + P depth (Fig. 6.40)",
        check=_known_mode(DepthMode),
    )
    mass_lock_time: float = checked_field(
        default=-1.0,
        description="time after which the moving-mass command is 0 and held; < 0: never",
        unit="s",
    )
    compensate_current: bool = checked_field(
        default=False,
        description="head into the current so the course over ground is yaw_setpoint (6.3.74)",
    )
    design_speed: float = checked_field(
        default=1.525,
        gt=0.0,
        description="U0: surge speed through the water the controllers are designed for",
        unit="m/s",
    )
    vehicle: str = checked_field(
        default="remus100",
        min_length=1,
        description="vehicle parameter set the controllers' model terms come from "
        "(built-in name, .toml path, a relative one from the host's working directory, "
        "or the set's TOML text)",
    )
    design_step: float = checked_field(
        default=0.01,
        gt=0.0,
        description="sample time the discrete LQR and sliding mode are designed for; "
        "should equal the communication step (or sample_period)",
        unit="s",
    )
    sample_period: float = checked_field(
        default=0.0,
        ge=0.0,
        description="a digital autopilot: samples at multiples of this period and holds its "
        "commands in between; 0: at every communication point (the continuous laws)",
        unit="s",
    )
    thrust_command: float = checked_field(
        default=9.0,
        description="propeller thrust sent on the thrust output (9 N: 1.525 m/s; 4 N: 1.017 m/s)",
        unit="N",
    )
    lqr_q_r: float = checked_field(
        default=DISSERTATION_Q_Y[0], ge=0.0, description="LQR weight on r (Q_y)",
        unit="s2/rad2",
    )  # fmt: skip
    lqr_q_p: float = checked_field(
        default=DISSERTATION_Q_Y[1], ge=0.0, description="LQR weight on p (Q_y)",
        unit="s2/rad2",
    )  # fmt: skip
    lqr_q_roll: float = checked_field(
        default=DISSERTATION_Q_Y[2], ge=0.0, description="LQR weight on phi (Q_y)",
        unit="1/rad2",
    )  # fmt: skip
    lqr_q_yaw: float = checked_field(
        default=DISSERTATION_Q_Y[3], ge=0.0, description="LQR weight on psi - psi_d (Q_y)",
        unit="1/rad2",
    )  # fmt: skip
    lqr_q_mass_position: float = checked_field(
        default=DISSERTATION_Q_Y[4], ge=0.0, description="LQR weight on y_v (Q_y)",
        unit="1/m2",
    )  # fmt: skip
    lqr_q_mass_velocity: float = checked_field(
        default=DISSERTATION_Q_Y[5], ge=0.0, description="LQR weight on y_vel (Q_y)",
        unit="s2/m2",
    )  # fmt: skip
    lqr_r: float = checked_field(
        default=DISSERTATION_R_U, gt=0.0, description="LQR weight on y_d (R_u)",
        unit="1/m2",
    )  # fmt: skip
    smc_eta: float = checked_field(
        default=1.0, gt=0.0, description="sliding-mode reaching rate eta (6.3.38)",
        unit="rad/s", quantity=REACHING_RATE,
    )  # fmt: skip
    smc_boundary_layer: float = checked_field(
        default=0.5, gt=0.0, description="sliding-mode boundary layer Phi on s (6.3.73)",
        unit="rad",
    )  # fmt: skip
    k0: float = checked_field(
        default=0.5, gt=0.0, description="backstepping gain k0 (6.3.55); 0.3 in currents/slow",
        unit="1/s",
    )  # fmt: skip
    k1: float = checked_field(
        default=1.0, gt=0.0, description="backstepping gain k1 (6.3.58); 0.8 in currents/slow",
        unit="1/s",
    )  # fmt: skip
    k2: float = checked_field(
        default=1.0, gt=0.0, description="backstepping gain k2 (6.3.60)",
        unit="1/s",
    )  # fmt: skip
    k3: float = checked_field(
        default=1.0, gt=0.0, description="backstepping gain k3 (6.3.62)",
        unit="1/s",
    )  # fmt: skip
    k4: float = checked_field(
        default=1.0, gt=0.0, description="backstepping gain k4 (6.3.64)",
        unit="1/s",
    )  # fmt: skip
    eta0: float = checked_field(
        default=0.08, ge=0.0, description="thruster margin eta0 (6.3.72), sway acceleration",
        unit="m/s2",
    )  # fmt: skip
    thruster_boundary_layer: float = checked_field(
        default=0.01, gt=0.0, description="thruster boundary layer Phi on z2 (6.3.73)",
        unit="m/s",
    )  # fmt: skip
    command_filter_frequency: float = checked_field(
        default=10.0, gt=0.0,
        description="natural frequency of the command filters giving alpha1..3 derivatives",
        unit="rad/s", quantity=ANGULAR_FREQUENCY,
    )  # fmt: skip
    depth_gamma: float = checked_field(
        default=TABLE_6_2_GAMMA, description="depth loop gain gamma, theta_d per depth error "
        "(Table 6.2)", unit="rad/m",
    )  # fmt: skip
    depth_k_p: float = checked_field(
        default=TABLE_6_2_K_P, description="pitch loop gain K_p, fin per pitch error (Table 6.2)",
        unit="1",
    )  # fmt: skip
    depth_tau_d: float = checked_field(
        default=TABLE_6_2_TAU_D, ge=0.0, description="pitch loop derivative time tau_d "
        "(Table 6.2)", unit="s",
    )  # fmt: skip
    fin_angle_limit: float = checked_field(
        default=DEFAULT_FIN_LIMIT, gt=0.0, description="stern-plane limit |delta_s| (25 deg)",
        unit="rad",
    )  # fmt: skip
    depth_pitch_limit: float = checked_field(
        default=0.0, description="depth loop's pitch set-point limit |theta_d| "
        "(0: none; at most pi/2)", unit="rad", check=_pitch_limit, standalone=True,
    )  # fmt: skip
    mass_position_cmd_limit: float = checked_field(
        default=0.06, gt=0.0, description="moving-mass command limit |y_d| (the 6 cm stroke)",
        unit="m",
    )  # fmt: skip
    tunnel_force_limit: float = checked_field(
        default=10.0, ge=0.0, description="tunnel-thruster force limit |F_t|",
        unit="N",
    )  # fmt: skip

    @classmethod
    def build(cls, **values: Any) -> AutopilotConfig:
        """Validate ``values``; raise :class:`AutopilotConfigError` naming every bad one."""
        return cls.from_mapping(values)


def field_unit(name: str) -> str:
    """The unit of an :class:`AutopilotConfig` field ('' if dimensionless)."""
    return AutopilotConfig.field_info()[name].unit


def field_quantity(name: str) -> str:
    """The declared quantity of an :class:`AutopilotConfig` field ('' where its unit says
    what it is)."""
    return AutopilotConfig.field_info()[name].quantity
