"""A checkpoint that cannot be written (a full disk) stops the run where it was asked
for: results.csv holds the rows up to there and no others, the checkpoint before it is
kept whole, and the run resumes from that one to the uninterrupted run's results."""

from __future__ import annotations

import errno
import json
from pathlib import Path

import pytest

import cosim.outputs.checkpoint_file as checkpoint_file
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.runner import RunOptions, resume_run, run_scenario


def _fail_from(monkeypatch: pytest.MonkeyPatch, call: int) -> None:
    """checkpoint.json's writes fail from the ``call``-th on as a full disk fails them."""
    write, calls = checkpoint_file._write_synced, [0]

    def full(path: Path, data: bytes) -> None:
        calls[0] += 1
        if calls[0] >= call:
            raise OSError(errno.ENOSPC, "No space left on device")
        write(path, data)

    monkeypatch.setattr(checkpoint_file, "_write_synced", full)


def test_a_checkpoint_on_a_full_disk_stops_the_run_at_its_point(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    common = {"stop_time": 10.0, "no_rrd": True, "fmu_dir": fmu_dir}
    whole = run_scenario("bs-3", tmp_path / "whole", **common)
    out = tmp_path / "full"
    _fail_from(monkeypatch, 3)  # the checkpoints at t = 2 and 4 written, t = 6 not
    failed = run_scenario("bs-3", out, checkpoint_every=2.0, **common).result
    assert not failed.complete
    assert failed.error is not None and "No space left on device" in failed.error
    assert failed.time_reached == pytest.approx(6.0)
    lines = (out / "results.csv").read_bytes().splitlines(keepends=True)
    expected = (whole.paths["results"]).read_bytes().splitlines(keepends=True)
    assert len(lines) == 602  # the header, t = 0 to 6 s
    assert lines == expected[: len(lines)]
    assert json.loads((out / CHECKPOINT_FILE).read_text())["time"] == pytest.approx(4.0)
    monkeypatch.undo()
    resumed = resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert resumed.result.complete
    assert (out / "results.csv").read_bytes() == b"".join(expected)
