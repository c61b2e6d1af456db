"""What a Monte Carlo study answers in numbers: each metric's distribution over the runs,
and which factor moves it most.

``statistics.csv``, one row per metric: ``runs`` (the runs that gave it: a failed run
gives no metric, nor a figure never reached, such as a settling time), ``missing`` (the
study's other runs), ``mean``, ``std`` (the sample standard deviation, ddof = 1), ``min``,
``p05``, ``p50``, ``p95`` and ``max`` over those runs. The percentiles are
``numpy.percentile``'s default ``"linear"`` method (Hyndman and Fan's type 7, as pandas'
``quantile`` and R's default): p95 of 1, 2, 3, 4, 5 is 4.8.

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
MIN_RUNS_FOR_RANKS = 3  # a rank correlation of two runs is +-1 whatever the factor does
Row = Mapping[str, Any]
Cell = float | int | str | None


def metric_statistics(
    rows: Sequence[Row], metrics: Sequence[str], units: Mapping[str, str]
) -> list[dict[str, Cell]]:
    """One record per metric: its unit, the runs that gave it and those that did not,
    and mean, std, min, the :data:`PERCENTILES` and max over the first (None where there
    is no value)."""
    records: list[dict[str, Cell]] = []
    for metric in metrics:
        values = np.asarray([row[metric] for row in rows if row[metric] is not None], float)
        record: dict[str, Cell] = {"metric": metric, "unit": units.get(metric, "1")}
        record.update(runs=int(values.size), missing=len(rows) - int(values.size))
        have = values.size > 0
        record["mean"] = float(np.mean(values)) if have else None
        record["std"] = float(np.std(values, ddof=1)) if values.size > 1 else None
        record["min"] = float(np.min(values)) if have else None
        for q in PERCENTILES:
            at = np.percentile(values, q, method=PERCENTILE_METHOD) if have else None
            record[f"p{q:02d}"] = None if at is None else float(at)
        record["max"] = float(np.max(values)) if have else None
        records.append(record)
    return records


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
    return ["metric", "unit", "runs", "missing", "mean", "std", "min", *middle, "max"]


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
