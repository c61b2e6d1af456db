"""``auv-cosim sweep``: a study from its file to its table, figures and index page.

:func:`run_study` reads and checks everything before the first run -- the study file, each
factor against the scenario and its FMUs, each grid value (and the first sample) through
the scenario's own checks, the metric names, the output folder -- then runs what is not
yet in the table on Dask, appending each row as it arrives, and finally sorts the table and
writes ``runs.parquet``, a Monte Carlo study's statistics (:mod:`cosim.study.statistics`),
the figures (``figures/``) and ``index.html``, and, if the study
asks for one, ``overlay.rrd`` (:mod:`cosim.study.overlay`, :mod:`cosim.viz.overlay`).

The overlay is drawn from the chosen runs' ``results.csv``. A run kept in ``runs/<id>/``
is read from there; the others are run again, after the table is done, with their files
kept (``runs/<id>/``, as with ``keep = "all"``). Re-running is the cheaper way: best and
worst are known only at the end, so keeping them as they ran would mean shipping every
run's results to the client; a run is deterministic (its row depends on its factor
values alone), so the re-run is the run; and at most OVERLAY_CAP runs run twice. It also
serves ``--resume`` of a study whose runs were never kept.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import shlex
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cosim.errors import FLAGS, CosimError, OptionNames, counted, did_you_mean
from cosim.limits import check_local_study, unwritten
from cosim.paths import DEFAULT_FMU_DIR, path_text
from cosim.progress_bars import progress_bar
from cosim.scenario import unit_doubts
from cosim.scenario.arguments import home_expanded
from cosim.scenario.checks import ScenarioError, range_text
from cosim.scenario.unit_doubts import ANGLE_UNIT, FULL_TURN_RAD
from cosim.scratch import process_folder
from cosim.study import collector, fork_server
from cosim.study import folder as study_folder
from cosim.study.design import PlannedRun, plan
from cosim.study.execution import (
    EarlyClient,
    Job,
    StudyPlugin,
    check_scheduler,
    execute,
    make_job,
    open_client,
    read_interfaces,
)
from cosim.study.factors import FactorKind, ScenarioFacts, StartValue, Value, resolve_factor
from cosim.study.fmu_store import kept_unpacked
from cosim.study.overlay import check_choice, choose, label, notes, spread
from cosim.study.page import write_index
from cosim.study.plots import (
    Drafts,
    default_metrics,
    draft_figures,
    figure_alts,
    plotted_metrics,
    write_figures,
)
from cosim.study.prefetch import Prefetch
from cosim.study.signals import StudyStopped
from cosim.study.spec import (
    MAX_RUNS,
    Normal,
    NoRoomError,
    StudyEndedError,
    StudyError,
    StudySpec,
    check_size,
    load_study,
    study_label,
)
from cosim.study.statistics import write_statistics
from cosim.study.table import CSV_NAME, PARQUET_NAME, PLACE, TAIL, Row, RunsTable
from cosim.study.task import (
    COUPLING_ERROR,
    FMU_LOG_FILE,
    Base,
    Doubts,
    RunRecord,
    base_mission_doubts,
    checked_point,
    prepare,
    scenario_text,
    study_files,
)
from cosim.study.units import units
from cosim.study.unpacked import unpack
from cosim.viz.rrd_file import OVERLAY_FILE

STUDIES_DIR = Path("studies")
FIGURES_FOLDER = "figures"


@dataclass(frozen=True)
class StudyOutcome:
    """A finished study: where its outputs are and how its runs went."""

    out_dir: Path
    total: int
    complete: int
    failed: int
    skipped: int  # already in the table when this session started
    ran: int  # run by this session
    elapsed_s: float
    paths: Mapping[str, Path]
    warnings: tuple[str, ...] = ()
    first_failure: str | None = None  # the first failed row's run, factors and error
    again: int = 0  # runs run again for the overlay (not kept in runs/)


@dataclass(frozen=True)
class Cluster:
    """Where the runs go: a local cluster of ``workers`` processes, or ``scheduler``."""

    workers: int
    scheduler: str | None = None
    security: Any = None  # distributed.Security for a tls:// scheduler
    dashboard: bool = False
    client: EarlyClient | None = None  # a local cluster started early, if any

    def __post_init__(self) -> None:
        if self.scheduler is None and self.workers < 1:
            raise StudyError(f"--workers {self.workers}: expected at least 1 worker process")


def run_study(
    study_file: Path,
    out_dir: Path | None = None,
    *,
    cluster: Cluster,
    resume: bool = False,
    fmu_dir: Path = DEFAULT_FMU_DIR,
    progress: bool = False,
    overlay: int | None = None,
    max_runs: int = MAX_RUNS,
    label: str | None = None,
    names: OptionNames = FLAGS,
    fmu_log: Mapping[str, tuple[str, ...]] | None = None,
) -> StudyOutcome:
    """Run the study (or what a killed one left, with ``resume``) into ``out_dir``
    (default ``studies/<study file name>``). ``overlay``: draw that many runs, spread over
    the study, in overlay.rrd (instead of the study file's ``overlay``); a study of more
    than ``max_runs`` runs is refused before any is built; ``label`` names the study in a
    refusal (default: :func:`~cosim.study.spec.study_label`) and ``names`` its options
    (the command's flags, or the API's keywords); ``fmu_log`` turns instances' debug
    logging on (instance -> categories, none: every one), each run's log written to its
    folder's fmu-log.txt (docs/studies.md). Raises :class:`StudyError`
    (a CosimError) for a study that cannot run; failed runs are rows of the table."""
    started = time.perf_counter()
    _check_cluster(cluster)
    spec = load_study(study_file, label := label or study_label(study_file))
    check_size(spec, label, max_runs, names)
    base, factors, metrics, runs = _planned(spec, study_file, fmu_dir, fmu_log, names)
    entries = spread(runs, overlay, names) if overlay is not None else spec.overlay
    if entries:
        check_choice(entries, runs, metrics)
    out_dir = out_dir if out_dir is not None else STUDIES_DIR / study_file.stem
    with study_folder.lock(out_dir, names):
        study_folder.claim(out_dir, _identity(spec, base), resume, CSV_NAME, names)
        csv_path = out_dir / CSV_NAME
        table = _open_table(csv_path, spec, metrics, runs, resume)
        skipped = len(table.done)
        todo = [run for run in runs if run.id not in table.done]
        warnings: list[str] = []
        again = 0
        # the page's matplotlib, loaded while the client waits and beside the last runs
        drawing = Prefetch(cluster.workers if cluster.scheduler is None else 0)
        with ExitStack() as stack:
            session = _Session(cluster, stack)
            try:
                if todo:
                    _execute(
                        out_dir, spec, base, factors, table, todo, session, progress, len(runs),
                        drawing,
                    )  # fmt: skip
            except BaseException as exc:
                if not resume and not table.done:  # nothing to resume: leave no study
                    study_folder.discard_new(out_dir, CSV_NAME)
                elif isinstance(exc, StudyStopped | StudyEndedError):
                    kept = f"{counted(len(table.done), 'finished run')} kept in {csv_path}"
                    exc.where = f"{kept} ({names.switch('resume')})"
                raise
            with _kept_rows(csv_path, len(table.done), names):
                rows, paths = _finish(
                    out_dir, spec, base, factors, metrics, runs, table, session, drawing,
                    overlay_runs=bool(entries),
                )  # fmt: skip
            if entries:
                paths["overlay"], warnings, again = _overlay(
                    out_dir, entries, base, factors, runs, rows, session, progress
                )
    complete = sum(row["status"] == "complete" for row in rows)
    return StudyOutcome(
        out_dir, len(runs), complete, len(rows) - complete, skipped, len(todo),
        time.perf_counter() - started, paths, tuple(warnings), _first_failure(rows, spec.factors),
        again,
    )  # fmt: skip


def _check_cluster(cluster: Cluster) -> None:
    """Refuse a scheduler that cannot run the study, or a local study this process's
    limits do not allow (the local workers share them)."""
    if cluster.scheduler is not None:
        check_scheduler(cluster.scheduler, cluster.security)
    else:
        check_local_study()


def _finish(
    out_dir: Path,
    spec: StudySpec,
    base: Base,
    factors: Mapping[str, FactorKind],
    metrics: Sequence[str],
    runs: list[PlannedRun],
    table: RunsTable,
    session: _Session,
    drawing: Prefetch,
    overlay_runs: bool,
) -> tuple[list[Row], dict[str, Path]]:
    """The finished table's rows, and the study's tables and page written; the cluster
    closed while the page is made unless ``overlay_runs`` are still to run on it."""
    unit_of = units([*spec.factors, *metrics], base.fmu_paths)
    rows = table.finish(runs, unit_of)
    if not overlay_runs:
        session.done()
    paths = _tables(out_dir, spec, metrics, rows, unit_of)
    drawing.wait()
    # the overlay drawn now, or by an earlier session of this study (its runs are the
    # table's: resumed without --overlay, the page still names it)
    drawn = overlay_runs or (out_dir / OVERLAY_FILE).is_file()
    paths["index"] = _write_report(
        out_dir, spec, base, factors, metrics, rows, overlay=drawn, drafts=drawing.drafts
    )
    return rows, paths


def _tables(
    out_dir: Path,
    spec: StudySpec,
    metrics: Sequence[str],
    rows: Sequence[Mapping[str, Any]],
    unit_of: Mapping[str, str],
) -> dict[str, Path]:
    """The study's tables: runs.csv and runs.parquet (written), and for a Monte Carlo
    study its statistics and sensitivity tables, written here from ``rows``."""
    paths = {"table": out_dir / CSV_NAME, "parquet": out_dir / PARQUET_NAME}
    if spec.random.factors:
        paths.update(write_statistics(out_dir, rows, spec.factors, metrics, unit_of))
    return paths


def _first_failure(rows: Sequence[Mapping[str, Any]], factors: Sequence[str]) -> str | None:
    """ "run <id> (<factor> = <value>, ...): <error>" of the first failed row, or None: what
    a study's last lines say about its failures (the table has every one)."""
    row = next((row for row in rows if row["status"] != "complete"), None)
    if row is None:
        return None
    values = ", ".join(f"{name} = {row[name]!r}" for name in factors)
    return f"run {row['run']} ({values}): {row['error']}"


def _open_table(
    csv_path: Path, spec: StudySpec, metrics: Sequence[str], runs: list[PlannedRun], resume: bool
) -> RunsTable:
    """The study's table: what a killed study left, to resume it, else a new one."""
    if resume and csv_path.is_file():
        return RunsTable.reopen(csv_path, spec.factors, metrics, runs)
    return RunsTable.create(csv_path, spec.factors, metrics)


def report(outcome: StudyOutcome) -> str:
    """The lines ``auv-cosim sweep`` prints at the end."""
    lines = [
        f"study {outcome.out_dir}: {_runs(outcome.total)}, {outcome.complete} complete, "
        f"{outcome.failed} failed ({outcome.skipped} already in the table, {outcome.ran} "
        f"run now{_again(outcome.again)}) in {outcome.elapsed_s:.1f} s"
    ]
    width = max([8, *map(len, outcome.paths)])
    lines += [f"  {name:<{width}} {path}" for name, path in outcome.paths.items()]
    if outcome.first_failure is not None:
        lines.append(f"  first failed {outcome.first_failure}")
    lines += [f"  warning: {warning}" for warning in outcome.warnings]
    return "\n".join(lines)


def _again(count: int) -> str:
    """``, N run again for the overlay`` when the overlay ran any run again, else ""."""
    return f", {count} run again for the overlay" if count else ""


def _execute(
    out_dir: Path,
    spec: StudySpec,
    base: Base,
    factors: Mapping[str, FactorKind],
    table: RunsTable,
    todo: Sequence[PlannedRun],
    session: _Session,
    progress: bool,
    total: int,
    drawing: Prefetch,
) -> None:
    """Run ``todo`` on the cluster, appending each row (and kept folder) as it arrives;
    ``drawing`` begins before the cluster is waited for and is told how many runs are
    left after each."""
    # the FMUs first, alone (the workers wait for them), then the figures' first modules
    carried = session.carried(base, todo)
    job, plugin = make_job(
        base, factors, spec.keep, spec.check_step, session.unpacked(base), carried
    )
    # the workers' fork server warms up on the study, if it waits for it: the client then
    # has time to spare before the first run, for all of the page's matplotlib
    drawing.begin(spare=fork_server.hand_over(job, lambda: read_interfaces(job)))
    bar = _bar(progress, total, "runs", done=total - len(todo))
    failed = 0
    left = len(todo)

    def on_record(run: PlannedRun, record: RunRecord) -> None:
        nonlocal failed, left
        if record.no_room:
            raise NoRoomError(f"run {run.id} found no room for its files: {record.error}")
        left -= 1
        drawing.unfinished(left)
        kept = spec.keep == "all" or (spec.keep == "failed" and record.status != "complete")
        if kept or FMU_LOG_FILE in record.files:  # a run's debug log: its folder, kept or not
            text = scenario_text(base, factors, run.values)
            try:  # before its row: a run whose folder is not whole runs again at --resume
                study_folder.keep_run(out_dir, run.id, text, record.files, record.error)
            except OSError as exc:
                raise StudyEndedError(f"cannot write {exc.filename}: {unwritten(exc)}") from None
        table.append(run, record)
        if left == 1:  # the last run's worker alone busy: the page's figures drafted beside it
            rows = list(table.rows.values())
            drawing.draft(lambda: _draft_page(out_dir, spec, base, factors, table.metrics, rows))
        failed += record.status != "complete"
        if bar is not None:
            bar.set_postfix(failed=failed, refresh=False)
            bar.update(1)

    try:
        session.run(job, plugin, todo, on_record)
    finally:
        if bar is not None:
            bar.close()


def _bar(progress: bool, total: int, what: str, done: int = 0) -> Any:
    """A progress bar on stderr of ``total`` runs, ``done`` of them already, named
    ``what``; None without ``progress``."""
    if not progress:
        return None  # no bar at all, not a disabled one: tqdm's lock is not made
    return progress_bar(total=total, initial=done, unit="run", desc=what, dynamic_ncols=True)


class _Session:
    """The cluster's client, opened by the first task and closed with ``stack``: a study
    with nothing left to run starts no cluster, and the overlay's re-runs use the
    cluster the study's runs used."""

    def __init__(self, cluster: Cluster, stack: ExitStack) -> None:
        self.cluster = cluster
        self.stack = stack
        self.client: Any = None
        self.folder: Path | None = None  # the FMUs extracted for a local cluster

    def unpacked(self, base: Base) -> dict[str, str]:
        """A local cluster's FMUs extracted here, once, for all its workers, while the
        cluster may still be starting: kept for later studies of the same FMUs
        (:mod:`cosim.study.fmu_store`), or where they cannot be, in a folder removed with
        the session, or by the next process if this one is killed (:mod:`cosim.scratch`;
        :mod:`cosim.study.unpacked`); none for a remote cluster, whose workers extract
        their own."""
        if self.cluster.scheduler is not None:
            return {}
        kept = kept_unpacked(base.fmu_paths, self.stack)
        if kept is not None:
            return kept
        if self.folder is None:
            folder = tempfile.TemporaryDirectory(
                prefix="auv-cosim-fmus-", dir=process_folder(), ignore_cleanup_errors=True
            )
            self.folder = Path(self.stack.enter_context(folder))
        return unpack(base.fmu_paths, self.folder)

    def carried(self, base: Base, runs: Sequence[PlannedRun]) -> list[Path]:
        """The files these runs read (vehicle sets, series CSVs), for a remote cluster's
        workers, which may not see this machine's disk; none for a local cluster."""
        if self.cluster.scheduler is None:
            return []
        return study_files(base, [run.values for run in runs])

    def run(
        self,
        job: Job,
        plugin: StudyPlugin,
        runs: Sequence[PlannedRun],
        on_record: Callable[[PlannedRun, RunRecord], None],
    ) -> None:
        if self.client is None and self.cluster.client is not None:
            self.client = self.cluster.client()  # started early (execution.early_client)
        elif self.client is None:
            c = self.cluster
            workers = c.workers if c.scheduler is not None else min(c.workers, len(runs))
            self.client = self.stack.enter_context(
                open_client(workers, c.scheduler, c.security, c.dashboard)
            )  # (a local cluster of no more workers than runs: each would start for nothing)
        collector.resume()  # the client connected: collect what the runs' results leave
        execute(self.client, job, plugin, runs, on_record, self.cluster.scheduler is not None)

    def done(self) -> None:
        """No more tasks: a cluster started early starts closing now, on its own thread
        (closing a local cluster takes ~0.7 s, about what the page takes)."""
        if self.cluster.client is not None:
            self.cluster.client.close_soon()


def _overlay(
    out_dir: Path,
    entries: Sequence[str],
    base: Base,
    factors: Mapping[str, FactorKind],
    runs: Sequence[PlannedRun],
    rows: Sequence[Mapping[str, Any]],
    session: _Session,
    progress: bool,
) -> tuple[Path, list[str], int]:
    """overlay.rrd of the chosen runs (those not kept run again, and kept now, under a
    progress bar of their own with ``progress``), warnings for entries that chose nothing
    and runs without results, and how many runs ran again."""
    # imported here, for a study with an overlay only: rerun and scipy.spatial take ~0.6 s
    from cosim.viz.overlay import POSITION, SERIES, OverlayRun, write_overlay
    from cosim.viz.report import load_results

    by_id = {run.id: run for run in runs}
    by_row = {row["run"]: row for row in rows}
    chosen, empty = choose(entries, runs, by_row)
    folder = out_dir / study_folder.RUNS_FOLDER

    def results(run_id: str) -> Mapping[str, Any] | None:
        try:
            return load_results(folder / run_id)
        except CosimError:
            return None

    again = [by_id[run_id] for run_id in chosen if results(run_id) is None]
    if again:
        unpacked, carried = session.unpacked(base), session.carried(base, again)
        job, plugin = make_job(base, factors, "all", unpacked=unpacked, data_files=carried)

        bar = _bar(progress, len(again), "overlay")

        def keep(run: PlannedRun, record: RunRecord) -> None:
            text = scenario_text(base, factors, run.values)
            study_folder.keep_run(out_dir, run.id, text, record.files, record.error)
            if bar is not None:
                bar.update(1)

        try:
            session.run(job, plugin, again, keep)
        finally:
            if bar is not None:
                bar.close()
    found = {run_id: results(run_id) for run_id in chosen}
    missing = [run_id for run_id, found_results in found.items() if found_results is None]
    unit_of = units(factors, base.fmu_paths)
    shown = [
        OverlayRun(run_id, label(by_id[run_id], unit_of), run_results)
        for run_id in chosen
        if (run_results := found[run_id]) is not None
    ]
    text = notes(chosen, by_id, by_row, missing, empty, unit_of)
    drawn = [*POSITION, *(column for column, _ in SERIES.values())]
    # as the base names them, and each instance's own (the plants of several vehicles)
    own = [
        f"{instance}.{column.split('.', 1)[1]}" for instance in base.fmu_paths for column in drawn
    ]
    drawn_from = units([*drawn, *own], base.fmu_paths)
    path = write_overlay(out_dir / OVERLAY_FILE, shown, f"study {out_dir.name}", text, drawn_from)
    warnings = [f"overlay: {entry} chose no run (no complete run has a value)" for entry in empty]
    warnings += [f"overlay: run {run_id} left no results.csv" for run_id in missing]
    return path, warnings, len(again)


@contextmanager
def _kept_rows(csv_path: Path, count: int, names: OptionNames = FLAGS) -> Iterator[None]:
    """A file of the finished study that cannot be written (a full disk) ends the study
    saying which, and that every run's row is kept in runs.csv, appended as it finished."""
    try:
        yield
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        raise StudyError(
            f"cannot write the study's results: {where}{exc.strerror or exc}; every finished "
            f"run's row is kept in {csv_path} ({count} in all; {names.switch('resume')} writes "
            "the rest once it can)"
        ) from exc


def _unit(name: str, quantities: Mapping[str, str]) -> str:
    """`` <unit>`` of a factor as its study file gives it (angles in rad), "" if none."""
    unit = quantities.get(name, "")
    return "" if unit in ("", "1") else f" {unit}"


def _random_text(spec: StudySpec, quantities: Mapping[str, str]) -> str:
    """The page's line on the random factors: each law with its parameters and unit."""
    if not spec.random.factors:
        return "none"
    laws = []
    for name, law in spec.random.factors.items():
        if isinstance(law, Normal):
            text = f"normal, mean {law.normal[0]}, std {law.normal[1]}"
        else:
            text = f"uniform on [{law.uniform[0]}, {law.uniform[1]})"
        laws.append(f"{name} ~ {text}{_unit(name, quantities)}")
    random = spec.random
    return f"{'; '.join(laws)}; n = {random.n}, seed = {random.seed}, {random.sampling}"


def _write_report(
    out_dir: Path,
    spec: StudySpec,
    base: Base,
    factors: Mapping[str, FactorKind],
    metrics: Sequence[str],
    rows: Sequence[Mapping[str, Any]],
    overlay: bool = False,
    drafts: Drafts | None = None,
) -> Path:
    """The study's page; with ``overlay``, it says where the recording of the chosen runs
    is and how to open it (the page was the only place a study's reader looked);
    ``drafts``: its figures drafted before the last run (:func:`_draft_page`)."""
    grid, candidates, caption = _plotted(out_dir, spec, base, factors, metrics)
    quantities = units([*spec.factors, *candidates], base.fmu_paths)
    randoms = list(spec.random.factors)
    figures = write_figures(
        rows, grid, randoms, candidates, out_dir / FIGURES_FOLDER, quantities, caption, drafts
    )
    alts = figure_alts(rows, grid, randoms, candidates, quantities)
    shown = set(plotted_metrics(rows, candidates))
    complete = sum(row["status"] == "complete" for row in rows)
    facts = {
        "scenario": f"{spec.scenario} ({base.scenario_id}), stop time {base.data['stop_time']} s",
        "grid": ", ".join(f"{k} = {v}{_unit(k, quantities)}" for k, v in grid.items()) or "none",
        "random": _random_text(spec, quantities),
        "runs": f"{len(rows)}: {complete} complete, {len(rows) - complete} failed",
    }
    if overlay:
        facts["overlay"] = (
            f"{OVERLAY_FILE}: the chosen runs in one Rerun recording; "
            f"auv-cosim view {shlex.quote(str(out_dir))} opens it"
        )
    not_plotted = [m for m in metrics if m not in shown]
    return write_index(out_dir, facts, rows, figures, not_plotted, alts, bool(randoms))


def _plotted(
    out_dir: Path,
    spec: StudySpec,
    base: Base,
    factors: Mapping[str, FactorKind],
    metrics: Sequence[str],
) -> tuple[dict[str, list[Value]], Sequence[str], str]:
    """What the page's figures plot: the grid's values (as the factors normalise them),
    the metrics they may plot and the caption above each figure."""
    grid = {
        name: [factors[name].normalize(v) for v in values] for name, values in spec.grid.items()
    }
    candidates = metrics if spec.metrics.collect is not None else default_metrics(metrics)
    return grid, candidates, f"study {path_text(out_dir.resolve().name)} ({base.scenario_id})"


def _draft_page(
    out_dir: Path,
    spec: StudySpec,
    base: Base,
    factors: Mapping[str, FactorKind],
    metrics: Sequence[str],
    rows: Sequence[Mapping[str, Any]],
) -> Drafts:
    """The page's figures drafted from the ``rows`` so far (:func:`draft_figures`)."""
    grid, candidates, caption = _plotted(out_dir, spec, base, factors, metrics)
    return draft_figures(rows, grid, list(spec.random.factors), candidates, caption)


def _planned(
    spec: StudySpec,
    study_file: Path,
    fmu_dir: Path,
    fmu_log: Mapping[str, tuple[str, ...]] | None,
    names: OptionNames,
) -> tuple[Base, dict[str, FactorKind], list[str], list[PlannedRun]]:
    """The study's base scenario, factors, metric columns and runs, every value checked.
    A :class:`ScenarioError` of its scenario (no such file, a value its checks refuse)
    is raised as the :class:`StudyError` a study raises, with the same message: a caller
    catching StudyError (``cosim.sweep``'s documented error) catches it too."""
    try:
        scenario_ref = _scenario_ref(spec.scenario, study_file.parent)
        base, facts = prepare(
            scenario_ref, spec.stop_time, fmu_dir, spec.check_step, study_file.parent, fmu_log,
            names,
        )  # fmt: skip
        factors = {name: resolve_factor(name, facts) for name in spec.factors}
        return base, factors, _metrics(spec, facts), _checked_plan(spec, base, factors, facts)
    except ScenarioError as exc:
        raise StudyError(str(exc)) from exc


def _scenario_ref(ref: str, study_dir: Path) -> str | Path:
    """A scenario file under the home folder (``~/my.toml``, as the API's paths and the
    command's options take it), else relative to the study file's folder, else the ref
    as given (a built-in id, or a path relative to the working directory)."""
    if ref.startswith("~"):
        try:
            return home_expanded(ref)
        except ValueError as exc:
            raise StudyError(f"scenario = {ref!r}: {exc}") from None
    candidate = study_dir / ref
    try:
        return candidate if candidate.is_file() else ref
    except (OSError, ValueError):  # a name too long, a NUL: the scenario's look-up names it
        return ref


def _metrics(spec: StudySpec, facts: ScenarioFacts) -> list[str]:
    """The metric columns: those the study file lists (checked) and, with check_step,
    the coupling error of each (what check_step is for), else all of them."""
    wanted = spec.metrics.collect
    if wanted is None:
        metrics = list(facts.metrics)
    else:
        unknown = [name for name in wanted if name not in facts.metrics]
        if unknown:
            raise StudyError(
                f"[metrics] collect: unknown metric {unknown[0]!r}"
                f"{did_you_mean(unknown[0], facts.metrics)}; a run reports: "
                f"{', '.join(facts.metrics)}"
            )
        errors = [f"{COUPLING_ERROR}{name}" for name in wanted] if spec.check_step else []
        metrics = list(dict.fromkeys([*wanted, *(e for e in errors if e in facts.metrics)]))
    clash = set(metrics) & {"run", *spec.factors, *TAIL, *PLACE}
    if clash:
        raise StudyError(f"metric {sorted(clash)[0]!r} has the name of another column")
    return metrics


def _checked_plan(
    spec: StudySpec, base: Base, factors: Mapping[str, FactorKind], facts: ScenarioFacts
) -> list[PlannedRun]:
    """The study's runs, every value through the scenario's own checks before any runs:
    each grid value, every sample's range, the first sample's type (it stands for all:
    every one is a float)."""
    doubts, untrusted = _check_grid_values(base, factors, spec)
    _check_random_kinds(spec, factors, facts)
    runs = plan(spec, {name: factor.normalize for name, factor in factors.items()})
    _check_sample_ranges(spec, factors, facts, runs)
    if spec.random.factors:
        first = {name: runs[0].values[name] for name in spec.random.factors}
        found, lines = checked_point(base, factors, first, check_step=spec.check_step)
        if spec.check_step:
            untrusted[f"{_point(first)} (the first sample)"] = lines
        _add_doubts(doubts, found)
        _add_doubts(doubts, {unit_doubts.UnitWarning: _sample_doubts(spec, base, runs)})
    if spec.check_step:
        _add_doubts(doubts, {unit_doubts.UnitWarning: _untrusted(untrusted)})
    for category, lines in doubts.items():  # once each, in the main process (its runs
        unit_doubts.warn(lines, category)  # go without)
    return runs


def _untrusted(found: Mapping[str, list[str]]) -> list[str]:
    """With ``check_step``, each reason a run's coupling error is not to be trusted, as
    ``run --check-step`` says it (:func:`cosim.engine.step_check.doubts`), ``found``
    by grid point (its values as :func:`_point` names them) and for the first sample: of
    every run (a reason each grid point has), else naming the grid point, or the first
    sample, that brings it."""
    every = set.intersection(*(set(lines) for lines in found.values()))
    return [
        "check_step: the coupling errors"
        + ("" if line in every else f" of the run with {point}")
        + f" are NOT TO BE TRUSTED: {line}"
        for point, lines in found.items()
        for line in lines
    ]


def _point(values: Mapping[str, Value]) -> str:
    """A run's factor values as a warning names them: ``name = value, ...``."""
    return ", ".join(f"{name} = {value!r}" for name, value in values.items())


def _add_doubts(doubts: Doubts, more: Doubts) -> None:
    """Append ``more``'s lines to ``doubts``, category by category."""
    for category, lines in more.items():
        doubts.setdefault(category, []).extend(lines)


def _check_random_kinds(
    spec: StudySpec, factors: Mapping[str, FactorKind], facts: ScenarioFacts
) -> None:
    """A random factor's variable is Real: its samples are real numbers (an Integer one
    was refused through its first sample's type, "2.02 is not an integer")."""
    for name in spec.random.factors:
        factor = factors[name]
        if isinstance(factor, StartValue) and not factor.real:
            kind = facts.instances[factor.instance][factor.variable].type
            raise StudyError(
                f"factor {name!r}: {factor.variable} is {kind}; a random factor draws real "
                "numbers, so it varies a Real variable (vary this one in [grid])"
            )


def _sample_doubts(spec: StudySpec, base: Base, runs: Sequence[PlannedRun]) -> list[str]:
    """A line for each random factor in rad with samples of more than a full turn (a
    distribution written in degrees), as a run warns of a start value."""
    unit_of = units(spec.random.factors, base.fmu_paths)
    found = []
    for name in spec.random.factors:
        values = [abs(float(run.values[name])) for run in _samples(spec, runs)]
        beyond = [v for v in values if v > FULL_TURN_RAD]
        if unit_of[name] == ANGLE_UNIT and beyond:
            found.append(
                f"factor {name!r}: {len(beyond)} of its {len(values)} samples are more than a "
                f"full turn (up to {max(beyond):g} rad, {math.degrees(max(beyond)):.0f} deg): "
                "angles are in radians"
            )
    return found


def _samples(spec: StudySpec, runs: Sequence[PlannedRun]) -> Sequence[PlannedRun]:
    """The runs of the first grid point: one run per Monte Carlo sample (every grid point
    runs the same n samples, the samples varying fastest), so samples are counted once."""
    return runs[: spec.random.n]


def _check_sample_ranges(
    spec: StudySpec,
    factors: Mapping[str, FactorKind],
    facts: ScenarioFacts,
    runs: Sequence[PlannedRun],
) -> None:
    """Every sample of a random start value within its variable's declared range, as the
    scenario's checks want each grid value (a distribution that reaches beyond it, a
    normal one on a gain declared >= 0, would otherwise run as failed rows)."""
    for name in spec.random.factors:
        low, high = factors[name].value_range(facts)
        values = [float(run.values[name]) for run in _samples(spec, runs)]
        outside = [v for v in values if not low <= v <= high]
        if outside:
            raise StudyError(
                f"factor {name!r}: {len(outside)} of its {len(values)} samples are outside "
                f"{range_text(low, high, name.rpartition('.')[2])} (from {min(values):.6g} "
                f"to {max(values):.6g}): expected a distribution within it"
            )


def _check_grid_values(
    base: Base, factors: Mapping[str, FactorKind], spec: StudySpec
) -> tuple[Doubts, dict[str, list[str]]]:
    """Every grid point (each combination of the grid's values) through the scenario's own
    checks (type, finite); what looks like a slip of units in the scenario with each, the
    mission it cannot fly (naming the point where the base scenario flies it), or a design
    not fit for it (:func:`cosim.study.task.check_values`), once each: a current's north
    and east parts can be beaten apart but not together. With ``check_step``, also each
    point's reasons its coupling error is not to be trusted, by its values (:func:`_point`):
    each point's scenario is resolved once for both."""
    doubts: Doubts = {}
    untrusted: dict[str, list[str]] = {}
    if not spec.grid:
        return doubts, untrusted
    grid = {
        name: [factors[name].normalize(v) for v in values] for name, values in spec.grid.items()
    }
    used = {name: factors[name] for name in grid}
    known = base_mission_doubts(base)
    for point in itertools.product(*grid.values()):
        values = dict(zip(grid, point, strict=True))
        found, lines = checked_point(base, used, values, known, spec.check_step)
        _add_doubts(doubts, found)
        if spec.check_step:
            untrusted[_point(values)] = lines
    return {category: list(dict.fromkeys(lines)) for category, lines in doubts.items()}, untrusted


# Settings a study's rows do not depend on; check_step, left out while false, keeps the
# identity of a study folder written before the setting existed (resume still works)
_NOT_IDENTITY = {False: {"keep", "overlay", "check_step"}, True: {"keep", "overlay"}}


def _identity(spec: StudySpec, base: Base) -> dict[str, Any]:
    """What the table's rows depend on (study.json): settings, scenario, FMU content and
    the content of every other file the scenario reads."""
    return {
        # without check_step the identity of a study written before it existed
        "study": spec.model_dump(mode="json", exclude=_NOT_IDENTITY[spec.check_step]),
        "scenario": _without_debug_logging(base.data),
        "fmus": {
            name: hashlib.sha256(path.read_bytes()).hexdigest()
            for name, path in base.fmu_paths.items()
        },
        "files": dict(base.files),
    }


def _without_debug_logging(data: Mapping[str, Any]) -> dict[str, Any]:
    """The scenario's data without its instances' debug-log keys: a debug log changes no
    row, so a study resumes with or without ``--fmu-log``."""
    instances = {
        name: {k: v for k, v in table.items() if k not in ("debug_logging", "log_categories")}
        for name, table in data.get("instances", {}).items()
    }
    return {**data, "instances": instances} if instances else dict(data)


def _runs(count: int) -> str:
    return f"{count} run" if count == 1 else f"{count} runs"
