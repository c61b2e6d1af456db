"""One Rerun recording overlaying several runs of a study: their paths in one 3D view and
their yaw, roll and depth on shared time axes.

Entity tree (one entity per run and signal, the run's id as the last path part; its label
-- the run id and its factor values -- as the line's name in the legends; the 3D paths
carry it too but do not print it: the paths start at one point, where every label would
print over the others)::

    world                    ViewCoordinates.FRD (static): NED, x north, y east, z down
    world/paths/<run id>     LineStrips3D (static): the whole path [north, east, down], m
    world/vehicles/<run id>  Points3D per step: where the run's vehicle is at the cursor
    yaw_deg/<run id>         Scalars per step: plant.yaw in degrees
    roll_deg/<run id>        Scalars per step: plant.roll in degrees
    depth_m/<run id>         Scalars per step: plant.down, m
    study                    TextDocument (static): the runs shown and why

A run of several vehicles (its results hold the position, yaw and roll of more than one
plant instance, :func:`plants_of`) gets each vehicle's path, point and lines one level
deeper, under its plant's name: ``world/paths/<run id>/<plant>``,
``world/vehicles/<run id>/<plant>``, ``yaw_deg/<run id>/<plant>`` ..., its label the run's
and the plant's, each line its own colour. One vehicle is drawn as above whatever its
plant instance is named.

The recording's application id is :data:`OVERLAY_APPLICATION_ID`, not a run recording's, so
the viewer keeps the two layouts apart. Each run gets its own colour (matplotlib's
``tab20`` cycle). The data comes from each run's ``results.csv`` (time in s, angles in
rad, positions in m).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from matplotlib import colormaps

from cosim.viz.display_units import NO_UNIT, scale_to, source_unit
from cosim.viz.layout import time_index
from cosim.viz.recording import APPLICATION_ID, FLUSH_TIMEOUT
from cosim.viz.rrd_file import RrdFile, drop_closed_streams, file_sink, pumped, set_sinks
from cosim.whole_file import fresh_file

POSITION = ("plant.north", "plant.east", "plant.down")
SERIES = {  # entity root -> (results column, the unit it is drawn in)
    "yaw_deg": ("plant.yaw", "deg"),
    "roll_deg": ("plant.roll", "deg"),
    "depth_m": ("plant.down", "m"),
}
REQUIRED = ("time", *POSITION, *(column for column, _ in SERIES.values()))
# the variables a plant instance's columns must hold for its vehicle to be drawn
VARIABLES = tuple(dict.fromkeys(name.split(".", 1)[1] for name in REQUIRED[1:]))


def plants_of(results: Mapping[str, object]) -> list[str]:
    """The instances whose columns in ``results`` hold every one of :data:`VARIABLES`
    (each a vehicle's plant: ``plant``, or ``plant_a`` and ``plant_b``), in column order."""
    instances = dict.fromkeys(name.split(".", 1)[0] for name in results if "." in name)
    return [i for i in instances if all(f"{i}.{v}" in results for v in VARIABLES)]


POINT_RADIUS = 0.3  # m, drawn radius of a run's vehicle in the 3D view
# The viewer gives recordings of one application id one layout: an overlay shares a run
# recording's, its panels show nothing of the other's entities (each drawn, empty, in the
# other's layout when both are open, or in a viewer that keeps the layout it last showed).
OVERLAY_APPLICATION_ID = f"{APPLICATION_ID}-overlay"


@dataclass(frozen=True)
class OverlayRun:
    """One run to overlay: its id, its label and its results (column -> values, SI)."""

    id: str
    label: str
    results: Mapping[str, np.ndarray]

    def __post_init__(self) -> None:
        missing = [name for name in REQUIRED if name not in self.results]
        if "time" not in self.results or not plants_of(self.results):
            raise ValueError(f"run {self.id}: its results lack {', '.join(missing)}")


def write_overlay(
    path: Path,
    runs: Sequence[OverlayRun],
    title: str,
    notes: str,
    units: Mapping[str, str] | None = None,
) -> Path:
    """Write ``path`` (replaced whole: written beside it, then renamed) overlaying ``runs``.

    ``title`` names the recording; ``notes`` (Markdown) is the ``study`` text document;
    ``units`` (column -> the unit its FMU declares) the unit each signal is drawn from (a
    yaw declared in deg is not scaled from rad; one not given: as our plant's, rad).
    Raises OSError if the file cannot be written.
    """
    tmp = path.with_name(path.name + ".tmp")
    # Rerun takes UTF-8 text: a folder's name in bytes that are no UTF-8 (surrogates) escaped
    title, notes = (text.encode(errors="backslashreplace").decode() for text in (title, notes))
    try:
        fresh_file(tmp)  # never written through a link planted at the name
        _write(tmp, runs, title, notes, units or {})
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    os.replace(tmp, path)
    return path


def _write(
    path: Path, runs: Sequence[OverlayRun], title: str, notes: str, units: Mapping[str, str]
) -> None:
    rec = rr.RecordingStream(OVERLAY_APPLICATION_ID)
    file = RrdFile(path) if pumped() else None  # see cosim.viz.rrd_file: why not FileSink
    try:
        sink = file.sink() if file is not None else file_sink(path)
        set_sinks(rec, OVERLAY_APPLICATION_ID, sink, overlay_blueprint())
        rec.send_recording_name(title)
        rec.log("world", rr.ViewCoordinates.FRD, static=True)
        rec.log("study", rr.TextDocument(notes, media_type=rr.MediaType.MARKDOWN), static=True)
        colors = colormaps["tab20"]  # 20 qualitative colours, one per vehicle drawn
        drawn = [(run, plant) for run in runs for plant in plants_of(run.results)]
        for k, (run, plant) in enumerate(drawn):
            color = tuple(int(255 * c) for c in colors(k % colors.N)[:3])
            _log_run(rec, run, plant, color, units)
        rec.flush(timeout_sec=FLUSH_TIMEOUT)
    finally:
        rec.disconnect()
        del rec
        drop_closed_streams()
        if file is not None:
            file.close(timeout=FLUSH_TIMEOUT)  # OSError if a write failed


def _log_run(
    rec: rr.RecordingStream,
    run: OverlayRun,
    plant: str,
    color: tuple[int, ...],
    units: Mapping[str, str],
) -> None:
    """The static path and label of the vehicle of instance ``plant`` in a run, and its
    per-step position and signals (each scaled from the unit ``units`` declares it in, by
    its own column's name or, as the study names them, ``plant.<variable>``; one that does
    not convert is left out); under the run's id, and the plant's name if the run has
    several (module)."""
    several = len(plants_of(run.results)) > 1
    tail = f"{run.id}/{rr.escape_entity_path_part(plant)}" if several else run.id
    label = f"{run.label} ({plant})" if several else run.label

    def own(column: str) -> str:  # plant.north -> <plant>.north
        return f"{plant}.{column.split('.', 1)[1]}"

    position = np.column_stack([run.results[own(name)] for name in POSITION])
    index = time_index(run.results["time"])
    rec.log(
        f"world/paths/{tail}",
        rr.LineStrips3D(
            [position], colors=[color], labels=[label], radii=[0.05], show_labels=False
        ),
        static=True,
    )
    rec.log(
        f"world/vehicles/{tail}",
        rr.Points3D.from_fields(colors=[color], radii=[POINT_RADIUS]),
        static=True,
    )
    rec.send_columns(
        f"world/vehicles/{tail}", indexes=index, columns=rr.Points3D.columns(positions=position)
    )
    for root, (column, shown) in SERIES.items():
        declared = units.get(own(column), units.get(column, NO_UNIT))
        scale = scale_to(source_unit(shown) if declared == NO_UNIT else declared, shown)
        if scale is None:
            continue
        entity = f"{root}/{tail}"
        rec.log(entity, rr.SeriesLines(names=[label], colors=[color]), static=True)
        values = np.asarray(run.results[own(column)], dtype=float) * scale
        rec.send_columns(entity, indexes=index, columns=rr.Scalars.columns(scalars=values))


def overlay_blueprint() -> rrb.Blueprint:
    """The 3D view of every path beside the three time-series panels and the notes (the
    file's default layout, and the notebook viewer's, which reads none from the file)."""
    legend = rrb.PlotLegend(corner=rrb.Corner2D.RightTop, visible=True)
    plots = [
        rrb.TimeSeriesView(origin=f"/{root}", name=name, plot_legend=legend)
        for root, name in (
            ("yaw_deg", "Yaw, deg"),
            ("roll_deg", "Roll, deg"),
            ("depth_m", "Depth, m"),
        )
    ]
    world = rrb.Spatial3DView(
        origin="/world",
        name="Paths (NED, grid 10 m)",
        line_grid=rrb.LineGrid3D(visible=True, spacing=10.0),
    )
    notes = rrb.TextDocumentView(origin="/study", name="Runs")
    return rrb.Blueprint(
        rrb.Horizontal(rrb.Vertical(world, notes, row_shares=[4, 1]), rrb.Vertical(*plots)),
        rrb.TimePanel(state="collapsed"),
        auto_views=False,
    )
