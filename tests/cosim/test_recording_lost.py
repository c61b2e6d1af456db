"""A recording that fails while the run steps (a full disk) is dropped and the run goes
on: the command exits 3 and says so in one line, ``cosim.run`` warns, and summary.json
names the failure; results.csv is whole."""

from __future__ import annotations

import errno
import json
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import cosim
from cosim import runner
from cosim.cli import main

NO_SPACE = os.strerror(errno.ENOSPC)


class FillingRecording:
    """A recording sink whose disk is full from its second chunk of rows on."""

    def __init__(self, rrd: Path) -> None:
        self.rrd, self.chunks = rrd, 0

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self.chunks += 1
        if self.chunks > 1:
            raise OSError(f"cannot write the recording {self.rrd}: {NO_SPACE}")

    def add_notes(self, notes: Sequence[tuple[float, str]]) -> None:
        pass

    def close(self) -> None:
        pass


@pytest.fixture
def filling_recording(monkeypatch: pytest.MonkeyPatch) -> None:
    def recorder(scenario: Any, rrd: Path | None, url: str | None, flushed: Any) -> Any:
        assert rrd is not None
        rrd.write_bytes(b"")  # as the sink would create it
        return FillingRecording(rrd)

    monkeypatch.setattr(runner, "rerun_sink", recorder)


def _rows_of(out: Path) -> Callable[[], tuple[int, int]]:
    def rows() -> tuple[int, int]:
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        lines = (out / "results.csv").read_text(encoding="utf-8").count("\n")
        return summary["rows"], lines - 1

    return rows


def test_the_command_exits_3_with_the_results_whole(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], filling_recording: None
) -> None:
    """The failing recording ended the whole run there, results.csv cut short, exit 1."""
    out = tmp_path / "run"
    args = ["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", str(out), "--quiet"]
    assert main([*args, "--stop-time", "30"]) == 3
    captured = capsys.readouterr()
    assert captured.err == (
        f"auv-cosim run: cannot write the recording {out / 'recording.rrd'}: {NO_SPACE}; "
        f"the run went on without it: results complete in {out}\n"
    )
    assert "recording.rrd (cut short: it could not be written)" in captured.out
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert summary["complete"] and summary["time_reached"] == 30.0
    assert summary["recording_error"].endswith(NO_SPACE)
    assert _rows_of(out)() == (3001, 3001)


def test_cosim_run_warns_and_returns_the_whole_run(
    fmu_dir: Path, tmp_path: Path, filling_recording: None
) -> None:
    """``cosim.run`` raised RunError for the run the recording had cut short."""
    out = tmp_path / "run"
    with pytest.warns(UserWarning, match=f"cosim.run: cannot write the recording .*{NO_SPACE}"):
        run = cosim.run("bs-3", stop_time=30.0, out=out, fmu_dir=fmu_dir)
    assert len(run.results) == 3001 and run.summary["recording_error"].endswith(NO_SPACE)


def test_the_lost_recording_warning_points_at_the_callers_line(
    fmu_dir: Path, tmp_path: Path, filling_recording: None
) -> None:
    """The warning named a line inside cosim/api.py, not the user's call."""
    with pytest.warns(UserWarning, match="cosim.run: ") as caught:
        cosim.run("bs-3", stop_time=30.0, out=tmp_path / "run", fmu_dir=fmu_dir)
    assert [Path(w.filename).name for w in caught] == [Path(__file__).name]


class RemovedRecording(FillingRecording):
    """A recording sink whose file is removed after its first chunk of rows."""

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self.chunks += 1
        if self.chunks == 2:
            self.rrd.unlink()


def test_a_recording_removed_while_written_leaves_the_run_complete(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:  # fmt: skip
    """A recording removed while the run wrote it (``--rrd`` in a folder removed) made the
    complete run incomplete at its end: "cannot record ...: it is not a regular file any
    more", exit 1."""

    def recorder(scenario: Any, rrd: Path | None, url: str | None, flushed: Any) -> Any:
        assert rrd is not None
        rrd.write_bytes(b"")
        return RemovedRecording(rrd)

    monkeypatch.setattr(runner, "rerun_sink", recorder)
    out, rrd = tmp_path / "run", tmp_path / "elsewhere" / "x.rrd"
    args = ["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", str(out), "--quiet"]
    assert main([*args, "--stop-time", "30", "--rrd", str(rrd)]) == 3
    assert capsys.readouterr().err == (
        f"auv-cosim run: the recording {rrd} was removed while the run wrote it; "
        f"the run went on without it: results complete in {out}\n"
    )
    assert _rows_of(out)() == (3001, 3001)


FILE_SIZE_LIMITED_RUN = """
import resource, sys
from cosim.cli import main
limit = int(sys.argv[1])
resource.setrlimit(resource.RLIMIT_FSIZE, (limit, resource.RLIM_INFINITY))
sys.exit(main(["run", "bs-3", "--stop-time", "120", "--fmu-dir", sys.argv[2],
               "--out", sys.argv[3], "--quiet"]))
"""


@pytest.mark.slow
def test_a_recording_cut_by_a_full_disk_keeps_most_of_what_fitted(
    run_python: Callable[..., Any], fmu_dir: Path, tmp_path: Path
) -> None:
    """A recording that fails is cut back to its last whole flush: a fast run flushed only
    every 5,000 rows (~3.2 MB of bs-3), so under a 3 MB file-size limit bs-3's recording
    kept its first 183 KB (the layout, no row). Flushed at least every BATCH_BYTES of rows,
    it keeps all but the last of those."""
    limit, out = 3 << 20, tmp_path / "run"
    done = run_python(FILE_SIZE_LIMITED_RUN, limit, fmu_dir, out)
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    assert "File too large" in summary["recording_error"], done.stderr
    kept = (out / "recording.rrd").stat().st_size
    assert kept >= limit // 2, f"{kept} bytes of the recording kept under a {limit}-byte limit"
