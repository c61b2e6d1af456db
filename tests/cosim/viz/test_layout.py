"""The recording's default layout leaves the time-series plots room for y ticks, its world
view follows the vehicle, its neutral lines show on both themes, and a study overlay does
not print every run's label over the others at the common start."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import rerun.blueprint as rrb

from cosim.viz import layout
from cosim.viz.layout import PANELS, build_blueprint, notebook_blueprint, plan_panels

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


def test_an_overlay_titled_with_bytes_not_utf8_is_written(tmp_path: Path) -> None:
    """A study's overlay is titled with its folder's name; one named in Latin-1 (the byte
    0xff, read as the surrogate U+DCFF) failed the study at its end: Rerun takes only
    UTF-8 ("UnicodeEncodeError")."""
    import os

    from cosim.viz.overlay import OverlayRun, write_overlay

    t = np.linspace(0.0, 1.0, 11)
    names = ("plant.north", "plant.east", "plant.down", "plant.yaw", "plant.roll")
    run = OverlayRun("run0", "run0", {"time": t, **{name: 0 * t for name in names}})
    title = "study " + os.fsdecode(b"st-\xff")
    path = write_overlay(tmp_path / "overlay.rrd", [run], title, f"# {title}")
    assert path.stat().st_size > 0


def test_an_overlay_and_a_run_s_recording_keep_their_own_layouts(tmp_path: Path) -> None:
    """The viewer gives recordings of one application id one layout (blueprint): a run's
    recording and a study's overlay opened together, or one after the other in a viewer
    that keeps the layout it last showed, drew one in the other's panels, empty (the
    overlay's /yaw_deg plots have no data in a run, a run's /attitude plots none in an
    overlay). Every run's recording shares one id; the overlays have another."""
    from rerun.chunk import RrdReader
    from scenario_factory import auv_scenario

    from cosim.viz.overlay import OverlayRun, write_overlay
    from cosim.viz.recording import RerunSink

    t = np.linspace(0.0, 1.0, 11)
    names = ("plant.north", "plant.east", "plant.down", "plant.yaw", "plant.roll")
    run = OverlayRun("run0", "run0", {"time": t, **{name: 0 * t for name in names}})
    overlays = [write_overlay(tmp_path / f"{k}.rrd", [run], "s", "") for k in "ab"]
    runs = [tmp_path / f"{k}.rrd" for k in "cd"]
    for path in runs:
        RerunSink(auv_scenario(tmp_path, path.stem, list(names)), path).close()

    def application(path: Path) -> str:
        return RrdReader(path).recordings()[0].application_id

    assert application(runs[0]) == application(runs[1])
    assert application(overlays[0]) == application(overlays[1])
    assert application(overlays[0]) != application(runs[0])


def _contrast(a: tuple[int, int, int], b: tuple[int, int, int]) -> float:
    """The WCAG 2 contrast ratio of two sRGB colours (1: none, 21: black on white)."""

    def luminance(rgb: tuple[int, int, int]) -> float:
        c = [v / 255 for v in rgb]
        lin = [v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4 for v in c]
        return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]

    high, low = sorted((luminance(a), luminance(b)), reverse=True)
    return (high + 0.05) / (low + 0.05)


LIGHT_THEME_BACKGROUND = (255, 255, 255)
DARK_THEME_BACKGROUND = (13, 16, 17)  # rerun's dark panels


@pytest.mark.parametrize("name", ["TRAJECTORY", "ENERGY", "NEUTRAL"])
@pytest.mark.parametrize("background", [LIGHT_THEME_BACKGROUND, DARK_THEME_BACKGROUND])
def test_the_track_and_neutral_lines_stand_out_on_both_themes(
    name: str, background: tuple[int, int, int]
) -> None:
    """The track was near white (240, 240, 240): invisible on the light theme."""
    assert _contrast(getattr(layout, name), background) >= 3.0


def _world_views(container) -> list:
    found = []
    for item in container.contents or []:
        if isinstance(item, rrb.Spatial3DView) and item.origin == "/world":
            found.append(item)
        elif hasattr(item, "contents"):
            found += _world_views(item)
    return found


def _eye_value(eye, name: str) -> list:
    return eye.__getattribute__(name).as_arrow_array().to_pylist()


def test_the_world_view_follows_the_vehicle(tmp_path: Path) -> None:
    """In the recording's layout and the notebook's, the world view's eye tracks a shape
    that moves with the vehicle, from a fixed distance, so the vehicle stays in view and
    in size. Tracking the body frame itself (a transform, no shape of its own) left the eye
    where the first frames put it: 30 s into bs-3 the vehicle was a dot 45 m away."""
    import rerun as rr
    from rerun.chunk import RrdReader

    from cosim.viz.scene import log_static_scene
    from plant_fmu.model.parameters import load_vehicle

    columns = [s.column for panel in PANELS for s in panel.series]
    rec = rr.RecordingStream("test")
    rec.set_sinks(rr.FileSink(str(tmp_path / "scene.rrd")))
    log_static_scene(rec, load_vehicle("remus100"), columns, show_depth_setpoint=False)
    rec.disconnect()
    shapes = {
        chunk.entity_path
        for chunk in RrdReader(tmp_path / "scene.rrd").stream()
        if any(":" in name and not name.startswith("Transform3D:")
               for name in chunk.to_record_batch().schema.names)
    }  # fmt: skip
    panels = plan_panels(columns)
    for blueprint in (build_blueprint(panels, depth_control=True), notebook_blueprint(panels)):
        (world,) = _world_views(blueprint.root_container)
        eye = world.properties["EyeControls3D"]
        (tracked,) = [str(e) for e in _eye_value(eye, "tracking_entity")]
        assert tracked.startswith(layout.VEHICLE_ENTITY + "/") and tracked in shapes, tracked
        (position,), (target,) = _eye_value(eye, "position"), _eye_value(eye, "look_target")
        assert 5.0 <= math.dist(position, target) <= 30.0  # m: the vehicle (1.6 m) readable
        assert position[2] < target[2]  # above it (z down)


def _views(container) -> list:
    """Every view under ``container``, depth first."""
    found = []
    for item in container.contents or []:
        found += _views(item) if isinstance(item, rrb.Container) else [item]
    return found


@pytest.mark.parametrize("depth_control", [True, False])
def test_the_events_and_faults_log_has_a_view(depth_control: bool) -> None:
    """The notes a run logs -- events fired, faults started and stopped, live overrides,
    pauses -- show in the default layout: with auto views off, an entity no view names is
    in the recording but nowhere on screen."""
    from cosim.viz.recording import NOTES_ENTITY

    columns = [s.column for panel in PANELS for s in panel.series]
    blueprint = build_blueprint(plan_panels(columns), depth_control=depth_control)
    logs = [v for v in _views(blueprint.root_container) if isinstance(v, rrb.TextLogView)]
    assert [view.origin for view in logs] == [f"/{NOTES_ENTITY}"]


def test_the_notebook_layout_shows_the_events_log_behind_the_heading_loop() -> None:
    """Inline in a notebook, a run that failed or was stopped showed plots that simply
    stopped: its events log (events, faults, how the run ended) was in no view. It is a
    tab behind the heading loop, which stays the one shown."""
    from cosim.viz.recording import NOTES_ENTITY

    columns = [s.column for panel in PANELS for s in panel.series]
    root = notebook_blueprint(plan_panels(columns)).root_container
    logs = [v for v in _views(root) if isinstance(v, rrb.TextLogView)]
    assert [view.origin for view in logs] == [f"/{NOTES_ENTITY}"]
    (tabs,) = [item for item in root.contents if isinstance(item, rrb.Tabs)]
    assert tabs.contents[tabs.active_tab or 0].name == "Heading loop"
