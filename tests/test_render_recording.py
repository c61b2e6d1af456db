"""scripts/render_recording.py run wrongly: a run folder or .rrd file that holds no
recording is refused in one line naming it, before any viewer starts (it started the
headless viewer and ended in rerun's ConnectionError traceback)."""

from __future__ import annotations

from pathlib import Path

import pytest
from repo_paths import script_module

from cosim.viz import screenshot


@pytest.fixture
def no_viewer(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if anything starts a viewer."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError(f"a viewer was started: {args}")

    monkeypatch.setattr(screenshot.subprocess, "Popen", refuse)


@pytest.mark.parametrize("kind", ["missing folder", "run without a recording", "missing file"])
def test_a_run_without_a_recording_is_refused_in_one_line(
    kind: str, tmp_path: Path, no_viewer: None
) -> None:
    run = {
        "missing folder": tmp_path / "runs" / "bs-3",
        "run without a recording": tmp_path,  # a run with --no-rrd, say
        "missing file": tmp_path / "recording.rrd",
    }[kind]
    out = tmp_path / "shot.png"
    render = script_module("render_recording")
    with pytest.raises(SystemExit) as stop:
        render.main([str(run), "--time", "6", "--out", str(out)])
    message = str(stop.value.code)
    assert message.startswith("render_recording: ") and "\n" not in message, message
    assert str(run) in message and "no recording" in message, message
    assert not out.exists()


def test_rendering_a_missing_recording_starts_no_viewer(tmp_path: Path, no_viewer: None) -> None:
    with pytest.raises(screenshot.ScreenshotError, match="no recording: no such file"):
        screenshot.render_screenshots(tmp_path / "recording.rrd", [(1.0, tmp_path / "a.png")])
