"""``--rrd FILE`` writes only a new file or over a regular file holding a recording this
tool wrote (with ``--overwrite``): never over a user's document, another run's results, a
run folder's own manifest, a FIFO, a device, a link or a folder, whatever the flags. On
the test FMUs of tests/fmus, in process."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.outputs.folder import MANIFEST_FILE, RunFolder


def earlier_run(loop_file: Path, folder: Path) -> Path:
    assert main(["run", str(loop_file), "--out", str(folder)]) == 0
    return folder


def a_pdf(loop_file: Path, tmp: Path) -> Path:
    (tmp / "thesis.pdf").write_bytes(b"%PDF-1.7 my thesis\n")
    return tmp / "thesis.pdf"


def another_runs_results(loop_file: Path, tmp: Path) -> Path:
    return earlier_run(loop_file, tmp / "other") / "results.csv"


def a_running_runs_results(loop_file: Path, tmp: Path) -> Path:
    folder = RunFolder.claim(tmp / "running")  # held (locked) for the rest of the test
    (folder.path / "results.csv").write_text("time,x\n0,1\n")
    return folder.path / "results.csv"


def the_runs_own_manifest(loop_file: Path, tmp: Path) -> Path:
    return earlier_run(loop_file, tmp / "out") / MANIFEST_FILE


def another_runs_manifest(loop_file: Path, tmp: Path) -> Path:
    return earlier_run(loop_file, tmp / "other") / MANIFEST_FILE


def a_fifo(loop_file: Path, tmp: Path) -> Path:
    os.mkfifo(tmp / "fifo")
    return tmp / "fifo"


def a_link_to_a_recording(loop_file: Path, tmp: Path) -> Path:
    (tmp / "link.rrd").symlink_to(earlier_run(loop_file, tmp / "other") / "recording.rrd")
    return tmp / "link.rrd"


def a_device(loop_file: Path, tmp: Path) -> Path:
    return Path(os.devnull)


def a_folder(loop_file: Path, tmp: Path) -> Path:
    (tmp / "folder.rrd").mkdir()
    return tmp / "folder.rrd"


TARGETS: dict[str, Callable[[Path, Path], Path]] = {
    f.__name__.replace("_", " "): f
    for f in (
        a_pdf, another_runs_results, a_running_runs_results, the_runs_own_manifest,
        another_runs_manifest, a_fifo, a_link_to_a_recording, a_device, a_folder,
    )
}  # fmt: skip


def state(path: Path) -> tuple[str, bytes | None]:
    """What is at ``path``: its kind and (a regular file's) bytes."""
    if path.is_symlink():
        return "link", os.readlink(path).encode()
    if path.is_dir():
        return "folder", None
    if path.is_fifo() or path.is_char_device():
        return "special", None
    return "file", path.read_bytes()


@pytest.mark.timeout(60)  # the FIFO hung the run
@pytest.mark.parametrize("target", list(TARGETS))
def test_a_recording_path_must_be_new_or_an_earlier_recording(
    loop_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], target: str
) -> None:
    """--overwrite --rrd FILE wrote a recording over any existing file (a user's PDF,
    another run's results.csv, a running run's results.csv, the run's own manifest);
    --rrd naming a FIFO hung the run."""
    rrd = TARGETS[target](loop_file, tmp_path)
    before = state(rrd)
    out = tmp_path / "out"
    out_before = sorted(os.listdir(out)) if out.exists() else None
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--rrd", str(rrd), "--overwrite"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--rrd {rrd}" in err, err
    assert state(rrd) == before
    assert (sorted(os.listdir(out)) if out.exists() else None) == out_before


def test_an_earlier_recording_is_replaced_with_overwrite_only(
    loop_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rrd = earlier_run(loop_file, tmp_path / "other") / "recording.rrd"
    old = rrd.read_bytes()
    command = ["run", str(loop_file), "--out", str(tmp_path / "new"), "--rrd", str(rrd)]
    capsys.readouterr()
    assert main(command) == 1
    assert "exists; pass --overwrite to replace it" in capsys.readouterr().err
    assert rrd.read_bytes() == old
    assert main([*command, "--overwrite"]) == 0
    assert rrd.read_bytes().startswith(b"RRF") and rrd.read_bytes() != old
