"""The figure of ``auv-cosim analyze margins --plot``: the Bode diagram of the LQR loop
broken at the plant input, its margins marked. matplotlib without pyplot; the numbers
all come from :mod:`cosim.analysis.margins`.
"""

from __future__ import annotations

import math
from pathlib import Path

import control
import numpy as np
from matplotlib.figure import Figure

from cosim.analysis.margins import LoopMargins
from cosim.whole_file import write_whole


def plot_margins(loop: control.StateSpace, margins: LoopMargins, path: Path, title: str) -> Path:
    """|L| (dB) and the phase of L (deg) against frequency (rad/s) up to pi/h, with the
    gain crossovers (where the phase margins are read) and the phase crossovers (the gain
    margins) marked; written whole to ``path`` (PNG)."""
    nyquist = math.pi / margins.step
    omega = np.logspace(-3.0, math.log10(nyquist), 4000)
    response = np.asarray(control.frequency_response(loop, omega).complex).ravel()
    fig = Figure(figsize=(9, 7), constrained_layout=True)
    magnitude, phase = fig.subplots(2, 1, sharex=True)
    magnitude.semilogx(omega, 20 * np.log10(np.abs(response)), color="tab:blue")
    magnitude.axhline(0.0, color="gray", linewidth=0.8)
    magnitude.set_ylabel("|L| (dB)")
    degrees = np.degrees(np.unwrap(np.angle(response)))
    phase.semilogx(omega, degrees, color="tab:blue")
    low, high = math.floor(degrees.min() / 360.0), math.ceil(degrees.max() / 360.0)
    for k in range(low, high + 1):  # -180 deg and its equivalents within the curve's range
        if degrees.min() - 30.0 <= 180.0 + 360.0 * k <= degrees.max() + 30.0:
            phase.axhline(180.0 + 360.0 * k, color="gray", linewidth=0.8)
    phase.set_ylabel("phase of L (deg)")
    phase.set_xlabel("frequency (rad/s)")
    for crossing in margins.phase_margins:
        label = f"PM {crossing.value:.3g} deg at {crossing.frequency:.3g} rad/s"
        for ax in (magnitude, phase):
            ax.axvline(crossing.frequency, color="tab:green", linestyle="--", label=label)
    for crossing in margins.gain_margins:
        label = f"GM x {crossing.value:.3g} at {crossing.frequency:.3g} rad/s"
        for ax in (magnitude, phase):
            ax.axvline(crossing.frequency, color="tab:red", linestyle=":", label=label)
    magnitude.legend(loc="lower left", fontsize="small")
    for ax in (magnitude, phase):
        ax.grid(True, which="both", alpha=0.3)
        ax.set_xlim(omega[0], nyquist)
    fig.suptitle(title, fontsize="medium")
    path.parent.mkdir(parents=True, exist_ok=True)
    write_whole(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    return path
