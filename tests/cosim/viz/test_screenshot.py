"""Render a recording in the native Rerun viewer, headless, and check what it drew.

Needs a Vulkan driver: on Debian, ``apt-get install mesa-vulkan-drivers`` (lavapipe
renders on the CPU). Skipped with the reason where there is none or no ``rerun`` binary.
"""

from __future__ import annotations

import glob
import os
import subprocess
import sys

import numpy as np
import pytest
from matplotlib.image import imread
from scenario_factory import auv_scenario
from test_recording import feed, plant_run

from cosim.viz.layout import BLUE
from cosim.viz.recording import RerunSink, rerun_executable
from cosim.viz.screenshot import render_screenshots

ICD_FOLDERS = ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d")


def _why_not() -> str | None:
    if rerun_executable() is None:
        return "the `rerun` viewer binary is not installed (it ships with rerun-sdk)"
    has_icd = any(glob.glob(f"{d}/*.json") for d in ICD_FOLDERS) or "VK_ICD_FILENAMES" in os.environ
    if sys.platform == "linux" and not has_icd:
        return "no Vulkan driver: install Debian's mesa-vulkan-drivers to render headless"
    return None


pytestmark = pytest.mark.skipif(_why_not() is not None, reason=str(_why_not()))


@pytest.fixture(scope="module")
def rendered(tmp_path_factory: pytest.TempPathFactory, fmu_paths):
    folder = tmp_path_factory.mktemp("shot")
    env = dict(os.environ, HOME=str(folder / "home"))
    for name in ("XDG_CONFIG_HOME", "XDG_DATA_HOME", "XDG_CACHE_HOME", "XDG_RUNTIME_DIR"):
        env[name] = str(folder / "home" / name.lower())
    subprocess.run(
        [rerun_executable(), "analytics", "disable"], env=env, capture_output=True, check=True
    )
    times, columns, values = plant_run(4.0)
    rrd = folder / "recording.rrd"
    scenario = auv_scenario(fmu_paths["AuvAutopilot"].parent, "shot", columns)
    with RerunSink(scenario, rrd) as sink:
        feed(sink, times, values)
    shots = [(0.5, folder / "early.png"), (3.5, folder / "late.png")]
    reports = render_screenshots(rrd, shots, env=env, log=folder / "viewer.log")
    return [imread(png)[..., :3] for _, png in shots], reports


@pytest.mark.slow
def test_screenshot_is_not_blank_and_the_3d_views_show_the_motion(rendered):
    (early, late), _ = rendered
    height, width, _ = early.shape
    assert (height, width) == late.shape[:2] and width >= 1000
    assert early.std() > 0.05  # not a uniform image
    left = slice(0, int(0.4 * width))  # the world and chase views
    assert early[:, left].std() > 0.02
    moved = np.abs(early[:, left] - late[:, left]).mean(axis=2) > 0.1
    assert moved.mean() > 0.001  # the vehicle and its path moved between 0.5 s and 3.5 s


@pytest.mark.slow
def test_viewer_applied_the_blueprint_without_visualizer_errors(rendered):
    _, reports = rendered
    names = {r.name for r in reports}
    assert {"World (NED, grid 10 m)", "Chase view (level grid 1 m)", "Yaw ψ (deg)"} <= names
    assert {r.name: r.problems for r in reports if r.problems} == {}


@pytest.mark.slow
def test_yaw_line_is_drawn_in_its_colour(rendered):
    (_, late), _ = rendered
    width = late.shape[1]
    heading = late[:, int(0.45 * width) : int(0.72 * width)]  # the heading-loop column
    near_blue = np.linalg.norm(heading - np.array(BLUE) / 255.0, axis=2) < 0.12
    assert near_blue.sum() > 100
