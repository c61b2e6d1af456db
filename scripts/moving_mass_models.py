"""Regenerate ``docs/moving-mass-model.md``: what the two-body moving mass changes.

    python scripts/moving_mass_models.py [--out docs]

Runs lqr-2, bs-3, vert-1 and vert-2 through the co-simulation master twice, with the
plant's ``moving_mass_model`` = 0 (the dissertation's (6.3.11)-(6.3.13), the built-in
scenarios' default) and = 1 (hull and moving mass as two bodies, (6.2.28)), each with
``--check-step`` (the coupling error of its settling time, docs/coupling.md), and writes a
table of settling times and peaks with one figure per scenario (yaw, roll, mass position,
and depth where the run has a depth loop, both models overlaid) to
``docs/figures/moving-mass/``. Every number is computed from the runs; nothing is typed in.
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import tomli_w

from cosim.metrics.key_figures import YAW_TOLERANCE_RAD, settling_time
from cosim.outputs.results import read_csv
from cosim.runner import run_scenario
from cosim.scenario.spec import load_scenario, scenario_from_toml

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ("lqr-2", "bs-3", "vert-1", "vert-2")
MODELS = {0: "model 0 (dissertation)", 1: "model 1 (two bodies)"}
FIGURE_FOLDER = "figures/moving-mass"  # own folder: the reproduction script clears figures/
DEG = math.degrees(1.0)


@dataclass
class Run:
    """One scenario's results by column name, and its settling time's coupling error (s,
    None where it cannot be estimated)."""

    columns: dict[str, np.ndarray]
    settling_error: float | None = None

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def figures(self) -> dict[str, str]:
        """The compared figures, formatted: settling, peaks, and the late-run behaviour."""
        t, yaw, roll = self["time"], self["plant.yaw"], self["plant.roll"]
        setpoint = self.columns.get("controller.yaw_setpoint", 0.0)
        settled = settling_time(t, yaw - setpoint, YAW_TOLERANCE_RAD, angle=True)
        k_yaw = int(np.argmax(np.abs(yaw)))
        late = t >= t[-1] - 20.0
        values = {
            "yaw settles (1 deg) at": "never" if settled is None else f"{settled:.1f} s",
            "peak abs yaw": f"{DEG * abs(yaw[k_yaw]):.2f} deg at {t[k_yaw]:.1f} s",
            "peak abs roll": f"{DEG * np.max(np.abs(roll)):.2f} deg",
            "peak abs y_v": f"{100 * np.max(np.abs(self['plant.mass_position'])):.2f} cm",
            "peak abs rail speed": f"{100 * np.max(np.abs(self['plant.mass_velocity'])):.1f} cm/s",
            "roll peak to peak, last 20 s": f"{DEG * np.ptp(roll[late]):.2f} deg",
            "coupling error of the settling time (--check-step)": "n/a"
            if self.settling_error is None
            else f"{self.settling_error:+.3f} s",
        }
        if np.ptp(self["plant.down"]) > 0.0:  # a run with a depth loop (the 6-DOF plant)
            last = t >= t[-1] - 10.0
            values["depth at the end"] = f"{self['plant.down'][-1]:.3f} m"
            values["mean w, theta, last 10 s"] = (
                f"{np.mean(self['plant.w'][last]):.3f} m/s, "
                f"{np.mean(self['plant.pitch'][last]):.3f} rad"
            )
        return values


def run_both(sid: str, work: Path) -> dict[int, Run]:
    """The scenario with each moving-mass model (plant start value ``moving_mass_model``)."""
    base = load_scenario(sid)
    runs = {}
    for model in MODELS:
        data = base.spec.model_dump(by_alias=True, exclude_none=True)
        data["id"] = f"{sid}-model-{model}"
        data["instances"]["plant"].setdefault("start", {})["moving_mass_model"] = model
        scenario = scenario_from_toml(tomli_w.dumps(data), f"{sid} with model {model}")
        outcome = run_scenario(scenario, work / f"{sid}-{model}", no_rrd=True, check_step=True)
        if not outcome.result.complete:
            raise RuntimeError(f"{sid} with model {model} stopped: {outcome.result.error}")
        names, values = read_csv(outcome.paths["results"])
        check = outcome.result.coupling.get("check_step", {}).get("key_figures", {})
        error = check.get("yaw_settling_time_s", {}).get("error")
        runs[model] = Run({name: values[:, k] for k, name in enumerate(names)}, error)
        print(f"  {sid}, model {model}: done", file=sys.stderr)
    return runs


def panels_of(runs: dict[int, Run]) -> list[tuple[str, float, str]]:
    """The panels of a scenario's figure: (column, display scale, y label) of yaw, roll,
    y_v, and depth when it changes."""
    panels = [("plant.yaw", DEG, "yaw (deg)"), ("plant.roll", DEG, "roll (deg)"),
              ("plant.mass_position", 100.0, "y_v (cm)")]  # fmt: skip
    if np.ptp(runs[0]["plant.down"]) > 0.0:
        panels.append(("plant.down", 1.0, "depth (m)"))
    return panels


def alt_text(sid: str, runs: dict[int, Run]) -> str:
    """What the figure of ``sid`` shows, as the page's image text."""
    shown = ", ".join(label for _, _, label in panels_of(runs))
    return (
        f"{sid}: {shown} against time (s), one panel each, {MODELS[0]} solid and {MODELS[1]} dashed"
    )


def plot(sid: str, runs: dict[int, Run], path: Path) -> None:
    """Yaw, roll, y_v (and depth) of both models against time."""
    panels = panels_of(runs)
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(7.0, 1.9 * len(panels)))
    for ax, (column, scale, label) in zip(axes, panels, strict=True):
        for model, style in ((0, "-"), (1, "--")):
            ax.plot(runs[model]["time"], scale * runs[model][column], style, label=MODELS[model])
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(loc="upper right", fontsize="small")
    axes[0].set_title(f"{sid}: the moving mass as in the dissertation and as a second body")
    axes[-1].set_xlabel("time (s)")
    ends = [float(runs[model]["time"][-1]) for model in runs]
    axes[-1].set_xlim(float(runs[0]["time"][0]), max(ends))  # the run's start to its stop
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def markdown(results: dict[str, dict[int, Run]]) -> str:
    lines = [
        "# The moving mass as a second body: what it changes",
        "",
        "Generated by `python scripts/moving_mass_models.py`; do not edit by hand. The plant "
        "parameter `moving_mass_model` selects how the internal moving mass acts on the hull "
        "(see [model.md](model.md#gravity-and-the-moving-mass)): 0, the dissertation's "
        "(6.3.11)-(6.3.13) and the default of every built-in scenario, or 1, hull, fluid and "
        "point mass as two bodies with every coupling term (6.2.28). Each scenario below ran "
        "through the master with both; every other setting is the built-in scenario's, its "
        "coupling included ([coupling.md](coupling.md)): the last row of each table is the "
        "coupling error `--check-step` estimates for the settling time, against which the "
        "difference between the models is to be read.",
        "",
    ]
    for sid, runs in results.items():
        figures = {model: run.figures() for model, run in runs.items()}
        yaw_gap = DEG * np.max(np.abs(runs[1]["plant.yaw"] - runs[0]["plant.yaw"]))
        lines += [
            f"## {sid}",
            "",
            f"| figure | {MODELS[0]} | {MODELS[1]} |",
            "|---|---|---|",
            *(f"| {name} | {figures[0][name]} | {figures[1][name]} |" for name in figures[0]),
            f"| largest yaw difference between the models | {yaw_gap:.3f} deg | |",
            "",
            f"![{alt_text(sid, runs)}]({FIGURE_FOLDER}/{sid}.png)",
            "",
        ]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="[docs]")
    args = parser.parse_args(argv)
    figures = args.out / FIGURE_FOLDER
    figures.mkdir(parents=True, exist_ok=True)
    results = {}
    with tempfile.TemporaryDirectory() as work:
        for sid in SCENARIOS:
            results[sid] = run_both(sid, Path(work))
            plot(sid, results[sid], figures / f"{sid}.png")
    page = args.out / "moving-mass-model.md"
    page.write_text(markdown(results) + "\n", encoding="utf-8")
    print(f"wrote {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
