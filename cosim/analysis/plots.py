"""Figures of the open-loop analysis: bifurcation diagrams (Figs. 5.6, 5.7, 5.9, 5.12) and
phase portraits (Figs. 5.4, 5.5). matplotlib figures without pyplot (the caller's backend is
left alone); no physics here: the branches and trajectories come from
:mod:`cosim.analysis.bifurcation` and :mod:`plant_fmu.model.stepping`.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib import style as mpl_style
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from cosim.analysis.bifurcation import Q_PROP, Sweep, cg_offset
from cosim.analysis.equilibria import Equilibrium
from cosim.whole_file import write_whole
from plant_fmu.model.dynamics import STATE_INDEX
from plant_fmu.model.parameters import VehicleParameters

PARAMETER_LABELS = {
    "roll_torque": "roll torque Q (N m)",
    "mass_position": "moving-mass position $y_v$ (cm)",
    "mu": r"fin-arm factor $\mu$ (5.1.62)",
    "eta": r"fin-area factor $\eta$ (5.1.63)",
}
# Display scale of the swept parameter (mass position in cm, as Fig. 5.12).
PARAMETER_SCALE = {"roll_torque": 1.0, "mass_position": 100.0, "mu": 1.0, "eta": 1.0}
SPECIAL_MARKERS: dict[str, dict[str, Any]] = {
    "fold": dict(marker="X", color="tab:red", s=90),
    "branch point": dict(marker="D", color="black", s=50),
    "hopf": dict(marker="*", color="tab:green", s=120),
}
# The colours of branches and trajectories, in order: matplotlib's petroff10 cycle, chosen
# to stay apart for colour-blind readers (tab10's orange and green are one colour to a
# reader with protanopia, its green and red to one with deuteranopia).
LINE_COLOURS: tuple[str, ...] = tuple(
    mpl_style.library["petroff10"]["axes.prop_cycle"].by_key()["color"]
)
STATE_LABELS = {
    "u": "u (m/s)",
    "v": "v (m/s)",
    "r": "r (rad/s)",
    "roll": r"$\phi$ (deg)",
    "p": "p (rad/s)",
}


def _display(name: str, values: np.ndarray) -> np.ndarray:
    return np.degrees(values) if name == "roll" else values


def _runs(stable: np.ndarray) -> list[slice]:
    """Contiguous index ranges of equal stability, each sharing its end with the next."""
    edges = [0, *(np.flatnonzero(np.diff(stable.astype(int))) + 1), len(stable)]
    return [slice(a, min(b + 1, len(stable))) for a, b in itertools.pairwise(edges)]


def plot_sweep(result: Sweep, params: VehicleParameters, path: Path, title: str = "") -> Path:
    """Bifurcation diagram of a :class:`Sweep`: the branches in (v, u, r) space as in
    Figs. 5.6, 5.7, 5.10, 5.13, and each state against the parameter as in Figs. 5.9, 5.12
    (solid: stable, dashed: unstable; markers at folds, branch points, Hopf points)."""
    scale = PARAMETER_SCALE[result.parameter]
    against = [n for n in ("roll", "v", "r", "u") if n in result.free_states]
    fig = Figure(figsize=(15, 7.5), constrained_layout=True)
    grid = fig.add_gridspec(2, 4)
    ax3d = fig.add_subplot(grid[:, 0:2], projection="3d")
    axes = [fig.add_subplot(grid[k // 2, 2 + k % 2]) for k in range(len(against))]
    for b, branch in enumerate(result.branches):
        color = LINE_COLOURS[b % len(LINE_COLOURS)]
        stable = branch.stable
        for run in _runs(stable):
            style = "-" if stable[run.start] else "--"
            ax3d.plot(
                branch.values("v")[run],
                branch.values("u")[run],
                branch.values("r")[run],
                style,
                color=color,
            )
            for ax, name in zip(axes, against, strict=True):
                ax.plot(
                    branch.parameters[run] * scale,
                    _display(name, branch.values(name)[run]),
                    style,
                    color=color,
                )
    for special in result.special_points:
        marker = SPECIAL_MARKERS[special.kind]
        ax3d.scatter(special.state["v"], special.state["u"], special.state["r"], **marker)
        for ax, name in zip(axes, against, strict=True):
            ax.scatter(
                special.parameter * scale,
                _display(name, np.array(special.state[name])),
                zorder=3,
                **marker,
            )
    ax3d.set_xlabel("v (m/s)")
    ax3d.set_ylabel("u (m/s)")
    ax3d.set_zlabel("r (rad/s)")
    ax3d.set_title("equilibrium branches in (v, u, r)")
    for ax, name in zip(axes, against, strict=True):
        ax.set_xlabel(PARAMETER_LABELS[result.parameter])
        ax.set_ylabel(STATE_LABELS[name])
        ax.grid(True, alpha=0.3)
        _secondary_axis(ax, result.parameter, params)
    legend = [
        Line2D([], [], color="gray", linestyle="-", label="stable"),
        Line2D([], [], color="gray", linestyle="--", label="unstable"),
    ] + [
        Line2D([], [], linestyle="", marker=m["marker"], color=m["color"], label=kind)
        for kind, m in SPECIAL_MARKERS.items()
        if any(s.kind == kind for s in result.special_points)
    ]
    ax3d.legend(handles=legend, loc="upper left")
    fig.suptitle(title or f"continuation over {result.parameter}")
    return _save(fig, path)


def sweep_alt(parameter: str) -> str:
    """The alt text of :func:`plot_sweep`'s figure over ``parameter`` (a key of
    :data:`PARAMETER_LABELS`)."""
    label = PARAMETER_LABELS[parameter].translate(str.maketrans("", "", "$\\{}"))
    return (
        f"Equilibrium branches over the {label}: in (v, u, r) with v, u in (m/s) and r in "
        "(rad/s), and beside it roll (deg), v, r and u against the parameter; solid stable, "
        "dashed unstable, folds, branch points and Hopf points marked"
    )


PHASE_ALT = (
    "Open-loop trajectories in (v, u, r), v and u in (m/s), r in (rad/s), and projected on "
    "(v, r), each coloured by the equilibrium it ends at; stable equilibria filled, "
    "unstable ones hollow"
)  # the alt text of plot_phase_portrait's figure


def _secondary_axis(ax: Axes, parameter: str, params: VehicleParameters) -> None:
    """A top axis in the dissertation's unit: Q / Q_prop (Fig. 5.9), y_g in cm (Fig. 5.12)."""
    if parameter == "roll_torque":
        top = ax.secondary_xaxis(
            "top", functions=(lambda q: np.divide(q, Q_PROP), lambda k: np.multiply(k, Q_PROP))
        )
        top.set_xlabel(r"Q / $Q_{prop}$")
    elif parameter == "mass_position":
        ratio = cg_offset(params, 1.0)  # y_g per y_v (both in cm here)
        top = ax.secondary_xaxis(
            "top", functions=(lambda y: np.multiply(y, ratio), lambda g: np.divide(g, ratio))
        )
        top.set_xlabel("CG offset $y_g = m_v g y_v / W$ (cm)")


def plot_phase_portrait(
    trajectories: Sequence[np.ndarray],
    equilibria: Sequence[Equilibrium],
    path: Path,
    title: str = "",
) -> Path:
    """Open-loop trajectories (state arrays, ``STATE_NAMES`` columns) projected onto
    (v, u, r) as in Figs. 5.4-5.5, and onto the (v, r) plane; each trajectory coloured by
    the equilibrium it ends nearest to; equilibria filled if stable, hollow if not."""
    iu, iv, ir = STATE_INDEX["u"], STATE_INDEX["v"], STATE_INDEX["r"]
    fig = Figure(figsize=(13, 6), constrained_layout=True)
    ax3d = fig.add_subplot(1, 2, 1, projection="3d")
    ax2d = fig.add_subplot(1, 2, 2)
    targets = np.array([[e.state[iu], e.state[iv], e.state[ir]] for e in equilibria])
    for x in trajectories:
        end = x[-1, [iu, iv, ir]]
        k = int(np.argmin(np.linalg.norm(targets - end, axis=1))) if len(targets) else 0
        color = LINE_COLOURS[k % len(LINE_COLOURS)]
        ax3d.plot(x[:, iv], x[:, iu], x[:, ir], color=color, linewidth=0.8)
        ax3d.scatter(x[0, iv], x[0, iu], x[0, ir], color=color, s=6)
        ax2d.plot(x[:, iv], x[:, ir], color=color, linewidth=0.8)
        ax2d.scatter(x[0, iv], x[0, ir], color=color, s=6)
    for k, eq in enumerate(equilibria):
        face = LINE_COLOURS[k % len(LINE_COLOURS)] if eq.stable else "white"
        style: dict[str, Any] = dict(
            s=80, edgecolors="black", facecolors=face, zorder=5, depthshade=False
        )
        ax3d.scatter(eq.state[iv], eq.state[iu], eq.state[ir], **style)
        style.pop("depthshade")
        ax2d.scatter(eq.state[iv], eq.state[ir], **style)
    ax3d.set_xlabel("v (m/s)")
    ax3d.set_ylabel("u (m/s)")
    ax3d.set_zlabel("r (rad/s)")
    ax2d.set_xlabel("v (m/s)")
    ax2d.set_ylabel("r (rad/s)")
    ax2d.grid(True, alpha=0.3)
    ax2d.set_title("projection on (v, r): filled = stable, hollow = unstable equilibrium")
    fig.suptitle(title or "open-loop phase portrait")
    return _save(fig, path)


def _save(fig: Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    write_whole(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    return path
