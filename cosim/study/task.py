"""One run of a study, and the adapter to ``cosim.run``: the only module that uses it.

The client calls :func:`prepare` once: it loads the scenario (``load_scenario``, the
study's stop time through ``Scenario.with_overrides``), keeps it as resolved TOML data
(``Scenario.to_toml``), and reads the facts a study checks factors against. A worker
calls :func:`run_one` per run: the FMU references point at the worker's own copies, the
run's factor values are written into the TOML data, and the data is resolved again
(``scenario_from_data``, so every value passes the scenario's own checks) and run
(``run_scenario(..., no_rrd=True, tail_guard=False)``: a killed task's run is run
again, so its folder needs no guard); the metrics are the numeric values of the run's
``summary.json``.
"""

from __future__ import annotations

import copy
import json
import tempfile
import time
import tomllib
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from cosim.errors import CosimError
from cosim.metrics.key_figures import KeyFigures
from cosim.metrics.manoeuvres import summary_metrics
from cosim.outputs.manoeuvre import scenario_metric_names
from cosim.runner import run_scenario
from cosim.scenario.spec import Scenario, load_scenario, scenario_from_data
from cosim.study.factors import FactorKind, ScenarioFacts, Value, Variable, apply_values
from cosim.study.spec import StudyError

KEEP_FILES = ("results", "summary")  # run_scenario outputs a kept run folder receives


@dataclass(frozen=True)
class Base:
    """The scenario every run starts from, as the client resolved it."""

    scenario_id: str
    data: Mapping[str, Any]  # the resolved scenario as TOML data (FMUs as referenced)
    fmu_paths: Mapping[str, Path]  # instance -> its FMU file on the client


@dataclass(frozen=True)
class RunRecord:
    """What one run reports back: one row of the table, and its files if kept."""

    status: str  # "complete" or "failed"
    error: str | None  # one line, None if complete
    metrics: Mapping[str, float | None]  # empty if failed
    wall_clock_s: float  # the whole task: set-up, stepping loop, outputs
    loop_s: float  # the stepping loop alone (0 if it never started)
    files: Mapping[str, bytes] = field(default_factory=dict)  # file name -> content


def prepare(
    scenario_ref: str | Path, stop_time: float | None, fmu_dir: Path
) -> tuple[Base, ScenarioFacts]:
    """Load the scenario (built-in FMUs built into ``fmu_dir`` if needed) and read what
    the study checks its factors and metrics against. Raises ``CosimError``."""
    scenario = load_scenario(scenario_ref, fmu_dir=fmu_dir)
    if stop_time is not None:
        scenario = scenario.with_overrides(stop_time=stop_time)
    driven = {c.target: c.source for c in scenario.connections}
    instances = {
        name: {
            v.name: Variable(
                v.name, v.type, v.causality, v.variability, driven.get(f"{name}.{v.name}")
            )
            for v in inst.model_description.modelVariables
        }
        for name, inst in scenario.instances.items()
    }
    base = Base(
        scenario_id=scenario.id,
        data=tomllib.loads(scenario.to_toml()),
        fmu_paths={name: inst.fmu_path for name, inst in scenario.instances.items()},
    )
    tables = {
        section: {t.get("name", f"{section[:-1]}-{k}"): t for k, t in enumerate(found, start=1)}
        for section in ("events", "faults")
        for found in [base.data.get(section, [])]
    }
    facts = ScenarioFacts(instances, _metric_names(scenario), tables["events"], tables["faults"])
    return base, facts


def check_values(
    base: Base, factors: Mapping[str, FactorKind], values: Mapping[str, Value]
) -> None:
    """Resolve the scenario with these values (no run): :class:`StudyError` if the
    scenario's own checks refuse one (a wrong type, a non-finite number)."""
    try:
        _scenario(base, base.fmu_paths, factors, values)
    except CosimError as exc:
        raise StudyError(f"factor values {dict(values)}: {exc}") from None


def run_one(
    base: Base,
    fmu_paths: Mapping[str, Path],
    factors: Mapping[str, FactorKind],
    values: Mapping[str, Value],
    keep: str = "none",
) -> RunRecord:
    """Run the base scenario with these factor values; never raises for a failed run.

    ``fmu_paths``: instance -> the FMU file to use in this process. ``keep`` ("all",
    "failed", "none") says whether the run's results.csv and summary.json come back.
    """
    started = time.perf_counter()
    metrics: dict[str, float | None] = {}
    files: dict[str, bytes] = {}
    loop_s = 0.0
    try:
        scenario = _scenario(base, fmu_paths, factors, values)
        with tempfile.TemporaryDirectory(prefix="auv-cosim-run-") as tmp:
            outcome = run_scenario(scenario, Path(tmp), no_rrd=True, tail_guard=False)
            result = outcome.result
            error = None if result.complete else result.error or "the run stopped early"
            if keep == "all" or (keep == "failed" and error is not None):
                files = {outcome.paths[k].name: outcome.paths[k].read_bytes() for k in KEEP_FILES}
            if error is None:
                metrics = _metrics(json.loads(outcome.paths["summary"].read_text("utf-8")))
        loop_s = result.wall_clock_s
    except CosimError as exc:
        error = str(exc)
    except Exception as exc:  # any other failure is this run's, not the study's
        error = f"{type(exc).__name__}: {exc}"
    status = "complete" if error is None else "failed"
    error = None if error is None else " ".join(error.split())  # one line in the table
    return RunRecord(status, error, metrics, time.perf_counter() - started, loop_s, files)


def scenario_text(
    base: Base, factors: Mapping[str, FactorKind], values: Mapping[str, Value]
) -> str:
    """The scenario one run ran, as a file ``auv-cosim run`` takes (FMUs as referenced)."""
    data = copy.deepcopy(dict(base.data))
    apply_values(data, factors, values)
    return f"# Scenario {base.scenario_id!r} with {dict(values)}\n" + tomli_w.dumps(data)


def _scenario(
    base: Base,
    fmu_paths: Mapping[str, Path],
    factors: Mapping[str, FactorKind],
    values: Mapping[str, Value],
) -> Scenario:
    data = copy.deepcopy(dict(base.data))
    for name, path in fmu_paths.items():
        data["instances"][name]["fmu"] = str(path)
    apply_values(data, factors, values)
    return scenario_from_data(data, where=f"{base.scenario_id} with {dict(values)}")


def _metrics(run_summary: Mapping[str, Any]) -> dict[str, float | None]:
    """The numeric summary values that describe the run's motion: the key figures, the
    manoeuvre metrics of a scenario with a ``manoeuvre`` (``tactical_diameter_m``, ...),
    the time reached and every final value (``final.<column>``). Wall clock and
    real-time factor are left out (they vary between identical runs), as are the settings."""
    metrics = dict(run_summary["key_figures"])
    metrics.update(summary_metrics(run_summary))
    metrics["time_reached"] = run_summary["time_reached"]
    metrics.update({f"final.{k}": v for k, v in run_summary["final_values"].items()})
    return metrics


def _metric_names(scenario: Scenario) -> tuple[str, ...]:
    """The names :func:`_metrics` gives a run of ``scenario``, in the same order."""
    figures = KeyFigures(scenario.record).figures()
    manoeuvre = scenario_metric_names(scenario)
    return (*figures, *manoeuvre, "time_reached", *(f"final.{c}" for c in scenario.record))
