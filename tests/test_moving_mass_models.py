"""``scripts/moving_mass_models.py``: the page comparing the two moving-mass models."""

from __future__ import annotations

import re

import numpy as np
import pytest
from repo_paths import script_module

models = script_module("moving_mass_models")


def _run(depth_changes: bool) -> object:
    t = np.linspace(0.0, 30.0, 301)
    columns = {name: 0.01 * np.sin(t) for name in ("plant.yaw", "plant.roll", "plant.w")}
    columns |= {"time": t, "plant.mass_position": 0.02 + 0 * t, "plant.mass_velocity": 0 * t}
    columns |= {"plant.pitch": 0 * t, "plant.down": (0.1 * t if depth_changes else 0 * t)}
    return models.Run(columns)


@pytest.mark.parametrize("depth_changes", [False, True])
def test_each_figure_on_the_page_has_an_alt_text_saying_what_it_shows(
    depth_changes: bool,
) -> None:
    """docs/moving-mass-model.md showed each figure as ``![bs-3](...)``: a screen reader
    read the scenario's id, nothing of what the figure plots."""
    page = models.markdown({"bs-3": {0: _run(depth_changes), 1: _run(depth_changes)}})
    ((alt, name),) = re.findall(r"!\[([^\]]*)\]\(figures/moving-mass/([\w.-]+)\.png\)", page)
    assert alt != name and alt.startswith("bs-3")
    for said in ("yaw (deg)", "roll (deg)", "y_v (cm)", "time (s)", "solid", "dashed"):
        assert said in alt, alt
    assert ("depth (m)" in alt) == depth_changes, alt


def test_a_figures_time_axis_runs_from_0_to_the_stop_time(tmp_path, monkeypatch) -> None:
    """The figures' time axes had matplotlib's margins, from -1.5 s to 31.5 s for a run
    of 30 s: a reader saw time before the start and after the stop."""
    closed = []
    monkeypatch.setattr(models.plt, "close", closed.append)  # the figure kept to look at
    models.plot("bs-3", {0: _run(True), 1: _run(True)}, tmp_path / "bs-3.png")
    (figure,) = closed
    for ax in figure.axes:
        assert ax.get_xlim() == pytest.approx((0.0, 30.0)), ax.get_ylabel()
    assert figure.axes[-1].get_xlabel() == "time (s)"
    monkeypatch.undo()
    models.plt.close(figure)
