"""The resume of a long run: the rows it wrote up to its checkpoint are replayed into the
new results.csv a chunk at a time, never held whole (6 h of bs-3 at 10 ms are 2.16 million
rows of 36 columns: 620 MB as one table), and its real-time factor is of the simulated time
it stepped itself."""

from __future__ import annotations

import json
import signal
import tracemalloc
from pathlib import Path
from typing import Any

import pytest

import cosim.engine.master as master
import cosim.outputs.checkpoint_file as checkpoint_file
import cosim.outputs.results as results
from cosim.engine.signals import StopRequest
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.runner import RunOptions, execute, resume_run

CHUNK = 1_000  # rows parsed at a time in this test


def _stopped_after_first_checkpoint(
    monkeypatch: pytest.MonkeyPatch, fmu_dir: Path, out: Path, stop_time: float, every: float
) -> None:
    """bs-3 to ``stop_time`` s in ``out``, checkpointing every ``every`` s, SIGTERMed right
    after its first checkpoint is saved."""
    stop, save = StopRequest(), master._Saver.save

    def save_then_stop(self: Any, n: int) -> int:
        stop.signum = signal.SIGTERM
        return save(self, n)

    monkeypatch.setattr(master._Saver, "save", save_then_stop)
    options = RunOptions(out_dir=out, stop_time=stop_time, checkpoint_every=every,
                         no_rrd=True, fmu_dir=fmu_dir)  # fmt: skip
    assert not execute("bs-3", options, stop).result.complete
    monkeypatch.undo()


@pytest.mark.slow
def test_a_resume_holds_a_chunk_of_the_earlier_rows_not_all_of_them(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    out = tmp_path / "run"
    _stopped_after_first_checkpoint(monkeypatch, fmu_dir, out, 450.0, 400.0)
    rows = json.loads((out / CHECKPOINT_FILE).read_text())["rows"]
    assert rows > 40 * CHUNK
    with (out / "results.csv").open(encoding="utf-8") as file:
        columns = len(results.header_columns(file.readline()))
    table = rows * columns * 8  # bytes of the rows as one table of doubles

    monkeypatch.setattr(results, "READ_CHUNK_ROWS", CHUNK)
    read = checkpoint_file.read_checkpoint

    def traced_from_then_on(*args: Any) -> Any:
        # (reading checkpoint.json reserves its 256 MB limit, pages never touched)
        tracemalloc.stop()
        saved = read(*args)
        tracemalloc.start()
        return saved

    monkeypatch.setattr(checkpoint_file, "read_checkpoint", traced_from_then_on)
    try:
        resumed = resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert resumed.result.complete
    # the replay is start-up of its own, named in the report, not time unaccounted for
    assert resumed.result.startup_s["replay"] > 0.0
    assert peak < table / 3, f"the resume held {peak / 1e6:.1f} MB for {table / 1e6:.1f} MB of rows"


def test_a_resumed_run_s_real_time_factor_is_of_the_time_it_stepped(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    # resumed at t = 4 s of 10, the loop steps 6 s: its factor is 6 s over its wall clock,
    # not 10 s (a resume at 3 h of a 6 h run reported twice its speed)
    out = tmp_path / "run"
    _stopped_after_first_checkpoint(monkeypatch, fmu_dir, out, 10.0, 4.0)
    start = json.loads((out / CHECKPOINT_FILE).read_text())["time"]
    assert 0.0 < start < 10.0
    resumed = resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir)).result
    summary = json.loads((out / "summary.json").read_text())
    stepped = resumed.time_reached - start
    assert summary["real_time_factor"] == pytest.approx(stepped / summary["wall_clock_s"])
