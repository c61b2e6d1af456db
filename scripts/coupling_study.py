"""Measure the coupling error of the built-in scenarios; regenerate docs/coupling.md's tables.

    python scripts/coupling_study.py shipped [--scenarios bs-3 vert-1 ...] [--write]
    python scripts/coupling_study.py check-step [--scenarios bs-3 vert-1] [--write]
    python scripts/coupling_study.py adaptive [--scenarios vert-1 bs-3] [--tolerances ...] [--write]

``shipped``: every built-in scenario (or those named) as shipped, and again at 2.5, 1.25
and 0.625 ms with the same coupling: the continuous-time limit of each key figure by
Richardson from the runs at 1.25 and 0.625 ms (the order observed on 2.5 / 1.25 / 0.625
ms, else the coupling's nominal one) and the shipped run's error against it.

``check-step``: what ``auv-cosim run --check-step`` estimates for a scenario as shipped
and with held inputs (``extrapolation = "none"``), against its true error (the run minus
the run at 1/32 of its step).

``adaptive``: vert-1 and bs-3 with ``algorithm = "adaptive"`` at each tolerance, with each
error estimate, against fixed steps with the same extrapolation: each run's communication
steps (accepted and rejected) and plant doSteps (every attempt's, rejected ones counted),
its errors against a run at 0.3125 ms: the trajectory's (the largest distance of the
plant's outputs, |y - y_ref| / (|y_ref| + 1)) and the key figures' (relative), and the
doSteps a fixed step would take for the same trajectory error. That last figure comes from
twenty fixed steps (2.5 to 40 ms, not only powers of two: on vert-1 the error of a fixed
step is not monotonic in it, 12 ms is twice as accurate as 10 ms) and a least-squares line
through the six whose errors are nearest, log doSteps against log error; the header gives
the scatter of the fixed runs about such lines (the largest factor), the margin below
which a difference is not a result.

``--write`` replaces the table between the markers ``<!-- coupling_study.py <part> -->``
and ``<!-- end -->`` in docs/coupling.md (``shipped --scenarios``: only those scenarios'
rows, the others' kept); without it the table is printed. Runs go through
the master (no files written); the machine's load is printed beside the times.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from cosim.engine import master
from cosim.engine.step_check import check_step
from cosim.metrics.key_figures import KeyFigures
from cosim.metrics.richardson import Estimate, observed_order
from cosim.scenario.spec import ErrorEstimate, Scenario, builtin_scenarios, load_scenario

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "docs" / "coupling.md"
FINE_STEPS = (0.0025, 0.00125, 0.000625)  # s: the limit's runs
FIGURES = {  # key figure -> (label, unit scale, unit)
    "yaw_settling_time_s": ("yaw settling time", 1.0, "s"),
    "peak_abs_mass_position_m": ("peak mass position", 100.0, "cm"),
    "peak_abs_tunnel_force_N": ("peak tunnel force", 1.0, "N"),
}
# s: each divides 60 s; not only powers of two (the error scatters about its trend)
ADAPTIVE_FIXED_STEPS = tuple(
    ms * 1e-3
    for ms in (40, 32, 30, 25, 24, 20, 16, 15, 12.5, 12, 10, 8, 7.5, 6.4, 6, 5, 4, 3.2, 3, 2.5)
)
NEAREST = 6  # fixed runs in the line that gives a fixed step's doSteps for an error
ADAPTIVE_TOLERANCES = (1e-2, 1e-3, 1e-4, 1e-5)
ADAPTIVE_ESTIMATES: tuple[ErrorEstimate, ...] = ("extrapolation", "doubling")
# and, without --tolerances, the extrapolation estimate on vert-1 at the tolerances around
# 1e-3 too: whether it beats the fixed step there depends on the tolerance
MORE_TOLERANCES = {"vert-1": (2e-3, 1.25e-3, 8e-4, 5e-4)}


def figures_of(scenario: Scenario) -> tuple[dict[str, float | None], master.RunResult]:
    """The key figures of one run (through the master, nothing written)."""
    sink = KeyFigures(scenario.columns, scenario.key_instances)
    result = master.run(scenario, [sink], keep_rows=False)
    if not result.complete:
        raise RuntimeError(f"{scenario.id} at h = {scenario.coupling.step} s: {result.error}")
    return sink.figures(), result


def limit(values: Sequence[float], nominal: float) -> tuple[float, float]:
    """(limit, order) from the figure at 2.5, 1.25, 0.625 ms (Richardson on the last two)."""
    value, half, quarter = values
    observed = observed_order(value, half, quarter)
    order = observed or nominal
    return Estimate(value, half, quarter, order, observed is not None).limit, order


def shipped(ids: Sequence[str]) -> str:
    lines = [
        "| scenario | coupling | key figure | as shipped | limit | error | order |",
        "|---|---|---|---|---|---|---|",
    ]
    for sid in ids:
        base = load_scenario(sid)
        coupling = base.coupling
        how = f"{coupling.step * 1e3:g} ms, {coupling.algorithm}, {coupling.extrapolation}"
        ours, _ = figures_of(base)
        fine = [figures_of(base.with_overrides(step=h))[0] for h in FINE_STEPS]
        for key, (label, scale, unit) in FIGURES.items():
            value, values = ours[key], [run[key] for run in fine]
            finite = [v for v in values if v is not None]
            if value is None or len(finite) < len(values):
                continue
            f0, order = limit(finite, 2.0 if coupling.extrapolation_order else 1.0)
            error = (value - f0) / abs(f0) * 100.0 if f0 else 0.0
            lines.append(
                f"| {sid} | {how} | {label} | {scale * value:.4g} {unit} | "
                f"{scale * f0:.4g} {unit} | {error:+.2f} % | {order:.2g} |"
            )
        print(f"  {sid}: done ({_load()})", file=sys.stderr)
    return "\n".join(lines)


def check_steps(ids: Sequence[str]) -> str:
    lines = [
        "| scenario | inputs | key figure | estimated error | true error (against h/32) | ratio |",
        "|---|---|---|---|---|---|",
    ]
    for sid in ids:
        shipped_scenario = load_scenario(sid)
        for base in (shipped_scenario, shipped_scenario.with_overrides(extrapolation="none")):
            figures, result = figures_of(base)
            check = check_step(base, figures, result.final)
            truth, _ = figures_of(base.with_overrides(step=base.coupling.step / 32))
            for key, (label, scale, unit) in FIGURES.items():
                estimate, value, fine = check["key_figures"].get(key), figures[key], truth[key]
                if estimate is None or value is None or fine is None:
                    continue
                true_error = value - fine
                ratio = f"{estimate['error'] / true_error:.2f}" if true_error else "(both 0)"
                lines.append(
                    f"| {sid} | {base.coupling.extrapolation} | {label} | "
                    f"{scale * estimate['error']:+.3g} {unit} | {scale * true_error:+.3g} {unit} "
                    f"| {ratio} |"
                )
            print(f"  {sid} ({base.coupling.extrapolation}): done ({_load()})", file=sys.stderr)
    return "\n".join(lines)


def adaptive(tolerances: Sequence[float] | None, ids: Sequence[str]) -> str:
    """One table per scenario: fixed steps, then each error estimate at each tolerance
    (``None``: ADAPTIVE_TOLERANCES, and MORE_TOLERANCES for the extrapolation estimate)."""
    return "\n\n".join(_adaptive_table(sid, tolerances) for sid in ids)


def _adaptive_table(sid: str, given: Sequence[float] | None) -> str:
    base = load_scenario(sid)
    finest = base.with_overrides(step=0.0003125)
    reference, limits = _rows(finest), figures_of(finest)[0]
    runs = {f"fixed {h * 1e3:g} ms": base.with_overrides(step=h) for h in ADAPTIVE_FIXED_STEPS}
    for estimate in ADAPTIVE_ESTIMATES:
        tolerances = list(given or ADAPTIVE_TOLERANCES)
        if given is None and estimate == "extrapolation":
            tolerances = sorted({*tolerances, *MORE_TOLERANCES.get(sid, ())}, reverse=True)
        runs.update(
            {f"{estimate}, tol {tol:g}": base.with_overrides(
                algorithm="adaptive", tolerance=tol, error_estimate=estimate)
             for tol in tolerances}
        )  # fmt: skip
    lines = [
        "| run | steps accepted / rejected | plant doSteps | trajectory error | settling time "
        "error | peak mass position error | fixed step's doSteps for that error | "
        "doSteps / fixed's | wall clock (s) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    fixed: list[tuple[float, float]] = []  # (trajectory error, doSteps) of the fixed runs
    for name, scenario in runs.items():
        sink = KeyFigures(scenario.columns, scenario.key_instances)
        started = time.perf_counter()
        result = master.run(scenario, [sink])
        wall = time.perf_counter() - started
        if not result.complete:  # a stopped run's error would look small
            raise RuntimeError(f"{sid} {name}: {result.error}")
        figures, taken = sink.figures(), result.coupling
        steps = f"{taken.get('accepted_steps', result.rows - 1)} / {taken.get('rejected_steps', 0)}"
        do_steps = taken.get("do_steps", {}).get("plant", result.rows - 1)
        error = _error(result, reference)
        relative = [_relative(figures[key], limits[key]) for key in list(FIGURES)[:2]]
        if name.startswith("fixed"):
            fixed.append((error, do_steps))
        same, ratio = "", ""
        if not name.startswith("fixed"):
            errors = [e for e, _ in fixed]
            if min(errors) <= error <= max(errors):
                n_fixed = _same_error(fixed, error)
                same, ratio = f"{n_fixed:.0f}", f"{do_steps / n_fixed:.2f}"
            else:
                same = "(outside the fixed runs)"
        lines.append(
            f"| {name} | {steps} | {do_steps} | {error:.2e} | {relative[0]} | {relative[1]} | "
            f"{same} | {ratio} | {wall:.1f} |"
        )
        print(f"  {sid} {name}: done", file=sys.stderr)
    head = (
        f"{sid}, {base.coupling.extrapolation} extrapolation; errors against a run at 0.3125 "
        f"ms; the fixed runs' doSteps lie within a factor {_scatter(fixed):.2f} of the lines "
        f"through their nearest {NEAREST} ({_load()}):"
    )
    return "\n".join([head, "", *lines])


def _line(points: Sequence[tuple[float, float]]) -> tuple[float, float]:
    """(slope, intercept) of the least-squares line log doSteps = intercept + slope log
    error through ``points`` (trajectory error, doSteps)."""
    log_e, log_n = np.log([e for e, _ in points]), np.log([n for _, n in points])
    slope, intercept = np.polyfit(log_e, log_n, 1)
    return float(slope), float(intercept)


def _same_error(fixed: Sequence[tuple[float, float]], error: float) -> float:
    """The doSteps a fixed step would take for ``error``: the line (log-log) through the
    ``NEAREST`` fixed runs whose errors are nearest it (their error falls about as a power
    of the step, with a scatter: vert-1's is not monotonic in the step)."""
    nearest = sorted(fixed, key=lambda p: abs(np.log(p[0] / error)))[:NEAREST]
    slope, intercept = _line(nearest)
    return float(np.exp(intercept + slope * np.log(error)))


def _scatter(fixed: Sequence[tuple[float, float]]) -> float:
    """The largest factor between a fixed run's doSteps and the line's through the
    ``NEAREST`` other fixed runs of the closest steps (its own left out)."""
    worst = 0.0
    for i, (error, n) in enumerate(fixed):
        others = [p for j, p in enumerate(fixed) if j != i]
        nearest = sorted(others, key=lambda p: abs(np.log(p[1] / n)))[:NEAREST]
        slope, intercept = _line(nearest)
        worst = max(worst, abs(float(np.log(n)) - intercept - slope * float(np.log(error))))
    return float(np.exp(worst))


def _relative(value: float | None, limit: float | None) -> str:
    if value is None or not limit:
        return "n/a"
    return f"{(value - limit) / abs(limit):+.1e}"


def _rows(scenario: Scenario) -> master.RunResult:
    result = master.run(scenario)
    if not result.complete:
        raise RuntimeError(f"{scenario.id}: {result.error}")
    return result


def _error(result: master.RunResult, reference: master.RunResult) -> float:
    """max over the plant's outputs and the run's rows of |y - y_ref| / (|y_ref| + 1)."""
    assert result.times is not None and reference.times is not None
    worst = 0.0
    for k, column in enumerate(result.columns):
        if not column.startswith("plant.") or column not in reference.columns:
            continue
        ref = np.interp(result.times, reference.times, reference.column(column))
        assert result.values is not None
        worst = max(worst, float(np.max(np.abs(result.values[:, k] - ref) / (np.abs(ref) + 1))))
    return worst


def _load() -> str:
    return f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}"


def write(part: str, table: str, only: Sequence[str] | None = None) -> None:
    """``table`` between the part's markers in :data:`PAGE`; with ``only`` (the scenarios
    ``table`` measured) the page's rows of every other built-in scenario are kept, in the
    built-in order."""
    text = PAGE.read_text(encoding="utf-8")
    marker = re.compile(
        rf"(<!-- coupling_study.py {re.escape(part)} -->\n)(.*?)(\n<!-- end -->)", re.DOTALL
    )
    found = marker.search(text)
    if found is None:
        raise SystemExit(f"{PAGE}: no marker <!-- coupling_study.py {part} --> ... <!-- end -->")
    if only is not None:
        table = _merged(found[2], table, only)
    PAGE.write_text(marker.sub(lambda m: m[1] + table + m[3], text), encoding="utf-8")
    print(f"wrote the {part} table of {PAGE}")


def _merged(page_table: str, table: str, only: Sequence[str]) -> str:
    """``table``'s header, then the rows of each built-in scenario: from ``table`` for
    those in ``only``, else from ``page_table`` (a scenario no longer built in loses its)."""
    ids = list(builtin_scenarios())
    rows: dict[str, list[str]] = {sid: [] for sid in ids}
    for source, measured in ((page_table, False), (table, True)):
        for line in source.splitlines()[2:]:
            sid = line.split("|")[1].strip()
            if sid in rows and (sid in only) == measured:
                rows[sid].append(line)
    return "\n".join(table.splitlines()[:2] + [line for sid in ids for line in rows[sid]])


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("part", choices=["shipped", "check-step", "adaptive"])
    parser.add_argument("--scenarios", nargs="+", help="built-in ids [every one / bs-3 vert-1]")
    parser.add_argument(
        "--tolerances",
        type=float,
        nargs="+",
        help="adaptive [1e-2 1e-3 1e-4 1e-5; the extrapolation on vert-1 also 2e-3 1.25e-3 "
        "8e-4 5e-4]",
    )
    parser.add_argument("--write", action="store_true", help="into docs/coupling.md")
    args = parser.parse_args(argv)
    if args.part == "shipped":
        table = shipped(args.scenarios or list(builtin_scenarios()))
    elif args.part == "check-step":
        table = check_steps(args.scenarios or ["bs-3", "vert-1"])
    else:
        table = adaptive(args.tolerances, args.scenarios or ["vert-1", "bs-3"])
    if args.write:  # the shipped table of a few scenarios keeps the others' rows
        write(args.part, table, args.scenarios if args.part == "shipped" else None)
    else:
        print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
