"""A killed run's folder resumed as users handle it: copied elsewhere first (``cp -a``,
``rsync``: its files' device, inode and perhaps times change, their content does not),
and resumed without repeating the recording options it was started with."""

from __future__ import annotations

import json
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from killed_runs import kill_after_checkpoint

from cosim.api import resume
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.runner import run_scenario

STOP = "30"  # s of bs-3, a checkpoint every 5 s


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", "run", *args, "--quiet"]


def _killed(fmu_dir: Path, out: Path, *recording: str) -> Path:
    """bs-3 killed (SIGTERM) once its first checkpoint is written, in ``out``."""
    command = _cli("bs-3", "--out", str(out), "--fmu-dir", str(fmu_dir), "--stop-time", STOP,
                   "--checkpoint-every", "5", *recording)  # fmt: skip
    assert kill_after_checkpoint(command, out) == 128 + signal.SIGTERM
    assert json.loads((out / "summary.json").read_text())["complete"] is False
    return out


@pytest.fixture(scope="module")
def whole(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The uninterrupted run's results.csv."""
    out = tmp_path_factory.mktemp("whole") / "run"
    run_scenario("bs-3", out, stop_time=float(STOP), no_rrd=True, fmu_dir=fmu_dir)
    return out / "results.csv"


@pytest.fixture(scope="module")
def killed(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A killed run started with --no-rrd (never resumed: tests resume copies of it)."""
    return _killed(fmu_dir, tmp_path_factory.mktemp("killed") / "run", "--no-rrd")


def _resume(fmu_dir: Path, out: Path, *options: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(_cli("--resume", str(out), "--fmu-dir", str(fmu_dir), *options),
                          capture_output=True, text=True, timeout=600)  # fmt: skip


def _copy_times_kept(source: Path, target: Path) -> None:
    shutil.copytree(source, target)  # as cp -a, rsync -a: new inodes, times kept


def _copy_times_new(source: Path, target: Path) -> None:
    shutil.copytree(source, target, copy_function=shutil.copyfile)  # as cp -r


@pytest.mark.slow
@pytest.mark.parametrize("copy", [_copy_times_kept, _copy_times_new], ids=["cp-a", "cp-r"])
def test_a_killed_run_copied_elsewhere_resumes_to_the_uninterrupted_results(
    killed: Path, whole: Path, fmu_dir: Path, tmp_path: Path, copy: Callable[[Path, Path], None]
) -> None:
    """Guards a copied run folder being refused because its files have new inodes."""
    out = tmp_path / "moved" / "run"
    copy(killed, out)
    resumed = _resume(fmu_dir, out)
    assert resumed.returncode == 0, resumed.stderr
    assert (out / "results.csv").read_bytes() == whole.read_bytes()


@pytest.mark.slow
def test_a_copy_whose_results_differ_is_refused_naming_resume(
    killed: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """A copy whose results.csv is not the run's (its last row cut) is refused in one line
    naming ``--resume DIR`` (the option the user gave), the folder left as it was."""
    out = tmp_path / "run"
    shutil.copytree(killed, out)
    results = out / "results.csv"
    results.write_bytes(results.read_bytes().rsplit(b"\n", 2)[0] + b"\n")
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    resumed = _resume(fmu_dir, out)
    assert resumed.returncode != 0
    said = resumed.stderr.strip()
    assert "\n" not in said and f"--resume {out}: results.csv is not a file" in said, said
    assert "--out" not in said, said
    assert {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()} == before


@pytest.mark.slow
def test_a_run_without_a_recording_resumes_without_one(
    whole: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards a resume without --no-rrd writing a recording the run never had."""
    out = _killed(fmu_dir, tmp_path / "run", "--no-rrd")
    resumed = _resume(fmu_dir, out)
    assert resumed.returncode == 0, resumed.stderr
    assert not (out / "recording.rrd").exists()
    assert (out / "results.csv").read_bytes() == whole.read_bytes()


@pytest.mark.slow
def test_a_run_recording_elsewhere_resumes_recording_there(fmu_dir: Path, tmp_path: Path) -> None:
    """Guards a resume without --rrd PATH writing the recording into the run folder."""
    elsewhere = tmp_path / "recordings" / "long.rrd"
    elsewhere.parent.mkdir()
    out = _killed(fmu_dir, tmp_path / "run", "--rrd", str(elsewhere))
    written = elsewhere.stat().st_size
    resumed = _resume(fmu_dir, out)
    assert resumed.returncode == 0, resumed.stderr
    assert not (out / "recording.rrd").exists()
    assert elsewhere.stat().st_size > written  # the whole run's recording, rewritten
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is True


@pytest.mark.slow
def test_a_resume_asked_for_a_recording_writes_one(
    killed: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """The recording the checkpoint keeps is a default: ``recording=True`` (``--rrd``)
    writes the folder's recording.rrd for a run that had none."""
    out = tmp_path / "run"
    shutil.copytree(killed, out)
    assert json.loads((out / CHECKPOINT_FILE).read_text())["every_s"] == 5.0
    run = resume(out, recording=True, fmu_dir=fmu_dir)
    assert run.summary["complete"] is True
    assert (out / "recording.rrd").stat().st_size > 0
