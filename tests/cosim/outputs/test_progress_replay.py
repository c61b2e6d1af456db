"""A resumed run's progress bar: the rows replayed up to the checkpoint are a phase of
their own, and the bar of steps starts past them, so its rate is the stepping's."""

from __future__ import annotations

import errno
from pathlib import Path

import numpy as np
import pytest

import cosim.outputs.checkpoint_file as checkpoint_file
from cosim.outputs.sinks import ProgressSink
from cosim.runner import RunOptions, resume_run, run_scenario


def test_replayed_rows_are_not_counted_as_steps(capsys: pytest.CaptureFixture) -> None:
    """The replayed rows went into the bar as steps: read from results.csv several times
    faster than stepped, they made the bar's first rate high and its time left short."""
    bar = ProgressSink(10, "bs-3")
    bar.replayed_rows = 5
    for count in (3, 3, 4):  # the last replayed row arrives with the first stepped one
        bar.add_rows(np.zeros(count), np.zeros((count, 1)))
    bar.close()
    err = capsys.readouterr().err
    assert "bs-3: replaying the rows to the checkpoint (3 of 5)" in err, err
    assert "(5 of 5)" in err, err
    shown = [int(part.split("/")[0].split()[-1]) for part in err.split("\r") if "/10 " in part]
    assert shown and min(shown) == 5, err  # the bar starts at the checkpoint's row


def test_a_resumed_run_s_bar_starts_at_its_checkpoint(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """The runner tells the bar the rows its checkpoint replays: a run of bs-3 stopped by a
    full disk at its second checkpoint (t = 1 s), resumed from the first (t = 0.5 s)."""
    write, calls = checkpoint_file._written_beside, [0]

    def full_from_the_second(path: Path, data: bytes) -> Path:
        calls[0] += 1
        if calls[0] >= 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return write(path, data)

    monkeypatch.setattr(checkpoint_file, "_written_beside", full_from_the_second)
    out = tmp_path / "run"
    common = {"stop_time": 2.0, "no_rrd": True, "fmu_dir": fmu_dir}
    assert not run_scenario("bs-3", out, checkpoint_every=0.5, **common).result.complete
    monkeypatch.undo()
    capsys.readouterr()
    resumed = resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir, progress=True))
    assert resumed.result.complete
    err = capsys.readouterr().err
    assert "bs-3: replaying the rows to the checkpoint (51 of 51)" in err, err
    shown = [int(part.split("/")[0].split()[-1]) for part in err.split("\r") if "/201 " in part]
    assert shown and min(shown) == 51, err
