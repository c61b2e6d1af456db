"""One run of a study, and the adapter to ``cosim.run``: the only module that uses it.

The client calls :func:`prepare` once: it loads the scenario (``load_scenario``, the
study's stop time through ``Scenario.with_overrides``), keeps it as resolved TOML data
(``Scenario.to_toml``), and reads the facts a study checks factors against. A worker
calls :func:`run_one` per run: the FMU references point at the worker's own copies, the
run's factor values are written into the TOML data, and the data is resolved again
(``scenario_from_data``, so every value passes the scenario's own checks) and run
(``cosim.runner.execute`` with ``no_rrd=True, tail_guard=False``: a killed task's run is
run again, so its folder needs no guard; its stop request its study's, which ends it as
the study ends, :mod:`cosim.study.in_flight`); the metrics are the numeric values of the run's
``summary.json``.
"""

from __future__ import annotations

import copy
import errno
import hashlib
import json
import os
import tempfile
import time
import tomllib
from collections.abc import Collection, Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import tomli_w

from cosim.engine.adaptive import points_step
from cosim.engine.signals import StopRequest
from cosim.engine.slave import collect_debug_log
from cosim.engine.step_check import doubts as step_doubts
from cosim.engine.step_check import has_coupling_error, not_checkable
from cosim.errors import FLAGS, CosimError, OptionNames
from cosim.fmus.interface import check_own_packages
from cosim.metrics.key_figures import key_figures
from cosim.metrics.manoeuvres import summary_metrics
from cosim.outputs.manoeuvre import scenario_metric_names
from cosim.runner import RunOptions, execute, with_fmu_log
from cosim.scenario.design_doubts import DesignWarning, design_doubts
from cosim.scenario.mission_doubts import mission_doubts
from cosim.scenario.spec import FILE_SUFFIXES, Scenario, load_scenario, scenario_from_data
from cosim.scenario.timeline_spec import unreached
from cosim.scenario.unit_doubts import UnitWarning, doubts
from cosim.scratch import process_folder
from cosim.study.factors import FactorKind, ScenarioFacts, Value, Variable, apply_values
from cosim.study.spec import StudyError

KEEP_FILES = ("results", "summary")  # the run's outputs a kept run folder receives
FMU_LOG_FILE = "fmu-log.txt"  # a run's debug log (docs/studies.md): its folder, kept or not
# A metric's estimated coupling error (Richardson from h, h/2, h/4: docs/coupling.md), in
# the metric's unit, is the column named this prefix + the metric's name
COUPLING_ERROR = "coupling_error."


@dataclass(frozen=True)
class Base:
    """The scenario every run starts from, as the client resolved it."""

    scenario_id: str
    data: Mapping[str, Any]  # the resolved scenario as TOML data (FMUs as referenced)
    fmu_paths: Mapping[str, Path]  # instance -> its FMU file on the client
    files: Mapping[str, str] = field(default_factory=dict)  # file it reads -> its SHA-256
    folder: str = ""  # the study file's: a factor's value naming a file is relative to it


@dataclass(frozen=True)
class RunRecord:
    """What one run reports back: one row of the table, and its files if kept."""

    status: str  # "complete" or "failed"
    error: str | None  # one line, None if complete
    metrics: Mapping[str, float | None]  # empty if failed
    wall_clock_s: float  # the whole task: set-up, stepping loop, outputs
    loop_s: float  # the stepping loop alone (0 if it never started)
    files: Mapping[str, bytes] = field(default_factory=dict)  # file name -> content (kept)
    no_room: bool = False  # it failed because a disk had no room for its files (no_room)


# why the system refuses a write for want of room: a full disk, a quota, a file size limit
# (``ulimit -f``), as the run's error gives it (``OSError.strerror``)
NO_ROOM = tuple(os.strerror(code) for code in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG))


def no_room(error: str | None) -> bool:
    """Whether a run's ``error`` says that a disk had no room for its files: not the run's
    failure, but every later run's on the same disk."""
    return error is not None and any(why in error for why in NO_ROOM)


def prepare(
    scenario_ref: str | Path,
    stop_time: float | None,
    fmu_dir: Path,
    check_step: bool = False,
    folder: Path | None = None,
    fmu_log: Mapping[str, tuple[str, ...]] | None = None,
    names: OptionNames = FLAGS,
) -> tuple[Base, ScenarioFacts]:
    """Load the scenario (built-in FMUs built into ``fmu_dir`` if needed) and read what
    the study checks its factors and metrics against; ``check_step`` adds the coupling
    error metrics; a factor's value naming a file (a vehicle set) is relative to
    ``folder``, the study file's (the working directory without one); ``fmu_log`` turns
    instances' debug logging on (``sweep --fmu-log``, as ``names`` gives it). Raises
    ``CosimError`` (with ``check_step``, a scenario whose error cannot be
    estimated: adaptive, or with a noise or dropout fault; an FMU built by an older
    auv-cosim that no run could load: :func:`cosim.fmus.interface.check_own_packages`)."""
    scenario = load_scenario(scenario_ref, fmu_dir=fmu_dir)
    if stop_time is not None:
        scenario = scenario.with_overrides(stop_time=stop_time, names=None)  # the study file's key
    if fmu_log:
        scenario = with_fmu_log(scenario, fmu_log, names)
    for inst in scenario.instances.values():
        check_own_packages(inst.fmu_path)  # every run would fail on it: refused at once
    reason = not_checkable(scenario) if check_step else None
    if reason is not None:
        raise StudyError(f"check_step = true: {reason}")
    driven = {c.target: c.source for c in scenario.connections}
    instances = {
        name: {
            v.name: Variable(
                v.name, v.type, v.causality, v.variability, driven.get(f"{name}.{v.name}"),
                v.min, v.max, v.names,
            )
            for v in inst.interface.variables.values()
        }
        for name, inst in scenario.instances.items()
    }  # fmt: skip
    base = Base(
        scenario_id=scenario.id,
        data=tomllib.loads(scenario.to_toml()),
        fmu_paths={name: inst.fmu_path for name, inst in scenario.instances.items()},
        files=referenced_files(scenario),
        folder=str(folder.resolve()) if folder is not None else "",
    )
    tables = {
        section: {t.get("name", f"{section[:-1]}-{k}"): t for k, t in enumerate(found, start=1)}
        for section in ("events", "faults")
        for found in [base.data.get(section, [])]
    }
    metrics = _metric_names(scenario, check_step)
    facts = ScenarioFacts(instances, metrics, tables["events"], tables["faults"])
    return base, facts


def referenced_files(scenario: Scenario) -> dict[str, str]:
    """Every file the scenario reads besides its FMUs (vehicle sets, series CSVs) -> the
    SHA-256 of its content: a study's rows depend on them."""
    paths = [p for inst in scenario.instances.values() for p in inst.files().values()]
    paths += [e.series.path for e in scenario.events if e.series is not None]
    found = {}
    for path in sorted(set(paths)):
        try:
            found[str(path)] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError as exc:
            raise StudyError(f"cannot read {path}: {exc.strerror or exc}") from None
    return found


Doubts = dict[type[UserWarning], list[str]]
"""Warning lines by the category a study warns them as (once each, before its runs)."""


def check_values(
    base: Base,
    factors: Mapping[str, FactorKind],
    values: Mapping[str, Value],
    known: Collection[str] = (),
) -> Doubts:
    """Resolve the scenario with these values (no run): :class:`StudyError` if the
    scenario's own checks refuse one (a wrong type, a non-finite number). Returns, as
    :class:`~cosim.scenario.unit_doubts.UnitWarning` lines, what looks like a slip of units
    in it (:func:`cosim.scenario.unit_doubts.doubts`), the mission it cannot fly
    (:func:`cosim.scenario.mission_doubts.mission_doubts`; a line not in ``known``, the
    base scenario's, names these values) and the events and faults the run ends before
    (:func:`cosim.scenario.timeline_spec.unreached`); and as
    :class:`~cosim.scenario.design_doubts.DesignWarning` lines an autopilot design that
    does not fit the plant (:func:`cosim.scenario.design_doubts.design_doubts`: an
    autopilot designed for another vehicle than a plant parameter varied, say)."""
    return checked_point(base, factors, values, known)[0]


def checked_point(
    base: Base,
    factors: Mapping[str, FactorKind],
    values: Mapping[str, Value],
    known: Collection[str] = (),
    check_step: bool = False,
) -> tuple[Doubts, list[str]]:
    """:func:`check_values`, and with ``check_step`` why the run's coupling error is not
    to be trusted (:func:`cosim.engine.step_check.doubts`, as ``run --check-step`` says
    it), of the scenario resolved once (~50 ms)."""
    point = ", ".join(f"{name} = {value!r}" for name, value in values.items())
    try:
        # named by its id alone: the refusal names the values first
        scenario = _scenario(base, base.fmu_paths, factors, values, where=base.scenario_id)
    except CosimError as exc:
        raise StudyError(f"the run with {point}: {exc}" if point else str(exc)) from None
    return _doubts(scenario, point, known), step_doubts(scenario) if check_step else []


def _doubts(scenario: Scenario, point: str, known: Collection[str]) -> Doubts:
    """:func:`check_values`'s lines of the resolved ``scenario`` with the values ``point``."""
    coupling = scenario.coupling
    late = unreached(
        scenario.events, scenario.faults, scenario.stop_time, coupling.step, points_step(coupling)
    )
    mission = [
        line if line in known or not point else f"{line} (with {point})"
        for line in mission_doubts(scenario)
    ]
    return {
        UnitWarning: doubts(scenario) + mission + late,
        DesignWarning: design_doubts(scenario),
    }


def base_mission_doubts(base: Base) -> list[str]:
    """The lines of the mission the base scenario, no factor set, cannot fly
    (:func:`cosim.scenario.mission_doubts.mission_doubts`)."""
    return mission_doubts(_scenario(base, base.fmu_paths, {}, {}))


def run_one(
    base: Base,
    fmu_paths: Mapping[str, Path],
    factors: Mapping[str, FactorKind],
    values: Mapping[str, Value],
    keep: str = "none",
    check_step: bool = False,
    carried: Mapping[str, Path] | None = None,
    stop: StopRequest | None = None,
) -> RunRecord:
    """Run the base scenario with these factor values; never raises for a failed run.

    ``fmu_paths``: instance -> the FMU file to use in this process. ``keep`` ("all",
    "failed", "none") says whether the run's results.csv and summary.json come back;
    ``check_step`` also runs it at h / 2 and h / 4 for its coupling error metrics;
    ``carried``: a file the run reads as the client named it -> its copy in this process
    (a remote worker's, :func:`study_files`); ``stop``: the run's :class:`StopRequest`, set
    to end it at its next step (the study ended, :mod:`cosim.study.in_flight`).
    """
    started = time.perf_counter()
    metrics: dict[str, float | None] = {}
    files: dict[str, bytes] = {}
    loop_s = 0.0
    # the debug log collected, not shown on a worker's stderr: the run's folder
    with collect_debug_log() as debug_log:
        try:
            scenario = _scenario(base, fmu_paths, factors, values, carried)
            # in the process's scratch folder, which the next process removes if this one is
            # killed mid-run (cosim.scratch)
            with tempfile.TemporaryDirectory(prefix="auv-cosim-run-", dir=process_folder()) as tmp:
                options = RunOptions(
                    out_dir=Path(tmp),
                    no_rrd=True,
                    tail_guard=False,
                    check_step=check_step,
                    unit_doubts=False,
                    results_csv=keep != "none",
                )
                outcome = execute(scenario, options, stop)
                result = outcome.result
                error = None if result.complete else result.error or "the run stopped early"
                if keep == "all" or (keep == "failed" and error is not None):
                    paths = [outcome.paths[k] for k in KEEP_FILES]
                    files = {path.name: path.read_bytes() for path in paths}
                if error is None:
                    metrics = _metrics(json.loads(outcome.paths["summary"].read_text("utf-8")))
            loop_s = result.wall_clock_s
        except CosimError as exc:
            error = str(exc)
        except Exception as exc:  # any other failure is this run's, not the study's
            error = f"{type(exc).__name__}: {exc}"
    if debug_log:
        files[FMU_LOG_FILE] = "".join(f"{line}\n" for line in debug_log).encode()
    status = "complete" if error is None else "failed"
    error = None if error is None else " ".join(error.split())  # one line in the table
    took = time.perf_counter() - started
    return RunRecord(status, error, metrics, took, loop_s, files, no_room(error))


def warm_up(
    base: Base, fmu_paths: Mapping[str, Path], carried: Mapping[str, Path] | None = None
) -> None:
    """Run the base scenario for one communication step and throw the result away: this
    process then has the FMUs extracted and their libraries loaded, their Python modules
    imported and their compiled code loaded (what a process's first run pays for, ~1-3 s),
    so its first real run costs what every later one does. Never raises: a run that fails
    here fails again, with its reason, as a task."""
    data = copy.deepcopy(dict(base.data))
    data["stop_time"] = data["coupling"]["step"]
    for timed in ("events", "faults"):  # they may be refused beyond the short stop time
        data.pop(timed, None)
    run_one(Base(base.scenario_id, data, base.fmu_paths), fmu_paths, {}, {}, carried=carried)


def scenario_text(
    base: Base, factors: Mapping[str, FactorKind], values: Mapping[str, Value]
) -> str:
    """The scenario one run ran, as a file ``auv-cosim run`` takes (FMUs as referenced)."""
    data = copy.deepcopy(dict(base.data))
    apply_values(data, factors, values)
    _files_from(data, base.folder, {})
    return f"# Scenario {base.scenario_id!r} with {dict(values)}\n" + tomli_w.dumps(data)


def _scenario(
    base: Base,
    fmu_paths: Mapping[str, Path],
    factors: Mapping[str, FactorKind],
    values: Mapping[str, Value],
    files: Mapping[str, Path] | None = None,
    where: str | None = None,
) -> Scenario:
    """The base scenario with ``values`` set, resolved; a refusal names it as ``where``
    (by default its id with the values: a run's error in the table)."""
    data = copy.deepcopy(dict(base.data))
    for name, path in fmu_paths.items():
        data["instances"][name]["fmu"] = str(path)
    apply_values(data, factors, values)
    _files_from(data, base.folder, files or {})
    if files:
        data = _relocated(data, files)
    named = f"{base.scenario_id} with {dict(values)}" if where is None else where
    return scenario_from_data(data, where=named)


def study_files(base: Base, values: Iterable[Mapping[str, Value]]) -> list[Path]:
    """Every file the runs of these factor values read, as this process finds them: the
    base scenario's (vehicle sets, series CSVs) and each factor value naming one. A
    remote worker gets a copy of each, wherever it runs (no shared disk needed)."""
    found = {Path(path) for path in base.files}
    for run_values in values:
        for value in run_values.values():
            if isinstance(value, str) and value.endswith(FILE_SUFFIXES):
                path = _named_file(value, base.folder)
                if path.is_file():
                    found.add(path)
    return sorted(found)


def _relocated(data: Any, files: Mapping[str, Path]) -> Any:
    """``data`` with every text that is a key of ``files`` (a file as the client named
    it) replaced by its copy here."""
    if isinstance(data, dict):
        return {key: _relocated(value, files) for key, value in data.items()}
    if isinstance(data, list):
        return [_relocated(value, files) for value in data]
    if isinstance(data, str) and data in files:
        return str(files[data])
    return data


def _named_file(value: str, folder: str, shipped: Mapping[str, Path] | None = None) -> Path:
    """The file a factor value names: beside the study file (``folder``) when it is there
    or was copied from there (``shipped``), else relative to the working directory."""
    beside = Path(folder, value)
    found = folder and (beside.is_file() or str(beside.resolve()) in (shipped or {}))
    return (beside if found else Path(value)).resolve()


def _files_from(data: dict[str, Any], folder: str, shipped: Mapping[str, Path]) -> None:
    """Start values naming a file (the base scenario's are absolute already, a factor's
    as the study file writes it) made absolute, in place: relative to ``folder`` (the
    study file's) when the file is there, else to the working directory, as the study's
    ``scenario`` is; a run, and the scenario file kept of it, read the file the study
    named wherever they run from."""
    for instance in data["instances"].values():
        start = instance.get("start", {})
        for key, value in start.items():
            if isinstance(value, str) and value.endswith(FILE_SUFFIXES):
                start[key] = str(_named_file(value, folder, shipped))


def _metrics(run_summary: Mapping[str, Any]) -> dict[str, float | None]:
    """The numeric summary values that describe the run's motion: the key figures, the
    manoeuvre metrics of a scenario with a ``manoeuvre`` (``tactical_diameter_m``, ...),
    the time reached and every final value (``final.<column>``). Wall clock and
    real-time factor are left out (they vary between identical runs), as are the settings."""
    metrics = dict(run_summary["key_figures"])
    metrics.update(summary_metrics(run_summary))
    metrics["time_reached"] = run_summary["time_reached"]
    metrics.update({f"final.{k}": v for k, v in run_summary["final_values"].items()})
    check = run_summary.get("coupling", {}).get("check_step")
    if check is not None:  # a figure the check could not estimate (or a failed check): None
        estimated = dict(check.get("key_figures", {}))
        estimated.update({f"final.{k}": e for k, e in check.get("final_values", {}).items()})
        finals = [f"final.{k}" for k in run_summary["final_values"]]
        for name in [*filter(has_coupling_error, run_summary["key_figures"]), *finals]:
            metrics[f"{COUPLING_ERROR}{name}"] = estimated.get(name, {}).get("error")
    return metrics


def _metric_names(scenario: Scenario, check_step: bool = False) -> tuple[str, ...]:
    """The names :func:`_metrics` gives a run of ``scenario``, in the same order."""
    figures = key_figures(scenario.record, scenario.key_vehicles).names()  # no column: none
    manoeuvre = scenario_metric_names(scenario)
    finals = tuple(f"final.{c}" for c in scenario.record)
    checked = (*filter(has_coupling_error, figures), *finals)
    errors = tuple(f"{COUPLING_ERROR}{name}" for name in checked) if check_step else ()
    return (*figures, *manoeuvre, "time_reached", *finals, *errors)
