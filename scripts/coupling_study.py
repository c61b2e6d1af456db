"""Measure the coupling error of the built-in scenarios; regenerate docs/coupling.md's tables.

    python scripts/coupling_study.py shipped [--scenarios bs-3 vert-1 ...] [--write]
    python scripts/coupling_study.py check-step [--scenarios bs-3 vert-1] [--write]
    python scripts/coupling_study.py adaptive [--scenarios vert-1 bs-3] [--tolerances ...] [--write]
    python scripts/coupling_study.py scatter [--scenarios vert-1 bs-3] [--write]
    python scripts/coupling_study.py guarantee [--scenarios vert-1] [--tolerances ...] [--write]

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

``scatter``: how a fixed step's trajectory error (as in ``adaptive``, against the same run
at 0.3125 ms) scatters about its trend: nine steps within 4 % of each of 5, 2.5, 1.25 and
0.625 ms, each dividing the stop time; per band the least, median and largest error, the
median over the centre step squared, the plant output and time of the largest, and how
much of that output's difference from the reference over the second half of each run is
the reference shifted in time (an oscillation's phase error); the header gives the
reference's own error (against a run at half its step) and the slope of log median error
against log step.

``guarantee``: the adaptive step at tolerances within a factor 1.25 of 1e-3 (the
extrapolation estimate; 2 % apart and at 0.9, 1, 1.1 and 1.25e-3), against fixed steps
1 % apart from 4 to 20 ms (each dividing the stop time), both as a user choosing a step
meets them, whose error scatters on both sides.
(a) The median: the doSteps a fixed step takes for each adaptive run's trajectory error on
the least-squares line log error against log doSteps through all the fixed runs. (b) The
guarantee: the worst trajectory error of the adaptive runs over the tolerance
neighbourhood, and the fixed step a user must pick so that every measured step at or
below it reaches that error (the envelope: the finest steps' errors are below it, so the
steps under 4 ms, whose errors the scatter table bounds, do not change it); the adaptive
neighbourhood's doSteps (at 1e-3, and its most) against the envelope step's.

``--write`` replaces the table between the markers ``<!-- coupling_study.py <part> -->``
and ``<!-- end -->`` in docs/coupling.md (``shipped --scenarios``: only those scenarios'
rows, the others' kept; a page without the part's markers is refused before the first
run); without it the table is printed. Runs go through
the master (no files written); the machine's load is printed beside the times. The
tables hold one vehicle's key figures: a scenario of several vehicles (two plants) is
refused before the first run, naming its plants.
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
REFERENCE_STEP = 0.0003125  # s: the run the adaptive and scatter tables' errors are against
SCATTER_CENTRES = (0.005, 0.0025, 0.00125, 0.000625)  # s: the scatter table's steps
# the guarantee table: tolerances within a factor 1.25 of 1e-3 (the middle one is the one
# a user picks), fixed steps 1 % apart from GUARANTEE_STEPS[0] to GUARANTEE_STEPS[1]
GUARANTEE_CENTRE = 1e-3
GUARANTEE_TOLERANCES = tuple(  # 0.8 to 1.25 times the centre, 2 % apart, and 0.9, 1, 1.1, 1.25
    sorted(
        {*(round(8e-4 * 1.02**j, 9) for j in range(23)), 9e-4, 1e-3, 1.1e-3, 1.25e-3}, reverse=True
    )
)
GUARANTEE_STEPS = (0.004, 0.02)  # s
# the scenarios a part measures when --scenarios names none (shipped: every built-in)
DEFAULT_SCENARIOS = {
    "check-step": ["bs-3", "vert-1"],
    "adaptive": ["vert-1", "bs-3"],
    "scatter": ["vert-1", "bs-3"],
    "guarantee": ["vert-1"],
}


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
    finest = base.with_overrides(step=REFERENCE_STEP)
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


def scatter(ids: Sequence[str]) -> str:
    """One table per scenario: the trajectory error (against the run at 0.3125 ms) of the
    fixed steps within 4 % of each of SCATTER_CENTRES, as shipped otherwise."""
    return "\n\n".join(_scatter_table(sid) for sid in ids)


def _scatter_table(sid: str) -> str:
    base = load_scenario(sid)
    stop = base.stop_time
    reference = _rows(base.with_overrides(step=REFERENCE_STEP))
    own = _worst(_rows(base.with_overrides(step=REFERENCE_STEP / 2)), reference)
    lines = [
        "| steps (ms) | trajectory error: least / median / largest | largest / least "
        "| median / h² (1/s²) | largest at | that output's time shift at the end (µs): "
        "least / largest | left after the shift: median |",
        "|---|---|---|---|---|---|---|",
    ]
    medians: list[tuple[float, float]] = []  # (centre step, median error)
    for centre in SCATTER_CENTRES:
        # steps of stop / n, n within 4 % of stop / centre: each divides the stop time
        steps = [stop / round(stop / centre * (1.0 + j / 100.0)) for j in range(-4, 5)]
        runs = []  # (error, output, time, shift, left)
        for h in steps:
            result = _rows(base.with_overrides(step=h))
            error, column, at = _worst(result, reference)
            runs.append((error, column, at, *_time_shift(result, reference, column)))
        errors = sorted(run[0] for run in runs)
        median = float(np.median(errors))
        medians.append((centre, median))
        largest, column, at, _, _ = max(runs)
        shifts = sorted(run[3] * 1e6 for run in runs)
        left = float(np.median([run[4] for run in runs]))
        lines.append(
            f"| {steps[-1] * 1e3:.4g} to {steps[0] * 1e3:.4g} | {errors[0]:.2e} / "
            f"{median:.2e} / {largest:.2e} | {largest / errors[0]:.1f} | "
            f"{median / centre**2:.3g} | {column.removeprefix('plant.')}, {at:.2f} s | "
            f"{shifts[0]:+.3g} / {shifts[-1]:+.3g} | {left:.0%} |"
        )
        print(f"  {sid} {centre * 1e3:g} ms: done", file=sys.stderr)
    order = _line(medians)[0]  # the slope of log median error against log step
    head = (
        f"{sid}, {base.coupling.extrapolation} extrapolation, nine steps within 4 % of each "
        f"of {', '.join(f'{h * 1e3:g}' for h in SCATTER_CENTRES)} ms; errors against a run at "
        f"{REFERENCE_STEP * 1e3:g} ms, whose own error against a run at half its step is "
        f"{own[0]:.1e} ({own[1].removeprefix('plant.')}, {own[2]:.2f} s); the median falls "
        f"as the step to the power {order:.2f}:"
    )
    return "\n".join([head, "", *lines])


def guarantee(tolerances: Sequence[float] | None, ids: Sequence[str]) -> str:
    """One table per scenario: the adaptive step at each tolerance (``None``:
    GUARANTEE_TOLERANCES) against dense fixed steps, by the median and by the envelope."""
    return "\n\n".join(_guarantee_table(sid, tolerances or GUARANTEE_TOLERANCES) for sid in ids)


def _dense_steps(stop: float) -> list[float]:
    """Steps 1 % apart over GUARANTEE_STEPS, longest first, each dividing ``stop``."""
    fewest, most = (round(stop / h) for h in reversed(GUARANTEE_STEPS))
    counts = sorted({*(round(fewest * 1.01**j) for j in range(400)), most})
    counts = [n for n in counts if n <= most]
    return [stop / n for n in counts]


def _guarantee_table(sid: str, tolerances: Sequence[float]) -> str:
    base = load_scenario(sid)
    reference = _rows(base.with_overrides(step=REFERENCE_STEP))
    fixed: list[tuple[float, float]] = []  # (trajectory error, doSteps)
    for h in _dense_steps(base.stop_time):
        fixed.append((_error(_rows(base.with_overrides(step=h)), reference), base.stop_time / h))
    print(f"  {sid}: {len(fixed)} fixed steps done ({_load()})", file=sys.stderr)
    trend = _trend(fixed)
    lines = [
        "| tolerance | plant doSteps | trajectory error | (a) median fixed step's doSteps "
        "for that error | doSteps / median's | (b) fixed envelope's doSteps for that error |",
        "|---|---|---|---|---|---|",
    ]
    adaptive_runs: list[tuple[float, float, float]] = []  # (tolerance, error, doSteps)
    for tol in sorted(tolerances, reverse=True):
        scenario = base.with_overrides(
            algorithm="adaptive", tolerance=tol, error_estimate="extrapolation"
        )
        result = _rows(scenario)
        error, do_steps = _error(result, reference), result.coupling["do_steps"]["plant"]
        adaptive_runs.append((tol, error, do_steps))
        median = _on_trend(trend, error)
        lines.append(
            f"| {tol:g} | {do_steps} | {error:.2e} | {median:.0f} | {do_steps / median:.2f} | "
            f"{_shown(_envelope(fixed, error))} |"
        )
        print(f"  {sid} tol {tol:g}: done", file=sys.stderr)
    return "\n".join(
        [_guarantee_head(sid, base, fixed, trend), "", *lines, "",
         _guarantee_verdict(adaptive_runs, fixed, base.stop_time)]
    )  # fmt: skip


def _guarantee_head(
    sid: str, base: Scenario, fixed: Sequence[tuple[float, float]], trend: tuple[float, float]
) -> str:
    """The table's header: the fixed runs, their trend and their scatter about it."""
    off = [abs(np.log(e) - trend[1] - trend[0] * np.log(n)) for e, n in fixed]
    return (
        f"{sid}, {base.coupling.extrapolation} extrapolation; errors against a run at "
        f"{REFERENCE_STEP * 1e3:g} ms; {len(fixed)} fixed steps 1 % apart from "
        f"{GUARANTEE_STEPS[0] * 1e3:g} to {GUARANTEE_STEPS[1] * 1e3:g} ms, whose error falls "
        f"as doSteps to the power {trend[0]:.2f} (least squares, log-log) and lies within a "
        f"factor {np.exp(max(off)):.1f} of that line ({_load()}):"
    )


def _guarantee_verdict(
    runs: Sequence[tuple[float, float, float]], fixed: Sequence[tuple[float, float]], stop: float
) -> str:
    """(a), the same cost and (b), a sentence each: the adaptive runs' doSteps against the
    median fixed step's for their errors; the errors of both at the same doSteps; the
    neighbourhood's worst error, and the doSteps the adaptive runs and the envelope's
    fixed step take for it."""
    ratios = [n / _on_trend(_trend(fixed), error) for _, error, n in runs]
    median = (
        f"Median: over {len(runs)} tolerances the adaptive step takes {min(ratios):.2f} to "
        f"{max(ratios):.2f} times the doSteps of the median fixed step for its error (geometric "
        f"mean {np.exp(np.mean(np.log(ratios))):.2f}), fewer at {sum(r < 1 for r in ratios)}."
    )
    fewest, most = min(run[2] for run in runs), max(run[2] for run in runs)
    alike = [e for e, n in fixed if fewest <= n <= most]  # the fixed steps of the same cost
    same_cost = (
        f"At the same cost ({fewest:.0f} to {most:.0f} doSteps) the {len(alike)} fixed steps' "
        f"errors are {_spread(alike)} (least / median / largest), the adaptive runs' "
        f"{_spread([run[1] for run in runs])}."
    )
    worst_tol, worst, _ = max(runs, key=lambda run: run[1])
    middle = min(runs, key=lambda run: abs(np.log(run[0] / GUARANTEE_CENTRE)))
    envelope = _envelope(fixed, worst)
    if envelope is None:
        return f"{median} {same_cost} Worst error {worst:.2e}: outside the envelope."
    return (
        f"{median} {same_cost} Guaranteed error: over tolerances {min(runs)[0]:g} to "
        f"{max(runs)[0]:g} the worst trajectory error is {worst:.2e} (at {worst_tol:g}); "
        f"every fixed step at or below {1e3 * stop / envelope:.4g} ms ({envelope:.0f} "
        f"doSteps) reaches it. The adaptive step takes {middle[2]:.0f} doSteps at "
        f"{middle[0]:g} ({middle[2] / envelope:.2f} times the envelope's) and at most "
        f"{most:.0f} "
        f"({most / envelope:.2f} times)."
    )


def _time_shift(
    result: master.RunResult, reference: master.RunResult, column: str
) -> tuple[float, float]:
    """How much of the run's difference from ``reference`` in ``column`` over the run's
    second half is the reference shifted in time, y - y_ref ~ -s(t) y_ref', by a shift
    s(t) = s0 + s1 t that may drift (an oscillation's period off too), fitted by least
    squares: (s at the run's end, s; the part of the difference the shift leaves, as a
    fraction of the difference's 2-norm)."""
    assert result.times is not None and reference.times is not None
    late = result.times >= result.times[-1] / 2
    times = result.times[late]
    ref = reference.column(column)
    slope = np.interp(times, reference.times, np.gradient(ref, reference.times))
    difference = result.column(column)[late] - np.interp(times, reference.times, ref)
    basis = -np.column_stack([slope, times * slope])
    (s0, s1), *_ = np.linalg.lstsq(basis, difference, rcond=None)
    left = np.linalg.norm(difference - basis @ [s0, s1]) / np.linalg.norm(difference)
    return float(s0 + s1 * times[-1]), float(left)


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


def _trend(fixed: Sequence[tuple[float, float]]) -> tuple[float, float]:
    """(slope, intercept) of the least-squares line log error = intercept + slope log
    doSteps through the fixed runs ``fixed`` (trajectory error, doSteps): the error is what
    scatters at a given step, so it is the regressed variable."""
    slope, intercept = np.polyfit(np.log([n for _, n in fixed]), np.log([e for e, _ in fixed]), 1)
    return float(slope), float(intercept)


def _on_trend(trend: tuple[float, float], error: float) -> float:
    """The doSteps at which the line ``trend`` (:func:`_trend`) reaches ``error``."""
    slope, intercept = trend
    return float(np.exp((np.log(error) - intercept) / slope))


def _envelope(fixed: Sequence[tuple[float, float]], error: float) -> float | None:
    """The doSteps of the longest fixed step at or below which every step of ``fixed``
    (trajectory error, doSteps) reaches ``error``; None where the finest misses it or the
    coarsest already reaches it (the envelope is then outside the steps measured)."""
    ordered = sorted(fixed, key=lambda run: run[1], reverse=True)  # finest first
    reached = None
    for run_error, do_steps in ordered:
        if run_error > error:
            break
        reached = do_steps
    return None if reached == ordered[-1][1] else reached


def _spread(errors: Sequence[float]) -> str:
    """Least / median / largest of ``errors``."""
    if not errors:
        return "(none)"
    return " / ".join(f"{e:.2e}" for e in (min(errors), float(np.median(errors)), max(errors)))


def _shown(do_steps: float | None) -> str:
    return "(outside the steps measured)" if do_steps is None else f"{do_steps:.0f}"


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
    return _worst(result, reference)[0]


def _worst(result: master.RunResult, reference: master.RunResult) -> tuple[float, str, float]:
    """(the trajectory error, :func:`_error`; the plant output and the time, s, of it)."""
    assert result.times is not None and result.values is not None
    assert reference.times is not None
    worst = (0.0, "", 0.0)
    for k, column in enumerate(result.columns):
        if not column.startswith("plant.") or column not in reference.columns:
            continue
        ref = np.interp(result.times, reference.times, reference.column(column))
        error = np.abs(result.values[:, k] - ref) / (np.abs(ref) + 1)
        i = int(np.argmax(error))
        if error[i] > worst[0]:
            worst = (float(error[i]), column, float(result.times[i]))
    return worst


def _load() -> str:
    return f"load {' '.join(f'{x:.2f}' for x in os.getloadavg())}"


def write(part: str, table: str, only: Sequence[str] | None = None) -> None:
    """``table`` between the part's markers in :data:`PAGE`; with ``only`` (the scenarios
    ``table`` measured) the page's rows of every other built-in scenario are kept, in the
    built-in order."""
    text = PAGE.read_text(encoding="utf-8")
    marker = _marker(part)
    found = marker.search(text)
    if found is None:
        raise SystemExit(_no_marker(part))
    if only is not None:
        table = _merged(found[2], table, only)
    PAGE.write_text(marker.sub(lambda m: m[1] + table + "\n<!-- end -->", text), encoding="utf-8")
    print(f"wrote the {part} table of {PAGE}")


def _marker(part: str) -> re.Pattern[str]:
    """The part's markers in :data:`PAGE` and the table between them (none yet, too)."""
    return re.compile(
        rf"(<!-- coupling_study.py {re.escape(part)} -->\n)(.*?)(\n?<!-- end -->)", re.DOTALL
    )


def _no_marker(part: str) -> str:
    return f"{PAGE}: no marker <!-- coupling_study.py {part} --> ... <!-- end -->"


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


def _check_arguments(parser: argparse.ArgumentParser, args: argparse.Namespace) -> None:
    """Refuse (one line, before a run) an id that is no built-in scenario, and tolerances
    given to a part that reads none or that no run could meet."""
    known = builtin_scenarios()
    for scenario in args.scenarios or []:
        if scenario not in known:
            parser.error(
                f"--scenarios: unknown scenario {scenario!r}; expected built-in ids "
                f"({', '.join(known)})"
            )
    for scenario in args.scenarios or DEFAULT_SCENARIOS.get(args.part, list(known)):
        _one_vehicle(parser, scenario)
    if args.tolerances is not None and args.part not in ("adaptive", "guarantee"):
        parser.error(
            f"--tolerances: only with adaptive or guarantee (the {args.part} part reads none)"
        )
    for tolerance in args.tolerances or []:
        if not (np.isfinite(tolerance) and tolerance > 0.0):
            parser.error(f"--tolerances: {tolerance!r} is not a positive finite number")


def _one_vehicle(parser: argparse.ArgumentParser, sid: str) -> None:
    """Refuse (one line) a scenario of several vehicles: every table holds one vehicle's
    key figures (:data:`FIGURES`, the plain names), and the coupling error of a fleet,
    each plant's figures named after it, is not what they measure."""
    fleet = load_scenario(sid).key_vehicles
    if len(fleet) > 1:
        plants = ", ".join(v.roles["plant"] for v in fleet)
        parser.error(
            f"--scenarios: {sid} has {len(fleet)} vehicles (plants {plants}); the tables "
            "hold one vehicle's key figures: expected a scenario of one plant"
        )


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "part", choices=["shipped", "check-step", "adaptive", "scatter", "guarantee"]
    )
    parser.add_argument("--scenarios", nargs="+", help="built-in ids [every one / bs-3 vert-1]")
    parser.add_argument(
        "--tolerances",
        type=float,
        nargs="+",
        help="adaptive [1e-2 1e-3 1e-4 1e-5; the extrapolation on vert-1 also 2e-3 1.25e-3 "
        "8e-4 5e-4]; guarantee [8e-4 to 1.25e-3, 2 %% apart, and 9e-4 1e-3 1.1e-3]",
    )
    parser.add_argument("--write", action="store_true", help="into docs/coupling.md")
    args = parser.parse_args(argv)
    _check_arguments(parser, args)
    if args.write and _marker(args.part).search(PAGE.read_text(encoding="utf-8")) is None:
        parser.error(_no_marker(args.part))  # before the runs, not after them
    ids = args.scenarios or DEFAULT_SCENARIOS.get(args.part, list(builtin_scenarios()))
    if args.part == "shipped":
        table = shipped(ids)
    elif args.part == "check-step":
        table = check_steps(ids)
    elif args.part == "scatter":
        table = scatter(ids)
    elif args.part == "guarantee":
        table = guarantee(args.tolerances, ids)
    else:
        table = adaptive(args.tolerances, ids)
    if args.write:  # the shipped table of a few scenarios keeps the others' rows
        write(args.part, table, args.scenarios if args.part == "shipped" else None)
    else:
        print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
