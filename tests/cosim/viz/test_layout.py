"""The recording's default layout leaves the time-series plots room for y ticks, and a
study overlay does not print every run's label over the others at the common start."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rerun.blueprint as rrb

from cosim.viz.layout import PANELS, build_blueprint, plan_panels

MAX_STACKED = 3  # plots in one column of a loop: more leave one y tick ("0") each


def _loops(container) -> list:
    """Every container holding time-series views, depth first."""
    found = []
    for item in container.contents or []:
        if isinstance(item, rrb.TimeSeriesView):
            found.append(container)
        elif hasattr(item, "contents"):
            found += _loops(item)
    return list({id(c): c for c in found}.values())


def test_no_loop_stacks_more_than_three_plots_in_a_column() -> None:
    columns = [s.column for panel in PANELS for s in panel.series]
    blueprint = build_blueprint(plan_panels(columns), depth_control=True)
    loops = _loops(blueprint.root_container)
    assert {loop.name for loop in loops} >= {"Heading loop", "Depth loop", "Vehicle"}
    for loop in loops:
        plots = sum(isinstance(item, rrb.TimeSeriesView) for item in loop.contents)
        per_column = plots if loop.grid_columns is None else math.ceil(plots / loop.grid_columns)
        assert per_column <= MAX_STACKED, (loop.name, plots, loop.grid_columns)


def test_overlay_paths_do_not_print_their_labels(tmp_path: Path) -> None:
    from rerun.chunk import RrdReader

    from cosim.viz.overlay import OverlayRun, write_overlay

    t = np.linspace(0.0, 1.0, 11)
    runs = [
        OverlayRun(
            f"run{k}",
            f"run{k}: v_0 = {k}",
            {
                "time": t,
                "plant.north": t,
                "plant.east": k * t,
                "plant.down": 0 * t,
                "plant.yaw": 0 * t,
                "plant.roll": 0 * t,
            },
        )
        for k in range(3)
    ]
    path = write_overlay(tmp_path / "overlay.rrd", runs, "study", "notes")
    shown = []
    for chunk in RrdReader(path).stream():
        batch = chunk.to_record_batch()
        shown += [c for c in batch.schema.names if c.endswith("show_labels")]
        for name in batch.schema.names:
            if name.endswith("show_labels"):
                assert batch.column(name).to_pylist() == [[False]]
    assert shown, "the paths say nothing about their labels"
