"""The study's figures (matplotlib figures drawn without pyplot, so a notebook's
backend is left alone), from the sorted table rows.

* ``grid_<factor>.png`` for each grid factor: every metric against that factor (one
  panel per metric), one line per combination of the other grid factors; with random
  factors as well, each point is the mean over the samples at that grid point that have
  the metric (a settling time never reached has none, nor has a failed run), and the
  axis says over how many ("mean of 3 to 4 samples" where some had none).
* ``histograms.png`` (Monte Carlo): the distribution of every metric over the samples.
* ``scatter_matrix.png`` (Monte Carlo): the random factors and the first metrics against
  each other (histograms on the diagonal), at most :data:`SCATTER_MAX` variables.

Each line of a grid figure has its own marker and dash and is labelled with the other
factors' values in the units the axes use (angles in degrees), and lines that coincide
(the same value at every point: +-v0 of a symmetric vehicle) are named in a note wrapped
to the panel's width, so none hides another; a line is not drawn across a gap in the
grid (a missing point, or a step over 1.5 times the grid's smallest one) nor between the
values of a factor that is not a number. Titles are readable
(:func:`cosim.study.units.title`) and angles are drawn in degrees
(:func:`cosim.study.units.shown`).

Only metrics with at least two distinct finite values are drawn (a constant or missing
metric is a line on the index page instead), the one that varies most first (its range
over the largest magnitude it takes: a final value at noise level comes last), at most
:data:`PANELS_MAX`; failed runs have no metrics and drop out. The study chooses which
metrics are candidates (:func:`default_metrics` when ``[metrics]`` lists none). Every
axis is labelled with its unit and its tick labels are plain numbers (no offset such as
``1e-5+1.5249``, which reads as a different number).
"""

from __future__ import annotations

import itertools
import math
import textwrap
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from cosim.study.units import DIMENSIONLESS, shown, title
from cosim.whole_file import write_whole

if TYPE_CHECKING:  # matplotlib is imported where a figure is drawn (~0.35 s, at the end)
    from matplotlib.figure import Figure

PANEL_COLUMNS = 4
PANEL_SIZE_IN = (3.4, 2.6)
XTICKS_MAX = 5  # grid values labelled one by one up to this many
PANELS_MAX = 12  # metrics drawn per figure (matplotlib takes ~0.1-0.3 s per panel)
SCATTER_MAX = 5  # variables in the scatter matrix (5 x 5 panels)
HISTOGRAM_BINS = 20
DPI = 100
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*")  # one per line of a grid figure
DASHES = ("-", "--", ":", "-.")
GAP_FACTOR = 1.5  # a grid step over this many times the smallest one is a gap: no line
NOTE_FONT_PT = 6  # the note naming lines that coincide
TITLE_IN = 0.35  # the height a figure's title takes above its panels, inches
NOTE_CHAR_EM = 0.6  # a character's mean width in DejaVu Sans, in em (wide, to fit)
Row = Mapping[str, Any]


# the mark of cosim.metrics.key_figures.ACTIVITY_FIGURES' names, matched here without
# importing that module into the command's process (tests check the two agree)
ACTIVITY_MARK = "_variation_"


def default_metrics(metrics: Sequence[str]) -> list[str]:
    """The metrics a study plots unless ``[metrics] collect`` names some: the key figures
    and the manoeuvre metrics, not ``time_reached``, the final values or the commands'
    activity (their total variation per second: in runs.csv, drawn where ``collect`` names
    them; a page of the figures it drew before, and no panel more to draw by default)."""
    return [
        m
        for m in metrics
        if m != "time_reached"
        and not m.startswith("final.")
        and ACTIVITY_MARK not in m.rsplit(".", 1)[-1]
    ]


def plotted_metrics(rows: Sequence[Row], metrics: Sequence[str]) -> list[str]:
    """The metrics drawn: those with two distinct finite values or more, the one that
    varies most (:func:`variation`) first, at most PANELS_MAX."""
    spread = {}
    for name in metrics:
        values = _floats(rows, name)
        finite = values[np.isfinite(values)]
        if finite.size and np.unique(finite).size > 1:
            spread[name] = variation(finite)
    return sorted(spread, key=lambda name: -spread[name])[:PANELS_MAX]


def variation(values: np.ndarray) -> float:
    """How much finite ``values`` vary: their range over the largest magnitude among
    them (1 or more for values of both signs, ~1e-5 for noise on a constant)."""
    scale = float(np.max(np.abs(values)))
    return float(np.ptp(values)) / scale if scale > 0 else 0.0


def axis_label(name: str, units: Mapping[str, str]) -> str:
    """An axis label: the quantity's title and the unit it is drawn in, "title [unit]"."""
    return f"{title(name)} [{shown(name, units)[1]}]"


def value_label(name: str, value: Any, units: Mapping[str, str]) -> str:
    """A factor's value as a legend shows it: its title, and the value in the unit its
    axis is drawn in, with that unit ("plant.v_0 = -0.1 m/s", a yaw set-point in deg like
    the axes beside it); a value that is no number as it is, a dimensionless one bare."""
    if not _is_number(value):
        return f"{title(name)} = {value}"
    scale, unit = shown(name, units)
    suffix = "" if unit == DIMENSIONLESS else f" {unit}"
    return f"{title(name)} = {value * scale:.6g}{suffix}"


GRID_TITLE = "Metrics against {}"  # each grid factor's figure
HISTOGRAMS_TITLE = "Distributions over the samples"
SCATTER_TITLE = "Scatter matrix"


def figure_alts(
    rows: Sequence[Row],
    grid: Mapping[str, Sequence[Any]],
    random_factors: Sequence[str],
    metrics: Sequence[str],
    units: Mapping[str, str],
) -> dict[str, str]:
    """The alt text of each figure :func:`write_figures` draws from the same arguments
    (title -> text): which metrics its panels plot against what, each with its unit."""
    shown = plotted_metrics(rows, metrics)
    if not shown:
        return {}
    panels = "; ".join(axis_label(metric, units) for metric in shown)
    means = (
        ", each point the mean over the samples at that grid point that gave it"
        if random_factors
        else ""
    )
    alts = {}
    for factor in grid:
        others = [name for name in grid if name != factor]
        lines = f", a line per value of {' and '.join(others)}" if others else ""
        alts[GRID_TITLE.format(factor)] = (
            f"One panel per metric ({panels}) against {axis_label(factor, units)}{lines}{means}"
        )
    if random_factors:
        alts[HISTOGRAMS_TITLE] = f"Histograms of the runs over each metric: {panels}"
        variables = [*random_factors, *shown][:SCATTER_MAX]
        alts[SCATTER_TITLE] = (
            f"Each pair of {'; '.join(axis_label(v, units) for v in variables)} plotted "
            "against each other, their histograms on the diagonal"
        )
    return alts


def write_figures(
    rows: Sequence[Row],
    grid: Mapping[str, Sequence[Any]],
    random_factors: Sequence[str],
    metrics: Sequence[str],
    folder: Path,
    units: Mapping[str, str],
    caption: str = "",
    drafts: Drafts | None = None,
) -> dict[str, Path]:
    """Every figure of the study into ``folder``; returns title -> path. ``units``: the
    unit of each factor and metric (:mod:`cosim.study.units`); ``caption``: what was run
    (the study and its scenario), put before each figure's title above its panels, so that
    a figure lifted out of the page still says what it plots; ``drafts``: figures made
    ready before the last run (:func:`draft_figures`), each used where it fits."""
    folder.mkdir(parents=True, exist_ok=True)
    shown = plotted_metrics(rows, metrics)
    figures: dict[str, Path] = {}
    if not shown:
        return figures
    for factor in grid:
        path = folder / f"grid_{_file_safe(factor)}.png"
        figures[GRID_TITLE.format(factor)] = plot_grid_factor(
            rows, grid, factor, shown, path, units, _titled(caption, GRID_TITLE.format(factor)),
            drafts,
        )  # fmt: skip
    if random_factors:
        figures[HISTOGRAMS_TITLE] = plot_histograms(
            rows, shown, folder / "histograms.png", units, _titled(caption, HISTOGRAMS_TITLE),
            drafts,
        )  # fmt: skip
        variables = [*random_factors, *shown][:SCATTER_MAX]
        figures[SCATTER_TITLE] = plot_scatter_matrix(
            rows, variables, folder / "scatter_matrix.png", units, _titled(caption, SCATTER_TITLE)
        )
    return figures


def _titled(caption: str, name: str) -> str:
    """A figure's title: what was run, then what the figure shows ("" without a caption)."""
    return f"{caption}: {name}" if caption else ""


# ticks made ahead on each axis of a draft beyond the number its length holds: the y axes
# of the benchmark's page drew 9 where get_tick_space said 8 (a tick past each end)
EXTRA_TICKS = 2


class Drafts:
    """Figures of panels made ready before the last rows are in (:func:`draft_figures`),
    by their number of panels and title, each taken once by the figure that fits it. A
    draft holds what a figure's drawing does not take from the rows: the figure, its
    panels and their settings (:func:`_new_panels`) and each axis's tick objects, which
    matplotlib otherwise makes at the first draw, as many as it draws (~1 ms each, a
    third of drawing the benchmark's page); made after the axis's tick settings, they
    are the ticks the draw would make, given their places and labels as it draws, and
    those beyond what it draws stay undrawn: the PNG is the same, byte for byte."""

    def __init__(self) -> None:
        self._figures: dict[tuple[int, str], tuple[Figure, list[Any]]] = {}

    def add(self, n: int, figure_title: str) -> None:
        """Make a figure of ``n`` panels titled ``figure_title`` ready, with its ticks."""
        fig, axes = _new_panels(n, figure_title)
        for ax in axes:
            for axis in (ax.xaxis, ax.yaxis):
                axis.get_major_ticks(axis.get_tick_space() + EXTRA_TICKS)
        self._figures[(n, figure_title)] = (fig, axes)

    def take(self, n: int, figure_title: str) -> tuple[Figure, list[Any]] | None:
        """The draft of ``n`` panels titled ``figure_title`` (then no longer held), if any."""
        return self._figures.pop((n, figure_title), None)

    def __len__(self) -> int:
        """How many drafts are held, not yet taken."""
        return len(self._figures)


def draft_figures(
    rows: Sequence[Row],
    grid: Mapping[str, Sequence[Any]],
    random_factors: Sequence[str],
    metrics: Sequence[str],
    caption: str = "",
) -> Drafts:
    """Drafts of the figures :func:`write_figures` draws from the same arguments, for the
    metrics the ``rows`` so far plot: a row more can only add a metric (two distinct
    values stay two), so the last rows rarely change them, and a draft that no longer
    fits is left unused. Each grid factor's figure and the histograms; the scatter
    matrix, a figure of its own making, is not drafted."""
    drafts = Drafts()
    shown = plotted_metrics(rows, metrics)
    if shown:
        for factor in grid:
            drafts.add(len(shown), _titled(caption, GRID_TITLE.format(factor)))
        if random_factors:
            drafts.add(len(shown), _titled(caption, HISTOGRAMS_TITLE))
    return drafts


def plot_grid_factor(
    rows: Sequence[Row],
    grid: Mapping[str, Sequence[Any]],
    factor: str,
    metrics: Sequence[str],
    path: Path,
    units: Mapping[str, str],
    figure_title: str = "",
    drafts: Drafts | None = None,
) -> Path:
    """Each metric against ``factor``: a line per combination of the other grid factors,
    the mean over the runs sharing a grid point (the Monte Carlo samples, if any); with
    ``figure_title`` above the panels (in a figure of ``drafts`` if one fits)."""
    others = [name for name in grid if name != factor]
    x_values = list(grid[factor])
    numeric = all(_is_number(v) for v in x_values)
    scale = shown(factor, units)[0] if numeric else 1.0
    x = np.asarray(x_values, dtype=float) * scale if numeric else np.arange(len(x_values))
    by_point: dict[tuple[Any, ...], list[Row]] = {}
    for row in rows:
        by_point.setdefault(tuple(row[name] for name in grid), []).append(row)
    fig, axes = _panels(len(metrics), figure_title, drafts)
    lines: dict[str, list[tuple[str, np.ndarray]]] = {metric: [] for metric in metrics}
    counts: dict[str, list[int]] = {metric: [] for metric in metrics}
    for k, combo in enumerate(itertools.product(*(grid[name] for name in others))):
        fixed = dict(zip(others, combo, strict=True))
        label = ", ".join(value_label(name, value, units) for name, value in fixed.items())
        points = [
            by_point.get(tuple({**fixed, factor: value}[name] for name in grid), [])
            for value in x_values
        ]
        style = {"marker": MARKERS[k % len(MARKERS)], "markersize": max(7 - 1.5 * k, 3),
                 "linestyle": DASHES[k % len(DASHES)] if numeric else "none"}  # fmt: skip
        for ax, metric in zip(axes, metrics, strict=False):
            y = np.asarray([_mean(point, metric) for point in points]) * shown(metric, units)[0]
            ax.plot(*_broken_at_gaps(x, y, numeric), label=label or None, **style)
            lines[metric].append((label, y))
            counts[metric] += [_count(point, metric) for point in points]
    samples = max(len(point_rows) for point_rows in by_point.values())
    for ax, metric in zip(axes, metrics, strict=False):
        averaged = counts[metric] if samples > 1 else []
        _label_panel(ax, metric, factor, units, lines[metric], averaged)
        if not numeric or len(x_values) <= XTICKS_MAX:
            ax.set_xticks(x, [f"{v * scale:g}" if numeric else str(v) for v in x_values])
        else:
            from matplotlib.ticker import MaxNLocator

            ax.xaxis.set_major_locator(MaxNLocator(nbins=XTICKS_MAX))
    if others:
        axes[0].legend(fontsize=7)
    return _save(fig, path)


def _label_panel(
    ax: Any,
    metric: str,
    factor: str,
    units: Mapping[str, str],
    lines: Sequence[tuple[str, np.ndarray]],
    averaged: Sequence[int],
) -> None:
    """Title, axis labels (``averaged``: how many Monte Carlo samples gave the metric at
    each point, empty for one run per point: the points are means over those, and the
    axis says how many), and a note naming the lines that coincide."""
    _panel_title(ax, title(metric))
    ax.set_xlabel(axis_label(factor, units), fontsize=8)
    ax.set_ylabel(f"{_mean_of(averaged)}[{shown(metric, units)[1]}]", fontsize=8)
    same = coinciding(lines)
    if same:
        note = "; ".join(" and ".join(group) for group in same)
        text = _wrapped(f"same values: {note}", ax, NOTE_FONT_PT)
        ax.text(0.02, 0.97, text, transform=ax.transAxes, fontsize=NOTE_FONT_PT, va="top")
        _headroom(ax, text.count("\n") + 1)


def _panel_title(ax: Any, text: str) -> None:
    """``text`` above panel ``ax``, at the panel's top (``y=1``, where matplotlib puts it).
    Given, not left to matplotlib: on its own it looks for tick labels above the panel at
    every draw, laying out the y axis's ticks once more (~15 % of drawing a grid figure),
    and there are none (ticks at the bottom, no offset text: :func:`_plain_ticks`)."""
    ax.set_title(text, fontsize=9, y=1.0)


def _headroom(ax: Any, note_lines: int) -> None:
    """Raise the top of panel ``ax``'s y axis so that its data sits below a note of
    ``note_lines`` lines at its top (the note was written across the highest points)."""
    height_pt = ax.get_position().height * ax.figure.get_figheight() * 72
    # the note starts 3 % below the top; a line is about 1.2 font sizes, plus a gap
    band = min(0.03 + (note_lines * 1.2 * NOTE_FONT_PT + 4) / height_pt, 0.6)
    bottom, top = ax.get_ylim()
    ax.set_ylim(bottom, bottom + (top - bottom) / (1 - band))


def _mean_of(averaged: Sequence[int]) -> str:
    """ "mean of n samples " (or "mean of n1 to n2 samples " where failed runs and
    missing figures left fewer at some points) for the points of a panel, each the mean
    of ``averaged[i]`` values; "" for no mean (one run per point)."""
    counted = [count for count in averaged if count > 0]
    if not counted:
        return ""
    low, high = min(counted), max(counted)
    if low == high:
        return f"mean of {low} sample{'s' if low > 1 else ''} "
    return f"mean of {low} to {high} samples "


def _wrapped(text: str, ax: Any, font_pt: float) -> str:
    """``text`` broken into lines that fit the width of panel ``ax`` (matplotlib's own
    ``wrap=True`` wraps at the figure's edge: a note ran on across the next panels)."""
    width_in = ax.get_position().width * ax.figure.get_figwidth()
    chars = max(20, int(width_in * 72 / (NOTE_CHAR_EM * font_pt)))
    return textwrap.fill(text, width=chars, break_on_hyphens=False)


def coinciding(lines: Sequence[tuple[str, np.ndarray]]) -> list[list[str]]:
    """Groups of line labels whose values are equal at every point (NaN where NaN): on a
    plot, the later ones hide the first."""
    groups: list[list[str]] = []
    firsts: list[np.ndarray] = []
    for label, y in lines:
        for group, first in zip(groups, firsts, strict=True):
            if np.allclose(y, first, rtol=1e-9, atol=0.0, equal_nan=True):
                group.append(label)
                break
        else:
            groups.append([label])
            firsts.append(y)
    return [group for group in groups if len(group) > 1]


def _broken_at_gaps(x: np.ndarray, y: np.ndarray, numeric: bool) -> tuple[np.ndarray, np.ndarray]:
    """``x``, ``y`` with a NaN between neighbours across a gap of the grid, so the line
    breaks there; unchanged for a factor that is no number (drawn without lines). A gap
    is a step over GAP_FACTOR times the grid's smallest, on a linear scale and, for a grid
    of positive values, on a logarithmic one too (0.25, 0.5, 1 has none)."""
    if not numeric or x.size < 3:
        return x, y
    gaps = _wide_steps(x)
    if np.all(x > 0):
        gaps &= _wide_steps(np.log(x))
    at = np.flatnonzero(gaps) + 1
    return np.insert(x, at, np.nan), np.insert(y, at, np.nan)


def _wide_steps(x: np.ndarray) -> np.ndarray:
    """Which steps of the sorted grid ``x`` exceed GAP_FACTOR times the smallest one."""
    steps = np.abs(np.diff(x))
    positive = steps[steps > 0]
    if positive.size == 0:
        return np.zeros(steps.shape, dtype=bool)
    return steps > GAP_FACTOR * np.min(positive)


def plot_histograms(
    rows: Sequence[Row],
    metrics: Sequence[str],
    path: Path,
    units: Mapping[str, str],
    figure_title: str = "",
    drafts: Drafts | None = None,
) -> Path:
    """One histogram per metric over every completed run; ``figure_title`` above them (in
    a figure of ``drafts`` if one fits)."""
    fig, axes = _panels(len(metrics), figure_title, drafts)
    for ax, metric in zip(axes, metrics, strict=False):
        scale, unit = shown(metric, units)
        values = _floats(rows, metric) * scale
        ax.hist(values[np.isfinite(values)], bins=HISTOGRAM_BINS)
        _panel_title(ax, title(metric))
        ax.set_xlabel(f"[{unit}]", fontsize=8)
        ax.set_ylabel("runs", fontsize=8)
    return _save(fig, path)


def plot_scatter_matrix(
    rows: Sequence[Row],
    variables: Sequence[str],
    path: Path,
    units: Mapping[str, str],
    figure_title: str = "",
) -> Path:
    """Every pair of ``variables`` as a scatter plot, histograms on the diagonal (their
    counts of runs on an axis of their own, at the right: the left one is the row's
    variable); ``figure_title`` above them."""
    n = len(variables)
    data = {name: _floats(rows, name) * shown(name, units)[0] for name in variables}
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2.2 * n, 2.2 * n + (TITLE_IN if figure_title else 0.0)))
    axes = fig.subplots(n, n, squeeze=False)
    _margins(fig, figure_title)
    fig.subplots_adjust(right=1 - 0.45 / fig.get_size_inches()[0])  # the last column's counts
    for (i, row_name), (j, col_name) in itertools.product(enumerate(variables), repeat=2):
        ax = axes[i][j]
        if i == j:
            _counts(ax, data[row_name])
        else:
            ax.scatter(data[col_name], data[row_name], s=6)
        if i == n - 1:
            ax.set_xlabel(
                axis_label(title(col_name), {title(col_name): units.get(col_name, "1")}), fontsize=7
            )
        if j == 0:
            ax.set_ylabel(
                axis_label(title(row_name), {title(row_name): units.get(row_name, "1")}), fontsize=7
            )
        ax.tick_params(labelsize=6)
        _plain_ticks(ax)
    return _save(fig, path)


def _counts(ax: Any, values: np.ndarray) -> None:
    """A histogram of ``values`` in the panel ``ax`` whose left axis belongs to its row's
    variable: the counts go on a twin axis at the right, labelled ``runs``, and the left
    axis shows no tick."""
    from matplotlib.ticker import MaxNLocator

    ax.set_yticks([])
    counts = ax.twinx()
    counts.hist(values[np.isfinite(values)], bins=HISTOGRAM_BINS)
    counts.set_ylabel("runs", fontsize=6)
    counts.yaxis.set_major_locator(MaxNLocator(integer=True))
    counts.tick_params(labelsize=6)


def _panels(
    n: int, figure_title: str = "", drafts: Drafts | None = None
) -> tuple[Figure, list[Any]]:
    """A figure of ``n`` panels in rows of :data:`PANEL_COLUMNS`, ``figure_title`` above:
    the one of ``drafts`` made for that many and that title, if any, else a new one."""
    drafted = drafts.take(n, figure_title) if drafts is not None else None
    return drafted if drafted is not None else _new_panels(n, figure_title)


def _new_panels(n: int, figure_title: str) -> tuple[Figure, list[Any]]:
    """A new figure of ``n`` panels (:func:`_panels`)."""
    cols = min(PANEL_COLUMNS, n)
    nrows = math.ceil(n / cols)
    from matplotlib.figure import Figure

    height = PANEL_SIZE_IN[1] * nrows + (TITLE_IN if figure_title else 0.0)
    fig = Figure(figsize=(PANEL_SIZE_IN[0] * cols, height))
    axes = fig.subplots(nrows, cols, squeeze=False)
    _margins(fig, figure_title)
    flat = [ax for row in axes for ax in row]
    for ax in flat[n:]:
        ax.set_visible(False)
    for ax in flat:
        ax.tick_params(labelsize=7)
        ax.grid(True, alpha=0.3)
        _plain_ticks(ax)
    return fig, flat[:n]


def _plain_ticks(ax: Any) -> None:
    """Tick labels as the numbers themselves: no offset ("+1.5249") and no common factor
    ("1e-5") above the axis, which read as another number."""
    for axis in (ax.xaxis, ax.yaxis):
        from matplotlib.ticker import ScalarFormatter

        formatter = ScalarFormatter(useOffset=False)
        formatter.set_scientific(False)
        axis.set_major_formatter(formatter)


def _margins(fig: Figure, figure_title: str = "") -> None:
    """Fixed margins in inches (tight_layout would double the time to save a figure), and
    :data:`TITLE_IN` more at the top for ``figure_title``, drawn there."""
    width, height = fig.get_size_inches()
    top = 0.35 + (TITLE_IN if figure_title else 0.0)
    fig.subplots_adjust(
        left=0.7 / width,
        right=1 - 0.2 / width,
        bottom=0.55 / height,
        top=1 - top / height,
        wspace=0.4,
        hspace=0.6,
    )
    if figure_title:
        fig.suptitle(figure_title, y=1 - 0.08 / height, va="top", fontsize=10)


def _floats(rows: Sequence[Row], name: str) -> np.ndarray:
    return np.asarray([np.nan if r[name] is None else float(r[name]) for r in rows], dtype=float)


def _count(rows: Sequence[Row], metric: str) -> int:
    """How many of ``rows`` have ``metric`` (what :func:`_mean` averages)."""
    return sum(r[metric] is not None for r in rows)


def _mean(rows: Sequence[Row], metric: str) -> float:
    """Mean of ``metric`` over ``rows`` (NaN if none has it)."""
    values = [float(r[metric]) for r in rows if r[metric] is not None]
    return float(np.mean(values)) if values else math.nan


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _file_safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "._-" else "_" for c in name)


def _save(fig: Figure, path: Path) -> Path:
    """Write ``fig`` to ``path`` as a PNG, whole or not at all (raises OSError naming it)."""
    write_whole(path, lambda tmp: fig.savefig(tmp, dpi=DPI, format="png"))
    return path
