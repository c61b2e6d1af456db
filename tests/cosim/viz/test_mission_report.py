"""The report of a waypoint mission (cosim.viz.report): the planned path and its waypoints
on the trajectory, read from the run's scenario.toml, and the guidance figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.viz import report

SCENARIO = """id = "mini-survey"
[instances.guidance]
fmu = "AuvGuidance"
[instances.guidance.start]
waypoints = "0, 0, 2; 40, 0, 2; 40, 15, 2"
"""


def _write_run(run_dir: Path, scenario: str | None) -> Path:
    """A run folder with a made-up track along the mission and the guidance's outputs."""
    t = np.arange(0.0, 40.0, 0.1)
    north = np.minimum(1.5 * t, 40.0)
    east = np.maximum(0.0, 1.5 * t - 40.0)
    columns = {"time": t, "plant.north": north, "plant.east": east,
               "guidance.cross_track_error": 0.3 * np.sin(t),
               "guidance.legs_completed": (1.5 * t >= 40.0) + (1.5 * t >= 55.0) * 1.0}  # fmt: skip
    run_dir.mkdir(parents=True)
    table = np.column_stack(list(columns.values()))
    lines = [",".join(columns)] + [",".join(map(repr, row)) for row in table.tolist()]
    (run_dir / "results.csv").write_text("\n".join(lines) + "\n")
    if scenario is not None:
        (run_dir / "scenario.toml").write_text(scenario)
    return run_dir


def _planned_paths(run_dir: Path, monkeypatch: pytest.MonkeyPatch) -> dict[str, list]:
    """Write the report; {figure file name: [(east, north) of its 'planned path' line]}."""
    drawn: dict[str, list] = {}
    save = report._save

    def capture(fig, path):
        drawn[path.name] = [
            line.get_xydata().tolist()
            for ax in fig.axes
            for line in ax.get_lines()
            if line.get_label() == "planned path"
        ]
        return save(fig, path)

    monkeypatch.setattr(report, "_save", capture)
    report.write_report(run_dir)
    return drawn


@pytest.mark.slow
def test_the_trajectory_shows_the_planned_path_of_the_runs_guidance(tmp_path, monkeypatch):
    drawn = _planned_paths(_write_run(tmp_path / "run", SCENARIO), monkeypatch)
    assert drawn["trajectory.png"] == [[[0.0, 0.0], [0.0, 40.0], [15.0, 40.0]]]  # east, north
    assert "mission.png" in drawn  # cross-track error and legs completed
    assert (tmp_path / "run" / "report" / "mission.png").stat().st_size > 10_000


@pytest.mark.slow
def test_a_run_without_guidance_has_no_planned_path(tmp_path, monkeypatch):
    drawn = _planned_paths(_write_run(tmp_path / "plain", None), monkeypatch)
    assert drawn["trajectory.png"] == []
    drawn = _planned_paths(_write_run(tmp_path / "other", 'id = "x"\n'), monkeypatch)
    assert drawn["trajectory.png"] == []


def test_a_mission_of_hundreds_of_waypoints_numbers_a_readable_few(tmp_path, monkeypatch):
    """300 waypoints of a 6 km lawnmower were each numbered on the trajectory figure: 300
    labels overprinted into one black band along the path. A few are numbered now, evenly
    spaced, with the first and the last; a short mission keeps every number."""
    t = np.arange(0.0, 10.0, 0.1)
    table = {"plant.north": 1.5 * t, "plant.east": np.zeros_like(t)}
    labels: dict[int, list[str]] = {}

    def capture(fig, path):
        labels[len(waypoints)] = [text.get_text() for text in fig.axes[0].texts]
        return path

    monkeypatch.setattr(report, "_save", capture)
    for count in (8, 300):
        waypoints = np.column_stack([50.0 * (np.arange(count) % 2), 20.0 * np.arange(count),
                                     np.full(count, 2.0)])  # fmt: skip
        report.plot_trajectory(table, tmp_path / "trajectory.png", waypoints)
    assert labels[8] == [str(k) for k in range(1, 9)]
    assert len(labels[300]) <= 30  # a few, not one a waypoint
    assert labels[300][0] == "1" and labels[300][-1] == "300"
    steps = np.diff([int(label) for label in labels[300][:-1]])
    assert len(set(steps.tolist())) == 1  # evenly spaced
