"""The study page's figures show what matters: by default the key figures and manoeuvre
metrics (not final values at noise level), the one that varies most first, every axis
with its unit, tick labels without an offset."""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import pytest

from cosim.study import plots
from cosim.study.units import units

V0 = [-0.10, -0.05, 0.05, 0.10]
METRICS = ["yaw_settling_time_s", "peak_abs_tunnel_force_N", "time_reached",
           "final.plant.u", "final.plant.yaw"]  # fmt: skip


def rows() -> list[dict]:
    return [
        {
            "plant.v_0": v,
            "yaw_settling_time_s": 3.0 + 0.01 * i,  # varies by ~1 %
            "peak_abs_tunnel_force_N": 9.0 * abs(v) / 0.1,  # varies by half its size
            "time_reached": 20.0,
            "final.plant.u": 1.5249 + 1e-5 * i,  # noise on a constant
            "final.plant.yaw": 1e-3 * v,
            "status": "complete",
        }
        for i, v in enumerate(V0)
    ]


def test_default_metrics_are_the_key_figures_ordered_by_variation() -> None:
    candidates = plots.default_metrics(METRICS)
    assert candidates == ["yaw_settling_time_s", "peak_abs_tunnel_force_N"]
    assert plots.plotted_metrics(rows(), candidates) == [
        "peak_abs_tunnel_force_N",
        "yaw_settling_time_s",
    ]
    everything = plots.plotted_metrics(rows(), METRICS)  # [metrics] collect: all of them
    assert everything[-1] == "final.plant.u" and "time_reached" not in everything


def test_axes_have_units_and_no_offset_tick_labels(tmp_path: Path, monkeypatch) -> None:
    kept: list[plt.Figure] = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: kept.append(fig) or path)
    quantities = {"plant.v_0": "m/s", "final.plant.u": "m/s"}
    plots.plot_grid_factor(
        rows(), {"plant.v_0": V0}, "plant.v_0", ["final.plant.u"], tmp_path / "g.png", quantities
    )
    (ax,) = [a for a in kept[0].axes if a.get_visible()]
    kept[0].canvas.draw()
    assert ax.get_xlabel() == "plant.v_0 [m/s]" and ax.get_ylabel() == "[m/s]"
    assert ax.yaxis.get_major_formatter().get_offset() == ""
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert labels and all(text.startswith("1.52") for text in labels), labels
    plt.close(kept[0])


@pytest.mark.slow
def test_units_come_from_the_model_descriptions_and_metric_names(fmu_paths) -> None:
    paths = {"plant": fmu_paths["AuvPlant"], "controller": fmu_paths["AuvAutopilot"]}
    found = units(
        ["plant.v_0", "final.plant.yaw", "yaw_settling_time_s", "peak_abs_tunnel_force_N",
         "events.turn.time", "events.turn.set.plant.thrust", "overshoot_pct", "time_reached"],
        paths,
    )  # fmt: skip
    assert found == {
        "plant.v_0": "m/s",
        "final.plant.yaw": "rad",
        "yaw_settling_time_s": "s",
        "peak_abs_tunnel_force_N": "N",
        "events.turn.time": "s",
        "events.turn.set.plant.thrust": "N",
        "overshoot_pct": "%",
        "time_reached": "s",
    }
