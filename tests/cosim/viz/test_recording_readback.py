"""A run's recording read back as an analyst reads it (docs/runs.md, "Reading a recording
in Python") holds results.csv: every column, every row once, at its time, the same
doubles in each plot's unit; and its events log holds each fault's start at its time,
for a run stopped and resumed from its checkpoint too."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pytest
from killed_runs import kill_after_checkpoint
from rerun.chunk import RrdReader

from cosim.runner import run_scenario
from cosim.scenario.spec import load_scenario
from cosim.viz.display_units import DRAWN_FROM

STOP_TIME = 120.0  # s: long enough that a SIGTERM after the first checkpoint finds it running
FAULT_START = 3.0  # s, mass-jam's jam (cosim/scenarios/mass-jam.toml)


@dataclass
class Readback:
    """What a recording holds of a run: per plot entity, its results.csv columns, their
    units and its rows (``sim_time`` in ns, values (rows, columns)); the events log."""

    columns: dict[str, list[str]]
    units: dict[str, list[str]]
    times: dict[str, np.ndarray]
    values: dict[str, np.ndarray]
    events: list[tuple[int, str]]  # (sim_time in ns, text)


def read_back(rrd: Path) -> Readback:
    columns: dict[str, list[str]] = {}
    units: dict[str, list[str]] = {}
    times: dict[str, list[np.ndarray]] = {}
    values: dict[str, list[np.ndarray]] = {}
    events: list[tuple[int, str]] = []
    for chunk in RrdReader(rrd).stream():
        batch = chunk.to_record_batch()
        names, entity = batch.schema.names, chunk.entity_path
        if "results_columns" in names:
            columns[entity] = batch["results_columns"][0].as_py()
            units[entity] = batch["units"][0].as_py()
            continue
        if "sim_time" not in names:
            continue
        nanos = batch["sim_time"].cast(pa.int64()).to_numpy()
        if "Scalars:scalars" in names:
            times.setdefault(entity, []).append(nanos)
            flat = batch["Scalars:scalars"].flatten().to_numpy()
            values.setdefault(entity, []).append(flat.reshape(batch.num_rows, -1))
        if "TextLog:text" in names:
            texts = batch["TextLog:text"].flatten().to_pylist()
            events += zip(nanos.tolist(), texts, strict=True)
    return Readback(
        columns, units,
        {e: np.concatenate(t) for e, t in times.items()},
        {e: np.concatenate(v) for e, v in values.items()},
        sorted(events),
    )  # fmt: skip


def assert_recording_is_results(run: Path) -> Readback:
    """The recording of ``run`` against its results.csv and summary.json's units."""
    back = read_back(run / "recording.rrd")
    results = pd.read_csv(run / "results.csv", dtype=float)
    declared = json.loads((run / "summary.json").read_text())["units"]
    nanos = np.rint(results["time"].to_numpy() * 1e9).astype(np.int64)
    plotted = [c for entity in back.columns for c in back.columns[entity]]
    assert sorted(plotted) == sorted(results.columns[1:]), "columns not plotted exactly once"
    for entity, names in back.columns.items():
        t = back.times[entity]
        assert len(np.unique(t)) == len(t), f"{entity}: a time recorded twice"
        order = np.argsort(t, kind="stable")
        np.testing.assert_array_equal(t[order], nanos, err_msg=f"{entity}: its times")
        shown = back.values[entity][order]
        for i, (name, unit) in enumerate(zip(names, back.units[entity], strict=True)):
            scale = 1.0 if unit == declared[name] else DRAWN_FROM[unit][1]
            expected = results[name].to_numpy() * scale
            np.testing.assert_array_equal(shown[:, i], expected, err_msg=f"{entity}: {name}")
    return back


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", "run", *args, "--quiet"]


@pytest.mark.slow
def test_a_resumed_runs_recording_holds_every_row_once_and_the_fault_start(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """mass-jam stopped by SIGTERM after its first checkpoint (t = 10 s, its mass jammed
    since 3 s) and resumed: the rewritten recording equals results.csv, and its events
    log still marks the jam at 3 s, once, before the run's end."""
    out = tmp_path / "run"
    common = ("--fmu-dir", str(fmu_dir))
    command = _cli("mass-jam", "--out", str(out), "--stop-time", f"{STOP_TIME:g}",
                   "--checkpoint-every", "10", *common)  # fmt: skip
    assert kill_after_checkpoint(command, out) == 128 + signal.SIGTERM
    resumed = subprocess.run(_cli("--resume", str(out), *common), capture_output=True,
                             text=True, timeout=600)  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    back = assert_recording_is_results(out)
    jam = [t for t, text in back.events if text.startswith("fault jam starts")]
    assert jam == [round(FAULT_START * 1e9)], back.events
    ends = [(t, text) for t, text in back.events if text.startswith("run complete")]
    end = f"run complete at t = {STOP_TIME:g} s (its stop time)"
    assert ends == [(round(STOP_TIME * 1e9), end)]


def test_a_yaw_set_point_a_turn_away_is_drawn_on_the_yaws_turn(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """bs-3 started at 350 deg with its set-point at 10 deg (20 deg to starboard): the
    recording's yaw plot drew the set-point 340 deg below the yaw, a turn away from the
    heading it names. It is drawn within 180 deg of the yaw, whole turns from its
    results.csv value, as the report draws it."""
    scenario = (
        load_scenario("bs-3", fmu_dir=fmu_dir)
        .with_start({"plant.yaw_0": math.radians(350.0), "controller.yaw_setpoint": 0.17453})
        .with_overrides(stop_time=0.5)
    )
    run = tmp_path / "run"
    assert run_scenario(scenario, run, fmu_dir=fmu_dir).result.complete
    back = read_back(run / "recording.rrd")
    results = pd.read_csv(run / "results.csv", dtype=float)
    entity = next(e for e, names in back.columns.items() if "controller.yaw_setpoint" in names)
    names = back.columns[entity]
    shown = back.values[entity][np.argsort(back.times[entity], kind="stable")]
    yaw = shown[:, names.index("plant.yaw")]
    setpoint = shown[:, names.index("controller.yaw_setpoint")]
    np.testing.assert_array_equal(yaw, np.degrees(1.0) * results["plant.yaw"].to_numpy())
    assert np.all(np.abs(setpoint - yaw) <= 180.0), (setpoint[0], yaw[0])
    turns = (setpoint - np.degrees(1.0) * results["controller.yaw_setpoint"].to_numpy()) / 360.0
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
