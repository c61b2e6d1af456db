"""The notebook's inline viewer finds the recording a folder holds, as ``auv-cosim view``
does: a run's ``recording.rrd`` or a study's ``overlay.rrd``."""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest
import rerun as rr

from cosim.errors import CosimError
from cosim.viz import notebook


def _recording(path: Path) -> None:
    """A small .rrd file at ``path``: one scalar logged."""
    stream = rr.RecordingStream("auv-cosim-test")
    stream.save(path)
    stream.log("value", rr.Scalars(1.0))
    stream.flush()


def test_a_study_folder_shows_its_overlay(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``inline_viewer(study.out_dir)`` said "study/recording.rrd: no recording there"
    for a study drawn with ``overlay=N``, whose folder holds overlay.rrd."""
    if importlib.util.find_spec("rerun_notebook") is None:
        pytest.skip("needs rerun-notebook")
    monkeypatch.setenv(notebook.ASSET_VARIABLE, notebook.OFFLINE_ASSETS)  # undone after
    _recording(tmp_path / "overlay.rrd")
    shown: list[Path] = []
    monkeypatch.setattr(
        rr.RecordingStream, "log_file_from_path", lambda self, path, **_: shown.append(path)
    )
    notebook.inline_viewer(tmp_path)
    assert shown == [tmp_path / "overlay.rrd"]


def test_a_folder_without_a_recording_says_what_would_hold_one(tmp_path: Path) -> None:
    with pytest.raises(CosimError) as refused:
        notebook.inline_viewer(tmp_path)
    assert "recording.rrd" in str(refused.value) and "overlay.rrd" in str(refused.value)


def _origins(node) -> list[str]:
    """The origin of every view in a blueprint, container or view, depth first."""
    if hasattr(node, "root_container"):
        return _origins(node.root_container)
    if hasattr(node, "origin"):
        return [str(node.origin)]
    return [origin for child in node.contents for origin in _origins(child)]


def test_a_study_s_overlay_keeps_its_layout_inline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The notebook viewer takes no layout from the file: an overlay.rrd was shown in
    rerun's own views instead of its paths beside its yaw, roll and depth plots."""
    if importlib.util.find_spec("rerun_notebook") is None:
        pytest.skip("needs rerun-notebook")
    import numpy as np
    import rerun.notebook

    from cosim.viz.overlay import POSITION, SERIES, OverlayRun, write_overlay

    monkeypatch.setenv(notebook.ASSET_VARIABLE, notebook.OFFLINE_ASSETS)  # undone after
    t = np.linspace(0.0, 1.0, 11)
    results = {"time": t, **{name: t for name in (*POSITION, *(c for c, _ in SERIES.values()))}}
    write_overlay(tmp_path / "overlay.rrd", [OverlayRun("r1", "r1: k = 1", results)], "s", "")
    layouts: list = []

    class Viewer:  # what inline_viewer hands its layout to
        def __init__(self, **options) -> None:
            layouts.append(options["blueprint"])
            self._viewer = type("Widget", (), {"update_panel_states": lambda *_: None})()

    monkeypatch.setattr(rerun.notebook, "Viewer", Viewer)
    monkeypatch.setattr(rr.RecordingStream, "log_file_from_path", lambda *_, **__: None)
    notebook.inline_viewer(tmp_path)
    assert layouts[0] is not None, "no layout: rerun's own views"
    assert {"/world", *(f"/{root}" for root in SERIES)} <= set(_origins(layouts[0]))


def _tracked(blueprint) -> list[str]:
    """The entity each 3-D view of ``blueprint`` has its eye follow."""
    import rerun.blueprint as rrb

    def views(node) -> list:
        if hasattr(node, "root_container"):
            return views(node.root_container)
        if isinstance(node, rrb.Spatial3DView):
            return [node]
        return [view for child in getattr(node, "contents", None) or [] for view in views(child)]

    found = []
    for view in views(blueprint):
        eye = view.properties.get("EyeControls3D")
        tracking = None if eye is None else eye.tracking_entity
        if tracking is not None:
            found += [str(e) for e in tracking.as_arrow_array().to_pylist()]
    return found


@pytest.mark.slow
def test_a_fleet_s_notebook_view_follows_its_first_vehicle(tmp_path: Path, fmu_dir: Path) -> None:
    """A run of two vehicles draws them under world/<plant>/vehicle: the notebook's world
    view tracked /world/vehicle/hull, an entity the recording does not have, so its eye
    followed nothing. It follows the first drawn vehicle's hull, as the file's own
    layout does."""
    from rerun.chunk import RrdReader
    from two_vehicles import two_vehicles_toml

    import cosim

    scenario = tmp_path / "two.toml"
    scenario.write_text(two_vehicles_toml(stop_time=0.2), encoding="utf-8")
    run = cosim.run(scenario, out=tmp_path / "run", fmu_dir=fmu_dir)
    rrd = run.out_dir / "recording.rrd"
    entities = set(RrdReader(rrd).stream().collect().schema().entity_paths())
    tracked = _tracked(notebook._layout(rrd))
    assert tracked == ["/world/plant_a/vehicle/hull"], tracked
    assert tracked[0] in entities, sorted(e for e in entities if e.startswith("/world"))


RELATIVE_HOME_LAYOUT = """
import os, sys
for name in ("XDG_CONFIG_HOME", "XDG_CACHE_HOME", "MPLCONFIGDIR"):
    os.environ.pop(name, None)
os.environ["HOME"], os.environ["TMPDIR"] = "home", sys.argv[1]
os.chdir(sys.argv[2])
from pathlib import Path

from cosim.viz import notebook

before = dict(os.environ)
assert notebook._layout(Path(sys.argv[3])) is not None
import matplotlib

print(matplotlib.get_configdir())
print("environment as it was" if dict(os.environ) == before else "environment changed")
"""


@pytest.mark.slow
def test_a_study_s_overlay_inline_under_a_relative_home_writes_nothing_there(
    run_python, tmp_path: Path
) -> None:
    """``inline_viewer(study)`` with ``HOME=home`` (relative) made ``home/.config/matplotlib``
    in the notebook's working folder: the overlay's layout imports matplotlib (its colours),
    which takes a relative HOME as it is. Its folder is auv-cosim's cache folder's, as the
    command's, and the caller's environment is as it was."""
    import numpy as np

    from cosim.viz.overlay import POSITION, SERIES, OverlayRun, write_overlay

    t = np.linspace(0.0, 1.0, 11)
    results = {"time": t, **{name: t for name in (*POSITION, *(c for c, _ in SERIES.values()))}}
    study = tmp_path / "study"
    study.mkdir()
    write_overlay(study / "overlay.rrd", [OverlayRun("r1", "r1: k = 1", results)], "s", "")
    scratch, work = tmp_path / "tmp", tmp_path / "work"
    scratch.mkdir()
    work.mkdir()
    done = run_python(RELATIVE_HOME_LAYOUT, scratch, work, study / "overlay.rrd")
    assert done.returncode == 0, done.stderr[-2000:]
    assert sorted(str(p.relative_to(work)) for p in work.rglob("*")) == []
    folder, environment = done.stdout.splitlines()[-2:]
    assert Path(folder).is_absolute() and Path(folder).is_relative_to(scratch), folder
    assert environment == "environment as it was"


def test_an_overlay_s_layout_puts_an_empty_mplconfigdir_back(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``MPLCONFIGDIR=`` (set, empty: matplotlib takes it as unset) under a relative HOME:
    the overlay's layout pointed matplotlib at auv-cosim's cache folder for its import and
    put back only an MPLCONFIGDIR that had been unset, so the notebook's environment kept
    the cache folder (every process it started later inherited it)."""
    monkeypatch.setenv("HOME", "home")
    monkeypatch.setenv("MPLCONFIGDIR", "")
    assert notebook._overlay_layout() is not None
    assert os.environ["MPLCONFIGDIR"] == ""
