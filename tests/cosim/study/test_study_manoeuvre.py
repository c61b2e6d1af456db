"""A study of a manoeuvre (its metrics in summary.json): the turning circle with two
moving-mass commands collects the steady turning diameter of each run."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from sweep_helpers import sweep, table

STUDY = """
scenario = "turning-circle"       # 60 s: a steady last turn
keep = "all"
[grid]
"plant.mass_position_cmd" = [0.04, 0.06]
[metrics]
collect = ["steady_turning_diameter_m", "tactical_diameter_m"]
"""


@pytest.mark.cluster
@pytest.mark.slow
def test_a_turning_circle_study_collects_the_steady_turning_diameter(
    tmp_path: Path, fmu_dir: Path
) -> None:
    study = tmp_path / "turns.toml"
    study.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "2")
    rows = {float(row["plant.mass_position_cmd"]): row for row in table(out)}
    assert set(rows) == {0.04, 0.06}
    for row in rows.values():
        assert row["status"] == "complete"
        summary = json.loads((out / "runs" / row["run"] / "summary.json").read_text("utf-8"))
        for name in ("steady_turning_diameter_m", "tactical_diameter_m"):
            assert row[name] == repr(summary[name]), name  # the run's own value, exactly
    # 60 s hold a steady turn in both runs, each on a circle of its own
    diameters = {float(row["steady_turning_diameter_m"]) for row in rows.values()}
    assert len(diameters) == 2 and min(diameters) > 5.0
