"""The units plots draw columns in, and the unit a column must be declared in for that.

A plot shows angles in degrees and the moving mass in centimetres (from a column its FMU
declares in rad, rad/s, m or m/s), everything else in the unit its FMU declares. The
recording (:mod:`cosim.viz.layout`) and the report (:mod:`cosim.viz.report`) check a
column's declared unit (summary.json's ``units``) against the unit their plot converts
from, so a column another tool's FMU declares in deg is not multiplied by 180/pi again
(a column declared "1", whose FMU may declare no unit, is taken as the plot expects).
"""

from __future__ import annotations

import math

import numpy as np

DEG = math.degrees(1.0)  # deg per rad
NO_UNIT = "1"  # summary.json's unit of a column whose FMU declares none (or a pure number)
# display unit -> (the declared unit it is drawn from, display units per declared unit)
DRAWN_FROM: dict[str, tuple[str, float]] = {
    "deg": ("rad", DEG),
    "deg/s": ("rad/s", DEG),
    "cm": ("m", 100.0),
    "cm/s": ("m/s", 100.0),
}


def source_unit(shown: str) -> str:
    """The unit a column is declared in for a plot in ``shown`` to scale it (rad for deg);
    ``shown`` itself for a unit drawn as declared."""
    return DRAWN_FROM.get(shown, (shown, 1.0))[0]


def scale_to(declared: str, shown: str) -> float | None:
    """Units ``shown`` per unit ``declared`` (1 for one unit); None if a column declared
    in ``declared`` cannot be drawn in ``shown``."""
    if declared == shown:
        return 1.0
    source, factor = DRAWN_FROM.get(shown, (shown, 1.0))
    return factor if declared == source else None


def on_turn_of(angles: np.ndarray, reference: np.ndarray, turn: float) -> np.ndarray:
    """``angles`` moved by whole turns (``turn``: 360 in deg, 2 pi in rad), sample by sample,
    to [-half, +half) a turn of ``reference``: a heading set-point drawn on the turn of
    the yaw it steers, which counts whole turns (10 deg beside a yaw of 350 deg is drawn at
    370), one half a turn away on the side the autopilot turns to (its ``wrap_angle``,
    controller_fmu/setpoint_shaping.py). An angle already there is returned bit for bit,
    and one whose distance is not finite (inf, NaN) as it is."""
    with np.errstate(invalid="ignore", over="ignore"):
        turns = np.floor((angles - reference) / turn + 0.5)
        moved: np.ndarray = np.where(np.isfinite(turns), angles - turn * turns, angles)
    return moved
