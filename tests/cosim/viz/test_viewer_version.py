"""`auv-cosim view` with a Rerun viewer of another version than the one that wrote the file.

A viewer reads the recordings of its own version and of the one before; one of another
version opened the file on an error inside its window, naming no version. The viewers here
are scripts that answer ``--version`` as ``rerun`` does and exit 0 on anything else.
"""

from __future__ import annotations

import os
import stat
import sys
from pathlib import Path

import pytest
import rerun as rr

from cosim.outputs.folder import RECORDING_FILE
from cosim.viz import recording
from cosim.viz.recording import rerun_executable, view_run
from cosim.viz.viewer_version import written_by

SDK = tuple(int(part) for part in rr.__version__.split("+")[0].split(".")[:3])


def fake_viewer(folder: Path, version: str) -> Path:
    """A ``rerun`` in ``folder`` that says it is ``version`` and opens anything (exit 0)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "rerun"
    path.write_text(
        "#!/bin/sh\n"
        f'if [ "$1" = "--version" ]; then echo "rerun-cli {version} (native_viewer) [rustc]"; '
        "fi\nexit 0\n"
    )
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    """A run folder whose recording this rerun-sdk wrote."""
    folder = tmp_path / "run"
    folder.mkdir()
    rec = rr.RecordingStream("auv-cosim")
    rec.save(str(folder / RECORDING_FILE))
    rec.log("x", rr.Scalars(1.0))
    rec.disconnect()
    return folder


def _view(run_dir: Path, viewer: Path, monkeypatch, capsys) -> str:
    """What ``auv-cosim view RUN_DIR`` prints on stderr with ``viewer`` and a display."""
    monkeypatch.setattr(recording, "rerun_executable", lambda: str(viewer))
    monkeypatch.setattr(recording, "display_problem", lambda: None)
    assert view_run(run_dir) == 0
    return capsys.readouterr().err


def test_the_file_says_which_rerun_wrote_it(run_dir: Path):
    assert written_by(run_dir / RECORDING_FILE) == SDK


@pytest.mark.skipif(sys.platform == "win32", reason="the fake viewer is a shell script")
def test_a_viewer_older_than_the_recording_is_named_with_both_versions(
    run_dir: Path, tmp_path: Path, monkeypatch, capsys
):
    older = f"{SDK[0]}.{SDK[1] - 1}.3"
    err = _view(run_dir, fake_viewer(tmp_path / "old", older), monkeypatch, capsys)
    wrote = ".".join(map(str, SDK))
    assert err.count("\n") == 1, err
    assert f"written by Rerun {wrote}" in err and f"is Rerun {older}" in err
    assert f"`pip install rerun-sdk=={wrote}`" in err


@pytest.mark.skipif(sys.platform == "win32", reason="the fake viewer is a shell script")
@pytest.mark.parametrize("minor_ahead", [0, 1])
def test_a_viewer_of_the_same_or_the_next_version_opens_it_without_a_word(
    run_dir: Path, tmp_path: Path, monkeypatch, capsys, minor_ahead: int
):
    version = f"{SDK[0]}.{SDK[1] + minor_ahead}.0"
    assert _view(run_dir, fake_viewer(tmp_path / "v", version), monkeypatch, capsys) == ""


@pytest.mark.skipif(sys.platform == "win32", reason="the fake viewer is a shell script")
def test_the_viewer_beside_this_python_wins_over_another_on_path(tmp_path: Path, monkeypatch):
    """The venv's ``rerun`` comes with the rerun-sdk that writes the recordings; another
    ``rerun`` on PATH (a cargo install, another venv) may be of any version."""
    other = fake_viewer(tmp_path / "elsewhere", "0.1.0")
    beside = fake_viewer(tmp_path / "venv" / "bin", ".".join(map(str, SDK)))
    monkeypatch.setenv("PATH", f"{other.parent}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.setattr(recording.sys, "executable", str(beside.parent / "python"))
    assert rerun_executable() == str(beside)


@pytest.mark.skipif(sys.platform == "win32", reason="the fake viewer is a shell script")
@pytest.mark.parametrize(
    ("ending", "said"),
    [("exit 2", "exited with status 2"), ("kill -s SEGV $$", "was killed by SIGSEGV")],
)
def test_a_viewer_that_fails_is_a_failed_command_not_its_exit_status(
    run_dir: Path, tmp_path: Path, monkeypatch, capsys, ending: str, said: str
):
    """``auv-cosim view`` exited with the viewer's own status: 2 (its usage error) read as
    a command line auv-cosim cannot parse, and a viewer killed by a signal gave -11, which
    the shell saw as 245. A viewer that fails is a failed command: exit 1, one line on
    stderr naming its status or its signal."""
    from cosim.cli import main

    viewer = tmp_path / "bin" / "rerun"
    viewer.parent.mkdir()
    version = ".".join(map(str, SDK))
    viewer.write_text(
        f'#!/bin/sh\nif [ "$1" = "--version" ]; then echo "rerun-cli {version} '
        f'(native_viewer) [rustc]"; exit 0; fi\n{ending}\n'
    )
    viewer.chmod(viewer.stat().st_mode | stat.S_IXUSR)
    monkeypatch.setattr(recording, "rerun_executable", lambda: str(viewer))
    monkeypatch.setattr(recording, "display_problem", lambda: None)
    assert main(["view", str(run_dir)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"auv-cosim view: the Rerun viewer {said}" in err, err
