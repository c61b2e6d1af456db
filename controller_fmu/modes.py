"""The autopilot's controller choices: which heading law and which depth law run.

The FMU parameters ``heading_mode`` and ``depth_mode`` are FMI Integers holding these
values; :class:`controller_fmu.autopilot.Autopilot` resolves them once, at construction,
into the controller objects it steps, so no mode is looked up per step.
"""

from __future__ import annotations

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
