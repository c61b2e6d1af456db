"""The report of a standard manoeuvre run (cosim.viz.report): its metrics in a table of
their own on the page, and a turning circle's marked on its trajectory where they were
measured; on a made-up track of known geometry."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from cosim.metrics.manoeuvres import manoeuvre_metrics, metric_names
from cosim.viz import report
from cosim.viz.report import figure_label

H = 0.05


def _turning_run(run_dir: Path) -> Path:
    """Straight north at 1.5 m/s for 2 s from the execute at t = 0, then a circle of radius
    5 m to starboard at 1.2 m/s: 90 deg at (8, 5), 180 deg at (3, 10) (north, east)."""
    t = np.arange(round(60.0 / H) + 1) * H
    theta = np.clip(1.2 * (t - 2.0) / 5.0, 0.0, None)
    north = np.where(t < 2.0, 1.5 * t, 3.0 + 5.0 * np.sin(theta))
    east = 5.0 * (1.0 - np.cos(theta))
    columns = {"time": t, "plant.north": north, "plant.east": east, "plant.yaw": theta,
               "plant.roll": np.full_like(t, 0.3),
               "plant.mass_position_cmd": np.full_like(t, 0.06)}  # fmt: skip
    run_dir.mkdir(parents=True)
    table = np.column_stack(list(columns.values()))
    lines = [",".join(columns)] + [",".join(map(repr, row)) for row in table.tolist()]
    (run_dir / "results.csv").write_text("\n".join(lines) + "\n")
    metrics = manoeuvre_metrics("turning-circle", columns)
    summary = {"scenario": "turning-circle", "status": "complete", "manoeuvre": "turning-circle"}
    (run_dir / "summary.json").write_text(json.dumps({**summary, **metrics}))
    return run_dir


def _drawn(run_dir: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, np.ndarray]:
    """Write the report; the trajectory's lines by label: (east, north) points."""
    drawn: dict[str, np.ndarray] = {}
    save = report._save

    def capture(fig, path):
        if path.name == "trajectory.png":
            for line in fig.axes[0].get_lines():
                drawn[line.get_label()] = line.get_xydata()
        return save(fig, path)

    monkeypatch.setattr(report, "_save", capture)
    report.write_report(run_dir)
    return drawn


@pytest.mark.slow
def test_a_turning_circle_gets_its_metrics_on_the_page_and_the_track(tmp_path, monkeypatch):
    run_dir = _turning_run(tmp_path / "run")
    drawn = _drawn(run_dir, monkeypatch)
    summary = json.loads((run_dir / "summary.json").read_text())
    assert summary["advance_m"] == pytest.approx(8.0, abs=1e-3)
    at_90 = f"90 deg: advance {summary['advance_m']:.2f} m, transfer {summary['transfer_m']:.2f} m"
    np.testing.assert_allclose(drawn[at_90], [[5.0, 8.0]], atol=1e-3)  # east, north
    at_180 = f"180 deg: tactical diameter {summary['tactical_diameter_m']:.2f} m"
    np.testing.assert_allclose(drawn[at_180], [[10.0, 3.0]], atol=1e-3)
    np.testing.assert_allclose(drawn["execute"], [[0.0, 0.0]])
    course = drawn["original course"]
    assert np.allclose(course[:, 0], 0.0) and course[-1, 1] > 8.0  # due north, past 90 deg
    page = (run_dir / "report" / "index.html").read_text()
    assert "<h2>Manoeuvre metrics: turning-circle</h2>" in page
    for name in metric_names("turning-circle"):
        value = summary[name]
        shown = "n/a" if value is None else f"{value:.6g}"
        assert f'<tr><th scope="row">{figure_label(name)}</th><td>{shown}</td>' in page


@pytest.mark.slow
def test_other_runs_get_no_marks_and_no_metric_table(tmp_path, monkeypatch):
    run_dir = _turning_run(tmp_path / "run")
    summary = json.loads((run_dir / "summary.json").read_text())
    (run_dir / "summary.json").write_text(json.dumps({"scenario": summary["scenario"]}))
    drawn = _drawn(run_dir, monkeypatch)
    assert "execute" not in drawn and "original course" not in drawn
    assert "Manoeuvre metrics" not in (run_dir / "report" / "index.html").read_text()


@pytest.mark.slow
def test_a_survey_page_lists_its_metrics(tmp_path, monkeypatch):
    run_dir = _turning_run(tmp_path / "run")
    metrics = {"cross_track_rms_m": 1.6, "cross_track_max_m": 5.0, "legs_completed": 7}
    (run_dir / "summary.json").write_text(json.dumps({"manoeuvre": "survey", **metrics}))
    drawn = _drawn(run_dir, monkeypatch)
    assert "execute" not in drawn
    page = (run_dir / "report" / "index.html").read_text()
    assert "<h2>Manoeuvre metrics: survey</h2>" in page
    assert '<tr><th scope="row">legs completed</th><td>7</td></tr>' in page
    assert '<tr><th scope="row">cross track rms (m)</th><td>1.6</td></tr>' in page
