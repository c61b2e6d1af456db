"""The Python API: run a scenario, load one, run a study, build the FMUs.

The command line and this module share one code path: :func:`run` calls
:func:`cosim.runner.execute` like ``auv-cosim run`` does, and :func:`sweep` calls
:func:`cosim.study.runner.run_study` like ``auv-cosim sweep``; the checks, the outputs
and the typed exceptions (:class:`cosim.errors.CosimError` and its subclasses, with the
same one-line messages) are theirs. What this module adds is the shape Python users
expect: results as a :class:`pandas.DataFrame` indexed by time, in memory, with no
output folder unless one is asked for (``out=``).

Example::

    import cosim

    run = cosim.run("bs-3", stop_time=20.0, start={"plant.v_0": -0.05})
    run.results["plant.yaw"]  # pandas Series, rad, indexed by time in s
"""

from __future__ import annotations

import dataclasses
import json
import tempfile
from collections.abc import Mapping
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from cosim.errors import CosimError
from cosim.paths import DEFAULT_FMU_DIR
from cosim.runner import RunOptions, execute

if TYPE_CHECKING:  # pandas and the scenario machinery load on first use, not on import
    import pandas as pd

    from cosim.runner import RunOutcome
    from cosim.scenario.spec import Scenario, StartValue

__all__ = ["Run", "RunError", "Study", "build_fmus", "load_scenario", "run", "sweep"]

STUDY_FILE = "study.toml"  # a study given as a dict is written to this file first


class RunError(CosimError):
    """A run that stopped before its stop time; ``run`` holds its partial results.

    The message is the reason ``auv-cosim run`` prints for the same run."""

    def __init__(self, message: str, run: Run) -> None:
        super().__init__(message)
        self.run = run


@dataclass(frozen=True)
class Run:
    """A finished run of :func:`run`.

    Attributes
    ----------
    scenario : Scenario
        The scenario as run (overrides and start values applied).
    results : pandas.DataFrame
        One row per communication step, indexed by ``time`` (s); one column per recorded
        variable, ``"<instance>.<variable>"``, in SI units (rad, m, m/s, N), and
        ``"fault.<name>"`` per fault (1.0 while it acts). The same numbers as the run's
        ``results.csv``. ``results.to_numpy()`` and ``results.index.to_numpy()`` give
        plain numpy arrays.
    summary : dict
        The run's ``summary.json``: how it ended, settings, key figures, final values.
    out_dir : pathlib.Path or None
        The run folder, if ``out`` was given; None for a run kept in memory only.
    """

    scenario: Scenario
    results: pd.DataFrame
    summary: dict[str, Any]
    out_dir: Path | None

    @property
    def complete(self) -> bool:
        """Whether the run reached its stop time."""
        return bool(self.summary["complete"])

    @property
    def coupling_error(self) -> dict[str, Any] | None:
        """With ``check_step``: the estimated error of every key figure and final value
        (summary.json's ``coupling.check_step``); None without."""
        check: dict[str, Any] | None = self.summary.get("coupling", {}).get("check_step")
        return check


@dataclass(frozen=True)
class Study:
    """A finished study of :func:`sweep`.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per run: ``run``, the factor values, ``status`` ("complete" or
        "failed"), ``error``, the metrics and ``wall_clock_s`` (``runs.parquet``).
    out_dir : pathlib.Path or None
        The study folder (table, figures, index.html, overlay.rrd), if ``out`` was
        given; None for a study kept in memory only.
    """

    table: pd.DataFrame
    out_dir: Path | None


def load_scenario(scenario: str | Path, *, fmu_dir: str | Path = DEFAULT_FMU_DIR) -> Scenario:
    """Read and check a built-in scenario id or a scenario TOML file.

    Parameters
    ----------
    scenario : str or pathlib.Path
        A built-in id (``auv-cosim scenarios`` lists them) or the path of a ``.toml`` file.
    fmu_dir : str or pathlib.Path, optional
        Where the built-in FMUs are (built there on first use). Default ``build/fmus``.

    Returns
    -------
    Scenario
        The resolved scenario; ``.with_start({"plant.u_0": 1.2})`` gives a checked copy
        with other start values, ``.with_overrides(stop_time=...)`` other settings.

    Raises
    ------
    cosim.scenario.checks.ScenarioError
        The file or a key in it is refused (the message names both).
    """
    from cosim.scenario.spec import load_scenario as load

    return load(scenario, fmu_dir=Path(fmu_dir))


def run(
    scenario: str | Path | Scenario,
    *,
    stop_time: float | None = None,
    step: float | None = None,
    algorithm: Literal["jacobi", "gauss-seidel", "adaptive"] | None = None,
    extrapolation: Literal["none", "linear", "quadratic"] | None = None,
    tolerance: float | None = None,
    check_step: bool = False,
    start: Mapping[str, StartValue] | None = None,
    out: str | Path | None = None,
    overwrite: bool = False,
    recording: bool = True,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
) -> Run:
    """Run a scenario and return its results, like ``auv-cosim run``.

    Parameters
    ----------
    scenario : str, pathlib.Path or Scenario
        A built-in id, a scenario ``.toml`` file, or a loaded :class:`Scenario`.
    stop_time, step, algorithm, extrapolation, tolerance, check_step : optional
        The command line's ``--stop-time``, ``--step`` (s) and coupling options
        (docs/coupling.md); ``check_step`` fills ``Run.coupling_error``.
    start : mapping, optional
        Start values ``{"<instance>.<variable>": value}`` in SI units, checked like the
        scenario file's (:meth:`Scenario.with_start`).
    out : str or pathlib.Path, optional
        Write the run folder there (results.csv, summary.json, scenario.toml and, unless
        ``recording`` is false or the scenario says ``output.rrd = false``,
        recording.rrd), with the command line's guarantees. Default: no folder, the
        results are kept in memory only (they grow with the stop time).
    overwrite : bool
        Replace an earlier run in ``out`` (``--overwrite``).
    recording : bool
        Write recording.rrd into ``out`` (ignored without ``out``).
    fmu_dir : str or pathlib.Path
        Where the built-in FMUs are (built there on first use). Default ``build/fmus``.

    Returns
    -------
    Run
        ``.results`` (DataFrame), ``.summary`` (dict), ``.out_dir``.

    Raises
    ------
    cosim.errors.CosimError
        The scenario, an option or the output folder is refused, or the FMUs cannot be
        set up; nothing has run (a :class:`~cosim.scenario.checks.ScenarioError` for
        the scenario).
    RunError
        The run stopped before its stop time (an FMU failed, Ctrl-C): the message says
        why, and ``error.run`` holds the partial results.
    """
    options = RunOptions(
        out_dir=None if out is None else Path(out),
        stop_time=stop_time,
        step=step,
        algorithm=algorithm,
        extrapolation=extrapolation,
        tolerance=tolerance,
        check_step=check_step,
        no_rrd=out is None or not recording,
        fmu_dir=Path(fmu_dir),
        overwrite=overwrite,
        keep_rows=True,
        tail_guard=out is not None,  # a temporary folder needs no guard: it is removed
    )
    if start:
        scenario = _loaded(scenario, options.fmu_dir).with_start(start)
    with ExitStack() as stack:
        if out is None:
            temporary = stack.enter_context(tempfile.TemporaryDirectory(prefix="auv-cosim-"))
            options = dataclasses.replace(options, out_dir=Path(temporary) / "run")
        outcome = execute(scenario, options)
        finished = _run_of(outcome, None if out is None else outcome.out_dir)
    if not finished.complete:
        where = "the error's run.results" if out is None else str(outcome.out_dir)
        raise RunError(f"{outcome.result.error} (partial results in {where})", finished)
    return finished


def sweep(
    study: str | Path | Mapping[str, Any],
    *,
    workers: int = 2,
    out: str | Path | None = None,
    resume: bool = False,
    overlay: int | None = None,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
) -> Study:
    """Run a parameter sweep or Monte Carlo study on a local Dask cluster, like
    ``auv-cosim sweep``.

    Parameters
    ----------
    study : str, pathlib.Path or mapping
        A study ``.toml`` file, or a dict with the same keys (``scenario``, ``[grid]``,
        ``[random]``, ...); a relative scenario path in a dict is relative to the
        working folder.
    workers : int
        Local worker processes.
    out : str or pathlib.Path, optional
        Write the study folder there (runs.csv, runs.parquet, figures, index.html, and
        overlay.rrd if asked for). Default: no folder, the table only.
    resume : bool
        Run only what a killed study in ``out`` left (``--resume``).
    overlay : int, optional
        Draw that many runs, spread over the study, in ``out``/overlay.rrd.
    fmu_dir : str or pathlib.Path
        Where the built-in FMUs are (built there on first use).

    Returns
    -------
    Study
        ``.table`` (DataFrame, one row per run), ``.out_dir``.

    Raises
    ------
    cosim.study.spec.StudyError
        The study cannot run (a bad key, factor or value); failed runs are rows of the
        table, not errors.
    """
    import pandas as pd

    from cosim.study.runner import Cluster, run_study

    with ExitStack() as stack:
        temporary = None
        if out is None or isinstance(study, Mapping):
            temporary = Path(stack.enter_context(tempfile.TemporaryDirectory(prefix="auv-cosim-")))
        study_file = _study_file(study, temporary)
        out_dir = Path(out) if out is not None else temporary / "study"  # type: ignore[operator]
        outcome = run_study(
            study_file,
            out_dir,
            cluster=Cluster(workers=workers),
            resume=resume,
            fmu_dir=Path(fmu_dir),
            overlay=overlay,
        )
        table = pd.read_parquet(outcome.paths["parquet"])
    return Study(table, None if out is None else out_dir)


def build_fmus(out: str | Path = DEFAULT_FMU_DIR, *, force: bool = False) -> dict[str, Path]:
    """Build the built-in FMUs into ``out`` (those out of date, or all with ``force``),
    like ``auv-cosim build``.

    Returns
    -------
    dict
        FMU name (``"AuvPlant"``, ...) -> its ``.fmu`` file.

    Raises
    ------
    cosim.errors.CosimError
        A build step failed (the message says which and why).
    """
    from cosim.fmus.build import build_fmus as build

    return build(Path(out), force=force)


def _loaded(scenario: str | Path | Scenario, fmu_dir: Path) -> Scenario:
    from cosim.scenario.spec import Scenario

    return scenario if isinstance(scenario, Scenario) else load_scenario(scenario, fmu_dir=fmu_dir)


def _run_of(outcome: RunOutcome, out_dir: Path | None) -> Run:
    """The :class:`Run` of a finished ``execute``: its kept rows and its summary.json."""
    import pandas as pd

    result = outcome.result
    times, values = result.times, result.values
    assert times is not None and values is not None  # run with keep_rows
    index = pd.Index(times, name="time")
    results = pd.DataFrame(values, index=index, columns=list(result.columns), copy=False)
    summary = json.loads(outcome.paths["summary"].read_text(encoding="utf-8"))
    return Run(result.scenario, results, summary, out_dir)


def _study_file(study: str | Path | Mapping[str, Any], folder: Path | None) -> Path:
    """The study's file: as given, or a dict written as TOML into ``folder``."""
    if not isinstance(study, Mapping):
        return Path(study)
    import tomli_w

    assert folder is not None
    path = folder / STUDY_FILE
    try:
        path.write_text(tomli_w.dumps(dict(study)), encoding="utf-8")
    except (TypeError, ValueError) as exc:
        raise CosimError(f"study {dict(study)!r}: cannot be written as TOML: {exc}") from None
    return path
