"""The autopilot's controller choices: which heading law and which depth law run.

The FMU parameters ``heading_mode`` and ``depth_mode`` are FMI Integers holding these
values; :class:`controller_fmu.autopilot.Autopilot` resolves them once, at construction,
into the controller objects it steps, so no mode is looked up per step. Which law reads
which of its parameters is listed here too (:func:`unused_parameters`: a scenario naming
a gain that no law it selects reads is warned of), in this light module so that a master
can ask without importing the controllers.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from enum import IntEnum


class HeadingMode(IntEnum):
    """Heading controller on the moving mass (Sec. 6.3)."""

    OFF = 0
    LQR = 1  # discrete LQR, (6.3.17)-(6.3.19)
    SLIDING_MODE = 2  # sampled sliding mode, (6.3.31)-(6.3.45)
    BACKSTEPPING = 3  # backstepping + tunnel thruster, (6.3.64), (6.3.72)


class DepthMode(IntEnum):
    """Depth controller on the stern planes (Fig. 6.40)."""

    OFF = 0
    PD = 1  # PD pitch + P depth, Table 6.2


def choices(mode: type[IntEnum]) -> str:
    """The allowed values of a mode enum for an error message, e.g. ``0 (OFF), 1 (PD)``."""
    return ", ".join(f"{member.value} ({member.name})" for member in mode)


_LQR_WEIGHTS = ("lqr_q_r", "lqr_q_p", "lqr_q_roll", "lqr_q_mass_position",
                "lqr_q_mass_velocity", "lqr_r")  # fmt: skip
_BACKSTEPPING = ("k0", "k1", "k2", "k3", "k4", "eta0", "thruster_boundary_layer",
                 "command_filter_frequency", "tunnel_force_limit")  # fmt: skip
HEADING_LAW_PARAMETERS: Mapping[str, frozenset[HeadingMode]] = {
    **{name: frozenset({HeadingMode.LQR, HeadingMode.SLIDING_MODE}) for name in _LQR_WEIGHTS},
    # the sliding mode's gain k comes from the LQR without psi (6.3.46)-(6.3.47)
    "lqr_q_yaw": frozenset({HeadingMode.LQR}),
    "design_step": frozenset({HeadingMode.LQR, HeadingMode.SLIDING_MODE}),
    "smc_eta": frozenset({HeadingMode.SLIDING_MODE}),
    "smc_boundary_layer": frozenset({HeadingMode.SLIDING_MODE}),
    **{name: frozenset({HeadingMode.BACKSTEPPING}) for name in _BACKSTEPPING},
}
"""The heading laws that read each heading-law parameter of the autopilot's
configuration (:class:`controller_fmu.autopilot.AutopilotConfig`)."""
DEPTH_LAW_PARAMETERS: tuple[str, ...] = ("depth_gamma", "depth_k_p", "depth_tau_d",
                                         "fin_angle_limit", "depth_pitch_limit",
                                         "design_step")  # fmt: skip
"""The parameters the depth law (``depth_mode`` pd) reads (design_step: its gains are
checked on the loop sampled so). A parameter in neither table (the modes, the design
speed, the vehicle, the mass command limit, ...) is read whatever the laws."""


def unused_parameters(
    names: Iterable[str], heading_modes: Iterable[HeadingMode], depth_mode: DepthMode
) -> dict[str, str]:
    """Those of ``names`` that none of the laws selected (any of ``heading_modes``, which a
    run may switch between, and ``depth_mode``) reads: name -> the laws that would, in
    words (e.g. ``"heading_mode lqr or sliding_mode"``)."""
    running = set(heading_modes)
    depth = depth_mode is DepthMode.PD
    unused = {}
    for name in names:
        heading = HEADING_LAW_PARAMETERS.get(name, frozenset())
        in_depth = name in DEPTH_LAW_PARAMETERS
        if not (heading or in_depth) or heading & running or (in_depth and depth):
            continue
        laws = []
        if heading:
            laws.append("heading_mode " + " or ".join(m.name.lower() for m in sorted(heading)))
        if in_depth:
            laws.append("depth_mode pd")
        unused[name] = " or ".join(laws)
    return unused
