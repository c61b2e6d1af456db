"""Chapter 6's closed-loop runs at a converged step: the built-in scenarios run through our
master (``cosim.runner``) at two communication steps, and every figure of a run taken at
their Richardson limit with the coupling error measured.

Why two steps: the instances exchange values only at communication steps (held or
extrapolated over each, as the scenario's ``[coupling]`` says), so every figure of a
closed-loop run depends on the step (the coupling error); the dissertation's simulations
are continuous-time (MATLAB). Each figure f is computed at ``COARSE`` = 1.25 ms and
``FINE`` = 0.625 ms with the scenario's own coupling (the LQR redesigned for each, as
``auv-cosim run --step`` does); ours is the Richardson limit 2 f(FINE) - f(COARSE), and
the coupling error of the FINE run, |f(FINE) - f(COARSE)|, is shown beside it and must
stay below the printed precision (else the row cannot be judged,
:func:`cosim.reproduction.record.evaluate`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from pathlib import Path

from cosim.reproduction.context import Context, NotRunError, RunData, Runner

COARSE, FINE = 0.00125, 0.000625  # s: the two communication steps of every Chapter 6 figure


def runner(
    work: Path, log: Callable[[str], None] | None = None, fmu_dir: Path | None = None
) -> Runner:
    """Runs a built-in scenario at a step with start values added into a folder under
    ``work`` (no recording; the FMUs in ``fmu_dir``, default: the master's) and reads its
    results."""
    options = {} if fmu_dir is None else {"fmu_dir": fmu_dir}

    def run(scenario_id: str, step: float, start: Mapping[str, float], held: bool) -> RunData:
        from cosim.outputs.results import read_csv
        from cosim.runner import run_scenario
        from cosim.scenario.spec import load_scenario

        scenario = load_scenario(scenario_id, **options)
        if start:
            scenario = scenario.with_start(start)
        name = "-".join(
            [scenario_id, f"{1e3 * step:g}ms", *(f"{k}={v:g}" for k, v in start.items())]
            + (["held"] if held else [])
        )
        started = time.perf_counter()
        coupling = {"extrapolation": "none"} if held else {}
        # its what-ifs change the plant and not the design on purpose (plant.a35, M_uq):
        # no doubt to raise about them
        outcome = run_scenario(
            scenario, work / name, no_rrd=True, step=step, unit_doubts=False, **coupling, **options
        )
        if log is not None:
            log(f"  {name}: ran in {time.perf_counter() - started:.0f} s")
        if not outcome.result.complete:
            raise RuntimeError(f"{name} did not complete: {outcome.result.error}")
        columns, values = read_csv(outcome.paths["results"])
        table = {column: values[:, k] for k, column in enumerate(columns)}
        return RunData(table, work / name)

    return run


def converged(
    ctx: Context,
    scenario_id: str,
    figure: Callable[[RunData], float | None],
    start: Mapping[str, float] | None = None,
) -> tuple[float, float]:
    """(the Richardson limit of ``figure`` of a scenario, the coupling error of its FINE
    run); ``start`` values added to the scenario's.

    Raises:
        NotRunError: scenarios are skipped.
        ValueError: the figure does not exist at one of the steps (a run that never
            settles).
    """
    coarse = figure(ctx.run(scenario_id, COARSE, start))
    fine = figure(ctx.run(scenario_id, FINE, start))
    if coarse is None or fine is None:
        raise ValueError(f"{scenario_id}: not at both steps ({coarse}, {fine})")
    return 2.0 * fine - coarse, abs(fine - coarse)


def finest(ctx: Context, scenario_id: str) -> RunData:
    """The FINE run of a scenario (figures, qualitative claims)."""
    if ctx.runner is None:
        raise NotRunError("scenarios skipped")
    return ctx.run(scenario_id, FINE)
