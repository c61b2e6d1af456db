"""A run with events and faults, through its outputs: summary.json lists the events fired
(with their times) and the faults, results.csv has the faults' columns, the recording a
TextLog entry per event and fault start/stop at its time, the report vertical markers,
and the run folder's scenario.toml reproduces the run."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rerun.chunk import RrdReader
from scenario_factory import loop_toml

from cosim.outputs.results import read_csv
from cosim.runner import run_scenario
from cosim.viz import report

EXTRA = """
[connections]
remove = ["plant.u"]
[[events]]
name = "gain-up"
time = 0.3
set = { "controller.k" = 4.0 }
[[events]]
name = "slow-down"
when = "plant.x > 1.5"
set = { "plant.u" = 0.5 }
[[faults]]
name = "jam"
kind = "stuck"
target = "controller.x"
start = 0.2
stop = 0.6
"""


@pytest.fixture(scope="module")
def run_dir(test_fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("timeline-run")
    scenario = folder / "open.toml"
    scenario.write_text(loop_toml(plant_start="u = 1.0") + EXTRA, encoding="utf-8")
    for fmu in test_fmu_dir.glob("*.fmu"):
        (folder / fmu.name).symlink_to(fmu)
    outcome = run_scenario(scenario, folder / "run")
    assert outcome.result.complete, outcome.result.error
    return folder / "run"


def test_summary_lists_the_events_fired_and_the_faults(run_dir: Path) -> None:
    summary = json.loads((run_dir / "summary.json").read_text())
    columns, table = read_csv(run_dir / "results.csv")
    x = table[:, columns.index("plant.x")]
    crossing = table[np.flatnonzero(x > 1.5)[0], 0]  # the first point where x > 1.5
    assert summary["events"] == [
        {"name": "gain-up", "time": pytest.approx(0.3), "set": {"controller.k": 4.0}},
        {"name": "slow-down", "time": pytest.approx(crossing), "set": {"plant.u": 0.5}},
    ]
    assert summary["faults"] == [
        {"name": "jam", "kind": "stuck", "target": "controller.x", "start": 0.2, "stop": 0.6}
    ]
    flag = table[:, columns.index("fault.jam")]
    assert np.array_equal(flag, ((table[:, 0] > 0.15) & (table[:, 0] < 0.55)).astype(float))


def test_summary_gives_a_faults_column_its_unit_a_flag(run_dir: Path) -> None:
    """A fault's results.csv column (1.0 while it acts) is dimensionless in summary.json's
    units, as is a variable its FMU declares no unit for (the test FMUs' x)."""
    units = json.loads((run_dir / "summary.json").read_text())["units"]
    columns, _ = read_csv(run_dir / "results.csv")
    assert list(units) == columns
    assert (units["time"], units["fault.jam"], units["plant.x"]) == ("s", "1", "1")


def test_the_recording_logs_each_event_and_fault_at_its_time(run_dir: Path) -> None:
    notes = []
    for chunk in RrdReader(run_dir / "recording.rrd").stream():
        if chunk.entity_path != "/events":
            continue
        batch = chunk.to_record_batch()
        texts = [t for row in batch.column("TextLog:text").to_pylist() for t in row]
        nanos = batch.column("sim_time").cast("int64").to_pylist()
        notes += list(zip(nanos, texts, strict=True))
    summary = json.loads((run_dir / "summary.json").read_text())
    crossing = round(summary["events"][1]["time"] * 1e9)
    assert sorted(notes) == sorted([
        (200_000_000, "fault jam starts: stuck on controller.x"),
        (300_000_000, "event gain-up: controller.k = 4.0"),
        (600_000_000, "fault jam stops: stuck on controller.x"),
        (crossing, "event slow-down: plant.u = 0.5"),
        (round(summary["time_reached"] * 1e9),
         f"run complete at t = {summary['time_reached']:g} s (its stop time)"),
    ])  # fmt: skip


def test_the_report_marks_events_and_faults_on_every_time_panel(
    run_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    summary = json.loads((run_dir / "summary.json").read_text())
    markers = report.markers_of(summary)
    assert [(m.time, m.label) for m in markers] == [
        (pytest.approx(0.3), "event gain-up"),
        (summary["events"][1]["time"], "event slow-down"),
        (0.2, "fault jam (stuck) starts (0.2 s)"),
        (0.6, "fault jam (stuck) stops (0.6 s)"),
    ]
    table = {"time": np.linspace(0.0, 1.0, 11), "plant.yaw": np.zeros(11), "plant.r": np.ones(11)}
    drawn = []
    monkeypatch.setattr(report, "_save", lambda fig, path: drawn.append(fig) or path)
    panels = (report.Panel("yaw", (report.Series("plant.yaw"),)),
              report.Panel("r", (report.Series("plant.r"),)))  # fmt: skip
    report.plot_time_histories(table, panels, "t", Path("unused.png"), markers)
    (fig,) = drawn
    for ax in fig.axes:
        vertical = sorted(
            line.get_xdata()[0] for line in ax.lines if len(set(line.get_xdata())) == 1
        )
        assert vertical == pytest.approx(sorted(m.time for m in markers))
    monkeypatch.undo()  # the whole report, its figures saved
    assert report.write_report(run_dir).is_file()


def test_the_run_folders_scenario_reproduces_the_run(run_dir: Path, tmp_path: Path) -> None:
    again = run_scenario(run_dir / "scenario.toml", tmp_path / "again", no_rrd=True)
    assert again.result.complete
    assert (tmp_path / "again" / "results.csv").read_bytes() == (
        run_dir / "results.csv"
    ).read_bytes()
