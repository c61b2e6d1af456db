"""A check_step study's coupling_error.<metric> columns are the figures the check
estimates: the commands' activity (a total variation per second, which grows as the step
shrinks) has no coupling error, and no column that would always be empty."""

from __future__ import annotations

from pathlib import Path

import pytest

import cosim
from cosim.metrics.key_figures import ACTIVITY_FIGURES
from cosim.scenario.spec import load_scenario
from cosim.study.task import COUPLING_ERROR, _metric_names, _metrics


def _activity(name: str) -> bool:
    return name.rsplit(".", 1)[-1] in ACTIVITY_FIGURES


def test_no_coupling_error_column_for_a_commands_activity(fmu_dir: Path) -> None:
    """runs.csv and runs.parquet had a coupling_error.<activity> column for each command's
    activity, empty in every run: summary.json's check_step leaves them out."""
    names = _metric_names(load_scenario("bs-3", fmu_dir=fmu_dir), check_step=True)
    assert any(_activity(name) for name in names)  # the figure itself stays
    errors = [
        name.removeprefix(COUPLING_ERROR) for name in names if name.startswith(COUPLING_ERROR)
    ]
    assert errors and not [name for name in errors if _activity(name)]


@pytest.mark.slow
def test_every_coupling_error_column_of_a_run_is_estimated(fmu_dir: Path) -> None:
    """The row a checked run gives the study has the columns the study names, in its
    order, and the check estimates each figure the run has (one without a value, a yaw
    not settled by the stop time, has no error either)."""
    run = cosim.run("bs-3", stop_time=0.5, check_step=True, fmu_dir=fmu_dir)
    row = _metrics(run.summary)
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir).with_overrides(stop_time=0.5)
    assert tuple(row) == _metric_names(scenario, check_step=True)
    errors = {
        n.removeprefix(COUPLING_ERROR): v for n, v in row.items() if n.startswith(COUPLING_ERROR)
    }
    empty = [name for name, error in errors.items() if error is None and row[name] is not None]
    assert empty == []
