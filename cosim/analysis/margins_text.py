"""``auv-cosim analyze margins``: the LQR loop's margins and poles, printed with units.

The numbers come from :mod:`cosim.analysis.margins` (python-control on the plant's own
linearisation); this module only words them.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path

import control
import numpy as np

from cosim.analysis.bifurcation import AnalysisError
from cosim.analysis.margins import (
    Crossing,
    LoopMargins,
    check_loop_arguments,
    depth_loop,
    loop_margins,
    lqr_loop,
    scaled_vehicle,
)
from cosim.errors import CosimError
from plant_fmu.model.parameters import VehicleParameterError, load_vehicle


def margins_command(
    vehicle: str,
    design_speed: float,
    step: float,
    speed: float | None = None,
    scale: Mapping[str, float] | None = None,
    plot: Path | None = None,
    loop_name: str = "lqr",
) -> int:
    """Print the margins of the LQR designed on ``vehicle`` at ``design_speed`` (m/s) for
    ``step`` (s) (``loop_name`` "depth": the depth PD of Table 6.2, sampled every
    ``step``), closed on the plant at ``speed`` (m/s, default ``design_speed``) with
    ``scale``'s parameters multiplied, and draw its Bode diagram into ``plot`` (PNG) if
    given; 0 on success."""
    try:
        design = load_vehicle(vehicle)
    except VehicleParameterError as exc:
        raise AnalysisError(str(exc)) from None
    check_loop_arguments({"--design-speed": design_speed, "--speed": speed}, step)
    plant = scaled_vehicle(design, scale or {})
    at = design_speed if speed is None else speed
    scaled = "".join(f", {name} x {factor:g}" for name, factor in (scale or {}).items())
    if loop_name == "depth":
        loop = depth_loop(plant, step, at)
        setting = (
            f"Table 6.2's gains, h = {step:g} s; plant {design.name}{scaled} at u = {at:g} m/s"
        )
        what, where = "depth PD loop", ("the fin angle delta_s", "delta_s")
    else:
        loop = lqr_loop(design, design_speed, step, plant, speed)
        setting = (
            f"designed on {design.name} at U0 = {design_speed:g} m/s for h = {step:g} s; plant "
            f"{design.name}{scaled} at u = {at:g} m/s"
        )
        what, where = "LQR heading loop", ("the servo command y_d", "y_d")
    margins = loop_margins(loop)
    print(f"{what} broken at the plant input ({where[0]}): {setting}")
    print(margins_table(margins))
    if plot is not None:
        _plot(loop, margins, plot, f"{what} L(z) broken at {where[1]}\n{setting}")
    return 0


def _plot(loop: control.StateSpace, margins: LoopMargins, plot: Path, title: str) -> None:
    """Draw the Bode diagram into ``plot`` and say so."""
    from cosim.analysis.margins_plot import plot_margins

    try:
        plot_margins(loop, margins, plot, title)
    except OSError as exc:
        raise CosimError(f"cannot write the Bode diagram to {plot}: {exc}") from None
    print(f"  Bode diagram    {plot}")


def margins_table(margins: LoopMargins) -> str:
    """The margins and poles as lines of text, every value with its unit."""
    largest = float(np.abs(margins.poles).max())
    lines = [
        f"closed loop: {'stable' if margins.stable else 'UNSTABLE'} (largest |z| "
        f"{largest:.6g}); poles as s = ln(z)/h [1/s]: {_poles(margins.continuous_poles)}"
    ]
    if not margins.stable:
        lines.append("(no margins: the loop is unstable as it is)")
        return "\n".join(lines)
    lower, upper = margins.lower_gain_margin, margins.upper_gain_margin
    lines.append(f"gain margin, down: {_gain(lower, margins.step)}")
    lines.append(f"gain margin, up:   {_gain(upper, margins.step)}")
    phase = margins.phase_margin
    lines.append(
        "phase margin:      "
        + (
            "none (no gain crossover)"
            if phase is None
            else f"{phase.value:.4g} deg at {phase.frequency:.4g} rad/s"
        )
    )
    delay = margins.delay_margin
    lines.append(
        "delay margin:      "
        + (
            "none (no gain crossover)"
            if delay is None
            else f"{delay.value:.4g} s ({delay.value / margins.step:.3g} steps of h), eating the "
            f"phase margin at {delay.frequency:.4g} rad/s"
        )
    )
    ms = margins.sensitivity_peak
    lines.append(
        f"sensitivity peak:  Ms = {ms:.4g} ({20 * math.log10(ms):.3g} dB) at "
        f"{margins.sensitivity_frequency:.4g} rad/s"
    )
    return "\n".join(lines)


def _gain(crossing: Crossing | None, step: float) -> str:
    if crossing is None:
        return "none up to the Nyquist frequency"
    where = f"{crossing.frequency:.4g} rad/s"
    if math.isclose(crossing.frequency, math.pi / step):
        where += " (the Nyquist frequency pi/h)"
    return f"x {crossing.value:.4g} ({20 * math.log10(crossing.value):+.3g} dB) at {where}"


def _poles(poles: np.ndarray) -> str:
    """Conjugate pairs once, as a +- b i, slowest (largest real part) last."""
    shown = sorted((z for z in poles if z.imag >= -1e-12), key=lambda z: z.real)
    return ", ".join(
        f"{z.real:.4g}" if abs(z.imag) < 1e-9 else f"{z.real:.4g} +- {abs(z.imag):.4g}i"
        for z in shown
    )
