"""A run's recording inline in a Jupyter notebook, working offline: rerun's notebook viewer.

rerun-notebook fetches its viewer (``widget.js`` and a 67 MB WebAssembly file) from
app.rerun.io unless the environment variable ``RERUN_NOTEBOOK_ASSET`` names another source
when it is first imported: ``serve-local`` serves the copies installed with it from a
server in the kernel's process on this machine, so the viewer works without a network
(``inline`` would embed 67 MB in the notebook instead). :func:`inline_viewer` sets
``serve-local`` (unless the environment chose a source) before it imports rerun.notebook,
and sizes the widget for a notebook cell: the cell's width, :data:`HEIGHT` pixels high, with
the side panels (blueprint, selection, time) collapsed.

The file is loaded into a recording stream with the file's own application and recording
ids, so the viewer shows one recording; its layout is the notebook's
(:func:`cosim.viz.layout.notebook_blueprint`: the world view beside the heading loop, the
events log a tab behind it), or
a study overlay's own, as rerun forwards a file's data but not the layout stored with it.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.errors import CosimError

if TYPE_CHECKING:  # rerun-notebook is optional: imported on first use
    from rerun.notebook import Viewer

ASSET_VARIABLE = "RERUN_NOTEBOOK_ASSET"
OFFLINE_ASSETS = "serve-local"  # rerun-notebook's own server of its installed viewer
HEIGHT = 560  # px: the plots readable, the whole widget on a laptop's screen
COLLAPSED = {"blueprint": "collapsed", "selection": "collapsed", "time": "collapsed"}


def offline_assets() -> str:
    """Make rerun-notebook serve its viewer from this machine; the source it will use.

    Warns (once, one line) when rerun-notebook was already imported with another source:
    the environment variable is read at import time only, so the kernel must be restarted.
    """
    os.environ.setdefault(ASSET_VARIABLE, OFFLINE_ASSETS)
    imported = sys.modules.get("rerun_notebook")
    source = getattr(imported, "ASSET_ENV", None) if imported is not None else None
    if source is not None and source != os.environ[ASSET_VARIABLE]:
        warnings.warn(
            f"rerun-notebook was imported before with {ASSET_VARIABLE}={source!r}: the inline "
            f"viewer loads from there; restart the kernel to use {os.environ[ASSET_VARIABLE]!r}",
            stacklevel=3,
        )
        return str(source)
    return os.environ[ASSET_VARIABLE]


def _layout(rrd: Path) -> Any:
    """The notebook layout for the run beside ``rrd`` (its results.csv names the columns;
    its summary.json and scenario.toml the vehicles, :func:`cosim.viz.fleet.run_vehicles`,
    whose first the world view follows), a study's overlay's own
    (:func:`cosim.viz.overlay.overlay_blueprint`); None (rerun's own views) for any other
    recording."""
    from cosim.outputs.results import header_columns
    from cosim.viz.fleet import drawn_roots, pairs, read_summary, run_vehicles
    from cosim.viz.layout import notebook_blueprint, plan_panels
    from cosim.viz.rrd_file import OVERLAY_FILE

    results = rrd.with_name("results.csv")
    try:
        with results.open(encoding="utf-8") as file:
            columns = header_columns(file.readline())[1:]
    except OSError:
        if rrd.name != OVERLAY_FILE:
            return None
        return _overlay_layout()
    summary = read_summary(rrd.parent)
    fleet = run_vehicles(rrd.parent, summary)
    units = summary.get("units")
    panels = plan_panels(columns, units if isinstance(units, dict) else None, pairs(fleet))
    return notebook_blueprint(panels, [root for _, root in drawn_roots(fleet, columns)])


def _overlay_layout() -> Any:
    """A study overlay's layout (:func:`cosim.viz.overlay.overlay_blueprint`), whose module
    imports matplotlib: under a relative HOME its folder is auv-cosim's cache folder's (as
    the command's: :func:`cosim.errors.matplotlib_folder_absolute`), not one below the
    notebook's working folder, for the import only (the caller's environment is put
    back; the folder matplotlib resolved stays its folder in the kernel)."""
    from cosim.errors import matplotlib_folder_absolute
    from cosim.user_cache import matplotlib_cache

    before = os.environ.get("MPLCONFIGDIR")
    matplotlib_folder_absolute(matplotlib_cache)
    try:
        from cosim.viz.overlay import overlay_blueprint  # matplotlib: for an overlay only
    finally:  # as it was: unset, or set (an empty value too, which matplotlib ignores)
        if before is None:
            os.environ.pop("MPLCONFIGDIR", None)
        else:
            os.environ["MPLCONFIGDIR"] = before
    return overlay_blueprint()


def inline_viewer(rrd: str | Path, height: int = HEIGHT) -> Viewer:
    """The notebook widget showing the recording ``rrd`` (a ``.rrd`` file, a run folder
    holding ``recording.rrd`` or a study folder holding ``overlay.rrd``, as ``auv-cosim
    view`` takes), ``height`` pixels high; display it by ending a cell with it.

    Raises:
        CosimError: no such recording, or rerun's notebook viewer is not installed.
    """
    from cosim.viz.recording import recording_in

    path = recording_in(Path(rrd))
    offline_assets()
    try:
        import rerun as rr
        from rerun.chunk import RrdReader
        from rerun.notebook import Viewer
    except ImportError as exc:
        raise CosimError(
            f'the notebook viewer needs rerun-notebook: pip install "rerun-sdk[notebook]" ({exc})'
        ) from None
    stored = RrdReader(path).recordings()[0]
    recording = rr.RecordingStream(stored.application_id, recording_id=stored.recording_id)
    viewer = Viewer(recording=recording, width="auto", height=height, blueprint=_layout(path))
    # rerun.notebook.Viewer takes no panel states; its widget does (rerun_notebook.Viewer)
    viewer._viewer.update_panel_states(COLLAPSED)
    recording.log_file_from_path(path)
    recording.flush()  # the file's data handed to the widget before the cell ends
    return viewer
