"""Where a resume writes its recording, and how its refusals name the folder: the
recording comes from checkpoint.json (a file anyone may edit), so a resume writes only a
recording the run itself wrote, and a refusal names what the user gave (``--resume DIR``),
never an ``--out`` or ``--rrd`` the user did not give."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from cosim.errors import CosimError
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.outputs.folder import lock_folder, unlock_folder
from cosim.outputs.run_files import RECORDING_APPLICATION, RECORDING_MAGIC, read_manifest
from cosim.runner import RunOptions, resume_run, run_scenario

FILES = ("results.csv", "scenario.toml", "summary.json", CHECKPOINT_FILE)


@pytest.fixture(scope="module")
def stopped(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short bs-3 run with a checkpoint at t = 0.4 s of 0.5 s, no recording."""
    out = tmp_path_factory.mktemp("stopped") / "run"
    run_scenario("bs-3", out, stop_time=0.5, checkpoint_every=0.2, no_rrd=True, fmu_dir=fmu_dir)
    return out


def _killed(stopped: Path, tmp_path: Path, recording: Path | None, wrote: bool) -> Path:
    """A copy of ``stopped`` as a run killed after its checkpoint, whose checkpoint names
    ``recording``; ``wrote``: its manifest lists that recording as the run's file."""
    out = tmp_path / "run"
    out.mkdir()
    for name in FILES:
        (out / name).write_bytes((stopped / name).read_bytes())
    summary = json.loads((out / "summary.json").read_text())
    summary.update(status="running", complete=False)
    (out / "summary.json").write_text(json.dumps(summary))
    data = json.loads((out / CHECKPOINT_FILE).read_text())
    data["recording"] = None if recording is None else str(recording)
    (out / CHECKPOINT_FILE).write_text(json.dumps(data))
    manifest = read_manifest(stopped)
    manifest.folder = out
    for name in FILES:
        manifest.record(out / name)
    if wrote and recording is not None:
        manifest.record(recording)
    return out


def _tree(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root``, each file with its bytes (a folder: None)."""
    return {
        str(p.relative_to(root)): (p.read_bytes() if p.is_file() else None)
        for p in sorted(root.rglob("*"))
    }


def _refusal(out: Path, fmu_dir: Path) -> str:
    """Resuming ``out`` (no recording option given) is refused in one line; its text."""
    with pytest.raises(CosimError) as refused:
        resume_run(out, RunOptions(fmu_dir=fmu_dir))
    said = str(refused.value)
    assert "\n" not in said, said
    return said


def test_a_checkpoint_recording_the_run_never_wrote_is_refused(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards an edited checkpoint making a resume create folders and a recording at a
    path the run never wrote (its manifest does not list it)."""
    elsewhere = tmp_path / "elsewhere" / "deeper" / "x.rrd"
    out = _killed(stopped, tmp_path, elsewhere, wrote=False)
    before = _tree(tmp_path)
    said = _refusal(out, fmu_dir)
    assert f"--resume {out}" in said and str(elsewhere) in said, said
    assert "--rrd PATH or --no-rrd" in said, said
    assert not (tmp_path / "elsewhere").exists()
    assert _tree(tmp_path) == before


def test_a_refused_recording_of_the_checkpoint_names_resume_not_rrd(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards the refusal of the checkpoint's recording (replaced since by a file that is
    no recording) naming an --rrd the resuming user never gave."""
    recording = tmp_path / "rec" / "x.rrd"
    recording.parent.mkdir()
    recording.write_text("not a recording\n")
    out = _killed(stopped, tmp_path, recording, wrote=True)
    recording.write_text("someone else's file now\n")
    before = _tree(tmp_path)
    said = _refusal(out, fmu_dir)
    assert "--rrd" not in said.split(";")[0], said
    assert f"--resume {out}" in said and str(recording) in said, said
    assert _tree(tmp_path) == before


def test_a_resume_of_a_folder_in_use_names_resume_not_out(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards the refusal of a resume whose folder another run holds telling the user to
    choose another --out, which a resume has none of."""
    out = _killed(stopped, tmp_path, None, wrote=False)
    fd = lock_folder(out)
    try:
        said = _refusal(out, fmu_dir)
    finally:
        unlock_folder(out, fd)
    assert "in use by" in said and "--out" not in said, said
    assert f"--resume {out}" in said, said


def test_a_recording_whose_folder_is_a_file_says_so(fmu_dir: Path, tmp_path: Path) -> None:
    """Guards --rrd under a path that is a file being refused as if another process had
    just created the recording."""
    (tmp_path / "file").write_text("a file, not a folder\n")
    rrd = tmp_path / "file" / "x.rrd"
    with pytest.raises(CosimError) as refused:
        run_scenario("bs-3", tmp_path / "run", stop_time=0.1, rrd=rrd, fmu_dir=fmu_dir)
    said = str(refused.value)
    assert "\n" not in said and "another process" not in said, said
    assert f"--rrd {rrd}" in said and os.strerror(20) in said, said  # ENOTDIR


def test_a_copy_of_a_run_recording_elsewhere_refuses_the_originals_recording(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards a run folder copied elsewhere (new inodes, as ``cp -a`` gives) whose run
    recorded to an absolute ``--rrd`` resuming into that same file, the recording of the
    folder it was copied from: the copy is refused in one line naming ``--rrd``."""
    recording = tmp_path / "rec" / "x.rrd"
    recording.parent.mkdir()
    # the head of a recording of ours (the magic bytes, our application id)
    recording.write_bytes(RECORDING_MAGIC + b"2 " + RECORDING_APPLICATION.encode() + b"\n")
    original = _killed(stopped, tmp_path, recording, wrote=True)
    copy = tmp_path / "copy"
    shutil.copytree(original, copy)
    before = _tree(tmp_path)
    said = _refusal(copy, fmu_dir)
    assert f"--resume {copy}" in said and str(recording) in said, said
    assert f"the folder it was copied from, {original}," in said, said
    assert said.endswith("resume with --rrd PATH or --no-rrd"), said
    assert _tree(tmp_path) == before


def _resumes_into(out: Path, recording: Path, fmu_dir: Path) -> None:
    """Resuming ``out`` (no recording option given) completes and writes its checkpoint's
    recording ``recording`` again, whole."""
    head = recording.read_bytes()
    assert resume_run(out, RunOptions(fmu_dir=fmu_dir)).result.complete
    written = recording.read_bytes()
    assert written.startswith(RECORDING_MAGIC) and written != head


@pytest.mark.slow
def test_a_run_folder_moved_to_another_disk_resumes_into_its_recording(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards a folder moved whole (``mv`` to another disk copies then removes it; a
    backup restored is the same: new inodes, no original left) being refused its own
    recording outside it as if it were a copy of a folder that no longer exists."""
    recording = tmp_path / "rec" / "x.rrd"
    recording.parent.mkdir()
    recording.write_bytes(RECORDING_MAGIC + b"2 " + RECORDING_APPLICATION.encode() + b"\n")
    original = _killed(stopped, tmp_path, recording, wrote=True)
    moved = tmp_path / "moved"
    shutil.copytree(original, moved)
    shutil.rmtree(original)
    _resumes_into(moved, recording, fmu_dir)


@pytest.mark.slow
def test_a_run_folder_whose_device_number_changed_resumes_into_its_recording(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards the resume after a reboot of a run on a network or FUSE file system, or a
    btrfs subvolume, whose device number is given at each mount (its files keep their
    path and bytes): the folder is the run's, not a copy, and writes its recording."""
    recording = tmp_path / "rec" / "x.rrd"
    recording.parent.mkdir()
    recording.write_bytes(RECORDING_MAGIC + b"2 " + RECORDING_APPLICATION.encode() + b"\n")
    out = _killed(stopped, tmp_path, recording, wrote=True)
    manifest = out / ".auv-cosim-run.json"
    data = json.loads(manifest.read_text())
    for entry in data["files"]:  # as the same files read after the remount
        entry["dev"] += 1
    manifest.write_text(json.dumps(data))
    _resumes_into(out, recording, fmu_dir)
