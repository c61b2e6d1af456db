"""What a Monte Carlo study answers in numbers: each metric's distribution over the runs,
and which factor moves it most.

``statistics.csv``, one row per metric: ``runs`` (the runs that gave it: a failed run
gives no metric, nor a figure never reached, such as a settling time), ``missing`` (the
study's other runs), ``mean``, ``std`` (the sample standard deviation, ddof = 1), ``min``,
``p05``, ``p50``, ``p95`` and ``max`` over those runs. The percentiles are
``numpy.percentile``'s default ``"linear"`` method (Hyndman and Fan's type 7, as pandas'
``quantile`` and R's default): p95 of 1, 2, 3, 4, 5 is 4.8. Two 95 % confidence intervals
treat the runs as independent draws (``sampling = "random"``; a Latin hypercube's runs are
not: for a metric monotonic in each factor its mean's interval is wider than it need be,
McKay, Beckman and Conover 1979): the mean's (``mean_ci_low``, ``mean_ci_high``: Student's
t) and the 95th percentile's (``p95_ci_low``, ``p95_ci_high``: order statistics, whatever
the distribution), whose upper bound needs 72 runs or more (fewer cannot bound p95 from
above, 0.95**71 > 0.025: an empty cell).

``sensitivity.csv``, one row per metric and numeric factor that varies: Spearman's rank
correlation ``rho`` of the factor with the metric (``scipy.stats.spearmanr``, over the
runs that gave the metric), its two-sided ``p_value`` and those ``runs``; a metric's
rows ordered by ``|rho|``, the factor that moves it most first. ``rho`` is empty where
it is undefined (the metric the same in every run). With a grid as well, every grid
point's samples are pooled.

An empty cell is a value that does not exist (no run gave the metric; a standard
deviation of one run). Floats are written as their shortest round-trip text, as
``runs.csv``'s are.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

import numpy as np

from cosim.whole_file import write_whole

STATISTICS_NAME = "statistics.csv"
SENSITIVITY_NAME = "sensitivity.csv"
PERCENTILES = (5, 50, 95)  # %, the p05, p50 and p95 columns
PERCENTILE_METHOD: Final = "linear"  # numpy's default, Hyndman and Fan's type 7
CONFIDENCE = 0.95  # of the intervals of the mean and of p95, two-sided
MIN_RUNS_FOR_RANKS = 3  # a rank correlation of two runs is +-1 whatever the factor does
Row = Mapping[str, Any]
Cell = float | int | str | None


def metric_statistics(
    rows: Sequence[Row], metrics: Sequence[str], units: Mapping[str, str]
) -> list[dict[str, Cell]]:
    """One record per metric: its unit, the runs that gave it and those that did not,
    and :func:`summary` over the first."""
    records: list[dict[str, Cell]] = []
    for metric in metrics:
        values = np.asarray([row[metric] for row in rows if row[metric] is not None], float)
        record: dict[str, Cell] = {"metric": metric, "unit": units.get(metric, "1")}
        record.update(runs=int(values.size), missing=len(rows) - int(values.size))
        record.update(summary(values))
        records.append(record)
    return records


def summary(values: np.ndarray) -> dict[str, float | None]:
    """mean with its :data:`CONFIDENCE` interval (Student's t), std, min, the
    :data:`PERCENTILES`, the interval of the 95th percentile (distribution-free: order
    statistics, ``scipy.stats.quantile_test``) and max of ``values``; None where a value
    does not exist (no values; a std or an interval of one; an upper bound of p95 from
    fewer than 72 values, where even the largest may lie below the true p95)."""
    from scipy import stats  # ~0.5 s to import: only a study that writes this pays it

    n = values.size
    if n == 0:
        return dict.fromkeys(_columns("statistics")[4:])
    mean, std = float(np.mean(values)), float(np.std(values, ddof=1)) if n > 1 else None
    found: dict[str, float | None] = {"mean": mean, "mean_ci_low": None, "mean_ci_high": None}
    if std is not None:
        half = float(stats.t.ppf(0.5 + CONFIDENCE / 2, n - 1)) * std / math.sqrt(n)
        found.update(mean_ci_low=mean - half, mean_ci_high=mean + half)
    found.update(std=std, min=float(np.min(values)))
    for q in PERCENTILES:
        found[f"p{q:02d}"] = float(np.percentile(values, q, method=PERCENTILE_METHOD))
    test = stats.quantile_test(values, q=0.0, p=0.95)
    interval: Any = test.confidence_interval(CONFIDENCE)  # low, high (the stubs say float)
    found.update(p95_ci_low=_finite(float(interval.low)), p95_ci_high=_finite(float(interval.high)))
    found["max"] = float(np.max(values))
    return found


def sensitivity(
    rows: Sequence[Row], factors: Sequence[str], metrics: Sequence[str]
) -> list[dict[str, Cell]]:
    """One record per metric and numeric factor that takes two values or more over the
    runs that gave the metric (at least :data:`MIN_RUNS_FOR_RANKS` of them): Spearman's
    rho, its p-value and the runs; each metric's records by ``|rho|``, largest first."""
    from scipy import stats  # ~0.5 s to import: only a study that writes this pays it

    records: list[dict[str, Cell]] = []
    numeric = [name for name in factors if all(_is_number(row[name]) for row in rows)]
    for metric in metrics:
        given = [row for row in rows if row[metric] is not None]
        y = np.asarray([row[metric] for row in given], dtype=float)
        found: list[dict[str, Cell]] = []
        for factor in numeric:
            x = np.asarray([row[factor] for row in given], dtype=float)
            if y.size < MIN_RUNS_FOR_RANKS or np.unique(x).size < 2:
                continue
            rho = p_value = math.nan
            if np.unique(y).size > 1:
                with warnings.catch_warnings():  # ties are ranked; a warning says nothing more
                    warnings.simplefilter("ignore")
                    result = stats.spearmanr(x, y)
                rho, p_value = float(result.statistic), float(result.pvalue)
            found.append({"metric": metric, "factor": factor, "rho": _finite(rho),
                          "p_value": _finite(p_value), "runs": int(y.size)})  # fmt: skip
        records += sorted(found, key=_strongest_first)
    return records


def _strongest_first(record: Mapping[str, Cell]) -> float:
    """Sort key: -|rho|, so the largest comes first; an undefined rho last."""
    rho = record["rho"]
    return -abs(rho) if isinstance(rho, float) else 1.0


def write_statistics(
    out_dir: Path,
    rows: Sequence[Row],
    factors: Sequence[str],
    metrics: Sequence[str],
    units: Mapping[str, str],
) -> dict[str, Path]:
    """``statistics.csv`` and ``sensitivity.csv`` of the study's ``rows`` into
    ``out_dir``; returns what each is called in the study's report -> its path."""
    paths = {"statistics": out_dir / STATISTICS_NAME, "sensitivity": out_dir / SENSITIVITY_NAME}
    tables = {
        "statistics": metric_statistics(rows, metrics, units),
        "sensitivity": sensitivity(rows, factors, metrics),
    }
    for name, records in tables.items():
        data = _csv_text(records, _columns(name)).encode("utf-8")
        write_whole(paths[name], functools.partial(Path.write_bytes, data=data))
    return paths


def _columns(name: str) -> list[str]:
    """The header of the table ``name`` ("statistics" or "sensitivity")."""
    if name == "sensitivity":
        return ["metric", "factor", "rho", "p_value", "runs"]
    middle = [f"p{q:02d}" for q in PERCENTILES]
    return ["metric", "unit", "runs", "missing", "mean", "mean_ci_low", "mean_ci_high", "std",
            "min", *middle, "p95_ci_low", "p95_ci_high", "max"]  # fmt: skip


def _csv_text(records: Sequence[Mapping[str, Cell]], columns: Sequence[str]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(columns)
    for record in records:
        writer.writerow([_cell(record[name]) for name in columns])
    return buffer.getvalue()


def _cell(value: Cell) -> str:
    if value is None:
        return ""
    return repr(value) if isinstance(value, float) else str(value)


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)
