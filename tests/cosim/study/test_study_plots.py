"""The study page's figures show what matters: by default the key figures and manoeuvre
metrics (not final values at noise level), the one that varies most first, every axis
with its unit, tick labels without an offset."""

from __future__ import annotations

import errno
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pytest
from chromium import CHROMIUM, overflow
from matplotlib.figure import Figure
from page_structure import problems, read_page

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
         "events.turn.time", "events.turn.set.plant.thrust", "overshoot_pct", "time_reached",
         "fin_angle_variation_rad_per_s"],
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
        "fin_angle_variation_rad_per_s": "rad/s",  # a rate: drawn in deg/s
    }


def _drawn(monkeypatch: pytest.MonkeyPatch) -> list[plt.Figure]:
    """The figures the plotting functions make, kept instead of saved."""
    kept: list[plt.Figure] = []
    monkeypatch.setattr(plots, "_save", lambda fig, path: kept.append(fig) or path)
    return kept


def _panels_of(figure: plt.Figure) -> list:
    return [ax for ax in figure.axes if ax.get_visible()]


SYMMETRIC = {"plant.v_0": [-0.1, 0.1], "controller.k0": [0.2, 0.5, 1.0]}


def _symmetric_rows() -> list[dict]:
    """A vehicle symmetric in v0: +-v0 give the same metrics."""
    return [
        {"plant.v_0": v, "controller.k0": k, "yaw_settling_time_s": 2.0 + 3.0 * k,
         "peak_abs_tunnel_force_N": 5.0 + k, "status": "complete"}
        for v in SYMMETRIC["plant.v_0"] for k in SYMMETRIC["controller.k0"]
    ]  # fmt: skip


def test_coinciding_lines_are_drawn_distinguishable_and_named(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """+-v0 gave equal metrics, and the second line hid the first (same marker, same
    solid line, nothing said)."""
    kept = _drawn(monkeypatch)
    metrics = ["yaw_settling_time_s", "peak_abs_tunnel_force_N"]
    plots.plot_grid_factor(
        _symmetric_rows(), SYMMETRIC, "controller.k0", metrics, tmp_path / "g.png", {}
    )
    for ax in _panels_of(kept[0]):
        styles = {(line.get_marker(), line.get_linestyle(), line.get_markersize())
                  for line in ax.get_lines()}  # fmt: skip
        assert len(styles) == len(ax.get_lines()) == 2, styles
        notes = " ".join(text.get_text().replace("\n", " ") for text in ax.texts)
        assert "plant.v_0 = -0.1 and plant.v_0 = 0.1" in notes, notes
    plt.close(kept[0])


def test_the_note_naming_coinciding_lines_covers_no_point(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The note naming the lines that coincide sat at the top of the panel over the data:
    on the study page's yaw-settling-time panel it was written across the highest point."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    kept = _drawn(monkeypatch)
    metrics = ["yaw_settling_time_s", "peak_abs_tunnel_force_N"]
    # settling faster with a higher gain: each panel's highest point is at its left
    rows = [{**row, "yaw_settling_time_s": 5.0 - 3.0 * row["controller.k0"]}
            for row in _symmetric_rows()]  # fmt: skip
    plots.plot_grid_factor(rows, SYMMETRIC, "controller.k0", metrics, tmp_path / "g.png", {})
    FigureCanvasAgg(kept[0]).draw()
    for ax in _panels_of(kept[0]):
        (note,) = ax.texts
        box = note.get_window_extent()
        for line in ax.get_lines():
            for x, y in ax.transData.transform(line.get_xydata()):
                assert not box.contains(x, y), (ax.get_title(), x, y)
    plt.close(kept[0])


def test_legend_values_carry_the_unit_the_axes_are_drawn_in(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The legend read "events.turn.set.controller.yaw_setpoint = 0.25" (radians, no unit)
    beside axes in degrees, and "plant.v_0 = -0.1" without its m/s."""
    kept = _drawn(monkeypatch)
    setpoint = "events.turn.set.controller.yaw_setpoint"
    grid = {"events.turn.time": [10.0, 20.0], setpoint: [0.25, 0.5], "controller.k0": [0.2, 0.5]}
    rows = [{"events.turn.time": t, setpoint: s, "controller.k0": k, "final.plant.yaw": 2 * s + k,
             "status": "complete"} for t in grid["events.turn.time"] for s in grid[setpoint]
            for k in grid["controller.k0"]]  # fmt: skip
    quantities = {**ANGLES, "events.turn.time": "s", "controller.k0": "1"}
    plots.plot_grid_factor(rows, grid, "events.turn.time", ["final.plant.yaw"],
                           tmp_path / "g.png", quantities)  # fmt: skip
    labels = [text.get_text() for text in _panels_of(kept[0])[0].get_legend().get_texts()]
    assert (
        labels[0] == "controller.yaw_setpoint set by event turn = 14.3239 deg, controller.k0 = 0.2"
    )
    plots.plot_grid_factor(_symmetric_rows(), SYMMETRIC, "controller.k0", ["yaw_settling_time_s"],
                           tmp_path / "g.png", {"plant.v_0": "m/s"})  # fmt: skip
    labels = [text.get_text() for text in _panels_of(kept[1])[0].get_legend().get_texts()]
    assert labels == ["plant.v_0 = -0.1 m/s", "plant.v_0 = 0.1 m/s"]
    for figure in kept:
        plt.close(figure)


def test_the_note_on_coinciding_lines_stays_within_its_panel(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The note ran on in one line across the neighbouring panels (matplotlib's wrap=True
    wraps at the figure's edge), over their titles and lines."""
    kept = _drawn(monkeypatch)
    values = [-0.1, -0.05, 0.05, 0.1]
    grid = {"plant.v_0": values, "controller.k0": [0.2, 0.5]}
    rows = [{"plant.v_0": v, "controller.k0": k, "yaw_settling_time_s": 2.0 + abs(v) + k,
             "peak_abs_tunnel_force_N": 5.0 + abs(v) * k, "peak_abs_mass_position_m": abs(v) + k,
             "status": "complete"} for v in values for k in grid["controller.k0"]]  # fmt: skip
    metrics = ["yaw_settling_time_s", "peak_abs_tunnel_force_N", "peak_abs_mass_position_m"]
    plots.plot_grid_factor(rows, grid, "controller.k0", metrics, tmp_path / "g.png",
                           {"plant.v_0": "m/s"})  # fmt: skip
    figure = kept[0]
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    renderer = FigureCanvasAgg(figure).get_renderer()
    for ax in _panels_of(figure):
        (note,) = ax.texts
        assert "same values" in note.get_text()
        box, panel = note.get_window_extent(renderer), ax.get_window_extent(renderer)
        assert panel.x0 <= box.x0 and box.x1 <= panel.x1, (note.get_text(), box, panel)
    plt.close(figure)


@pytest.mark.parametrize(
    ("values", "failed", "gaps"),
    [
        ([-0.10, -0.05, 0.05, 0.10], None, [(-0.05, 0.05)]),  # no run at v0 = 0
        ([0.0, 0.1, 0.2, 0.3, 1.0], None, [(0.3, 1.0)]),
        ([0.0, 0.1, 0.2, 0.3], 0.2, [(0.1, 0.3)]),  # the run at 0.2 failed
        ([0.0, 0.1, 0.2, 0.3], None, []),
        ([0.25, 0.5, 1.0, 2.0], None, []),  # a geometric grid has no gap
    ],
)
def test_no_line_is_drawn_across_a_gap_in_the_grid(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, values, failed, gaps
) -> None:
    """Lines joined grid points across a gap (v0 = -0.05 to 0.05 over v0 = 0, where no
    run was), as if the metric were known in between."""
    kept = _drawn(monkeypatch)
    rows = [{"plant.v_0": v, "yaw_settling_time_s": None if v == failed else 1.0 + v * v,
             "status": "complete"} for v in values]  # fmt: skip
    grid = {"plant.v_0": values}
    plots.plot_grid_factor(rows, grid, "plant.v_0", ["yaw_settling_time_s"], tmp_path / "g.png", {})
    (line,) = _panels_of(kept[0])[0].get_lines()
    x, y = np.asarray(line.get_xdata(), float), np.asarray(line.get_ydata(), float)
    joined = {(x[i], x[i + 1]) for i in range(len(x) - 1) if np.isfinite(y[i : i + 2]).all()}
    for low, high in gaps:
        assert not any(a <= low and b >= high for a, b in joined), (low, high, joined)
    assert sorted(x[np.isfinite(y)]) == [v for v in values if v != failed]  # every point
    if not gaps:
        assert len(joined) == len(values) - 1  # a regular grid is one line
    plt.close(kept[0])


def test_a_factor_that_is_no_number_gets_points_not_lines(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    kept = _drawn(monkeypatch)
    modes = ["lqr", "sliding-mode", "backstepping"]
    rows = [{"controller.heading_mode": m, "yaw_settling_time_s": float(i), "status": "complete"}
            for i, m in enumerate(modes)]  # fmt: skip
    plots.plot_grid_factor(rows, {"controller.heading_mode": modes}, "controller.heading_mode",
                           ["yaw_settling_time_s"], tmp_path / "g.png", {})  # fmt: skip
    (line,) = _panels_of(kept[0])[0].get_lines()
    assert line.get_linestyle() == "None" and line.get_marker() != "None"
    plt.close(kept[0])


ANGLES = {"events.turn.set.controller.yaw_setpoint": "rad", "final.plant.yaw": "rad",
          "final.plant.r": "rad/s", "peak_abs_tunnel_force_N": "N"}  # fmt: skip


def _turn_rows() -> list[dict]:
    return [
        {"events.turn.set.controller.yaw_setpoint": s, "final.plant.yaw": 0.98 * s + 0.01 * i,
         "final.plant.r": 0.001 * i, "peak_abs_tunnel_force_N": 5 + s, "status": "complete"}
        for i, s in enumerate([0.25, 0.5, 1.0, 0.25, 0.5, 1.0])
    ]  # fmt: skip


def test_angles_are_drawn_in_degrees_on_every_figure(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The study figures drew yaw in radians; the README promises degrees on plots."""
    kept = _drawn(monkeypatch)
    factor = "events.turn.set.controller.yaw_setpoint"
    metrics = ["final.plant.yaw", "final.plant.r", "peak_abs_tunnel_force_N"]
    rows = _turn_rows()
    plots.plot_grid_factor(rows, {factor: [0.25, 0.5, 1.0]}, factor, metrics,
                           tmp_path / "g.png", ANGLES)  # fmt: skip
    yaw, rate, force = _panels_of(kept[0])
    assert yaw.get_xlabel().endswith("[deg]") and yaw.get_ylabel() == "mean of 2 samples [deg]"
    assert rate.get_ylabel().endswith("[deg/s]") and force.get_ylabel().endswith("[N]")
    (line,) = yaw.get_lines()
    assert np.allclose(line.get_xdata(), np.degrees([0.25, 0.5, 1.0]))
    means = [
        np.mean([r["final.plant.yaw"] for r in rows if r[factor] == s]) for s in (0.25, 0.5, 1.0)
    ]
    assert np.allclose(line.get_ydata(), np.degrees(means))
    plots.plot_histograms(rows, ["final.plant.yaw"], tmp_path / "h.png", ANGLES)
    (histogram,) = _panels_of(kept[1])
    assert histogram.get_xlabel() == "[deg]"
    assert histogram.patches and max(p.get_x() + p.get_width() for p in histogram.patches) > 50
    plots.plot_scatter_matrix(rows, [factor, "final.plant.yaw"], tmp_path / "s.png", ANGLES)
    labels = [ax.get_xlabel() for ax in kept[2].axes] + [ax.get_ylabel() for ax in kept[2].axes]
    assert all(text.endswith("[deg]") for text in labels if text not in ("", "runs")), labels
    for figure in kept:
        plt.close(figure)


def test_panel_titles_are_readable_not_metric_ids(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    kept = _drawn(monkeypatch)
    metrics = ["yaw_settling_time_s", "peak_abs_tunnel_force_N"]
    plots.plot_grid_factor(
        _symmetric_rows(), SYMMETRIC, "plant.v_0", metrics, tmp_path / "g.png",
        {"yaw_settling_time_s": "s", "peak_abs_tunnel_force_N": "N"},
    )  # fmt: skip
    titles = [(ax.get_title(), ax.get_ylabel()) for ax in _panels_of(kept[0])]
    assert titles == [("yaw settling time", "[s]"), ("peak |tunnel force|", "[N]")]
    plt.close(kept[0])


def test_the_metrics_not_plotted_are_one_compact_line(tmp_path: Path) -> None:
    """The page listed 36 metric ids in a row ("not plotted"): the final values are now
    counted, their names folded away."""
    from cosim.study.page import write_index

    finals = [f"final.plant.x{i}" for i in range(30)]
    others = ["time_reached", "peak_abs_mass_position_m", "yaw_settling_time_s"]
    page = write_index(tmp_path, {"runs": "4"}, [], {}, [*others, *finals]).read_text()
    (line,) = [text for text in page.splitlines() if text.startswith("<p>Not plotted")]
    visible = line.split("<details")[0]
    assert "30 final values" in line and all(name in visible for name in others)
    assert not any(name in visible for name in finals)


def test_the_coupling_errors_of_final_values_are_folded_too(tmp_path: Path) -> None:
    """With check_step = true the page listed 35 coupling_error.final.<...> ids one by one
    after the folded final values."""
    from cosim.study.page import write_index

    finals = [f"final.plant.x{i}" for i in range(30)]
    errors = [f"coupling_error.{name}" for name in finals]
    others = ["time_reached", "coupling_error.yaw_settling_time_s"]
    page = write_index(tmp_path, {"runs": "4"}, [], {}, [*others, *finals, *errors]).read_text()
    (line,) = [text for text in page.splitlines() if text.startswith("<p>Not plotted")]
    visible = line.split("<details")[0]
    assert "30 final values" in line and "30 coupling errors of final values" in line
    assert all(name in visible for name in others)
    assert not any(name in visible for name in [*finals, *errors])


def test_a_metric_most_runs_never_reached_is_not_called_missing_in_every_run(
    tmp_path: Path,
) -> None:
    """A fault campaign over the fault's time: the heading recovered (a settling time) in
    one run of three. The page put heading_settling_time_s among the metrics "constant or
    missing in every run", hiding that two runs never recovered. The line says how many
    runs gave each metric some runs lacked."""
    from cosim.study.page import write_index

    rows = [
        {"run": "a", "status": "complete", "heading_settling_time_s": None, "time_reached": 20.0},
        {"run": "b", "status": "complete", "heading_settling_time_s": None, "time_reached": 20.0},
        {"run": "c", "status": "complete", "heading_settling_time_s": 2.5, "time_reached": 20.0},
    ]
    names = ["heading_settling_time_s", "time_reached"]
    page = write_index(tmp_path, {"runs": "3"}, rows, {}, names).read_text()
    (line,) = [text for text in page.splitlines() if text.startswith("<p>Not plotted")]
    assert "<code>heading_settling_time_s</code> (given by 1 of 3 runs)" in line, line
    assert "<code>time_reached</code>." in line, line  # every run gave it: nothing added
    assert "missing in every run" not in line, line


def test_the_not_plotted_sentence_reads_whole_around_its_folded_lists(tmp_path: Path) -> None:
    """The folded list of final values was a <details> inside the sentence's <p>: a browser
    ends the paragraph there, so the page read "Not plotted: time_reached," and, below the
    folded list, a line beginning ". (Constant or missing in every run ...)"."""
    from cosim.study.page import write_index

    finals = [f"final.plant.x{i}" for i in range(30)]
    page = write_index(tmp_path, {"runs": "4"}, [], {}, ["time_reached", *finals]).read_text()
    assert problems(page) == []
    (line,) = [text for text in page.splitlines() if text.startswith("<p>Not plotted")]
    assert line.endswith("every value is in runs.csv.)</p>"), line
    assert "30 final values" in line and "final.plant.x0" not in line
    assert "final.plant.x0, final.plant.x1" in page  # folded below, one click away


def test_the_scatter_matrix_counts_runs_on_an_axis_of_its_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The histograms on the scatter matrix's diagonal drew their counts on the axis the
    row's variable labels: the top-left panel read "plant.current_east [m/s]" beside ticks
    0.0 to 1.0 that were numbers of runs."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    kept = _drawn(monkeypatch)
    rng = np.random.default_rng(1)
    rows = [
        {"plant.current_east": c, "yaw_settling_time_s": t, "status": "complete"}
        for c, t in zip(rng.uniform(0.0, 0.3, 12), rng.uniform(5.0, 9.0, 12), strict=True)
    ]
    names = ["plant.current_east", "yaw_settling_time_s"]
    quantities = {"plant.current_east": "m/s", "yaw_settling_time_s": "s"}
    plots.plot_scatter_matrix(rows, names, tmp_path / "s.png", quantities)
    axes = kept[0].axes
    histograms = [ax for ax in axes if ax.patches]
    assert len(histograms) == 2
    FigureCanvasAgg(kept[0]).draw()
    for ax in histograms:
        assert ax.get_ylabel() == "runs" and ax.yaxis.get_label_position() == "right"
        assert ax.yaxis.label.get_window_extent().x1 <= kept[0].bbox.x1  # not cut off
    (row_label,) = [ax for ax in axes if ax.get_ylabel() == "plant.current_east [m/s]"]
    assert not row_label.patches and len(row_label.get_yticks()) == 0  # no counts beside it
    plt.close(kept[0])


UNITS_N = {"plant.v_0": "m/s", "peak_abs_tunnel_force_N": "N"}


def test_a_grid_figure_of_means_over_samples_says_so_on_its_axis(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With random factors beside the grid, each point is the mean over the samples, but
    the axis read "[N]" as for one run: the figure's numbers matched no row of runs.csv."""
    kept = _drawn(monkeypatch)
    grid = {"plant.v_0": [-0.1, 0.1]}
    rows = [{"plant.v_0": v, "peak_abs_tunnel_force_N": f, "status": "complete"}
            for v in grid["plant.v_0"] for f in (8.0, 9.0, 10.0)]  # fmt: skip
    metric = ["peak_abs_tunnel_force_N"]
    plots.plot_grid_factor(rows, grid, "plant.v_0", metric, tmp_path / "g.png", UNITS_N)
    (panel,) = _panels_of(kept[0])
    assert panel.get_ylabel() == "mean of 3 samples [N]"
    assert list(panel.get_lines()[0].get_ydata()) == [9.0, 9.0]
    plots.plot_grid_factor(rows[::3], grid, "plant.v_0", metric, tmp_path / "g.png", UNITS_N)
    assert _panels_of(kept[1])[0].get_ylabel() == "[N]"  # one run per point: no mean
    for figure in kept:
        plt.close(figure)


def test_a_mean_over_samples_counts_only_the_samples_that_gave_the_metric(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A failed sample (no metrics) or one whose figure does not exist drops out of its
    point's mean, but the axis still read "mean of 4 samples" for a point averaged over
    two: a reader took a mean of fewer runs for one of the full Monte Carlo size."""
    kept = _drawn(monkeypatch)
    grid = {"plant.v_0": [-0.1, 0.1]}
    forces = {-0.1: [8.0, 9.0, 10.0, 11.0], 0.1: [8.0, None, 10.0, None]}
    rows = [{"plant.v_0": v, "peak_abs_tunnel_force_N": f,
             "status": "failed" if f is None else "complete"}
            for v in grid["plant.v_0"] for f in forces[v]]  # fmt: skip
    metric = ["peak_abs_tunnel_force_N"]
    plots.plot_grid_factor(rows, grid, "plant.v_0", metric, tmp_path / "g.png", UNITS_N)
    (panel,) = _panels_of(kept[0])
    assert list(panel.get_lines()[0].get_ydata()) == [9.5, 9.0]
    assert panel.get_ylabel() == "mean of 2 to 4 samples [N]"
    alts = plots.figure_alts(rows, grid, ["plant.current_east"], metric, UNITS_N)
    assert "the mean over the samples at that grid point that gave it" in str(alts)
    for figure in kept:
        plt.close(figure)


@pytest.mark.parametrize(
    ("name", "shown"),
    [
        # Latin-1: the byte 0xff, read as the surrogate U+DCFF
        ("study-\udcff", "study-\\xff"),
        # Stüdie's UTF-8 bytes as Python holds them where it reads names as ASCII
        # (LC_ALL=C, PYTHONUTF8=0): the page said "Study St\\udcc3\\udcbcdie"
        ("St\udcc3\udcbcdie", "Stüdie"),
    ],
)
def test_a_study_folder_named_in_bytes_not_utf8_gets_its_page(
    tmp_path: Path, name: str, shown: str
) -> None:
    """The page's title names the study folder; one named in Latin-1 failed the study at
    its end, "UnicodeEncodeError". The name is written as its bytes read as UTF-8."""
    from cosim.study.page import write_index

    folder = tmp_path / name
    folder.mkdir()
    page = write_index(folder, {"runs": "4"}, [], {}, ["time_reached"])
    assert f"<h1>Study {shown}</h1>" in page.read_text(encoding="utf-8")


def test_the_study_page_reads_to_a_screen_reader(tmp_path: Path) -> None:
    """The summary table had no caption and its header cells no scope; the failed runs
    are a list under their own heading, not a colour."""
    from cosim.study.page import write_index

    (tmp_path / "figures").mkdir()
    figure = tmp_path / "figures" / "grid_plant.v_0.png"
    failed = {"run": "0003", "status": "failed", "error": "step failed at t = 1.2 s"}
    facts = {"scenario": "bs-3", "runs": "2: 1 complete, 1 failed"}
    rows = [{"run": "0002", "status": "complete", "error": ""}, failed]
    page = write_index(tmp_path, facts, rows, {"Metrics against plant.v_0": figure}, []).read_text()
    assert problems(page) == []
    (table,) = read_page(page).tables
    assert table.scopes == ["row", "row"] and table.caption
    assert "<h2>Failed runs</h2>" in page and "0003</code>: step failed at t = 1.2 s" in page


def test_each_study_figure_has_an_alt_text_naming_its_metrics_and_units(tmp_path: Path) -> None:
    """A study figure's alt text was its title, "Metrics against plant.v_0": a screen
    reader never heard which metrics the panels plot, nor in what units."""
    from cosim.study.page import write_index

    quantities = {"plant.v_0": "m/s", "controller.k0": "1/s", "yaw_settling_time_s": "s",
                  "peak_abs_tunnel_force_N": "N"}  # fmt: skip
    grid = {"plant.v_0": V0, "controller.k0": [0.2]}
    table = [{**row, "controller.k0": 0.2} for row in rows()]
    candidates = plots.default_metrics(METRICS)
    figures = plots.write_figures(table, grid, [], candidates, tmp_path / "figures", quantities)
    alts = plots.figure_alts(table, grid, [], candidates, quantities)
    page = write_index(tmp_path, {"runs": "4"}, table, figures, [], alts).read_text()
    assert problems(page) == []
    shown = dict(read_page(page).images)
    alt = shown["figures/grid_plant.v_0.png"]
    for said in ("peak |tunnel force| [N]", "yaw settling time [s]", "plant.v_0 [m/s]"):
        assert said in alt, alt
    assert "a line per value of controller.k0" in alt, alt


@pytest.mark.slow
@pytest.mark.viewer  # starts a browser
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt, .ci/run)")
def test_a_long_study_folder_name_does_not_make_a_phone_scroll_sideways(tmp_path: Path) -> None:
    """The page's heading names the study folder: one long word such as
    survey_current_sweep_over_the_cross_current_speed ran past a 375 px window."""
    from cosim.study.page import write_index

    pytest.importorskip("playwright.sync_api", reason="needs playwright (test extra)")
    folder = tmp_path / "survey_current_sweep_over_the_cross_current_speed"
    folder.mkdir()
    page = write_index(folder, {"runs": "4"}, [], {}, ["time_reached"])
    (tmp_path / "profile").mkdir()
    assert overflow(page, tmp_path / "profile") == []


def test_each_study_figure_names_its_study_in_a_title_clear_of_the_panels(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study figure lifted out of its page said neither which study nor which scenario
    it plots: each now has a title naming them, above its panels' titles, not on them."""
    kept = _drawn(monkeypatch)
    quantities = {"plant.v_0": "m/s", "yaw_settling_time_s": "s", "final.plant.u": "m/s",
                  "peak_abs_tunnel_force_N": "N"}  # fmt: skip
    candidates = plots.default_metrics(METRICS)
    plots.write_figures(rows(), {"plant.v_0": V0}, ["final.plant.u"], candidates,
                        tmp_path, quantities, caption="study demo (bs-3)")  # fmt: skip
    assert len(kept) == 3  # the grid figure, the histograms, the scatter matrix
    for figure in kept:
        text = figure.get_suptitle()
        assert "study demo (bs-3)" in text, text
        figure.draw_without_rendering()
        box = figure._suptitle.get_window_extent()
        assert box.y1 <= figure.bbox.y1, text  # inside the figure
        for ax in _panels_of(figure):
            assert box.y0 >= ax.title.get_window_extent().y1 - 0.5, text
            assert box.y0 >= ax.get_tightbbox().y1 - 0.5, text
        plt.close(figure)


def test_each_panel_title_sits_just_above_its_panel_clear_of_its_tick_labels(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A panel's title is placed at the panel's top by the figures themselves, not moved
    by matplotlib at each draw (it looked for tick labels above the panel, which there are
    none, at ~15 % of a figure's drawing): it must still sit just above the panel's frame,
    over none of its tick labels, on the grid figure and on the histograms."""
    kept = _drawn(monkeypatch)
    plots.write_figures(rows(), {"plant.v_0": V0}, ["final.plant.u"],
                        plots.default_metrics(METRICS), tmp_path, {})  # fmt: skip
    titled = [ax for figure in kept for ax in _panels_of(figure) if ax.get_title()]
    assert len(titled) >= 4  # two panels of the grid figure, two histograms
    for ax in titled:
        ax.figure.draw_without_rendering()
        title = ax.title.get_window_extent()
        frame = ax.bbox
        assert frame.y1 <= title.y0 <= frame.y1 + 12, (ax.get_title(), title, frame)
        for label in [*ax.get_xticklabels(), *ax.get_yticklabels()]:
            if label.get_visible() and label.get_text():
                box = label.get_window_extent()
                assert not box.overlaps(title), (ax.get_title(), label.get_text())


def _disk_fills_after_a_part(path_of: Callable[..., Any]) -> Callable[..., Any]:
    """A write method that leaves part of its file (``path_of`` its arguments), then
    fails as a full disk does."""

    def full(*args: Any, **kwargs: Any) -> Any:
        Path(path_of(*args)).write_bytes(b"\x89PNG a part")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    return full


def test_a_figure_the_disk_cannot_hold_is_named_and_leaves_no_part(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study's figure that filled the disk left a half PNG and ended the study with
    "cannot write the study's results: No space left on device", naming no file."""
    monkeypatch.setattr(Figure, "savefig", _disk_fills_after_a_part(lambda fig, fname: fname))
    path = tmp_path / "figure.png"
    with pytest.raises(OSError) as raised:
        plots._save(Figure(), path)
    assert (raised.value.errno, raised.value.filename) == (errno.ENOSPC, str(path))
    assert list(tmp_path.iterdir()) == []


def test_an_index_page_the_disk_cannot_hold_is_named_and_leaves_no_part(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study's index.html that filled the disk was left half written."""
    from cosim.study.page import write_index

    monkeypatch.setattr(Path, "write_text", _disk_fills_after_a_part(lambda path, text: path))
    with pytest.raises(OSError) as raised:
        write_index(tmp_path, {"runs": "1"}, [], {}, [])
    assert (raised.value.errno, raised.value.filename) == (
        errno.ENOSPC,
        str(tmp_path / "index.html"),
    )
    assert list(tmp_path.iterdir()) == []


def test_a_study_page_draws_no_command_activity_unless_collected() -> None:
    """The commands' total variation per second is in runs.csv but not drawn by default
    (a page of the figures it drew before); the mark plots matches agrees with the key
    figures' names, every other key figure still drawn."""
    from cosim.metrics.key_figures import _COLUMNS as FIGURE_COLUMNS
    from cosim.metrics.key_figures import ACTIVITY_FIGURES

    named = [*FIGURE_COLUMNS, *(f"plant_b.{name}" for name in FIGURE_COLUMNS)]
    drawn = plots.default_metrics(named)
    assert not set(drawn) & {*ACTIVITY_FIGURES, *(f"plant_b.{a}" for a in ACTIVITY_FIGURES)}
    assert len(drawn) == len(named) - 2 * len(ACTIVITY_FIGURES)
