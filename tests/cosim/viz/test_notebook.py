"""The notebook's inline viewer finds the recording a folder holds, as ``auv-cosim view``
does: a run's ``recording.rrd`` or a study's ``overlay.rrd``."""

from __future__ import annotations

import importlib.util
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
