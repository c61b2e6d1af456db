"""Which runs of a study ``overlay.rrd`` draws together, and the recording's notes.

A choice is a list of entries (the study file's ``overlay``, or ``--overlay N``): a run id;
``"best:<metric>"`` / ``"worst:<metric>"``, the complete run with the lowest / highest
value of a collected metric (the first in the study's order on a tie); ``"all"``. Ids,
metrics and the number of runs (at most :data:`OVERLAY_CAP`) are checked before the first
run (:func:`check_choice`); best and worst are known once the table is (:func:`choose`).
``--overlay N`` picks N runs spread evenly over the study's order (:func:`spread`), which
for a grid means its corners and points between.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

from cosim.errors import FLAGS, OptionNames, did_you_mean
from cosim.study.design import PlannedRun
from cosim.study.spec import OVERLAY_CAP, StudyError
from cosim.study.units import DIMENSIONLESS, IN_DEGREES


def check_choice(
    entries: Sequence[str], runs: Sequence[PlannedRun], metrics: Sequence[str]
) -> None:
    """:class:`StudyError` naming the entry if a run id is not one of the study's, a
    metric is not collected, or the choice can hold more than OVERLAY_CAP runs."""
    ids = {run.id for run in runs}
    for entry in entries:
        kind, _, metric = entry.partition(":")
        if kind in ("best", "worst") and metric not in metrics:
            raise StudyError(
                f"overlay entry {entry!r}: {metric!r} is not a collected metric"
                f"{did_you_mean(metric, metrics)} (collected: {', '.join(metrics)})"
            )
        if kind not in ("best", "worst", "all") and entry not in ids:
            raise StudyError(f"overlay entry {entry!r}: no run of this study has that id")
    most = len(runs) if "all" in entries else len(set(entries))
    if most > OVERLAY_CAP:
        raise StudyError(
            f"overlay {list(entries)}: up to {most} runs, more than the cap of {OVERLAY_CAP}; "
            "name fewer runs or use --overlay N"
        )


def check_count(n: int, names: OptionNames = FLAGS) -> None:
    """``--overlay N``: :class:`StudyError` unless 1 <= n <= OVERLAY_CAP, naming the option
    as ``names`` do (``--overlay 50`` or ``overlay=50``)."""
    if not 1 <= n <= OVERLAY_CAP:
        raise StudyError(
            f"{names.given('overlay', n)}: expected a number of runs from 1 to {OVERLAY_CAP}"
        )


def spread(runs: Sequence[PlannedRun], n: int, names: OptionNames = FLAGS) -> list[str]:
    """``--overlay N``: n run ids evenly spread over the study's order (first and last
    included); :class:`StudyError` unless 1 <= n <= OVERLAY_CAP, naming the option as
    ``names`` do (``--overlay 50`` or ``overlay=50``)."""
    check_count(n, names)
    if n >= len(runs):
        return [run.id for run in runs]
    last = len(runs) - 1
    picks = dict.fromkeys(round(k * last / max(1, n - 1)) for k in range(n))
    return [runs[i].id for i in picks]


def choose(
    entries: Sequence[str], runs: Sequence[PlannedRun], rows: Mapping[str, Mapping[str, Any]]
) -> tuple[dict[str, list[str]], list[str]]:
    """The chosen run ids, in the order first chosen, each with the entries that chose it,
    and the entries that chose nothing (a metric no complete run has a value of)."""
    chosen: dict[str, list[str]] = {}
    empty: list[str] = []
    for entry in entries:
        kind, _, metric = entry.partition(":")
        if kind == "all":
            picks = [run.id for run in runs]
        elif kind in ("best", "worst"):
            valued = [
                run.id
                for run in runs
                if rows[run.id]["status"] == "complete" and rows[run.id][metric] is not None
            ]
            sign = 1.0 if kind == "best" else -1.0
            picks = [min(valued, key=lambda i: sign * rows[i][metric])] if valued else []
        else:
            picks = [entry]
        if not picks:
            empty.append(entry)
        for run_id in picks:
            chosen.setdefault(run_id, []).append(entry)
    return chosen, empty


def label(run: PlannedRun, unit_of: Mapping[str, str]) -> str:
    """A run's name in the overlay: its id and its factor values, each with its unit
    (``unit_of``: factor -> unit, :func:`cosim.study.units.units`) and an angle in rad also
    in degrees, as the overlay's plots show angles (``plant.yaw_0 = 0.523599 rad (30 deg)``)."""
    values = ", ".join(
        f"{name} = {_with_unit(value, unit_of.get(name, DIMENSIONLESS))}"
        for name, value in run.values.items()
    )
    return f"{run.id}: {values}"


def _with_unit(value: Any, unit: str) -> str:
    """``value`` as a label shows it: with ``unit`` (none for "1"), an angle in degrees too."""
    if not isinstance(value, int | float) or isinstance(value, bool) or unit == DIMENSIONLESS:
        return _short(value)
    if unit in IN_DEGREES:
        degrees = _short(float(value) * math.degrees(1.0))
        return f"{_short(value)} {unit} ({degrees} {IN_DEGREES[unit]})"
    return f"{_short(value)} {unit}"


def notes(
    chosen: Mapping[str, list[str]],
    runs: Mapping[str, PlannedRun],
    rows: Mapping[str, Mapping[str, Any]],
    missing: Sequence[str],
    empty: Sequence[str],
    unit_of: Mapping[str, str],
) -> str:
    """The overlay's text document (Markdown): each run shown, why, its factor values (with
    their units, ``unit_of``: see :func:`label`), its status."""
    lines = [
        "# Runs in this overlay",
        "",
        "| run | chosen by | factors | status |",
        "|---|---|---|---|",
    ]
    for run_id, why in chosen.items():
        factors = label(runs[run_id], unit_of).partition(": ")[2]
        status = rows[run_id]["status"] + (" (no results)" if run_id in missing else "")
        lines.append(f"| `{run_id}` | {', '.join(why)} | {factors} | {status} |")
    if empty:
        lines += ["", f"Chose nothing (no complete run has a value): {', '.join(empty)}"]
    return "\n".join(lines) + "\n"


def _short(value: Any) -> str:
    return f"{value:.6g}" if isinstance(value, float) else str(value)
