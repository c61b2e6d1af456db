"""The open-loop analysis figures (``cosim.analysis.plots``) as a colour-blind reader sees
them."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from colour_vision import confused
from matplotlib.colors import to_hex

from cosim.analysis import plots
from cosim.analysis.equilibria import Equilibrium
from plant_fmu.model.dynamics import STATE_INDEX, STATE_NAMES


def _state(u: float, v: float, r: float) -> np.ndarray:
    x = np.zeros(len(STATE_NAMES))
    x[[STATE_INDEX["u"], STATE_INDEX["v"], STATE_INDEX["r"]]] = u, v, r
    return x


def test_trajectories_to_different_equilibria_differ_for_a_colour_blind_reader(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A phase portrait colours each trajectory by the equilibrium it ends at, and only by
    colour: with tab10's blue, orange and green (Figs. 5.4, 5.5) the orange and green
    trajectories were one colour to a reader with protanopia (Delta E 4.6)."""
    ends = [_state(1.5, -0.2, 0.2), _state(1.5, 0.0, 0.0), _state(1.5, 0.2, -0.2)]
    equilibria = [
        Equilibrium(x, ("u", "v", "r"), np.eye(3), np.array([sign, -1.0, -1.0]))
        for x, sign in zip(ends, (-1.0, 1.0, -1.0), strict=True)
    ]
    trajectories = [np.vstack([_state(1.0, 0.4, 0.4), end]) for end in ends]
    drawn = {}
    monkeypatch.setattr(plots, "_save", lambda fig, path: drawn.setdefault("fig", fig) and path)
    plots.plot_phase_portrait(trajectories, equilibria, tmp_path / "phase.png")
    projection = drawn["fig"].axes[1]  # (v, r): a line per trajectory
    colours = [to_hex(line.get_color()) for line in projection.get_lines()]
    assert len(set(colours)) == len(ends), colours
    assert confused(colours) == []
