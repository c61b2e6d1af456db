"""A full disk ends a run incomplete with exit 1 and the reason (a regression: a recording whose
disk filled up left rc 0, "complete" and an unreadable .rrd).

The mid-run cases write to a small tmpfs (mounted here when the tests run as root, else
skipped); /dev/full, which refuses every write with ENOSPC, stands in where no mount is
possible."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from cosim.errors import CosimError
from cosim.outputs.sinks import CsvSink

DEV_FULL = Path("/dev/full")


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 1 MB tmpfs at tmp_path/small, unmounted afterwards."""
    mount = tmp_path / "small"
    mount.mkdir()
    done = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)],
        capture_output=True,
        text=True,
    )
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield mount
    finally:
        subprocess.run(["umount", "-l", str(mount)], check=True)


def run_cli(fmu_dir: Path, *options: str) -> subprocess.CompletedProcess:
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir)]
    return subprocess.run([*command, "--quiet", *options], capture_output=True, text=True)


@pytest.mark.slow
def test_results_filling_the_disk_end_the_run_with_the_reason(fmu_dir: Path, small_disk: Path):
    out = small_disk / "run"
    done = run_cli(fmu_dir, "--out", str(out), "--stop-time", "60", "--no-rrd")
    assert done.returncode == 1
    assert done.stderr.count("\n") == 1
    assert f"cannot write {out / 'results.csv'}: No space left on device" in done.stderr
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "incomplete" and "No space left on device" in summary["error"]
    text = (out / "results.csv").read_text()
    assert text.endswith("\n") and text.count("\n") - 1 == summary["rows"]
    # the summary agrees with the file's last row (it said t = 2 s beyond it)
    header, last = text.splitlines()[0].split(","), text.splitlines()[-1].split(",")
    assert summary["time_reached"] == float(last[0])
    final = summary["final_values"]
    assert all(
        final[name] == float(value) for name, value in zip(header[1:], last[1:], strict=True)
    )


def fill(mount: Path, leave_pages: int = 0) -> None:
    """Fill the disk at ``mount``, then free ``leave_pages`` pages of 4 KiB."""
    filler = mount / "filler"
    with filler.open("wb", buffering=0) as f:
        try:
            while f.write(b"\0" * 4096):
                pass
        except OSError:
            pass
    size = filler.stat().st_size
    os.truncate(filler, max(0, size - 4096 * leave_pages))


@pytest.mark.parametrize(
    ("pages", "file"), [(0, ".auv-cosim.lock"), (1, "results.csv")], ids=["lock", "results"]
)
def test_a_disk_full_at_the_start_leaves_nothing_behind(
    fmu_dir: Path, small_disk: Path, pages: int, file: str
):
    """A full disk at the start left an empty results.csv (a folder later runs refused
    even with --overwrite) or, with 0 bytes free, a bare OSError and the lock file."""
    fill(small_disk, pages)
    out = small_disk / "run"
    done = run_cli(fmu_dir, "--out", str(out), "--stop-time", "1", "--no-rrd")
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert f"cannot write {out / file}: No space left on device" in done.stderr
    assert not out.exists()


@pytest.mark.slow
def test_a_recording_filling_the_disk_leaves_the_results_complete(
    fmu_dir: Path, small_disk: Path, tmp_path: Path
):
    """A recording whose disk filled up stopped the whole run at that point (results.csv
    cut short, exit 1) although results.csv had room: the run now goes on without the
    recording, says so in one line and exits 3, its results and summary whole."""
    # long enough that the rows reach the recording while the run steps (a 60 s run may
    # be done before its first hand-off to the sinks)
    out, rrd = tmp_path / "run", small_disk / "recording.rrd"
    done = run_cli(fmu_dir, "--out", str(out), "--stop-time", "600", "--rrd", str(rrd))
    assert done.returncode == 3, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    assert f"cannot write the recording {rrd}: No space left on device" in lines[0]
    assert f"results complete in {out}" in lines[0], lines[0]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "complete" and summary["time_reached"] == 600.0
    assert "No space left on device" in summary["recording_error"]
    text = (out / "results.csv").read_text()
    assert text.count("\n") - 1 == summary["rows"] == 60001


@pytest.mark.slow
def test_a_recording_on_a_device_refusing_every_write_is_refused(fmu_dir: Path, tmp_path: Path):
    if not DEV_FULL.exists():
        pytest.skip("no /dev/full")
    done = run_cli(fmu_dir, "--out", str(tmp_path / "run"), "--rrd", str(DEV_FULL), "--overwrite")
    assert done.returncode == 1 and done.stderr.count("\n") == 1
    assert "--rrd /dev/full: is not a regular file" in done.stderr
    assert not (tmp_path / "run").exists()  # refused before the first step


def test_results_on_a_device_refusing_every_write_name_it():
    if not DEV_FULL.exists():
        pytest.skip("no /dev/full")
    with pytest.raises(CosimError, match="cannot write /dev/full: No space left on device"):
        CsvSink(DEV_FULL, ("plant.yaw",))


def test_results_removed_while_written_stop_the_sink(tmp_path: Path):
    """results.csv removed while the run wrote it (its folder removed) took every later
    row into the removed file, to be lost when the run ended; the next rows now fail,
    naming the file."""
    path = tmp_path / "results.csv"
    sink = CsvSink(path, ("plant.yaw",))
    try:
        sink.add_rows(np.array([0.0]), np.array([[0.1]]))
        path.unlink()
        with pytest.raises(CosimError) as raised:
            sink.add_rows(np.array([0.01]), np.array([[0.2]]))
    finally:
        sink.close()
    assert str(raised.value) == f"cannot write {path}: it was removed while the run wrote it"


@pytest.mark.slow
def test_a_run_whose_folder_is_removed_stops_saying_so(fmu_dir: Path, tmp_path: Path):
    """A run whose folder was removed while it stepped went on to its stop time writing
    into the removed files, then said "cannot record .../recording.rrd: it is not a
    regular file any more (partial results in FOLDER)", a folder that no longer existed.
    It now stops at the next rows, naming results.csv, and says nothing is kept (not
    "partial results in" a folder whose rm -rf was under way as the run ended)."""
    out = tmp_path / "run"
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir)]
    command += ["--quiet", "--no-rrd", "--out", str(out), "--stop-time", "3000"]
    with subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    ) as proc:  # fmt: skip
        try:
            results = out / "results.csv"
            while proc.poll() is None and (
                not results.exists() or results.stat().st_size < 1_000_000
            ):
                time.sleep(0.05)
            for _ in range(100):  # the run may make a file between rmtree's listing and
                shutil.rmtree(out, ignore_errors=True)  # its rmdir: again, as rm -rf would
                if not out.exists():
                    break
            stdout, stderr = proc.communicate(timeout=300)
        finally:
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
    assert proc.returncode == 1, stderr
    lines = stderr.strip().splitlines()
    assert len(lines) == 1, stderr
    assert f"cannot write {out / 'results.csv'}: it was removed while the run wrote it" in lines[0]
    # the folder may still stand as the run ends (rm -rf under way), its results.csv gone
    kept = (f"nothing kept: {out} was removed", f"nothing kept: {out} holds no results.csv")
    assert any(said in lines[0] for said in kept), lines[0]
    reached = float(stdout.split("t = ", 1)[1].split(" ", 1)[0])
    assert reached < 3000.0, stdout  # it stopped, not stepped on into the removed file
    assert not out.exists()


def test_the_real_time_factor_is_the_loops_when_results_stopped_short(fmu_dir: Path) -> None:
    """Guards summary.json's real_time_factor, the loop's (docs/runs.md), for a run whose
    results.csv stopped short of the rows computed (a full disk): time_reached is then the
    file's last row, but the factor is of the simulated time the loop stepped, as the
    report's line says it; it was taken of the last row written instead."""
    import cosim
    from cosim.engine.master import RunResult
    from cosim.outputs.results import final_summary

    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    columns = scenario.columns
    result = RunResult(scenario, columns, rows=1001, time_reached=10.0,
                       final=np.ones(len(columns)), complete=False, error="disk full",
                       wall_clock_s=4.0)  # fmt: skip
    last_row = (2.0, np.zeros(len(columns)))  # the file's last row, at t = 2 s
    summary = final_summary({}, result, {}, "disk full", None, 201, last_row=last_row)
    assert summary["time_reached"] == 2.0  # the file's, as the summary agrees with it
    assert summary["real_time_factor"] == 10.0 / 4.0  # the loop stepped 10 s in 4 s
