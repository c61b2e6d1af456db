"""How far a run is from the continuous-time limit: ``auv-cosim run --check-step``.

The scenario runs again at half and at a quarter of its step (no outputs written, rows
not kept: only the key figures and the final values, :mod:`cosim.metrics.key_figures`),
and :mod:`cosim.metrics.richardson` turns the three values of each figure into the
estimated error of the run at the scenario's step, with the order observed on them. A
digital controller that samples at its own period (the autopilot's ``sample_period``)
keeps it in the checks: what is checked is the coupling, not the controller's design. So
does a delay fault (its ``steps`` doubled at h/2: the same delay in seconds); a noise or
dropout fault, which draws anew at every exchange, makes the finer runs other systems, and
is refused.

An event, series time or fault boundary between the points of the three runs applies at
another time in each (the first point at or after it), and an event on a condition fires
at the first point it holds: the runs then differ by where the jump lands, an error of
O(h) with no order Richardson extrapolation can find. The estimate is still made, but
the check says it cannot be trusted, naming the cause (:func:`doubts`).

Costs six times the run itself (2 + 4 times its steps), paid after it; a signal during
the checks stops them and the run keeps its results without an estimate.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from cosim.engine import master
from cosim.engine.signals import StopRequest
from cosim.errors import CosimError, seconds
from cosim.metrics.key_figures import ACTIVITY_FIGURES, key_figures
from cosim.metrics.richardson import estimate, run_order
from cosim.scenario.spec import Scenario
from cosim.scenario.timeline_spec import first_point

FINAL_PREFIX = "final."  # the estimate of a final value is named "final.<column>"
ROUNDING = 1e-13  # relative: values of the three runs closer than this agree to rounding


def not_checkable(scenario: Scenario) -> str | None:
    """Why ``scenario`` cannot have its coupling error estimated, or None: an adaptive
    run controls its error itself, and a noise or dropout fault draws anew at every
    exchange. The command, the API and a study ask it before the first step, so a run is
    refused at once rather than checked in vain after it."""
    coupling = scenario.coupling
    if coupling.algorithm == "adaptive":
        return (
            f"{scenario.id} runs the adaptive algorithm, which controls its error itself "
            f"(tolerance {coupling.tolerance!r}); check a fixed step (algorithm jacobi or "
            "gauss-seidel)"
        )
    drawn = [f for f in scenario.faults if f.kind in ("noise", "dropout")]
    if drawn:
        return (
            f"fault {drawn[0].name!r} ({drawn[0].kind}) draws anew at every exchange, so runs "
            "at h/2 and h/4 are other systems, not this one coupled more finely; check the "
            "scenario without it"
        )
    return None


def doubts(scenario: Scenario) -> list[str]:
    """Why the estimate of ``scenario``'s coupling error cannot be trusted (module
    docstring): each time of an event, a series or a fault boundary that the runs at h,
    h/2 and h/4 apply at different points (an instance with step multiple k sees it at
    its own points, every k h), and each event on a condition."""
    times: list[tuple[str, float, set[str]]] = []  # (key, time, the instances it acts on)
    found = []
    for event in scenario.events:
        acts_on = {ref.split(".", 1)[0] for ref in event.set}
        if event.time is not None:
            times.append((f"events.{event.name}.time", event.time, acts_on))
        if event.series is not None:
            on = {ref.split(".", 1)[0] for ref in event.series.columns}
            times += [(f"events.{event.name}.series time", t, on) for t in event.series.times]
        if event.when is not None:
            found.append(
                f"events.{event.name} fires when {event.when}, at the first point it holds: "
                "its time moves with the step, an error Richardson extrapolation does not model"
            )
    for fault in scenario.faults:
        on = {fault.target.split(".", 1)[0]}
        times.append((f"faults.{fault.name}.start", fault.start, on))
        if fault.stop is not None:
            times.append((f"faults.{fault.name}.stop", fault.stop, on))
    for key, time, acts_on in times:
        if time < scenario.stop_time:
            found += _moved(scenario, key, time, acts_on)
    return found


def _moved(scenario: Scenario, key: str, time: float, acts_on: set[str]) -> list[str]:
    """The doubt (one line, or none) that ``key``, at ``time`` (s), reaches the instances
    it ``acts_on`` at different times in the runs at h, h/2 and h/4: at the first point of
    each at or after it, every k h for an instance of step multiple k. The slowest of them
    is looked at first and the advice is a point of every one of them (the least common
    multiple of their k): a point of h alone still moves for an instance of k > 1."""
    h = scenario.coupling.step
    multiples = scenario.coupling.step_multiples
    steps = {multiples.get(name, 1) for name in acts_on} or {1}
    for k in sorted(steps, reverse=True):
        # the point each run applies it at, counted in steps of h/4: compared as whole
        # numbers, so that first_point's slack is the one tolerance of "on a point"
        quarters = [first_point(time, k * step) * k * round(4 * step / h)
                    for step in (h, h / 2, h / 4)]  # fmt: skip
        if len(set(quarters)) > 1:
            applied = [seconds(n * h / 4) for n in quarters]
            shown = f"{applied[0]}, {applied[1]} and {applied[2]} s"
            slow = sorted(name for name in acts_on if multiples.get(name, 1) == k)
            who = f" ({', '.join(slow)} steps every {k} h)" if k > 1 else ""
            every = math.lcm(*steps)
            return [
                f"{key} = {seconds(time)} s applies at {shown} in the runs at h, h/2 and h/4"
                f"{who}: its time moves with the step, an error Richardson extrapolation does "
                f"not model (put it on a point of {f'{every} h' if every > 1 else 'h'})"
            ]
    return []


def check_step(
    scenario: Scenario,
    figures: dict[str, float | None],
    final: np.ndarray,
    stop: StopRequest | None = None,
) -> dict[str, Any]:
    """The error estimate of a complete run of ``scenario`` whose key ``figures`` and
    ``final`` row (``scenario.columns``) are given: the summary's ``check_step`` entry.

    Raises :class:`CosimError` for an adaptive scenario (it controls its error itself),
    or if a check run does not complete (its reason)."""
    coupling = scenario.coupling
    reason = not_checkable(scenario)
    if reason is not None:
        raise CosimError(f"--check-step: {reason}")
    values = [_named(figures, scenario.columns, final)]
    steps = [coupling.step / 2, coupling.step / 4]
    for step in steps:
        checked = _same_delays(
            scenario.with_overrides(step=step, names=None), round(coupling.step / step)
        )
        sink = key_figures(scenario.columns, scenario.key_vehicles)
        result = master.run(checked, [sink], keep_rows=False, stop=stop)
        if not result.complete:
            raise CosimError(f"--check-step: the run at h = {step!r} s stopped: {result.error}")
        values.append(_named(sink.figures(), scenario.columns, result.final))
    nominal = 2.0 if coupling.extrapolation_order else 1.0  # as adaptive.coupling_order
    estimates, order = estimate(values, nominal)
    runs = [[getattr(e, part) for e in estimates.values()] for part in ("value", "half", "quarter")]
    figures_part = {k: e.as_dict() for k, e in estimates.items() if k in figures}
    finals = {k: e for k, e in estimates.items() if k.startswith(FINAL_PREFIX)}
    worst = max(finals.items(), key=lambda kv: _scaled(kv[1].error, kv[1].limit), default=None)
    return {
        "steps_s": [coupling.step, *steps],
        "doubts": doubts(scenario),
        "order": order,
        # the order seen on the runs' values together (else the coupling's nominal one),
        # and whether they differ beyond the rounding of doubles at all
        "order_observed": run_order(runs) is not None,
        "within_rounding": _within_rounding(runs),
        "key_figures": figures_part,
        "final_values": {k.removeprefix(FINAL_PREFIX): e.as_dict() for k, e in finals.items()},
        "largest_final_error": None
        if worst is None
        else {
            "column": (column := worst[0].removeprefix(FINAL_PREFIX)),
            "unit": _unit(scenario, column),
            **worst[1].as_dict(),
        },
    }


def _within_rounding(runs: list[list[float]]) -> bool:
    """Whether the values at h, h/2 and h/4 (``runs``) agree to the rounding of doubles
    (:data:`ROUNDING` of their size): then no error and no order can be seen in them."""
    return all(
        abs(a - b) <= ROUNDING * max(abs(a), abs(b))
        for ours, theirs in ((runs[0], runs[1]), (runs[1], runs[2]))
        for a, b in zip(ours, theirs, strict=True)
    )


def _unit(scenario: Scenario, column: str) -> str:
    """The unit ``column`` (``<instance>.<variable>``) is declared in, "" without one."""
    instance, _, variable = column.partition(".")
    inst = scenario.instances.get(instance)
    var = None if inst is None else inst.interface.variables.get(variable)
    return (var.unit or "") if var is not None else ""


def _same_delays(scenario: Scenario, factor: int) -> Scenario:
    """``scenario`` at a step ``factor`` times shorter with each delay fault's steps
    ``factor`` times more: the same delay in seconds."""
    faults = tuple(
        dataclasses.replace(f, steps=f.steps * factor) if f.kind == "delay" and f.steps else f
        for f in scenario.faults
    )
    return dataclasses.replace(scenario, faults=faults)


def has_coupling_error(figure: str) -> bool:
    """Whether the check estimates the key figure ``figure`` (``<vehicle>.`` prefixed or
    not): all but the commands' activity (a chattering command's total variation grows as
    h shrinks: it has no limit to estimate), so a study has no column of its error."""
    return figure.rsplit(".", 1)[-1] not in ACTIVITY_FIGURES


def _named(
    figures: dict[str, float | None], columns: tuple[str, ...], final: np.ndarray
) -> dict[str, float | None]:
    """The figures checked, by name: the key figures but the commands' activity (a
    chattering command's total variation grows as h shrinks: it has no limit to
    estimate), and the final values."""
    named = {k: v for k, v in figures.items() if has_coupling_error(k)}
    named.update({f"{FINAL_PREFIX}{c}": float(v) for c, v in zip(columns, final, strict=True)})
    return named


def _scaled(error: float, limit: float) -> float:
    """|error| / (|limit| + 1): the final values' ranking, as the adaptive algorithm
    weighs an error (a value near 0 is not ranked by its relative error)."""
    return abs(error) / (abs(limit) + 1.0) if math.isfinite(error) else math.inf


def summary_line(check: dict[str, Any]) -> str:
    """The run report's last line: every key figure's estimated error (and relative)."""
    parts = []
    for name, e in check["key_figures"].items():
        relative = e["relative_error"]
        share = f" ({relative * 100:+.2g} %)" if relative is not None else ""
        parts.append(f"{name} {e['error']:+.3g}{share}")
    worst = check["largest_final_error"]
    if worst is not None:
        unit = f" {worst['unit']}" if worst.get("unit") else ""
        parts.append(f"largest final-value error {worst['column']} {worst['error']:+.3g}{unit}")
    steps = ", ".join(f"{s:g}" for s in check["steps_s"])
    found = check.get("doubts") or []
    doubt = ""
    if found:
        more = f"; {len(found) - 1} more in summary.json" if len(found) > 1 else ""
        doubt = f" NOT TO BE TRUSTED ({found[0]}{more})"
    if check.get("within_rounding"):
        order = "the three runs agree to rounding: no error to see"
    elif check.get("order_observed", True):
        order = f"order {check['order']:.2g}"
    else:
        order = f"order {check['order']:.2g} assumed, none observed"
    return f"  coupling error{doubt} (Richardson from h = {steps} s, {order}): " + (
        ", ".join(parts) if parts else "no figure to check"
    )
