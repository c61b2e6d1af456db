"""A recording says how its run ended, at the time it ended, in its events log.

A run that failed or was stopped mid-way left a recording whose plots simply stopped:
someone in the viewer could not tell it from a run that reached its stop time, nor see why.
The runs are the master tests' loop (an integrator under a sampled gain, tests/fmus).
"""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pytest
from rerun.chunk import RrdReader
from scenario_factory import loop_toml

from cosim.outputs.folder import RECORDING_FILE
from cosim.runner import run_scenario
from cosim.scenario.spec import scenario_from_toml

EVENTS = "/events"


def notes(rrd: Path) -> list[tuple[float, str, str]]:
    """(sim_time in s, level, text) of every entry of the recording's events log."""
    found = []
    for chunk in RrdReader(rrd).stream():
        if chunk.entity_path != EVENTS:
            continue
        batch = chunk.to_record_batch()
        times = batch.column("sim_time").cast(pa.int64()).to_pylist()
        texts = batch.column("TextLog:text").to_pylist()
        names = batch.schema.names
        levels = (
            batch.column("TextLog:level").to_pylist()
            if "TextLog:level" in names
            else [None] * len(texts)
        )
        for t, text, level in zip(times, texts, levels, strict=True):
            found.append((t / 1e9, (level or [""])[0], text[0]))
    assert found, f"{rrd}: nothing in its events log ({EVENTS})"
    return sorted(found)


def _run(fmu_dir: Path, out: Path, plant_start: str = ""):
    scenario = scenario_from_toml(loop_toml(plant_start=plant_start), base_dir=fmu_dir)
    return run_scenario(scenario, out).result


@pytest.mark.slow
def test_a_failed_run_s_recording_ends_saying_why_where_it_failed(
    test_fmu_dir: Path, tmp_path: Path
):
    result = _run(test_fmu_dir, tmp_path / "run", "fail_at = 0.5")
    assert not result.complete
    last = notes(tmp_path / "run" / RECORDING_FILE)[-1]
    assert last[0] == pytest.approx(result.time_reached)
    assert last[1] == "ERROR"
    assert last[2] == f"run incomplete: {result.error}"


@pytest.mark.slow
def test_a_complete_run_s_recording_ends_saying_it_completed(test_fmu_dir: Path, tmp_path: Path):
    result = _run(test_fmu_dir, tmp_path / "run")
    assert result.complete
    last = notes(tmp_path / "run" / RECORDING_FILE)[-1]
    assert last[0] == pytest.approx(result.time_reached)
    assert last[1] == "INFO"
    assert last[2] == "run complete at t = 1 s (its stop time)"
