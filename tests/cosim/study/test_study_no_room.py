"""A study whose disk fills (or whose runs meet a quota or a file size limit) ends with
one line saying so and keeps every finished row; ``--resume`` runs the rest once there
is room. The study runs as ``auv-cosim sweep`` in a process group of its own, under
``ulimit -f`` (RLIMIT_FSIZE, which its workers inherit: a run's results.csv outgrows it),
with the test's own folder as TMPDIR."""

from __future__ import annotations

import csv
import errno
import os
import re
import resource
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from process_group import run_in_group

# 4 runs of bs-3, each writing ~9 MB of results.csv (kept if it fails: written by every
# run; with keep = "none" a run writes none)
STUDY = """scenario = "bs-3"
stop_time = 200.0
keep = "failed"
[grid]
"plant.v_0" = [-0.05, 0.05]
"controller.k0" = [0.2, 0.5]
"""
LIMIT = 2 << 20  # bytes a file: a run's results.csv outgrows it at about t = 45 s


def limited() -> None:
    """In the child before it runs the command: no file of it may grow past LIMIT."""
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def stopped_after_a_row(command: list[str], table: Path, env: dict[str, str]) -> None:
    """Run ``command`` (a study) until its table holds a row, then stop it with SIGINT."""
    proc = subprocess.Popen(command, env=env, text=True, start_new_session=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)  # fmt: skip
    try:
        deadline = time.monotonic() + 240
        while not (table.is_file() and table.read_text().count("\n") > 1):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no run finished"
            time.sleep(0.05)
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=120) == 130, proc.communicate()
    finally:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


@pytest.mark.slow
@pytest.mark.cluster
def test_a_study_out_of_room_ends_keeping_its_rows_for_resume(fmu_dir: Path, tmp_path: Path):
    """Every run past the point where the disk filled was a `failed` row ("No space left
    on device" in its error) and the study ran on through all of them; --resume skips a
    row of the table, so those runs were never run again, even with room."""
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "TMPDIR": str(tmp_path / "tmp")}
    (tmp_path / "study.toml").write_text(STUDY)
    table = tmp_path / "out" / "runs.csv"
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(tmp_path / "study.toml"),
               "--out", str(tmp_path / "out"), "--workers", "2", "--oversubscribe",
               "--fmu-dir", str(fmu_dir), "--quiet"]  # fmt: skip
    stopped_after_a_row(command, table, env)
    finished = table.read_text()
    full = run_in_group([*command, "--resume"], timeout=300, env=env, preexec_fn=limited)
    assert full.returncode == 1, full.stderr
    last = full.stderr.strip().splitlines()[-1]
    assert "found no room for its files" in last and os.strerror(errno.EFBIG) in last, full.stderr
    assert re.search(rf" \d+ finished runs? kept in {re.escape(str(table))} \(--resume\)", last)
    assert table.read_text().startswith(finished) and "failed" not in table.read_text()
    done = run_in_group([*command, "--resume"], timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    with table.open(encoding="utf-8") as file:
        rows = list(csv.DictReader(file))
    assert [row["status"] for row in rows] == ["complete"] * 4
    assert set(finished.splitlines()) <= set(table.read_text().splitlines())


# 4 runs of bs-3, each kept in runs/<id>/ with a results.csv of ~430 kB: a 1 MB disk
# holds two
KEPT_STUDY = """scenario = "bs-3"
stop_time = 10.0
keep = "all"
[grid]
"plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
"""


@pytest.fixture
def small_disk(tmp_path: Path) -> Iterator[Path]:
    """A 1 MB tmpfs at tmp_path/small, unmounted afterwards."""
    mount = tmp_path / "small"
    mount.mkdir()
    done = run_in_group(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(mount)], timeout=30)
    if done.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {done.stderr.strip()}")
    try:
        yield mount
    finally:
        run_in_group(["umount", "-l", str(mount)], timeout=30)


@pytest.mark.slow
@pytest.mark.cluster
def test_a_kept_run_folder_the_disk_cannot_hold_is_run_again_at_resume(
    fmu_dir: Path, tmp_path: Path, small_disk: Path
):
    """A kept run's folder that filled the study's disk ended the study with "OSError:
    [Errno 28] No space left on device", naming no file, its row already in runs.csv and
    its folder holding a results.csv cut mid-row (and no summary.json): --resume never
    wrote it again. The study now names the file, leaves that run's row out, and --resume
    runs it again once there is room."""
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "TMPDIR": str(tmp_path / "tmp")}
    (tmp_path / "study.toml").write_text(KEPT_STUDY)
    out = small_disk / "out"
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(tmp_path / "study.toml"),
               "--out", str(out), "--workers", "1", "--fmu-dir", str(fmu_dir),
               "--quiet"]  # fmt: skip
    full = run_in_group(command, timeout=300, env=env)
    assert full.returncode == 1, full.stderr
    last = full.stderr.strip().splitlines()[-1]
    assert "OSError" not in last and f"{out / 'runs'}/" in last, last
    assert os.strerror(errno.ENOSPC) in last and "--resume" in last, last

    def folders_whole() -> int:
        with (out / "runs.csv").open(encoding="utf-8") as file:
            rows = list(csv.DictReader(file))
        for row in rows:
            folder = out / "runs" / row["run"]
            summary = (folder / "summary.json").read_text(encoding="utf-8")
            lines = (folder / "results.csv").read_text(encoding="utf-8").count("\n")
            assert f'"rows": {lines - 1},' in summary, row["run"]
        return len(rows)

    assert folders_whole() < 4
    run_in_group(["mount", "-o", "remount,size=8m", str(small_disk)], timeout=30)
    done = run_in_group([*command, "--resume"], timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    assert folders_whole() == 4
