"""A Monte Carlo study's statistics and sensitivity tables, checked against hand-made
tables whose answers are worked out by hand (not copied from a run)."""

from __future__ import annotations

import csv
from pathlib import Path

import pandas as pd
import pytest

from cosim.study.statistics import metric_statistics, sensitivity, write_statistics

UNITS = {"y": "m", "a.x1": "m/s"}


def _rows() -> list[dict]:
    """Five complete runs, metric y = -x1**3 (ranks exactly reversed from x1), x2 ranked
    2, 1, 4, 3, 5; then a failed run (no metrics) with far-out factor values, which must
    count as missing and move nothing."""
    x1 = [0.1, 0.2, 0.3, 0.4, 0.5]
    x2 = [2.0, 1.0, 4.0, 3.0, 5.0]
    rows = [
        {"a.x1": a, "a.x2": b, "y": -(a**3), "flat": 1.0, "status": "complete"}
        for a, b in zip(x1, x2, strict=True)
    ]
    rows.append({"a.x1": 99.0, "a.x2": -99.0, "y": None, "flat": None, "status": "failed"})
    return rows


def test_percentiles_are_numpys_linear_method_over_the_runs_that_gave_the_metric() -> None:
    """p95 of 1, 2, 3, 4, 5 is 1 + 0.95 * 4 = 4.8 (type 7); a failed run and a figure a
    run did not give are counted as missing, not as values."""
    rows = [{"m": float(v), "status": "complete"} for v in (3, 1, 5, 2, 4)]
    rows += [{"m": None, "status": "failed"}, {"m": None, "status": "complete"}]
    (record,) = metric_statistics(rows, ["m"], {"m": "m"})
    assert record["runs"] == 5 and record["missing"] == 2
    assert record["mean"] == 3.0 and record["min"] == 1.0 and record["max"] == 5.0
    assert record["p05"] == pytest.approx(1.2) and record["p50"] == 3.0
    assert record["p95"] == pytest.approx(4.8)
    assert record["std"] == pytest.approx(2.5**0.5)  # sum of squares 10 over n - 1 = 4


def test_the_means_interval_is_students_t() -> None:
    """1, 2, 3, 4, 5: mean 3, s = sqrt(2.5), t(0.975, 4) = 2.7764 from a printed table:
    half-width 2.7764 * sqrt(2.5) / sqrt(5) = 1.9632."""
    (record,) = metric_statistics([{"m": float(v)} for v in range(1, 6)], ["m"], {})
    assert record["mean_ci_low"] == pytest.approx(3.0 - 1.9632, abs=1e-4)
    assert record["mean_ci_high"] == pytest.approx(3.0 + 1.9632, abs=1e-4)


@pytest.mark.parametrize(("n", "bounded"), [(16, False), (71, False), (72, True)])
def test_the_95th_percentile_is_bounded_from_above_from_72_runs_on(n: int, bounded: bool) -> None:
    """All n runs fall below the true p95 with probability 0.95**n: 0.0262 for 71 runs,
    more than the 0.025 a two-sided 95 % interval allows, so no run bounds p95 from above
    (an empty cell, not a number that reads as a bound); 0.0249 for 72, the largest run
    bounds it. The lower bound is one of the runs' values, below the estimate."""
    rows = [{"m": float(v)} for v in range(1, n + 1)]
    (record,) = metric_statistics(rows, ["m"], {})
    assert record["p95_ci_high"] == (float(n) if bounded else None)
    low = record["p95_ci_low"]
    assert isinstance(low, float) and low.is_integer() and low <= record["p95"]  # type: ignore[operator]


def test_one_run_and_no_run_give_empty_cells_not_numbers() -> None:
    """A study of one run has no standard deviation; a metric no run gave has no value."""
    one, none = metric_statistics(
        [{"m": 2.0, "n": None, "status": "complete"}], ["m", "n"], {"m": "s"}
    )
    assert one["runs"] == 1 and one["p95"] == 2.0 and one["std"] is None
    assert none["runs"] == 0 and none["missing"] == 1 and none["unit"] == "1"
    assert one["mean_ci_low"] is None and one["p95_ci_low"] is None
    assert all(none[k] is None for k in ("mean", "std", "min", "p05", "p50", "p95", "max"))
    assert none["mean_ci_high"] is None and none["p95_ci_high"] is None


def test_spearman_ranks_the_factor_that_moves_the_metric_first() -> None:
    """y falls with x1 exactly: rho = -1. Against x2: d = (-3, -3, 1, 1, 4), sum d^2 = 36,
    rho = 1 - 6 * 36 / (5 * 24) = -0.8. The failed run is left out of both."""
    records = sensitivity(_rows(), ["a.x1", "a.x2"], ["y"])
    assert [(r["factor"], r["runs"]) for r in records] == [("a.x1", 5), ("a.x2", 5)]
    assert records[0]["rho"] == pytest.approx(-1.0)
    assert records[1]["rho"] == pytest.approx(-0.8)
    assert 0.0 < records[1]["p_value"] < 1.0  # type: ignore[operator]


def test_a_constant_metric_or_factor_has_no_rank_correlation() -> None:
    """A metric the same in every run has no defined rho (an empty cell, listed last);
    a factor of one value (a grid of one point) or a name is not a varied number."""
    rows = [{**row, "g": 0.3, "mode": "full"} for row in _rows()]
    records = sensitivity(rows, ["g", "mode", "a.x1"], ["flat"])
    assert records == [{"metric": "flat", "factor": "a.x1", "rho": None, "p_value": None,
                        "runs": 5}]  # fmt: skip
    assert sensitivity(rows[:2], ["a.x1"], ["y"]) == []  # two runs rank nothing


def test_the_tables_read_back_with_pandas_as_numbers(tmp_path: Path) -> None:
    """Both files as a user reads them: numeric columns are floats or ints, an empty cell
    NaN, the metric's unit beside it."""
    rows = _rows()
    paths = write_statistics(tmp_path, rows, ["a.x1", "a.x2"], ["y", "flat"], UNITS)
    stats_table = pd.read_csv(paths["statistics"])
    assert list(stats_table["metric"]) == ["y", "flat"]
    assert stats_table["runs"].dtype == "int64" and stats_table["p95"].dtype == "float64"
    assert list(stats_table["unit"]) == ["m", "1"] and stats_table.loc[1, "std"] == 0.0
    ranks = pd.read_csv(paths["sensitivity"])
    assert ranks["rho"].dtype == "float64" and ranks["runs"].dtype == "int64"
    assert ranks["rho"][ranks["metric"] == "flat"].isna().all()  # undefined: empty, NaN
    assert list(ranks["factor"][ranks["metric"] == "y"]) == ["a.x1", "a.x2"]
    with paths["statistics"].open(encoding="utf-8") as f:
        header = next(csv.reader(f))
    assert header[:4] == ["metric", "unit", "runs", "missing"] and "p95" in header


@pytest.mark.cluster
@pytest.mark.slow
def test_a_monte_carlo_study_writes_its_statistics_over_its_complete_runs(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """A study with failed runs (a mass position the plant refuses): its statistics
    count them as missing and are those pandas computes from runs.csv's complete rows
    (its own quantile and rank correlation), the factor that moves a metric most first."""
    from sweep_helpers import sweep

    study = tmp_path / "mc.toml"
    study.write_text(
        'scenario = "bs-3"\nstop_time = 2.0\n[grid]\n"plant.mass_position_0" = [0.01, 0.5]\n'
        '[random]\nn = 4\nseed = 5\n"plant.current_east" = { uniform = [0.0, 0.3] }\n'
        '"plant.yaw_0" = { normal = [0.0, 0.2] }\n'
        '[metrics]\ncollect = ["final.plant.yaw", "final.plant.east"]\n',
        encoding="utf-8",
    )
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "2")
    runs = pd.read_csv(out / "runs.csv")
    complete = runs[runs["status"] == "complete"]
    assert len(runs) == 8 and len(complete) == 4  # mass_position_0 = 0.5 m is refused
    table = pd.read_csv(out / "statistics.csv").set_index("metric")
    ranks = pd.read_csv(out / "sensitivity.csv")
    for metric in ("final.plant.yaw", "final.plant.east"):
        assert table.loc[metric, "runs"] == 4 and table.loc[metric, "missing"] == 4
        assert table.loc[metric, "p95"] == pytest.approx(complete[metric].quantile(0.95))
        assert table.loc[metric, "std"] == pytest.approx(complete[metric].std())
        assert pd.isna(table.loc[metric, "p95_ci_high"])  # 4 runs bound no p95 from above
        mine = ranks[ranks["metric"] == metric]
        assert set(mine["factor"]) == {"plant.current_east", "plant.yaw_0"}  # grid: 1 value
        expected = complete[["plant.current_east", "plant.yaw_0", metric]].corr("spearman")
        for _, row in mine.iterrows():
            assert row["rho"] == pytest.approx(expected.loc[row["factor"], metric])
        assert list(mine["rho"].abs()) == sorted(mine["rho"].abs(), reverse=True)
    assert table.loc["final.plant.yaw", "unit"] == "rad"
    assert 'href="sensitivity.csv"' in (out / "index.html").read_text(encoding="utf-8")
