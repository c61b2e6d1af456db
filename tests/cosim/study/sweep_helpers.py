"""Helpers of the study tests: the small reference study, running sweep, reading runs.csv."""

from __future__ import annotations

import csv
from pathlib import Path

from cosim.cli import main

SMALL_STUDY = """
scenario = "bs-3"
stop_time = 1.0
[grid]
"plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
[random]
n = 3
seed = 11
sampling = "latin-hypercube"
"plant.current_east" = { uniform = [0.0, 0.2] }
"""
SMALL_RUNS = 12


def sweep(study: Path, out: Path, fmu_dir: Path, *args: str) -> None:
    """``auv-cosim sweep`` in this process; fails the test unless it exits 0."""
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet"]
    assert main([*argv, *args]) == 0


def table(out: Path) -> list[dict[str, str]]:
    """runs.csv's rows without the wall clock (the one column identical runs differ in)."""
    with (out / "runs.csv").open(encoding="utf-8", newline="") as f:
        rows = list(csv.DictReader(f))
    for row in rows:
        del row["wall_clock_s"]
    return rows
