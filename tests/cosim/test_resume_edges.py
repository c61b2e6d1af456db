"""Checkpoints and resumes at their edges: a checkpoint that cannot be written (a full
disk) stops the run where it was asked for, results.csv holding the rows up to there and
no others, the checkpoint before it kept whole and resumable; a resume that cannot write
its own leaves the folder as it was; a run stopped at t = 0 resumes; and a resume that
would not continue the run as it was (a vehicle file edited, --fmu-log) is refused, named.
A run stopped by a full disk is also the killed run the other tests start from."""

from __future__ import annotations

import errno
import json
import re
import signal
from pathlib import Path
from typing import Any

import pytest

import cosim.engine.master as master
import cosim.outputs.checkpoint_file as checkpoint_file
from cosim.engine.signals import StopRequest
from cosim.errors import CosimError
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.runner import RunOptions, execute, resume_run, run_scenario

ROOT = Path(__file__).resolve().parents[2]


def _fail_from(monkeypatch: pytest.MonkeyPatch, call: int) -> None:
    """checkpoint.json's writes fail from the ``call``-th on as a full disk fails them."""
    write, calls = checkpoint_file._written_beside, [0]

    def full(path: Path, data: bytes) -> Path:
        calls[0] += 1
        if calls[0] >= call:
            raise OSError(errno.ENOSPC, "No space left on device")
        return write(path, data)

    monkeypatch.setattr(checkpoint_file, "_written_beside", full)


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


def test_a_resume_that_cannot_checkpoint_leaves_the_folder_as_it_was(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The resume checkpoints again before the earlier run's files go: a full disk then
    stops it with the folder as it was, to resume once there is room."""
    common = {"stop_time": 10.0, "no_rrd": True, "fmu_dir": fmu_dir}
    whole = run_scenario("bs-3", tmp_path / "whole", **common)
    out = tmp_path / "full"
    _fail_from(monkeypatch, 3)
    assert not run_scenario("bs-3", out, checkpoint_every=2.0, **common).result.complete
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    _fail_from(monkeypatch, 1)
    with pytest.raises(CosimError, match="No space left on device"):
        resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    monkeypatch.undo()
    assert resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir)).result.complete
    assert (out / "results.csv").read_bytes() == whole.paths["results"].read_bytes()


def test_a_resume_refuses_a_vehicle_file_changed_since_the_checkpoint(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The scenario's vehicle file is read again by a resume: edited since, the run would
    go on with another vehicle than the rows before the checkpoint were computed with."""
    vehicle = tmp_path / "vehicle.toml"
    vehicle.write_bytes((ROOT / "plant_fmu/model/vehicles/remus100.toml").read_bytes())
    text = (ROOT / "cosim/scenarios/bs-3.toml").read_text(encoding="utf-8")
    scenario = tmp_path / "bs-3-vehicle.toml"
    scenario.write_text(
        text.replace(
            "[instances.plant.start]\n", '[instances.plant.start]\nvehicle = "vehicle.toml"\n'
        ),
        encoding="utf-8",
    )
    out = tmp_path / "run"
    _fail_from(monkeypatch, 3)
    stopped = run_scenario(scenario, out, checkpoint_every=2.0, stop_time=10.0, no_rrd=True,
                           fmu_dir=fmu_dir)  # fmt: skip
    assert not stopped.result.complete
    monkeypatch.undo()
    vehicle.write_text(vehicle.read_text().replace("\nI_zz = 3.45", "\nI_zz = 4.45"))
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    with pytest.raises(CosimError, match=re.escape(f"{vehicle} is not the file")) as refused:
        resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert "\n" not in str(refused.value)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_a_run_stopped_at_t_0_resumes_to_the_uninterrupted_results(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A signal as row 0 is recorded stops the run before its first step, checkpointed
    at t = 0: the resume steps on from there without recording row 0 a second time."""
    common = {"stop_time": 1.0, "no_rrd": True, "fmu_dir": fmu_dir}
    whole = run_scenario("bs-3", tmp_path / "whole", **common)
    stop, row_zero = StopRequest(), master._row_zero

    def signalled(*args: Any) -> int:
        stop.signum = signal.SIGTERM
        return row_zero(*args)

    monkeypatch.setattr(master, "_row_zero", signalled)
    out = tmp_path / "run"
    stopped = execute("bs-3", RunOptions(out_dir=out, checkpoint_every=0.5, **common), stop)
    assert stopped.result.time_reached == 0.0 and not stopped.result.complete
    assert json.loads((out / CHECKPOINT_FILE).read_text())["step"] == 0
    monkeypatch.undo()
    resumed = resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert resumed.result.rows == whole.result.rows
    assert (out / "results.csv").read_bytes() == whole.paths["results"].read_bytes()


def test_an_interval_past_any_double_step_count_checkpoints_only_on_signals(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """--checkpoint-every 1e308: so many steps are no float an int can take; the run is
    checkpointed where a signal stops it, and no other time."""
    out = tmp_path / "run"
    done = run_scenario("bs-3", out, stop_time=0.05, checkpoint_every=1e308, no_rrd=True,
                        fmu_dir=fmu_dir)  # fmt: skip
    assert done.result.complete
    assert not (out / CHECKPOINT_FILE).exists()


def test_a_resume_refuses_fmu_log_naming_it(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--fmu-log writes the instances' debug logging into the scenario, which the
    checkpoint's then differs from: named as the option it is, not as an edited file."""
    out = tmp_path / "run"
    _fail_from(monkeypatch, 2)
    stopped = run_scenario("bs-3", out, checkpoint_every=0.5, stop_time=2.0, no_rrd=True,
                           fmu_dir=fmu_dir)  # fmt: skip
    assert not stopped.result.complete
    monkeypatch.undo()
    options = RunOptions(no_rrd=True, fmu_dir=fmu_dir, fmu_log={"plant": ()})
    with pytest.raises(CosimError, match=r"^--fmu-log cannot be given with --resume: "):
        resume_run(out, options)
