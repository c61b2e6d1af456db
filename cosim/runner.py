"""``auv-cosim run``: check everything, claim the run folder, stream the run, report.

:func:`run_scenario` is the programmatic entry (tests, benchmarks); :func:`run_from_cli`
takes the command line's :class:`RunOptions` and prints where the outputs went and the key
figures. The order of a run:

1. the command line's numbers and the recording path are checked, and from now on
   SIGINT/SIGTERM/SIGHUP only stop the run (:mod:`cosim.engine.signals`);
2. the run folder is claimed (:mod:`cosim.outputs.folder`): a folder another run holds, or
   an earlier run without ``overwrite``, is refused at once, before numpy, fmpy or an FMU
   is loaded (this module imports those only then);
3. the scenario is loaded and every input checked (:mod:`cosim.scenario.spec`, the
   overrides, :func:`cosim.engine.master.preflight`); then the earlier run's files are set
   aside and every output opened (:mod:`cosim.outputs.run_outputs`): nothing has stepped
   yet, and a failure so far leaves nothing behind;
4. the master streams the rows to the outputs (:mod:`cosim.engine.master`), paced and
   steered live if asked (:mod:`cosim.live.session`: ``--real-time``, ``--control``,
   ``--interactive``; docs/live-runs.md); the earlier run's files are removed when the
   first step's rows arrive, and put back if the run fails or stops before that (it then
   raises :class:`NotStartedError`: the folder is as it was);
5. the outputs are closed and summary.json says how the run ended, whatever signal comes;
   a run that took live overrides rewrites scenario.toml with them as ``[[events]]``, so
   running that file replays it.

With ``checkpoint_every`` the master saves the run's state into the folder's
checkpoint.json as it steps and where a signal stops it; :func:`resume_run` checks that
checkpoint against the folder's scenario.toml, the FMUs and the version before step 2,
then runs the steps above from it (:mod:`cosim.engine.checkpoint`,
:mod:`cosim.outputs.checkpoint_file`).

A run that stops early keeps its partial results (``summary.json`` says ``"complete":
false`` and why) and exits non-zero with a one-line reason: 1 for a failure, 128 + the
signal number for a signal (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), also when the signal
came while the outputs were being completed. A recording that cannot be written (a full
disk) is no reason to stop: the run goes on without it, and exits 3 if it completes.
"""

from __future__ import annotations

import math
import os
import signal
import sys
import time
import warnings
from collections.abc import Callable, Mapping
from contextlib import AbstractContextManager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.engine.signals import REASONS, StopRequest, stop_on_signals
from cosim.errors import FLAGS, CosimError, OptionNames, counted, did_you_mean, seconds
from cosim.limits import (
    RUN_ADDRESS_SPACE,
    RUN_NO_RECORDING_ADDRESS_SPACE,
    RUN_OPEN_FILES,
    check_address_space,
    check_open_files,
)
from cosim.outputs.folder import (
    RECORDING_FILE,
    RESULTS_FILE,
    SCENARIO_FILE,
    RunFolder,
    ScenarioRef,
    check_recording_path,
)
from cosim.paths import DEFAULT_FMU_DIR, RUNS_DIR

if TYPE_CHECKING:  # imported at run time only once the run folder is claimed (step 2)
    from cosim.engine.checkpoint import Checkpointing
    from cosim.engine.master import RunResult
    from cosim.live.session import LiveSession
    from cosim.outputs.background import BackgroundSink
    from cosim.outputs.run_files import Manifest
    from cosim.outputs.run_outputs import RunOutputs
    from cosim.outputs.sinks import ProgressSink
    from cosim.scenario.spec import Algorithm, Coupling, Extrapolation, Scenario
    from cosim.viz.recording import RerunSink

RECORDING_LOST = 3  # the exit code of a complete run whose recording was cut short
MESSAGES_SHOWN = 3  # FMU log lines (warnings and worse) printed per instance


@dataclass(frozen=True)
class RunOptions:
    """How to run a scenario: the command line's options, typed.

    ``out_dir`` defaults to ``runs/<scenario id>``; the recording goes to ``rrd`` if given,
    else to ``<out_dir>/recording.rrd`` unless the scenario's ``output.rrd`` is false;
    ``no_rrd`` writes none; ``connect`` also streams to a running Rerun viewer;
    ``overwrite`` replaces an earlier run in ``out_dir``; ``keep_rows`` also keeps every
    row in memory (``outcome.result.column(...)``; memory grows with the stop time);
    ``tail_guard`` starts the process that cuts a killed run's torn last row
    (:mod:`cosim.outputs.tail_guard`; a study's task, whose killed run is run again, goes
    without: it costs ~20 ms a run). ``real_time`` paces the run at that real-time factor,
    ``control`` opens the control endpoint at that HOST:PORT, ``interactive`` reads keys
    from the terminal (docs/live-runs.md). ``extrapolation`` and ``tolerance`` override
    the scenario's ``[coupling]``; ``check_step`` also runs it at h / 2 and h / 4 and puts
    the estimated coupling error into the summary (:mod:`cosim.engine.step_check`).
    ``fmu_log`` turns debug logging on for these instances, with these log categories
    (none: every category), as their ``debug_logging`` and ``log_categories`` keys would
    (:meth:`cosim.scenario.spec.Scenario.with_debug_logging`).
    ``results_csv`` false writes no results.csv (a study's task that keeps no files: its
    rows' formatting is a quarter of a run's CPU, and its summary has every metric).
    ``names``: how a refusal names the options (the command line's flags, or the API's
    keywords: :class:`cosim.errors.OptionNames`). ``unit_doubts`` warns of an angle of
    more than a full turn given in rad and of an acceptance radius as long as a leg
    (:mod:`cosim.scenario.unit_doubts`; a study's task goes without: the study warns once),
    and of an autopilot designed for another vehicle than the plant's or given a gain no
    law it runs reads (:mod:`cosim.scenario.design_doubts`), and of a mission leg the
    vehicle cannot fly in the current or a waypoint past the stop time
    (:mod:`cosim.scenario.mission_doubts`). ``checkpoint_every`` (simulated s) writes
    the run's state into ``<out_dir>/checkpoint.json`` that often and where a signal stops
    it; ``resume`` continues the run in ``out_dir`` from its checkpoint (use
    :func:`resume_run`; :mod:`cosim.outputs.checkpoint_file`); ``rrd_from_checkpoint``:
    ``rrd`` is the checkpoint's recording, not one the user gave (a refusal says so).
    """

    out_dir: Path | None = None
    stop_time: float | None = None
    step: float | None = None
    algorithm: Algorithm | None = None
    extrapolation: Extrapolation | None = None
    tolerance: float | None = None
    check_step: bool = False
    rrd: Path | None = None
    no_rrd: bool = False
    connect: str | None = None
    fmu_dir: Path = DEFAULT_FMU_DIR
    overwrite: bool = False
    progress: bool = False
    keep_rows: bool = False
    tail_guard: bool = True
    real_time: float | None = None
    control: str | None = None
    interactive: bool = False
    names: OptionNames = FLAGS
    unit_doubts: bool = True
    results_csv: bool = True
    fmu_log: Mapping[str, tuple[str, ...]] | None = None
    checkpoint_every: float | None = None
    resume: bool = False
    rrd_from_checkpoint: bool = False


class NotStartedError(CosimError):
    """A run that failed or stopped before its first step in a folder holding an earlier
    run, which was put back as it was. ``exit_code``: 1, or 128 + the signal number."""

    def __init__(self, message: str, exit_code: int) -> None:
        super().__init__(message)
        self.exit_code = exit_code

    def __reduce__(self) -> tuple[type[NotStartedError], tuple[str, int]]:
        """Pickled with its exit code (a process pool's worker sends it to the caller)."""
        return type(self), (str(self), self.exit_code)


@dataclass
class RunOutcome:
    """A finished (or stopped) run and where its outputs are."""

    result: RunResult
    out_dir: Path
    paths: dict[str, Path]  # results, scenario, summary and (if written) recording
    figures: dict[str, float | None]  # the key figures (cosim.metrics.key_figures)
    signal: int | None = None  # the first stop signal received while the run was on
    manoeuvre: dict[str, Any] | None = None  # the manoeuvre and its metrics (summary.json)
    replaced: str | None = None  # what replacing an earlier run removed and kept (one line)
    recording_lost: str | None = None  # why the recording was cut short (the run went on)

    @property
    def exit_code(self) -> int:
        """0 complete, 3 complete but its recording cut short, 128 + signal number if a
        signal came, else 1."""
        if self.signal is not None:
            return 128 + self.signal
        if not self.result.complete:
            return 1
        return RECORDING_LOST if self.recording_lost is not None else 0


def run_scenario(
    scenario: str | Path | Scenario, out_dir: Path | None = None, **options: Any
) -> RunOutcome:
    """Run a scenario (id, file or loaded) into ``out_dir``; ``options`` are the other
    fields of :class:`RunOptions` (``stop_time=2.0, no_rrd=True, keep_rows=True``...).

    Raises :class:`CosimError` (one line) if the scenario, an option or a path is refused
    or the FMUs cannot be set up: nothing has stepped and no output is left. A failure
    during the run is reported in ``outcome.result`` (``complete`` false).
    """
    return execute(scenario, RunOptions(out_dir=out_dir, **options))


def execute(
    scenario: str | Path | Scenario, options: RunOptions, stop: StopRequest | None = None
) -> RunOutcome:
    """:func:`run_scenario` with the options as one object (see the module docstring).

    ``stop``: the caller's :class:`StopRequest`, its signal handlers installed (else this
    call installs them for its duration)."""
    _check_numbers(options)
    default_for = _reference(scenario) if options.out_dir is None else None
    out_dir = options.out_dir if options.out_dir is not None else RUNS_DIR / _id_of(scenario)
    if options.rrd is not None and not options.no_rrd:
        named = _recording_named(options, out_dir)
        check_recording_path(out_dir, options.rrd, options.overwrite, named)
    handlers: AbstractContextManager[StopRequest | None] = nullcontext(stop)
    if stop is None:
        stop = StopRequest()
        handlers = stop_on_signals(stop)
    with handlers:
        folder = RunFolder.claim(
            out_dir,
            options.overwrite,
            options.tail_guard,
            default_for,
            options.names,
            resuming=options.resume,
        )
        progress: ProgressSink | None = None
        checkpoints: Checkpointing | None = None
        stepped = False
        try:
            progress = _progress(_id_of(scenario), options)
            started = time.perf_counter()
            loaded = _checked_scenario(scenario, options, progress)
            if stop.requested:  # Ctrl-C while the FMUs were built: nothing to run or write
                raise _stopped_before_start(stop, folder.replacing, out_dir)
            prepared = time.perf_counter()
            checkpoints = _checkpoints(loaded, options, folder)
            replayed = _replayed(checkpoints)
            if progress:
                progress.replayed_rows = replayed
            session = _live_session(loaded, options, progress)
            try:
                outputs = _open_outputs(
                    loaded, folder, options, progress, checkpoints is not None, replayed
                )
                opened = time.perf_counter()
                result = _step(loaded, outputs, options, stop, session, progress, checkpoints)
                stepped = True
                if options.check_step and result.complete:
                    _check_step(loaded, outputs, result, stop, progress, session.live is not None)
            finally:
                session.close()
            if folder.replacing and not folder.committed:
                stepped = False
                outputs.discard()
                raise _not_started(result, stop, out_dir)
            result.startup_s = {
                "prepare": prepared - started, "outputs": opened - prepared, **result.startup_s
            }  # fmt: skip
            _complete(outputs, result, stop, live=session.live is not None)
        except BaseException as exc:
            folder.restore()  # an earlier run set aside goes back (if the run never stepped)
            said = isinstance(exc, NotStartedError)  # it says how the run stopped
            if stop.requested and isinstance(exc, CosimError) and not said:
                # what the start-up ran in a child process (pythonfmu's FMU build) got the
                # terminal's Ctrl-C too and failed of it: the stop is the cause to report
                raise _stopped_before_start(stop, folder.replacing, out_dir) from None
            raise
        finally:
            if checkpoints is not None and checkpoints.rows is not None:
                checkpoints.rows.close()  # the earlier results.csv, if not replayed
            if progress is not None:
                progress.close()
            folder.release(unused=not stepped)
    figures = outputs.figures.figures(result.complete)
    told = _resumed(checkpoints, loaded, out_dir) if options.resume else folder.replaced
    return RunOutcome(
        result, out_dir, outputs.paths, figures, stop.signum, outputs.manoeuvre_summary,
        told, outputs.recording_lost,
    )  # fmt: skip


def _resumed(checkpoints: Checkpointing | None, scenario: Scenario, out_dir: Path) -> str:
    """What the report says of a resumed run, in place of replacing the earlier one."""
    step = checkpoints.start["step"] if checkpoints and checkpoints.start else 0
    return f"resumed the run in {out_dir} at t = {seconds(step * scenario.coupling.step)} s"


def resume_run(
    out_dir: Path, options: RunOptions | None = None, stop: StopRequest | None = None
) -> RunOutcome:
    """Continue the run in ``out_dir`` from its checkpoint.json, as it was scenario.toml
    there: the rows up to the checkpoint are kept, the run's files rewritten whole (the
    recording too) and the rest appended as the uninterrupted run would have written them.
    ``options``: how to write the outputs (``no_rrd``, ``progress``, ``checkpoint_every``,
    ...; without ``no_rrd`` or ``rrd``, the recording the checkpointed run wrote, or
    none); what changes the run (``stop_time``, ``step``, ...) is refused. Raises
    :class:`CosimError` (one line) where the checkpoint cannot be resumed exactly."""
    from dataclasses import replace

    from cosim.outputs.checkpoint_file import read_checkpoint
    from cosim.scenario.spec import load_scenario

    options = options or RunOptions()
    names = options.names
    # (fmu_log too: the debug logging is part of the scenario, which the checkpoint's is)
    for name in ("stop_time", "step", "algorithm", "extrapolation", "tolerance", "fmu_log"):
        if getattr(options, name) not in (None, {}):  # (the command line gives {} for none)
            raise CosimError(
                f"{names.option(name)} cannot be given with {names.option('resume')}: the run "
                "resumes as it was checkpointed"
            )
    scenario = Path(out_dir) / SCENARIO_FILE
    if not scenario.is_file():
        raise CosimError(f"{names.given('resume', out_dir)}: no run there ({scenario} is missing)")
    # checked before the folder is claimed, whose own check of the earlier run's files
    # would refuse an edited scenario.toml without saying what the checkpoint needs
    saved = read_checkpoint(Path(out_dir), names)
    loaded = load_scenario(scenario, fmu_dir=options.fmu_dir)
    saved.check(loaded)
    if not options.no_rrd and options.rrd is None and saved.keeps_recording:  # as the run did
        rrd = _checkpoint_recording(saved.recording(), Path(out_dir), names)
        options = replace(options, no_rrd=rrd is None, rrd=rrd, rrd_from_checkpoint=True)
    resumed = replace(options, out_dir=Path(out_dir), overwrite=True, resume=True)
    return execute(loaded, resumed, stop)


def _checkpoint_recording(rrd: Path | None, out_dir: Path, names: OptionNames) -> Path | None:
    """The checkpoint's recording ``rrd``, which the resume writes again, if it is a file
    the run wrote (its manifest lists it) and ``out_dir`` is the run's folder, not a copy
    of it. checkpoint.json is a file anyone may edit: a recording elsewhere that the run
    never wrote is refused (one line), not created; so is, in a copied folder, the
    recording of the folder it was copied from, which that folder's run may resume."""
    from cosim.outputs.run_files import read_manifest

    if rrd is None or rrd == out_dir / RECORDING_FILE:
        return rrd
    manifest = read_manifest(out_dir, names, "resume")
    instead = (  # (the API's resume says recording=, not rrd=)
        "recording=True (its own recording.rrd) or recording=False"
        if names.keywords
        else f"{names.given('rrd', 'PATH')} or {names.switch('no_rrd')}"
    )
    if manifest.name_of(rrd) not in manifest.entries:
        raise CosimError(
            f"{names.given('resume', out_dir)}: its checkpoint's recording {rrd} is not a "
            f"file the run wrote (its manifest does not list it); resume with {instead}"
        )
    original = _copied_from(out_dir, manifest, rrd)
    if original is not None:
        raise CosimError(
            f"{names.given('resume', out_dir)}: its checkpoint's recording {rrd} is the "
            f"recording of the run in the folder it was copied from, {original}, which "
            f"may resume into it; resume with {instead}"
        )
    return rrd


def _copied_from(out_dir: Path, manifest: Manifest, rrd: Path) -> Path | None:
    """The folder ``out_dir`` is a copy of (``cp -a``, ``rsync -a``), if that folder is
    still there with the run's recording ``rrd`` in its own manifest: the folder
    ``manifest`` was saved in, when it is another folder than ``out_dir`` (not the same
    one by another path, a link or a bind mount). None for the run's own folder, even
    moved, restored from a backup or on a file system that numbers its devices and inodes
    anew at each mount (nothing of theirs is compared), and for a manifest that does not
    say where it was saved."""
    from cosim.outputs.run_files import read_manifest

    original = manifest.saved_in
    if original is None:
        return None
    try:
        if os.path.samefile(original, out_dir):
            return None
        theirs = read_manifest(original)
    except (OSError, CosimError):  # gone, or no run's folder any more
        return None
    return original if theirs.name_of(rrd) in theirs.entries else None


def _recording_named(options: RunOptions, out_dir: Path) -> str:
    """How a refusal of the recording's path names it: as given (``--rrd PATH``), or as
    the checkpoint of the run resumed in ``out_dir`` gave it."""
    if options.rrd_from_checkpoint:
        return f"{options.names.given('resume', out_dir)}: its checkpoint's recording {options.rrd}"
    return f"--rrd {options.rrd}"


def _checkpoints(
    scenario: Scenario, options: RunOptions, folder: RunFolder
) -> Checkpointing | None:
    """The run's checkpoints as ``options`` ask (none: None); a checkpoint to resume from
    read and checked against ``scenario`` and its FMUs. Raises :class:`CosimError` where
    the run's state cannot be saved or resumed exactly."""
    if options.checkpoint_every is None and not options.resume:
        return None
    from cosim.engine.checkpoint import Checkpointing, refusal
    from cosim.outputs.checkpoint_file import CHECKPOINT_FILE, CheckpointWriter, read_checkpoint

    paced = options.real_time is not None or options.control is not None or options.interactive
    reason = refusal(scenario, paced)
    if reason is not None:
        asked = options.names
        what = (asked.given("resume", folder.path) if options.resume
                else asked.given("checkpoint_every", options.checkpoint_every))  # fmt: skip
        raise CosimError(f"{what}: cannot checkpoint this run: {reason}")
    every_s, start, rows = options.checkpoint_every, None, None
    if options.resume:
        saved = read_checkpoint(folder.path, options.names)
        saved.check(scenario)
        start = saved.state(scenario)
        every_s = every_s if every_s is not None else saved.every_s
    every = 0  # steps between checkpoints (0: none but a signal's)
    if every_s is not None:  # past the run's end is as good as more (and inf: 1e308 / h)
        every = max(1, round(min(every_s / scenario.coupling.step, scenario.n_steps + 1)))
    source = str(folder.path / CHECKPOINT_FILE)
    writer = CheckpointWriter(folder, scenario, every_s, _recording_path(scenario, folder, options))
    if options.resume:  # results.csv opened last: no refusal above leaves it open
        rows = saved.rows(scenario.columns)
    return Checkpointing(every, writer, start, rows, source)


def _not_started(result: RunResult, stop: StopRequest, out_dir: Path) -> NotStartedError:
    """The error of a run that never took its first step in a folder of an earlier run."""
    reason = result.error or "the run stopped"
    return NotStartedError(
        f"{reason}, before the first step: the earlier run in {out_dir} is kept as it was",
        128 + stop.signum if stop.signum is not None else 1,
    )


def _stopped_before_start(stop: StopRequest, replacing: bool, out_dir: Path) -> NotStartedError:
    """The error of a run stopped by a signal before its first step."""
    kept = f": the earlier run in {out_dir} is kept as it was" if replacing else ""
    return NotStartedError(f"{stop.reason} before the first step{kept}", stop.exit_code)


def _live_session(
    scenario: Scenario, options: RunOptions, progress: ProgressSink | None
) -> LiveSession:
    """The run's pacing and live control as the options ask (nothing for a plain run); a
    paced run's real-time factors follow the progress bar."""
    from cosim.live.session import LiveSession

    session = LiveSession.open(scenario, options.real_time, options.control, options.interactive)
    if progress is not None:
        progress.status = session.status
    return session


def _step(
    scenario: Scenario,
    outputs: RunOutputs,
    options: RunOptions,
    stop: StopRequest,
    session: LiveSession,
    progress: ProgressSink | None,
    checkpoints: Checkpointing | None = None,
) -> RunResult:
    """Step the run through the master into the outputs; on a refusal before the first
    step the outputs are discarded and the error raised."""
    from cosim.engine import master
    from cosim.engine.pacing import interpreter_for_pacing

    paced = interpreter_for_pacing() if session.pacer is not None else nullcontext()
    try:
        with paced:
            return master.run(
                scenario,
                outputs.sinks,
                keep_rows=options.keep_rows,
                stop=stop,
                hand_off_interval=session.hand_off_interval or master.HAND_OFF_INTERVAL_S,
                pacer=session.pacer,
                live=session.live,
                on_phase=progress.phase if progress is not None else None,
                checkpoints=checkpoints,
            )
    except BaseException:  # refused or not set up: it never stepped
        outputs.discard()
        raise


def _check_step(
    scenario: Scenario,
    outputs: RunOutputs,
    result: RunResult,
    stop: StopRequest,
    progress: ProgressSink | None,
    live: bool = False,
) -> None:
    """``--check-step``: the coupling error of the complete run, into ``result.coupling``
    (summary.json); a check that cannot be made leaves its reason there instead. The
    checks run what the run ran: a live run's overrides as events at the times they were
    applied (its replay; without them the finer runs were another system's)."""
    from cosim.engine.step_check import check_step
    from cosim.live.session import replay_scenario

    if progress is not None:
        progress.phase("checking the step (h / 2, h / 4)")
    checked = replay_scenario(scenario, result, live) or scenario
    try:
        figures = outputs.figures.figures()
        result.coupling["check_step"] = check_step(checked, figures, result.final, stop)
    except CosimError as exc:
        result.coupling["check_step"] = {"error": str(exc)}


def _id_of(scenario: str | Path | Scenario) -> str:
    from cosim.scenario.spec import Scenario, scenario_id

    return scenario.id if isinstance(scenario, Scenario) else scenario_id(scenario)


def _reference(scenario: str | Path | Scenario) -> ScenarioRef:
    """The scenario's id and file (resolved): whose the default folder ``runs/<id>`` is."""
    from cosim.scenario.spec import Scenario, scenario_path

    if isinstance(scenario, Scenario):
        source = None if scenario.source is None else str(Path(scenario.source).resolve())
        return ScenarioRef(scenario.id, source)
    return ScenarioRef(_id_of(scenario), str(scenario_path(scenario).resolve()))


def _progress(label: str, options: RunOptions) -> ProgressSink | None:
    """The progress bar, when asked for (it first says what the run does before stepping)."""
    if not options.progress or options.interactive:  # the keys' status line instead
        return None
    from cosim.outputs.sinks import ProgressSink

    return ProgressSink(None, label)


def _check_numbers(options: RunOptions) -> None:
    """The times and the tolerance given, refused naming the option as its caller gave it
    (``--tolerance -1.0``, ``tolerance=-1.0``), not the scenario key they override."""
    from cosim.scenario.spec import TOLERANCE_RANGE

    times = (("stop_time", options.stop_time), ("step", options.step),
             ("checkpoint_every", options.checkpoint_every))  # fmt: skip
    for name, value in times:
        if value is not None and not (math.isfinite(value) and value > 0):
            shown = options.names.given(name, value)
            raise CosimError(f"{shown}: expected a finite number of seconds > 0")
    # before the FMUs are built (half a minute), where cosim.live refused it after them
    factor = options.real_time
    if factor is not None and not (math.isfinite(factor) and factor > 0):
        raise CosimError(f"--real-time {factor!r}: expected a finite factor > 0")
    low, high = TOLERANCE_RANGE
    if options.tolerance is not None and not low < options.tolerance < high:  # nan too
        shown = options.names.given("tolerance", options.tolerance)
        raise CosimError(f"{shown}: expected a relative error > {low:g} and < {high:g}")


def _check_tolerance_applies(scenario: Scenario, options: RunOptions) -> None:
    """A tolerance given for a run at a fixed step (the scenario's algorithm, or the one
    given, not adaptive): refused naming the options, not the scenario key."""
    algorithm = options.algorithm or scenario.coupling.algorithm
    if options.tolerance is not None and algorithm != "adaptive":
        names = options.names
        raise CosimError(
            f"{names.given('tolerance', options.tolerance)}: applies to "
            f"{names.given('algorithm', 'adaptive')} only, and {scenario.id} runs {algorithm!r}"
        )


def _checked_scenario(
    scenario: str | Path | Scenario, options: RunOptions, progress: ProgressSink | None = None
) -> Scenario:
    """The scenario with the overrides applied, every input checked; nothing written. The
    built-in FMUs are built here when out of date (the progress bar says so)."""
    from cosim.engine import master
    from cosim.scenario.checks import Source
    from cosim.scenario.spec import Scenario, load_scenario, overridden_keys

    if progress is not None:
        stale = _fmus_to_build(scenario, options.fmu_dir)
        progress.phase(f"building FMUs ({', '.join(stale)})" if stale else "loading the scenario")
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, fmu_dir=options.fmu_dir)
    _check_tolerance_applies(scenario, options)
    overrides = {"stop_time": options.stop_time, "step": options.step,
                 "algorithm": options.algorithm, "extrapolation": options.extrapolation,
                 "tolerance": options.tolerance}  # fmt: skip
    src = Source(scenario.described, overridden_keys(options.names, overrides))
    if src.given:
        scenario = scenario.with_overrides(
            stop_time=options.stop_time,
            step=options.step,
            algorithm=options.algorithm,
            extrapolation=options.extrapolation,
            tolerance=options.tolerance,
            names=options.names,
        )
    if options.fmu_log:
        scenario = with_fmu_log(scenario, options.fmu_log, options.names)
    if options.check_step:
        from cosim.engine.step_check import not_checkable

        reason = not_checkable(scenario)
        if reason is not None:
            raise CosimError(f"{options.names.switch('check_step')}: {reason}")
    master.preflight(scenario, src)
    if options.unit_doubts:
        from cosim.engine.adaptive import points_step
        from cosim.scenario import design_doubts, mission_doubts, timeline_spec, unit_doubts

        unit_doubts.warn(unit_doubts.doubts(scenario))
        late = timeline_spec.unreached(
            scenario.events, scenario.faults, scenario.stop_time, scenario.coupling.step,
            grid=points_step(scenario.coupling),
        )  # fmt: skip
        unit_doubts.warn(late, timeline_spec.TimelineWarning)
        live = options.interactive or options.control is not None
        doubts = design_doubts.design_doubts(scenario, live)
        unit_doubts.warn(doubts, design_doubts.DesignWarning)
        unit_doubts.warn(mission_doubts.mission_doubts(scenario), mission_doubts.MissionWarning)
    return scenario


def with_fmu_log(
    scenario: Scenario, logs: Mapping[str, tuple[str, ...]], names: OptionNames = FLAGS
) -> Scenario:
    """The scenario with the debug logging ``logs`` asks for (instance -> categories,
    none: every one: ``--fmu-log``); an instance it does not have, or a category its FMU
    does not declare, refused naming the option as ``names`` gives it."""
    from cosim.scenario.spec import log_category_problem

    for name, categories in logs.items():
        flag = ":".join((name, ",".join(categories))).rstrip(":")
        given = names.given("fmu_log", {name: list(categories)} if names.keywords else flag)
        instance = scenario.instances.get(name)
        if instance is None:
            raise CosimError(
                f"{given}: {scenario.id} has no instance {name!r}"
                f"{did_you_mean(name, scenario.instances)}: expected one of "
                f"{', '.join(scenario.instances)}"
            )
        problem = log_category_problem(instance.interface, list(categories)) if categories else None
        if problem is not None:
            raise CosimError(f"{given}: {problem}")
    return scenario.with_debug_logging({name: list(c) for name, c in logs.items()})


def check_scenario(scenario: str | Path, fmu_dir: Path = DEFAULT_FMU_DIR) -> str:
    """Check a scenario (id or file) as a run would before its first step, against the
    FMUs in ``fmu_dir`` (built there when out of date), stepping nothing and writing
    nothing; warnings as a run gives them. Raises :class:`CosimError` (one line) where a
    run would refuse it; returns what it would run, in one line."""
    checked = _checked_scenario(scenario, RunOptions(fmu_dir=fmu_dir))
    coupling = checked.coupling
    instances = ", ".join(
        f"{name} ({inst.fmu_path.stem}{_debug_log_note(inst.debug_logging)})"
        for name, inst in checked.instances.items()
    )
    if coupling.algorithm == "adaptive":
        steps = (
            f"adaptive steps of up to {coupling.max_step:g} s (tolerance {coupling.tolerance:g})"
        )
    else:
        steps = _fixed_steps(round(checked.stop_time / coupling.step), coupling)
    return f"a valid scenario: {instances}; {checked.stop_time:g} s in {steps}"


def _debug_log_note(categories: tuple[str, ...] | None) -> str:
    """How :func:`check_scenario` names an instance's debug logging ("" when off)."""
    if categories is None:
        return ""
    return f", debug log: {', '.join(categories) or 'every category'}"


def _fmus_to_build(scenario: str | Path | Scenario, fmu_dir: Path) -> list[str]:
    """The built-in FMUs the scenario file names (``fmu = "AuvPlant"``) that are missing
    or out of date in ``fmu_dir``: loading it builds them. None for a loaded Scenario, or
    a file that does not read (loading it then says why)."""
    import tomllib

    from cosim.fmus.build import out_of_date
    from cosim.scenario.spec import Scenario, ScenarioError, scenario_path

    if isinstance(scenario, Scenario):
        return []
    try:
        instances = tomllib.loads(scenario_path(scenario).read_text("utf-8"))["instances"]
        named = {str(instance.get("fmu")) for instance in instances.values()}
    except (OSError, ValueError, KeyError, AttributeError, RecursionError, ScenarioError):
        return []
    return [name for name in out_of_date(fmu_dir) if name in named]


def _replayed(checkpoints: Checkpointing | None) -> int:
    """The rows a resume hands on again, up to its checkpoint, before its first step (0
    for a run from t = 0)."""
    if checkpoints and checkpoints.start and checkpoints.rows is not None:
        return int(checkpoints.start["rows"])
    return 0


def _open_outputs(
    scenario: Scenario,
    folder: RunFolder,
    options: RunOptions,
    progress: ProgressSink | None,
    checkpointed: bool = False,
    replayed: int = 0,
) -> RunOutputs:
    """Set the earlier run's files aside, lock the recording the run writes, then open
    every output (``checkpointed``: for a run that checkpoints; ``replayed``: the rows a
    resume hands on before its first step, the earlier run's files kept until then)."""
    from cosim.outputs.run_outputs import RunOutputs

    rrd = _recording_path(scenario, folder, options)
    folder.start_guard(folder.path / RESULTS_FILE, rrd)
    folder.set_aside_earlier_run()
    if rrd is not None:
        folder.lock_recording(rrd, _recording_named(options, folder.path))
    recorder = rerun_sink if options.real_time is None else _background_rerun_sink
    outputs = RunOutputs.open(scenario, folder, rrd, options.connect, progress, recorder,
                              options.results_csv, checkpointed, replayed)  # fmt: skip
    if outputs.csv is not None:
        outputs.csv.warm_up()
    return outputs


def _background_rerun_sink(
    scenario: Scenario,
    rrd: Path | None,
    url: str | None,
    on_flushed: Callable[[int], None] | None,
) -> BackgroundSink | None:
    """:func:`rerun_sink` fed from a thread of its own (a paced run: its sends would make
    steps late, :mod:`cosim.outputs.background`)."""
    from cosim.outputs.background import BackgroundSink

    sink = rerun_sink(scenario, rrd, url, on_flushed)
    return None if sink is None else BackgroundSink(sink)


def _recording_path(scenario: Scenario, folder: RunFolder, options: RunOptions) -> Path | None:
    if options.no_rrd:
        return None
    if options.rrd is not None:  # asked for explicitly: wins over the scenario's output.rrd
        return options.rrd
    return folder.path / RECORDING_FILE if scenario.rrd else None


def rerun_sink(
    scenario: Scenario,
    rrd: Path | None,
    url: str | None,
    on_flushed: Callable[[int], None] | None,
) -> RerunSink | None:
    """The Rerun sink for the file or the viewer (the outputs' ``Recorder``); None, with
    a warning, where rerun cannot be imported."""
    try:
        from cosim.viz.recording import RerunSink
    except ImportError as exc:
        warnings.warn(
            f"no Rerun recording: cannot import cosim.viz.recording ({exc})", stacklevel=3
        )
        return None
    try:
        return RerunSink(scenario, rrd, url, on_flushed)
    except (OSError, ValueError) as exc:
        raise CosimError(f"cannot start the Rerun recording: {exc}") from None


def _complete(outputs: RunOutputs, result: RunResult, stop: StopRequest, live: bool) -> None:
    """Close the outputs and write the final summary; a failure makes the run incomplete
    (a summary that cannot be written keeps saying "running", and the reason is printed).
    A ``live`` run's scenario.toml is rewritten to replay it (its overrides, where it
    stopped)."""
    from cosim.engine.master import ending_note
    from cosim.live.session import replay_scenario

    problem = outputs.close(ending_note(result))
    if problem is not None and result.error is None:
        result.complete, result.error = False, problem
    replay = replay_scenario(result.scenario, result, live)
    problem = outputs.write_scenario(replay) if replay is not None else None
    if problem is not None and result.error is None:
        result.complete, result.error = False, problem
    problem = outputs.finish(result, result.error, stop.signal)
    if problem is not None and result.error is None:
        result.complete, result.error = False, problem


def run_from_cli(scenario: str | None, options: RunOptions, held: StopRequest | None = None) -> int:
    """``auv-cosim run``: 0 if the run completed, 128 + signal number if a signal came,
    1 on failure. A signal while the report is printed is ignored too. Refused at once
    under an address-space or (recorded) open-files limit too small for the run
    (:mod:`cosim.limits`). ``held``: the stop signals the command recorded before this
    call; one there stops the run before its first step."""
    if options.no_rrd and options.connect is None:
        check_address_space("a run", RUN_NO_RECORDING_ADDRESS_SPACE)
    else:
        check_address_space("a run with its recording", RUN_ADDRESS_SPACE)
        check_open_files("a run with its recording", RUN_OPEN_FILES)
    stop = StopRequest()
    with stop_on_signals(stop):
        if held is not None and held.signum is not None:  # taken up once this call catches them
            stop.record(held.signum)
        try:
            if options.resume and options.out_dir is not None:
                outcome = resume_run(options.out_dir, options, stop)
            else:
                outcome = execute(scenario or "", options, stop)
        except NotStartedError as exc:
            print(f"auv-cosim run: {exc}", file=sys.stderr)
            return exc.exit_code
        _print_outcome(outcome)
    return outcome.exit_code


def _print_outcome(outcome: RunOutcome) -> None:
    result = outcome.result
    if outcome.replaced is not None:
        print(f"auv-cosim run: {outcome.replaced}", file=sys.stderr)
    print(report(outcome))
    if outcome.signal is not None and result.complete:
        reason = REASONS.get(signal.Signals(outcome.signal).name, "stopped")
        print(
            f"auv-cosim run: {reason} while the outputs were completed; the run is complete "
            f"in {outcome.out_dir}",
            file=sys.stderr,
        )
    elif not result.complete:
        print(f"auv-cosim run: {result.error} ({_kept(outcome.out_dir)})", file=sys.stderr)
    elif outcome.recording_lost is not None:
        print(
            f"auv-cosim run: {outcome.recording_lost}; the run went on without it: results "
            f"complete in {outcome.out_dir}",
            file=sys.stderr,
        )


def _kept(out_dir: Path) -> str:
    """What an unfinished run's folder keeps, said as the run ends: a folder being removed
    (``rm -rf``) may still stand then, its results.csv already gone, so a folder without
    one keeps nothing either."""
    if not out_dir.is_dir():
        return f"nothing kept: {out_dir} was removed"
    if not (out_dir / "results.csv").is_file():
        return f"nothing kept: {out_dir} holds no results.csv"
    return f"partial results in {out_dir}"


def report(outcome: RunOutcome) -> str:
    """The lines printed after a run: how far it got, where the outputs are, key figures."""
    result = outcome.result
    scenario = result.scenario
    t_end = result.time_reached
    lines = [
        f"scenario {scenario.id}: {'complete' if result.complete else 'INCOMPLETE'}, "
        f"t = {seconds(t_end)} of {seconds(scenario.stop_time)} s, {_steps(result)}"
    ]
    if result.ended is not None:
        lines.append(f"  {result.ended}")
    if scenario.unrecorded:
        lines.append(f"  not recorded (String: results.csv holds numbers): "
                     f"{', '.join(scenario.unrecorded)}")  # fmt: skip
    if result.real_time is not None:
        paced = result.real_time
        lines.append(
            f"  paced at {paced['target_factor']:g}x real time: achieved "
            f"{_fmt(paced['achieved_factor'])}x, {paced['late_steps']} late step(s), "
            f"at most {paced['max_lateness_s'] * 1e3:.1f} ms late"
        )
    if result.overrides:
        lines.append(f"  {len(result.overrides)} live override(s) (summary.json; "
                     "scenario.toml replays them)")  # fmt: skip
    cut = {"recording": " (cut short: it could not be written)"} if outcome.recording_lost else {}
    lines += [f"  {name:<10} {path}{cut.get(name, '')}" for name, path in outcome.paths.items()]
    figures = outcome.figures
    if any(v is not None for v in figures.values()):  # (a run without our plant has none)
        from cosim.metrics.key_figures import why_none_of

        fleet, done = scenario.key_vehicles, outcome.result.complete
        spanned = t_end > 0.0  # rows from t = 0 to t_end: a rate needs two

        def shown(k: str, v: float | None) -> str:
            if v is not None:
                return _fmt(v)
            return why_none_of(k, scenario.columns, fleet, done, spanned)

        lines.append("  " + ", ".join(f"{k} = {shown(k, v)}" for k, v in figures.items()))
    if outcome.manoeuvre:
        lines.append(_manoeuvre_line(outcome.manoeuvre))
    lines += logged_lines(result)
    lines.append(timing(result))
    check = result.coupling.get("check_step")
    if check is not None:
        lines.append(_check_line(check))
    return "\n".join(lines)


def logged_lines(result: RunResult) -> list[str]:
    """The report's lines of what the FMUs logged (warnings and worse): the first
    :data:`MESSAGES_SHOWN` kept per instance, then how many more it logged and how many
    of them summary.json keeps (the last ones: a run keeps
    :data:`cosim.engine.slave.LOG_LINES_KEPT` an instance)."""
    lines = []
    for name, messages in result.messages.items():
        lines += [f"  {name} logged: {message}" for message in messages[:MESSAGES_SHOWN]]
        logged = result.messages_logged.get(name, len(messages))
        if logged > MESSAGES_SHOWN:
            kept = (
                "summary.json"
                if logged == len(messages)
                else f"summary.json keeps the last {len(messages)} of {logged}"
            )
            lines.append(f"  {name} logged {logged - MESSAGES_SHOWN} more ({kept})")
    return lines


def _manoeuvre_line(manoeuvre: dict[str, Any]) -> str:
    """The manoeuvre and its metrics in one line; a survey's legs as "2 of 7", with the
    waypoints it did not reach (summary.json's legs_total, first_waypoint_not_reached)
    and the first it passed outside the acceptance radius (its ``legs``)."""
    metrics = {k: v for k, v in manoeuvre.items() if k not in ("manoeuvre", "legs")}
    total = metrics.pop("legs_total", None)
    first = metrics.pop("first_waypoint_not_reached", None)
    shown = {k: v if isinstance(v, str) else _fmt(v) for k, v in metrics.items()}
    if total is not None and metrics.get("legs_completed") is not None:
        shown["legs_completed"] += f" of {total}"
        if first is not None:
            last = total + 1  # the waypoints, numbered from 1
            which = f"waypoints {first} to {last}" if first < last else f"waypoint {last}"
            shown["legs_completed"] += f": {which} not reached"
    outside = [
        leg
        for leg in manoeuvre.get("legs", ())
        if leg["completed_at_s"] is not None and leg["within_acceptance_radius"] is False
    ]
    if outside:
        more = f" ({len(outside) - 1} more: summary.json legs)" if len(outside) > 1 else ""
        shown["legs_completed"] += (
            f"; waypoint {outside[0]['to_waypoint']} passed {outside[0]['closest_m']:.3g} m "
            f"off, outside the acceptance radius{more}"
        )
    return f"  {manoeuvre['manoeuvre']}: " + ", ".join(f"{k} = {v}" for k, v in shown.items())


def _steps(result: RunResult) -> str:
    """What the run stepped: its steps, their size and the coupling."""
    coupling = result.scenario.coupling
    if coupling.algorithm == "adaptive":
        taken = result.coupling
        discarded = taken.get("discarded_steps")
        return (
            f"{taken.get('accepted_steps')} adaptive steps of {_fmt(taken.get('smallest_step_s'))}"
            f" to {_fmt(taken.get('largest_step_s'))} s ({taken.get('rejected_steps')} "
            f"rejected{f', {discarded} of them discarded by an FMU' if discarded else ''}, "
            f"{_over_tolerance(taken)}tolerance {coupling.tolerance:g})"
        )
    return _fixed_steps(result.rows - 1, coupling, result.coupling.get("input_derivatives"))


def _over_tolerance(taken: dict[str, Any]) -> str:
    """The accepted steps that missed an adaptive run's tolerance, as the report says
    them ("" if none): the kinks stepped across as they are, and those at the shortest
    step (a tolerance below what the coupling reaches there)."""
    over, kinks = taken.get("steps_over_tolerance") or 0, taken.get("kinks") or 0
    if not over:
        return ""
    shortest = over - kinks
    parts = [f"{kinks} kinks"] if kinks else []
    if shortest:
        parts.append(
            "all at the shortest step" if not kinks else f"{shortest} at the shortest step"
        )
    return f"{over} over the tolerance ({', '.join(parts)}), "


def _fixed_steps(count: int, coupling: Coupling, takers: list[str] | None = None) -> str:
    """``count`` steps of the fixed communication step, with the coupling; ``takers``: the
    instances that were sent input derivatives (None: not known yet). Extrapolation reaches
    only FMUs declaring canInterpolateInputs: where none does, the inputs were held."""
    inputs = f", inputs {coupling.extrapolation}" if coupling.extrapolation != "none" else ""
    if inputs and takers == []:
        inputs = (
            f", inputs held: no FMU takes input derivatives (canInterpolateInputs) for "
            f"extrapolation = {coupling.extrapolation!r}"
        )
    return f"{counted(count, 'step')} of {seconds(coupling.step)} s ({coupling.algorithm}{inputs})"


def _check_line(check: dict[str, Any]) -> str:
    """The report's last line for ``--check-step``: the estimate, or why there is none."""
    from cosim.engine.step_check import summary_line

    if "error" in check:
        return f"  coupling error not estimated: {check['error']}"
    return summary_line(check)


STARTUP_LABELS = {
    "prepare": "scenario and FMU build",
    "outputs": "outputs",
    "load_fmus": "loading FMUs",
    "initialise": "initialising (and compiling)",
    "replay": "replaying the rows to the checkpoint",
}


def timing(result: RunResult) -> str:
    """The report's last line: the start-up before the loop, by phase, and the stepping
    loop with its real-time factor (only the loop's speed is the simulator's)."""
    wall, startup = result.wall_clock_s, result.startup_s
    stepped = result.time_reached - result.time_started  # a resumed run's from its checkpoint
    speed = f" ({stepped / wall:.1f}x real time)" if wall > 0 else ""
    phases = ", ".join(f"{STARTUP_LABELS.get(k, k)} {v:.2f}" for k, v in startup.items())
    return (
        f"  wall clock: start-up {sum(startup.values()):.2f} s ({phases}), "
        f"stepping loop {wall:.2f} s{speed}"
    )


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4g}"
