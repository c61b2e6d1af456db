"""The Python API: run a scenario, load one, run a study, build the FMUs.

The command line and this module share one code path: :func:`run` calls
:func:`cosim.runner.execute` like ``auv-cosim run`` does, and :func:`sweep` calls
:func:`cosim.study.runner.run_study` like ``auv-cosim sweep``; the checks, the outputs
and the typed exceptions (:class:`cosim.errors.CosimError` and its subclasses, with the
same one-line messages, naming ``stop_time=`` where the command line names
``--stop-time``) are theirs. What this module adds is the shape Python users expect:
results as a :class:`pandas.DataFrame` indexed by time, in memory, with no output folder
unless one is asked for (``out=``).

>>> import cosim
>>> run = cosim.run("bs-3", stop_time=2.0, start={"plant.v_0": -0.05})
>>> yaw = run.results["plant.yaw"]  # pandas Series, rad, indexed by time in s
>>> len(yaw), float(yaw.index[-1])
(201, 2.0)
"""

from __future__ import annotations

import dataclasses
import io
import json
import multiprocessing
import numbers
import os
import signal
import tempfile
from collections.abc import Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, overload

import cosim.environ_writes as environ_writes
from cosim.engine.signals import REASONS
from cosim.errors import KEYWORDS, CosimError, counted, matplotlib_folder_absolute, plain, shown
from cosim.limits import open_files_limit_kept
from cosim.paths import DEFAULT_FMU_DIR, path_text, undecoded
from cosim.runner import NotStartedError, RunOptions, execute
from cosim.scenario.arguments import (
    choice_argument,
    home_expanded,
    number_argument,
    seconds_argument,
)
from cosim.scratch import process_folder
from cosim.study.signals import StudyStopped, stop_study_on_signals

if TYPE_CHECKING:  # pandas and the scenario machinery load on first use, not on import
    from typing import TypeAlias

    import numpy as np
    import pandas as pd
    from distributed.security import Security

    from cosim.runner import RunOutcome
    from cosim.scenario.spec import Algorithm, Extrapolation, Scenario, StartInput, StartValue
    from cosim.study.runner import Cluster, StudyOutcome

    Number: TypeAlias = float | np.integer[Any] | np.floating[Any]  # a numpy one as its value
    Count: TypeAlias = int | np.integer[Any]
    Flag: TypeAlias = bool | np.bool_  # an on/off option: a numpy bool as its value

__all__ = [
    "Run", "RunError", "RunInterrupted", "Study", "SweepInterrupted", "build_fmus",
    "load_scenario", "resume", "run", "sweep",
]  # fmt: skip

STUDY_FILE = "study.toml"  # a study given as a dict is written to this file first
DICT_LABEL = "study (given as a dict)"  # how a refusal names it (not by that file)
ALGORITHMS = ("jacobi", "gauss-seidel", "adaptive")  # RunOptions.algorithm
EXTRAPOLATIONS = ("none", "linear", "quadratic")  # RunOptions.extrapolation


class RunError(CosimError):
    """A run that failed before its stop time (an FMU failed); ``run`` holds its partial
    results.

    The message is the reason ``auv-cosim run`` prints for the same run."""

    def __init__(self, message: str, run: Run) -> None:
        super().__init__(message)
        self.run = run

    def __reduce__(self) -> tuple[type[RunError], tuple[str, Run]]:
        """Pickled with its run (a process pool's worker sends it to the caller)."""
        return type(self), (str(self), self.run)


class RunInterrupted(KeyboardInterrupt):
    """A run that a stop signal (Ctrl-C, a notebook's stop button, SIGTERM) ended; ``run``
    holds its partial results.

    A KeyboardInterrupt, as Ctrl-C is anywhere in Python, not a CosimError: ``except
    CosimError`` (or ``except Exception``) around runs in a loop lets it through, so the
    stop ends the loop, not only the run it came in."""

    def __init__(self, message: str, run: Run) -> None:
        super().__init__(message)
        self.run = run

    def __reduce__(self) -> tuple[type[RunInterrupted], tuple[str, Run]]:
        """Pickled with its run, as :class:`RunError` is."""
        return type(self), (str(self), self.run)


class SweepInterrupted(KeyboardInterrupt):
    """A study that a stop signal (Ctrl-C, a notebook's stop button, SIGTERM) ended before
    all its runs finished; ``study`` holds the rows of those that did.

    The message says why it stopped and where the finished rows are. A KeyboardInterrupt,
    not a CosimError, for the reason :class:`RunInterrupted` is."""

    def __init__(self, message: str, study: Study) -> None:
        super().__init__(message)
        self.study = study

    def __reduce__(self) -> tuple[type[SweepInterrupted], tuple[str, Study]]:
        """Pickled with its study, as :class:`RunError` is with its run."""
        return type(self), (str(self), self.study)


@dataclass(frozen=True, eq=False)
class Run:
    """A finished run of :func:`run`.

    Compared and hashed by identity, as objects are (``run in runs``, ``{run}``); two
    runs' tables compare with ``a.results.equals(b.results)``. Picklable (a process pool
    returns it), with its scenario and its table's units.

    Attributes
    ----------
    scenario : Scenario
        The scenario as run (overrides and start values applied).
    results : pandas.DataFrame
        One row per communication step, indexed by ``time`` (s); one column per recorded
        variable, ``"<instance>.<variable>"``, in SI units (rad, m, m/s, N), and
        ``"fault.<name>"`` per fault (1.0 while it acts). The same numbers as the run's
        ``results.csv``. ``results.attrs["units"]``: the unit of ``time`` and of each
        column (summary.json's ``units``). ``results.to_numpy()`` and
        ``results.index.to_numpy()`` give plain numpy arrays.
    summary : dict
        The run's ``summary.json``: how it ended, settings, key figures, final values
        (``outputs``, the files written, is empty for a run kept in memory only).
    out_dir : pathlib.Path or None
        The run folder, absolute, if ``out`` was given; None for a run kept in memory only.
    """

    scenario: Scenario
    results: pd.DataFrame
    summary: dict[str, Any]
    out_dir: Path | None

    def __repr__(self) -> str:
        """One line (a notebook shows it for a cell ending in ``cosim.run(...)``), not the
        scenario, table and summary in full, named by its class (Run or SavedRun)."""
        rows, columns = self.results.shape
        return (
            f"{type(self).__name__}(scenario={self.scenario.id!r}, complete={self.complete}, "
            f"results=<{rows} rows x {columns} columns>, out_dir={self.out_dir!r})"
        )

    @property
    def complete(self) -> bool:
        """Whether the run reached its stop time (summary's ``complete``; False once the
        caller took it out of the summary, the caller's dict)."""
        return self.summary.get("complete") is True

    @property
    def coupling_error(self) -> dict[str, Any] | None:
        """With ``check_step``: the estimated error of every key figure and final value
        (summary.json's ``coupling.check_step``); None without."""
        coupling = self.summary.get("coupling")
        check = coupling.get("check_step") if isinstance(coupling, dict) else None
        return check if isinstance(check, dict) else None


@dataclass(frozen=True, eq=False, repr=False)  # (repr: Run's one line, its own name)
class SavedRun(Run):
    """A :class:`Run` written to its run folder: what :func:`run` with ``out`` and
    :func:`resume` return. The same, but typed for what it holds: ``out_dir`` is a
    ``pathlib.Path``, never None, so a strictly type-checked script reads the folder
    without first asserting that it is there.

    Attributes
    ----------
    out_dir : pathlib.Path
        The run folder, absolute.
    """

    out_dir: Path


@dataclass(frozen=True, eq=False)
class Study:
    """A finished study of :func:`sweep`.

    Compared and hashed by identity, and picklable, as :class:`Run` is.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per run: ``run``, the factor values, ``status`` ("complete" or
        "failed"), ``error``, the metrics, ``wall_clock_s`` and the run's ``point`` and
        ``sample`` in the study's design (``runs.parquet``).
    out_dir : pathlib.Path or None
        The study folder (table, figures, index.html, overlay.rrd), absolute, if ``out``
        was given; None for a study kept in memory only.
    statistics, sensitivity : pandas.DataFrame or None
        A Monte Carlo study's ``statistics.csv`` (each metric's mean, percentiles and
        their confidence intervals) and ``sensitivity.csv`` (Spearman's rank correlation
        of each factor with each metric), docs/studies.md; None for a grid study.
    """

    table: pd.DataFrame
    out_dir: Path | None
    statistics: pd.DataFrame | None = None
    sensitivity: pd.DataFrame | None = None

    def __repr__(self) -> str:
        """One line, not the table in full."""
        rows, columns = self.table.shape
        return f"Study(table=<{rows} rows x {columns} columns>, out_dir={self.out_dir!r})"


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

    Examples
    --------
    >>> scenario = cosim.load_scenario("bs-3")
    >>> scenario.stop_time, scenario.coupling.step  # s
    (60.0, 0.01)
    >>> scenario.with_start({"plant.u_0": 1.2}).instances["plant"].start["u_0"]  # m/s
    1.2
    """
    from cosim.scenario.checks import ScenarioError
    from cosim.scenario.spec import load_scenario as load

    path = _scenario_path(scenario, ScenarioError)
    return load(path, fmu_dir=_folder("fmu_dir", fmu_dir, ScenarioError))


# typed per ``out``: with a folder, a SavedRun (its out_dir a Path); without, a Run
@overload
def run(
    scenario: str | Path | Scenario,
    *,
    stop_time: Number | None = None,
    step: Number | None = None,
    algorithm: Algorithm | None = None,
    extrapolation: Extrapolation | None = None,
    tolerance: Number | None = None,
    check_step: Flag = False,
    start: Mapping[str, StartInput] | None = None,
    out: None = None,
    overwrite: Flag = False,
    recording: Flag = True,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
    progress: Flag = False,
    checkpoint_every: Number | None = None,
    fmu_log: Mapping[str, Sequence[str]] | None = None,
) -> Run: ...


@overload
def run(
    scenario: str | Path | Scenario,
    *,
    stop_time: Number | None = None,
    step: Number | None = None,
    algorithm: Algorithm | None = None,
    extrapolation: Extrapolation | None = None,
    tolerance: Number | None = None,
    check_step: Flag = False,
    start: Mapping[str, StartInput] | None = None,
    out: str | Path,
    overwrite: Flag = False,
    recording: Flag = True,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
    progress: Flag = False,
    checkpoint_every: Number | None = None,
    fmu_log: Mapping[str, Sequence[str]] | None = None,
) -> SavedRun: ...


def run(
    scenario: str | Path | Scenario,
    *,
    stop_time: Number | None = None,
    step: Number | None = None,
    algorithm: Algorithm | None = None,
    extrapolation: Extrapolation | None = None,
    tolerance: Number | None = None,
    check_step: Flag = False,
    start: Mapping[str, StartInput] | None = None,
    out: str | Path | None = None,
    overwrite: Flag = False,
    recording: Flag = True,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
    progress: Flag = False,
    checkpoint_every: Number | None = None,
    fmu_log: Mapping[str, Sequence[str]] | None = None,
) -> Run:
    """Run a scenario and return its results, like ``auv-cosim run``.

    Parameters
    ----------
    scenario : str, pathlib.Path or Scenario
        A built-in id, a scenario ``.toml`` file, or a loaded :class:`Scenario`.
    stop_time, step : float, optional
        The simulated time to run to and the communication step (how often the FMUs
        exchange values), s, > 0 (``--stop-time``, ``--step``; a numpy number as its
        value). Default: the scenario's.
    algorithm : {"jacobi", "gauss-seidel", "adaptive"}, optional
        How the FMUs take turns (``--algorithm``, docs/coupling.md): all from the values
        exchanged at the step's start, one after another, or Gauss-Seidel with an
        error-controlled step. Default: the scenario's.
    extrapolation : {"none", "linear", "quadratic"}, optional
        What an exchanged value does across a step: held, or extrapolated from its last
        values (``--extrapolation``). Default: the scenario's.
    tolerance : float, optional
        Adaptive only: the relative error a step may make, > 0 and < 1 (``--tolerance``).
        Default: the scenario's, 0.001 unless it sets one.
    check_step : bool
        Also run at half and a quarter of the step and fill ``Run.coupling_error``, the
        estimated coupling error (``--check-step``). Default: False.
    start : mapping, optional
        Start values ``{"<instance>.<variable>": value}`` in SI units (bool, int, float,
        str or a numpy scalar), checked like the scenario file's (:meth:`Scenario.with_start`;
        a vehicle set ``.toml`` named is relative to the working folder).
    out : str or pathlib.Path, optional
        Write the run folder there (results.csv, summary.json, scenario.toml and, unless
        ``recording`` is false or the scenario says ``output.rrd = false``, recording.rrd),
        as the command line does. Default: no folder, the results kept in memory only.
    overwrite : bool
        Replace an earlier run in ``out`` (``--overwrite``). Default: False, refused.
    recording : bool
        Write recording.rrd into ``out`` (ignored without ``out``). Default: True.
    fmu_dir : str or pathlib.Path
        Where the built-in FMUs are (built there on first use). Default ``build/fmus``.
        A loaded ``scenario`` runs the FMUs it was loaded with: another folder is refused.
    progress : bool
        Show the command line's progress bar on stderr (under the cell in a notebook,
        removed when the run ends). Default: nothing shown.
    checkpoint_every : float, optional
        Simulated seconds between the run's states saved into ``out``
        (``--checkpoint-every``; needs ``out``): :func:`resume` continues it if killed.
    fmu_log : mapping, optional
        ``{instance: [log categories]}`` (``[]``: all): their debug log on stderr, as ``--fmu-log``.

    Returns
    -------
    Run
        ``.results`` (DataFrame), ``.summary`` (dict), ``.out_dir``; with ``out``, a
        :class:`SavedRun`, whose ``out_dir`` is typed ``Path`` (never None).

    Raises
    ------
    cosim.errors.CosimError
        The scenario, an argument (each checked first: another type, such as a Decimal or
        a string for a flag, a number out of range, an empty path or one with a NUL byte,
        named with what was expected) or the output folder is refused, or the FMUs cannot
        be set up; nothing has run (:class:`~cosim.scenario.checks.ScenarioError`: the
        scenario).
    RunError
        The run failed before its stop time (an FMU failed): the message says why, and
        ``error.run`` holds the partial results.
    RunInterrupted
        Ctrl-C (a notebook's stop button) ended the run: a KeyboardInterrupt, whose
        ``run`` holds the partial results.

    Examples
    --------
    >>> run = cosim.run("bs-3", stop_time=1.0, algorithm="jacobi")
    >>> run.complete, run.results.shape  # t = 0 to 1 s at the 10 ms step: 101 rows
    (True, (101, 35))
    """
    settings = {
        "stop_time": stop_time, "step": step, "algorithm": algorithm,
        "extrapolation": extrapolation, "tolerance": tolerance, "check_step": check_step,
        "progress": progress, "checkpoint_every": checkpoint_every, "fmu_log": fmu_log,
    }  # fmt: skip
    options = _run_options(out, recording, fmu_dir, overwrite, settings)
    scenario = _started(scenario, _start(start), fmu_dir is DEFAULT_FMU_DIR, options.fmu_dir)
    return _executed(scenario, options, in_memory=out is None)


def _started(
    scenario: object, start: dict[str, StartValue] | None, default_fmus: bool, fmu_dir: Path
) -> Path | Scenario:
    """:func:`run`'s ``scenario`` checked, with the ``start`` values (already checked) if
    any; ``fmu_dir`` the FMUs' folder, ``default_fmus`` whether it was left unsaid."""
    scenario = _scenario_argument(scenario, None if default_fmus else fmu_dir)
    return _loaded(scenario, fmu_dir).with_start(start) if start else scenario


def _temporary_folder() -> tempfile.TemporaryDirectory[str]:
    """A folder for a run or study kept in memory, in this process's scratch folder: a
    kernel killed meanwhile (the OOM killer) leaves it to the next run (cosim.scratch)."""
    return tempfile.TemporaryDirectory(prefix="auv-cosim-", dir=process_folder())


def _executed(scenario: str | Path | Scenario, options: RunOptions, in_memory: bool) -> Run:
    """:func:`run`'s run of ``scenario``, in a temporary folder removed after it when
    ``in_memory``; a run that failed raises :class:`RunError`, one a stop signal ended
    :class:`RunInterrupted`."""
    with ExitStack() as stack:
        if in_memory:
            temporary = stack.enter_context(_temporary_folder())
            options = dataclasses.replace(options, out_dir=Path(temporary) / "run")
        with _stopped_before_start():
            outcome = execute(scenario, options)
        return _finished(outcome, in_memory, "cosim.run", stacklevel=4)


@contextmanager
def _stopped_before_start() -> Iterator[None]:
    """A stop signal before the run's first step (the FMUs built or loaded): Python's
    KeyboardInterrupt saying so, with no run to hold, not the runner's NotStartedError, a
    CosimError that a loop going on after a failed run would swallow."""
    try:
        yield
    except NotStartedError as exc:
        if exc.exit_code == 1:  # failed, not stopped
            raise
        raise KeyboardInterrupt(str(exc)) from None


def _finished(outcome: RunOutcome, in_memory: bool, caller: str, stacklevel: int) -> Run:
    """The :class:`Run` of ``outcome``; :class:`RunError` if it failed, :class:`RunInterrupted`
    if a stop signal ended it (``in_memory``: its folder is about to be removed); a lost
    recording warned of as ``caller``'s, at the line ``stacklevel`` frames up."""
    finished = _run_of(outcome, None if in_memory else outcome.out_dir.absolute())
    where = "the error's run.results" if in_memory else str(outcome.out_dir)
    if outcome.signal is not None:  # the user's stop, even if the run had just completed
        reason = REASONS.get(signal.Signals(outcome.signal).name, "stopped")
        raise RunInterrupted(
            f"{outcome.result.error or reason} (partial results in {where})", finished
        )
    if not finished.complete:
        raise RunError(f"{outcome.result.error} (partial results in {where})", finished)
    if outcome.recording_lost is not None:  # the run went on without it (a full disk)
        import warnings

        warnings.warn(
            f"{caller}: {outcome.recording_lost}; the run went on without it",
            stacklevel=stacklevel,
        )
    return finished


def resume(
    out: str | Path,
    *,
    recording: Flag | None = None,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
    progress: Flag = False,
    checkpoint_every: Number | None = None,
) -> SavedRun:
    """Continue a killed run from its last checkpoint, like ``auv-cosim run --resume OUT``.

    Parameters
    ----------
    out : str or pathlib.Path
        The folder of a run started with ``checkpoint_every`` (:func:`run`) and stopped
        before its stop time (a batch system's time limit, a kernel restarted).
    recording : bool, optional
        Write ``out``/recording.rrd (True) or no recording (False). Default: as the
        checkpointed run did (none, its recording.rrd, or the file it wrote elsewhere).
    fmu_dir, progress : optional
        As :func:`run`'s.
    checkpoint_every : float, optional
        Simulated seconds between checkpoints from here on. Default: the checkpointed
        run's.

    Returns
    -------
    SavedRun
        The whole run: its rows up to the checkpoint, kept, and the rest, written as the
        uninterrupted run would have written them (docs/runs.md).

    Raises
    ------
    cosim.errors.CosimError
        No checkpoint in ``out``, the run there complete, or its scenario, FMUs or
        auv-cosim version changed since: nothing is touched.
    RunError, RunInterrupted
        As :func:`run`.
    """
    from cosim.outputs.run_files import RECORDING_FILE
    from cosim.runner import resume_run

    folder = _folder("out", out)
    recording = None if recording is None else _flag("recording", recording)
    settings = {"progress": progress, "checkpoint_every": checkpoint_every}
    options = _run_options(folder, recording is not False, fmu_dir, False, settings)
    if recording is not None:  # said: the folder's recording.rrd, or none
        rrd = folder / RECORDING_FILE if recording else None
        options = dataclasses.replace(options, rrd=rrd)
    with _stopped_before_start():
        outcome = resume_run(folder, dataclasses.replace(options, out_dir=None))
    finished = _finished(outcome, False, "cosim.resume", stacklevel=3)
    assert isinstance(finished, SavedRun)  # kept in its folder: _run_of's SavedRun
    return finished


def sweep(
    study: str | Path | Mapping[str, Any],
    *,
    workers: Count | None = None,
    out: str | Path | None = None,
    resume: Flag = False,
    overlay: Count | None = None,
    fmu_dir: str | Path = DEFAULT_FMU_DIR,
    oversubscribe: Flag = False,
    max_runs: Count = 100_000,
    progress: Flag = False,
    scheduler: str | None = None,
    security: Security | None = None,
    fmu_log: Mapping[str, Sequence[str]] | None = None,
) -> Study:
    """Run a parameter sweep or Monte Carlo study on a local Dask cluster, like
    ``auv-cosim sweep``.

    Parameters
    ----------
    study : str, pathlib.Path or mapping
        A study ``.toml`` file, or a dict of its keys (``scenario``, ``[grid]``, ``[random]``,
        ...; a numpy array or scalar, a tuple or a path counts as its list, number or text;
        a relative scenario path in it is relative to the working folder).
    workers : int, optional
        Local worker processes, at most the machine's cores unless ``oversubscribe``.
        Default: one per core (a numpy integer, here or below, counts as its int).
    scheduler : str, optional
        A Dask cluster of one's own (``--scheduler``), ``tcp://HOST:PORT`` or
        ``tls://HOST:PORT`` (``security``: a ``distributed.Security``); not with ``workers``.
    out : str or pathlib.Path, optional
        Write the study folder there (runs.csv, runs.parquet, statistics.csv..., figures,
        index.html, overlay.rrd if asked for). Default: no folder, the table only.
    resume : bool
        Run only what a killed study in ``out`` left (``--resume``); needs ``out``.
    overlay : int, optional
        Draw that many runs (1 to 20), spread over the study, in ``out``/overlay.rrd;
        needs ``out``. Default: the study's ``overlay``, else none.
    fmu_dir : str or pathlib.Path
        Where the built-in FMUs are (built there on first use).
    oversubscribe : bool
        Allow more ``workers`` than cores (``--oversubscribe``).
    max_runs : int
        Refuse a study of more runs (``--max-runs``; up to 10,000,000). Default 100,000.
    progress : bool
        Show the command line's progress bar of the runs on stderr. Default: none.
    fmu_log : mapping, optional
        Turn instances' debug logging on in every run (``--fmu-log``): ``{instance: [log
        categories]}``, ``[]`` for every category; each run's messages go to
        ``runs/<run id>/fmu-log.txt`` in the study folder (in ``out``).

    Returns
    -------
    Study
        ``.table`` (DataFrame, one row per run), ``.out_dir``.

    Raises
    ------
    cosim.study.spec.StudyError
        The study cannot run (a bad key, factor or value, its scenario refused, an
        argument of the wrong type or out of range), or it is called at a script's top
        level without an ``if __name__ == "__main__":`` guard (workers import it); failed
        runs are rows of the table (one warning line counts them, naming the first).
    SweepInterrupted
        Ctrl-C (a notebook's stop button) stopped the study and its workers: a
        KeyboardInterrupt (``except CosimError`` lets it through) whose ``study.table``
        holds the finished runs' rows (with ``out``, runs.csv too, for ``resume=True``).
    """
    # a stop while Dask is imported (~1 s) is the study's too (StudyStopped)
    with stop_study_on_signals():
        try:
            from cosim.study.spec import StudyError

            cluster = _cluster(workers, oversubscribe, scheduler, security)
            study = _study_argument(study)
            out = None if out is None else _folder("out", out, StudyError)
            options = _sweep_options(out, resume, overlay, fmu_dir, max_runs, progress, fmu_log)
            return _swept(study, out, cluster, options)
        except StudyStopped as stop:  # before the study's folder was known, or after it
            kept = out if isinstance(out, Path) and plain(resume) is True else None  # resumed
            raise _stopped(stop.signum, kept) from None


def _sweep_options(
    out: Path | None,
    resume: Flag,
    overlay: Count | None,
    fmu_dir: str | Path,
    max_runs: Count,
    progress: Flag,
    fmu_log: Mapping[str, Sequence[str]] | None,
) -> dict[str, Any]:
    """:func:`sweep`'s options checked (each refused naming it: StudyError), as
    :func:`_swept` takes them."""
    from cosim.study.spec import StudyError

    overlay = None if overlay is None else _count("overlay", overlay, StudyError)
    resume = _flag("resume", resume, StudyError)
    options = {"resume": resume, "overlay": overlay,
               "max_runs": _count("max_runs", max_runs, StudyError),
               "fmu_dir": _folder("fmu_dir", fmu_dir, StudyError)}  # fmt: skip
    logs = _fmu_log(fmu_log, StudyError)
    _check_needs_out(out, resume, overlay)
    if out is None and logs:
        raise StudyError(f"fmu_log={shown(fmu_log)} needs out= (the study folder the runs' "
                         "fmu-log.txt go to)")  # fmt: skip
    return {**options, "progress": _flag("progress", progress, StudyError), "fmu_log": logs}


def _cluster(
    workers: object, oversubscribe: object, scheduler: object, security: object
) -> Cluster:
    """:func:`sweep`'s cluster: local (its workers checked, and the caller's script guarded:
    each worker imports it) or the one at ``scheduler``. Raises StudyError."""
    from cosim.study.execution import check_main_guard, local_workers
    from cosim.study.runner import Cluster
    from cosim.study.spec import StudyError

    if scheduler is None:
        check_main_guard("cosim.sweep")
        oversubscribe = _flag("oversubscribe", oversubscribe, StudyError)
        return Cluster(workers=local_workers(plain(workers), oversubscribe))
    if not isinstance(scheduler, str):
        raise StudyError(
            f"scheduler={shown(scheduler)}: expected the address of a Dask scheduler, "
            "tcp://HOST:PORT or tls://HOST:PORT"
        )
    if workers is not None:
        raise StudyError("give workers= (a local cluster) or scheduler=, not both")
    return Cluster(workers=0, scheduler=scheduler, security=_security(security))


def _security(value: object) -> Security | None:
    """:func:`sweep`'s ``security``: None or a ``distributed.Security`` (the TLS files of a
    ``tls://`` scheduler). Raises StudyError."""
    from distributed.security import Security

    from cosim.study.spec import StudyError

    if value is None or isinstance(value, Security):
        return value
    raise StudyError(
        f"security={shown(value)}: expected a distributed.Security (the TLS files: "
        "Security(tls_ca_file=..., tls_client_cert=..., tls_client_key=...)) or None"
    )


def _swept(
    study: Path | Mapping[str, Any], out: Path | None, cluster: Cluster, options: dict[str, Any]
) -> Study:
    """:func:`sweep` of its checked arguments (``options``: run_study's ``resume``,
    ``fmu_dir``, ``overlay``, ``max_runs`` and ``progress``); a stop signal (Ctrl-C, a notebook's
    interrupt; the caller's :func:`~cosim.study.signals.stop_study_on_signals` raises
    StudyStopped) raises :class:`SweepInterrupted` with the finished rows."""
    from cosim.study.collector import gc_diagnosis_registered
    from cosim.study.runner import run_study
    from cosim.user_cache import matplotlib_cache

    with ExitStack() as stack:
        out_dir = out
        try:
            # what the study sets in the caller's environment (the workers' pre-spawn
            # environment, numba's and matplotlib's folders), put back as it ends
            stack.enter_context(environ_writes.recorded())
            # a relative HOME: matplotlib's folder absolute for the study's figures, as the
            # command's, not in the caller's working folder (put back with the environment)
            matplotlib_folder_absolute(matplotlib_cache)
            stack.enter_context(open_files_limit_kept())  # a local study raises it for workers
            stack.callback(_restore_start_method, multiprocessing.get_start_method(allow_none=True))
            temporary = None
            if out is None or isinstance(study, Mapping):
                temporary = Path(stack.enter_context(_temporary_folder()))
            study_file = _study_file(study, temporary)
            out_dir = Path(out) if out is not None else temporary / "study"  # type: ignore[operator]
            label = DICT_LABEL if isinstance(study, Mapping) else None
            if cluster.scheduler is None:  # a local cluster: its scheduler starts on a thread
                stack.enter_context(gc_diagnosis_registered())
            outcome = run_study(
                study_file, out_dir, cluster=cluster, label=label, names=KEYWORDS, **options
            )
            table = _read_parquet(outcome.paths["parquet"])
            statistics, sensitivity = (_read_csv(outcome.paths.get(n)) for n in _MONTE_CARLO)
        except StudyStopped as stop:
            raise _stopped(stop.signum, out_dir, kept=out is not None) from None
    _warn_of(outcome)
    return Study(table, None if out is None else out_dir.absolute(), statistics, sensitivity)


_MONTE_CARLO = ("statistics", "sensitivity")  # the tables only a Monte Carlo study writes


def _read_csv(path: Path | None) -> pd.DataFrame | None:
    """The table of the CSV file ``path`` (read from its bytes, as :func:`_read_parquet`
    reads), None for none."""
    import pandas as pd

    return None if path is None else pd.read_csv(io.BytesIO(path.read_bytes()))


def _restore_start_method(before: str | None) -> None:
    """Leave multiprocessing's default start method unchosen if it was (``before`` None):
    each worker the fork server starts fixes it, as a side effect of the standard library's,
    and the caller's own ``multiprocessing.set_start_method("spawn")`` then raised "context
    has already been set"."""
    if before is None:
        multiprocessing.set_start_method(None, force=True)


def _warn_of(outcome: StudyOutcome) -> None:
    """One warning line for the failed runs (naming the first, as ``auv-cosim sweep``'s
    report does) and one for each of the study's warnings: a notebook cell showing a
    table of NaN metrics would otherwise not say why."""
    import warnings

    if outcome.failed:
        warnings.warn(
            f"cosim.sweep: {outcome.failed} of {outcome.total} runs failed, the first "
            f"{outcome.first_failure} (the table's error column has each)",
            stacklevel=4,  # the line of sweep's caller (here <- _swept <- sweep <- caller)
        )
    for warning in outcome.warnings:
        warnings.warn(f"cosim.sweep: {warning}", stacklevel=4)


def _stopped(signum: int, out_dir: Path | None, kept: bool = True) -> SweepInterrupted:
    """The :class:`SweepInterrupted` of a study the signal ``signum`` ended: the rows its
    ``out_dir``/runs.csv holds (the folder ``kept`` for ``resume=True``, else about to be
    removed; None: stopped before it had one, no rows), in one line."""
    import pandas as pd

    from cosim.study.table import CSV_NAME

    csv_path = None if out_dir is None else out_dir / CSV_NAME
    # a run id is hexadecimal text, at times all decimal digits: never read as a number
    found = csv_path is not None and csv_path.is_file()
    table = pd.read_csv(csv_path, dtype={"run": str}) if found else pd.DataFrame()
    reason = REASONS.get(signal.Signals(signum).name, "stopped")
    where = "the error's study.table"
    if kept and len(table) and out_dir is not None and csv_path is not None:
        where += f" and {csv_path.absolute()} (resume=True runs the others)"
    study = Study(table, out_dir.absolute() if kept and len(table) and out_dir else None)
    finished = counted(len(table), "finished run")
    return SweepInterrupted(f"{reason}: {finished} kept in {where}", study)


def _read_parquet(path: Path) -> pd.DataFrame:
    """The table of ``path``, read from its bytes: pyarrow encodes a file name it is given
    as strict UTF-8, and a folder named in bytes that are no UTF-8 failed there."""
    import pandas as pd

    return pd.read_parquet(io.BytesIO(path.read_bytes()))


def build_fmus(
    out: str | Path = DEFAULT_FMU_DIR, *, force: Flag = False, portable: Flag = False
) -> dict[str, Path]:
    """Build the built-in FMUs into ``out`` (those out of date, or all with ``force``),
    like ``auv-cosim build``; ``portable``: as ``--portable``, FMUs that record no Python
    of this machine (to hand on or publish).

    Returns
    -------
    dict
        FMU name (``"AuvPlant"``, ...) -> its ``.fmu`` file (an absolute path).

    Raises
    ------
    cosim.errors.CosimError
        A build step failed (the message says which and why).
    """
    from cosim.fmus.build import OTHER_BUILD_FOLDER
    from cosim.fmus.build import build_fmus as build

    built = build(
        _folder("out", out),
        force=_flag("force", force),
        other=OTHER_BUILD_FOLDER,
        portable=_flag("portable", portable),
    )
    return {name: path.absolute() for name, path in built.items()}  # right after os.chdir


def _study_argument(study: object) -> Path | Mapping[str, Any]:
    """:func:`sweep`'s ``study``: a mapping as given, else the path of a study file."""
    from cosim.study.spec import StudyError

    if isinstance(study, Mapping):
        return study
    expected = "a study file (str or pathlib.Path) or a mapping of its keys"
    return _path("study", study, expected, StudyError)


def _check_needs_out(out: Path | None, resume: bool, overlay: int | None) -> None:
    """:func:`sweep`'s ``resume`` and ``overlay`` act on its folder: refused without ``out``
    (before any run, not found out at the end)."""
    from cosim.study.spec import StudyError

    if out is None and resume:
        raise StudyError("resume=True needs out= (the study folder to resume)")
    if out is None and overlay is not None:
        raise StudyError(f"overlay={overlay} needs out= (the study folder overlay.rrd goes to)")


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
    if out_dir is None:  # the files were in a temporary folder, removed on return
        summary["outputs"] = {}
    results.attrs["units"] = dict(summary["units"])  # time and every column: summary.json's
    if out_dir is None:
        return Run(result.scenario, results, summary, None)
    return SavedRun(result.scenario, results, summary, out_dir)


def _study_file(study: str | Path | Mapping[str, Any], folder: Path | None) -> Path:
    """The study's file: as given, or a dict written as TOML into ``folder``."""
    if not isinstance(study, Mapping):
        return Path(study)
    import tomli_w

    from cosim.study.spec import StudyError

    assert folder is not None
    path = folder / STUDY_FILE
    data = {key: _toml_value(value, str(key)) for key, value in study.items()}
    try:
        path.write_text(tomli_w.dumps(data), encoding="utf-8")
    except (TypeError, ValueError) as exc:
        raise StudyError(f"study {dict(study)!r}: cannot be written as TOML: {exc}") from None
    return path


def _toml_value(value: object, key: str) -> object:
    """A value of a study dict as its TOML file holds it: a numpy array or scalar as its
    list or Python number (``np.linspace(-0.1, 0.1, 5)``), a tuple as a list, a path as its
    text, in mappings and lists too; None, a number of another type (a Decimal, which TOML
    would hold as a float, a Fraction: :func:`run` refuses both), and a name holding bytes
    that are no UTF-8 (read as surrogates), which TOML cannot hold, refused naming ``key``."""
    from cosim.study.spec import StudyError

    if type(value).__module__ == "numpy" and hasattr(value, "tolist"):
        value = value.tolist()  # an array: nested lists of Python numbers; a scalar: one
    if isinstance(value, Mapping):
        return {name: _toml_value(item, f"{key}.{name}") for name, item in value.items()}
    if isinstance(value, list | tuple):
        return [_toml_value(item, f"{key}[{i}]") for i, item in enumerate(value)]
    if isinstance(value, os.PathLike):
        value = os.fspath(value)
    if isinstance(value, str) and undecoded(value):
        raise StudyError(
            f"{DICT_LABEL}: key {key!r} = {value!r}: a name in bytes that are no UTF-8 "
            f"({path_text(value)}), which a study's TOML cannot hold: rename the file"
        )
    if value is None:
        raise StudyError(
            f"{DICT_LABEL}: key {key!r} = None: expected a value (leave the key out for its "
            "default)"
        )
    if isinstance(value, numbers.Number) and not isinstance(value, int | float):
        raise StudyError(
            f"{DICT_LABEL}: key {key!r} = {shown(value)}: expected a bool, int, float or str "
            "(or a numpy scalar of one)"
        )
    return value


# --- the arguments, checked: one line naming the value and what was expected -------------


def _run_options(
    out: object, recording: object, fmu_dir: object, overwrite: object, settings: Mapping[str, Any]
) -> RunOptions:
    """:func:`run`'s options, each checked (``settings``: the run's overrides by name)."""
    recording = _flag("recording", recording)
    every = seconds_argument("checkpoint_every", settings.get("checkpoint_every"))
    if every is not None and out is None:
        raise CosimError(
            f"checkpoint_every={every!r}: needs out= (a run kept in memory leaves no folder "
            "to resume)"
        )
    return RunOptions(
        out_dir=None if out is None else _folder("out", out),
        stop_time=seconds_argument("stop_time", settings.get("stop_time")),
        step=seconds_argument("step", settings.get("step")),
        algorithm=choice_argument("algorithm", settings.get("algorithm"), ALGORITHMS),  # type: ignore[arg-type]
        extrapolation=choice_argument(
            "extrapolation", settings.get("extrapolation"), EXTRAPOLATIONS
        ),  # type: ignore[arg-type]
        tolerance=number_argument("tolerance", settings.get("tolerance")),
        check_step=_flag("check_step", settings.get("check_step", False)),
        checkpoint_every=every,
        fmu_log=_fmu_log(settings.get("fmu_log"), CosimError),
        progress=_flag("progress", settings["progress"]),
        no_rrd=out is None or not recording,
        fmu_dir=_folder("fmu_dir", fmu_dir),
        overwrite=_flag("overwrite", overwrite),
        keep_rows=True,
        tail_guard=out is not None,  # a temporary folder needs no guard: it is removed
        names=KEYWORDS,  # refusals name stop_time=, out=, ..., not the command line's flags
    )


def _flag(name: str, value: object, error: type[CosimError] = CosimError) -> bool:
    """True or False, or a numpy bool as its Python value (else ``error``, as each check
    here raises: the type the caller's docstring names)."""
    value = plain(value)
    if not isinstance(value, bool):
        raise error(f"{name}={shown(value)}: expected True or False")
    return value


def _count(name: str, value: object, error: type[CosimError] = CosimError) -> int:
    """A whole number >= 1 (an int, or a numpy integer taken as its int)."""
    value = plain(value)
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise error(f"{name}={shown(value)}: expected a whole number >= 1")
    return value


def _fmu_log(value: object, error: type[CosimError]) -> dict[str, tuple[str, ...]]:
    """``fmu_log``: {instance: [log categories]} (``[]``: every one), as
    :meth:`Scenario.with_debug_logging` takes it; the instances and categories are checked
    against the scenario later, naming the keyword."""
    from cosim.scenario.spec import debug_logs

    return {} if value is None else debug_logs(value, "fmu_log", error)


def _path(
    name: str,
    value: object,
    expected: str = "a str or pathlib.Path",
    error: type[CosimError] = CosimError,
) -> Path:
    """A path argument: a non-empty str or os.PathLike without a NUL byte (else
    ``expected`` is what the refusal says was expected)."""
    if not isinstance(value, str | os.PathLike):
        raise error(f"{name}={shown(value)}: expected {expected}")
    text = value if isinstance(value, str) else value.__fspath__()  # os.fspath: TypeError
    if not isinstance(text, str):  # a path in bytes, or no path at all
        gave = f"its __fspath__ gave {type(text).__name__}"
        raise error(f"{name}={shown(value)}: expected {expected} ({gave})")
    if "\0" in text:
        raise error(f"{name}={shown(value)}: expected a path without a NUL byte")
    if not text:  # Path("") is "."; an unset setting's "" is no choice of the working folder
        raise error(f"{name}='': expected a non-empty path ('.' names the working folder)")
    try:
        return Path(home_expanded(text))
    except ValueError as exc:
        raise error(f"{name}={shown(value)}: {exc}") from None


def _folder(name: str, value: object, error: type[CosimError] = CosimError) -> Path:
    """A folder argument: a path (:func:`_path`) that is a folder if it exists."""
    path = _path(name, value, error=error)
    if os.path.exists(path) and not path.is_dir():  # os.path: False for a name too long
        raise error(f"{name}={shown(value)}: is a file; expected a folder")
    return path


def _scenario_argument(value: object, fmu_dir: Path | None) -> Path | Scenario:
    """:func:`run`'s ``scenario``: a path (:func:`_path`), or a Scenario the loader made
    (:meth:`Scenario.check_loaded`) with its FMUs in ``fmu_dir`` if one was given (its FMUs
    are those it was loaded with: another folder would be ignored)."""
    from cosim.scenario.spec import Scenario

    if not isinstance(value, Scenario):
        return _scenario_path(value, CosimError)
    value.check_loaded()
    if fmu_dir is not None and fmu_dir.resolve() != value.fmu_dir.resolve():
        raise CosimError(
            f"fmu_dir={str(fmu_dir)!r}: the scenario was loaded with the FMUs in "
            f"{str(value.fmu_dir)!r}; expected no fmu_dir, or cosim.load_scenario(..., "
            "fmu_dir=...) to load it with others"
        )
    return value


def _scenario_path(value: object, error: type[CosimError]) -> Path:
    """A ``scenario`` argument that is no Scenario: a path (:func:`_path`, else ``error``)
    of a built-in id or a file; one that is no file (a folder, a missing file) refused as
    a ScenarioError naming ``scenario=``."""
    from cosim.scenario.spec import scenario_path

    path = _path("scenario", value, error=error)
    scenario_path(path, given=KEYWORDS.given("scenario", value))
    return path


def _start(value: object) -> dict[str, StartValue] | None:
    """Start values: a mapping of "<instance>.<variable>" to a bool, int, float or str (or
    a numpy scalar of one, taken as its Python value)."""
    if value is None:
        return None
    if not isinstance(value, Mapping):
        raise CosimError(
            f"start={shown(value)}: expected a mapping {{'<instance>.<variable>': value}}"
        )
    values: dict[str, StartValue] = {}
    for key, given in value.items():
        item = plain(given)
        if not isinstance(key, str) or "\0" in key:
            raise CosimError(f"start key {shown(key)}: expected '<instance>.<variable>'")
        if not isinstance(item, bool | int | float | str):
            raise CosimError(
                f"start[{key!r}]={shown(item)}: expected a bool, int, float or str (or a "
                "numpy scalar of one)"
            )
        if isinstance(item, int) and not isinstance(item, bool) and abs(item) > 1e300:
            raise CosimError(f"start[{key!r}]={shown(item)}: expected a number within range")
        if isinstance(item, str) and "\0" in item:
            raise CosimError(f"start[{key!r}]={shown(item)}: expected a string without a NUL byte")
        values[key] = item
    return values
