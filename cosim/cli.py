"""The ``auv-cosim`` command: parse, call one function, report. No logic lives here.

Every command exits 0 on success and non-zero with a one-line reason on stderr on failure
(2 for a usage error, 1 for a failed command, 130 for Ctrl-C, 141 for a reader that stopped
reading: :data:`EXIT_CODES`, which every ``--help`` ends with). ``run`` and ``sweep`` also
end on SIGTERM (143) and SIGHUP (129) like on Ctrl-C, with their partial results written.
"""

from __future__ import annotations

import os
import signal
import sys


def _interrupted_while_starting(_signum: int, _frame: object) -> None:
    """SIGINT's handler from the command's first lines to ``main``: a Ctrl-C while the
    command imports its modules and defines its names ends it in one line and 130."""
    if sys.stderr is not None:  # None: the command started with descriptor 2 closed
        print("auv-cosim: interrupted (Ctrl-C) while starting", file=sys.stderr)
    raise SystemExit(130)


def _is_the_commands_start() -> bool:
    """Whether this module runs as the command (its script, python -m cosim, python -m
    cosim.cli), not imported by a caller, whose Ctrl-C stays its own KeyboardInterrupt."""
    main_spec = getattr(sys.modules.get("__main__"), "__spec__", None)
    script = os.path.splitext(os.path.basename((sys.argv or [""])[0]))[0]
    return (
        __name__ == "__main__"
        or script == "auv-cosim"
        or getattr(main_spec, "name", None) == "cosim.__main__"
    )


# a Ctrl-C anywhere in this module's body (its imports, patterns compiled, names defined),
# not only in its imports: one line and 130, no traceback; a SIGINT the command started
# with ignored (`auv-cosim run ... &` in a script) stays ignored. main() puts Python's
# own handler back. Hence the imports below it:
# ruff: noqa: E402
if _is_the_commands_start() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _interrupted_while_starting)

from cosim.study import command_end

if _is_the_commands_start():  # before any exit handler is registered (logging's, Dask's)
    command_end.arm()

import argparse
import codecs
import errno
import gc
import re
import shutil
import textwrap
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, nullcontext
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

from cosim.errors import (
    CosimError,
    did_you_mean,
    matplotlib_folder_absolute,
    matplotlib_folder_in_one_line,
    matplotlib_off_screen,
    one_line,
    one_line_warnings,
    unencodable,
)
from cosim.limits import check_local_study, out_of_memory
from cosim.paths import DEFAULT_FMU_DIR, DOCS_DIR
from cosim.scenario.arguments import home_expanded
from cosim.study.collector import paused
from cosim.viz.ports import FILE_PORT, WEB_PORT
from fmu_runtime.log_text import shortened
from plant_fmu.model.state_layout import MAX_SPEED  # a module of constants, imports nothing

if TYPE_CHECKING:
    from cosim.analysis.bifurcation import OperatingConditions
    from cosim.engine.signals import StopRequest

FMU_DIR_HELP = "the built-in FMUs' folder, built there when missing or out of date [%(default)s]"
# cosim.scenario.spec.DEFAULT_TOLERANCE, not imported: every command would pay for the
# scenario model's import (tests/cosim/test_cli.py checks the two agree)
_DEFAULT_TOLERANCE = "0.001"


# what "-" is refused with: no option of the command reads or writes a stream
_NO_STREAM = "(standard input and output are not read or written here; ./- names a file '-')"


def _path_arg(text: str) -> Path:
    """A path option's value: refused when empty (an unset shell variable, ``--fmu-dir
    "$FMUS"``), which ``Path`` would read as the working folder, as the API refuses it,
    and when ``-``, which a pipeline means as standard input or output (``--ssp -`` wrote
    an archive into a file named ``-``). A leading ``~`` is the home folder, as the API
    takes it: a shell leaves it in ``--out=~/x``, which named a folder ``~`` here."""
    if not text:
        raise argparse.ArgumentTypeError("expected a non-empty path ('.' names the working folder)")
    if text == "-":
        raise argparse.ArgumentTypeError(f"'-': expected a file or folder name {_NO_STREAM}")
    try:
        return Path(home_expanded(text))
    except ValueError as exc:
        raise argparse.ArgumentTypeError(f"{text!r}: {exc}") from None


def _scenario_arg(text: str) -> str:
    """A scenario id or file: ``-`` refused (a scenario is read from a file, more than
    once), where it said "unknown scenario '-'"."""
    if text == "-":
        raise argparse.ArgumentTypeError(f"'-': expected a scenario id or file {_NO_STREAM}")
    return text


# a time typed with its unit ("60s", "10 ms", "2min"): refused, naming the plain number
_TIME_WITH_UNIT = re.compile(
    r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:e[-+]?\d+)?)\s*"
    r"(ms|s|sec|secs|seconds?|min|mins|minutes?|h|hr|hours?)\s*$",
    re.IGNORECASE,
)
_SECONDS_PER_UNIT = {"ms": 1e-3, "s": 1.0, "m": 60.0, "h": 3600.0}  # by the unit's start


def _seconds(option: str) -> Callable[[str], float]:
    """A time option's value, in seconds as a plain number: ``--stop-time 60s`` is refused
    naming the number to type (``--stop-time 60``), where argparse's own float said only
    "invalid float value". The range is checked with the scenario (finite, > 0)."""

    def seconds(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            pass
        match = _TIME_WITH_UNIT.match(text)
        hint = ""
        if match is not None:
            unit = match[2].lower()
            factor = _SECONDS_PER_UNIT["ms" if unit == "ms" else unit[0]]
            hint = f" ({option} {float(match[1]) * factor:.12g})"
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected a number of seconds, without a unit{hint}"
        )

    return seconds


def _build(args: argparse.Namespace) -> int:
    from cosim.fmus.build import OTHER_BUILD_FOLDER, build_fmus

    built = build_fmus(args.out, force=args.force, other=OTHER_BUILD_FOLDER, portable=args.portable)
    for name, path in built.items():
        print(f"{name}: {path}")
    return 0


def _validate(args: argparse.Namespace) -> int:
    from cosim.fmus.build import FMUS
    from cosim.fmus.validation import checked, checked_files, validate_files, validate_folder

    scenarios = [arg for arg in args.fmus if _is_scenario(arg)]
    if scenarios:
        return _validate_scenarios(args, scenarios)
    if args.fmus and args.fmu_dir is not None:
        raise CosimError("give FMU files or --fmu-dir DIR, not both")
    if args.fmus:
        problems = validate_files(args.fmus)
    else:
        fmu_dir = args.fmu_dir or DEFAULT_FMU_DIR
        problems = validate_folder(fmu_dir)
        paths = {name: fmu_dir / f"{name}.fmu" for name in FMUS}
    for problem in problems:
        print(problem)
    if problems:
        raise CosimError(f"{len(problems)} problem(s) found in the FMUs")
    for line in checked_files(args.fmus) if args.fmus else checked(paths):
        print(line)
    print("every FMU is valid")
    return 0


def _is_scenario(arg: Path) -> bool:
    """A scenario file (``.toml``) or a scenario id (no such file, and not named .fmu)
    given to validate."""
    suffix = arg.suffix.lower()
    return suffix == ".toml" or (suffix != ".fmu" and not arg.exists())


def _validate_scenarios(args: argparse.Namespace, scenarios: list[Path]) -> int:
    """``auv-cosim validate SCENARIO...``: each checked as a run checks it (its keys, its
    FMUs and their variables, its coupling), nothing stepped or written."""
    from cosim.runner import check_scenario

    others = [str(arg) for arg in args.fmus if arg not in scenarios]
    if others:
        raise CosimError(f"give scenarios or FMU files, not both (FMUs: {', '.join(others)})")
    refused = 0
    for scenario in scenarios:
        try:
            print(f"{scenario}: {check_scenario(str(scenario), args.fmu_dir or DEFAULT_FMU_DIR)}")
        except CosimError as exc:
            refused += 1
            print(one_line(str(exc)))  # it names the file (or the id) itself
    if refused:
        raise CosimError(f"{refused} of {len(scenarios)} scenario(s) refused")
    return 0


def _scenarios(args: argparse.Namespace) -> int:
    from cosim.scenario.spec import builtin_scenarios

    if args.copy is not None:
        return _copy_scenario(*args.copy)
    for line in listing(builtin_scenarios(), shutil.get_terminal_size((0, 0)).columns):
        print(line)
    return 0


MIN_SUMMARY_COLUMNS = 30  # narrower, a summary goes on lines of its own below its id
_GLUE = "\xa0"  # a space textwrap does not break at (it breaks at ASCII whitespace only)


def listing(entries: dict[str, str], columns: int) -> list[str]:
    """``entries`` (id -> summary) as lines: each id, then its summary in a column beside
    the ids. ``columns``: the terminal's width in characters (``COLUMNS``, else the
    terminal's; 0 for a pipe or a file: one line each, for grep). Within a width, a summary
    is wrapped short of the last column; where beside the ids fewer than
    :data:`MIN_SUMMARY_COLUMNS` are left, it goes below its id, indented by 4."""
    width = max(map(len, entries), default=0)
    if columns <= 0:
        return [f"{entry:<{width}} {summary}" for entry, summary in entries.items()]
    beside = columns - 1 - (width + 1) >= MIN_SUMMARY_COLUMNS
    indent = " " * (width + 1 if beside else 4)
    lines = []
    for entry, summary in entries.items():
        glued = summary.replace(" = ", f"{_GLUE}={_GLUE}")  # "v0 = -0.05" on one line
        wrapped = textwrap.wrap(
            glued, columns - 1, initial_indent=indent, subsequent_indent=indent,
            break_long_words=False, break_on_hyphens=False,
        )  # fmt: skip
        wrapped = [line.replace(_GLUE, " ") for line in wrapped]
        if beside:
            wrapped[0] = f"{entry:<{width}} {wrapped[0].lstrip()}"
        lines += wrapped if beside else [entry, *wrapped]
    return lines


def _copy_scenario(scenario_id: str, file: str) -> int:
    from cosim.scenario.builtin_copy import copy_builtin

    dest = copy_builtin(scenario_id, Path(file))
    print(f"copied {scenario_id} to {dest}: edit it, then `auv-cosim run {dest}`")
    return 0


def _run(args: argparse.Namespace) -> int:
    from cosim.runner import RunOptions, run_from_cli

    if (args.scenario is None) == (args.resume is None):
        given = "both" if args.scenario is not None else "neither"
        raise CosimError(f"give a scenario or --resume OUT, not {given}")
    if args.resume is not None and args.out is not None:
        raise CosimError(f"--resume {args.resume} continues in that folder: --out cannot be given")
    options = RunOptions(
        checkpoint_every=args.checkpoint_every,
        resume=args.resume is not None,
        out_dir=args.out if args.resume is None else args.resume,
        stop_time=args.stop_time,
        step=args.step,
        algorithm=args.algorithm,
        extrapolation=args.extrapolation,
        tolerance=args.tolerance,
        check_step=args.check_step,
        rrd=args.rrd,
        no_rrd=args.no_rrd,
        connect=args.connect,
        fmu_dir=args.fmu_dir,
        overwrite=args.overwrite,
        progress=_progress_bar(args),
        real_time=args.real_time,
        control=args.control,
        interactive=args.interactive,
        fmu_log=_fmu_logs(args.fmu_log or []),
    )
    return run_from_cli(args.scenario, options, args.held_stop)


def _fmu_log_arg(text: str) -> tuple[str, tuple[str, ...]]:
    """``--fmu-log INSTANCE[:CATEGORY,...]`` as (instance, categories); no categories: all."""
    name, colon, listed = text.partition(":")
    categories = tuple(c.strip() for c in listed.split(",")) if colon else ()
    if not name.strip() or any(not c for c in categories):
        raise argparse.ArgumentTypeError(
            f"{text!r}: expected INSTANCE or INSTANCE:CATEGORY,... (an instance name, then "
            "any of its log categories, comma-separated)"
        )
    return name.strip(), categories


def _fmu_logs(given: list[tuple[str, tuple[str, ...]]]) -> dict[str, tuple[str, ...]]:
    """Each instance's categories over every ``--fmu-log`` naming it (one naming none:
    every category)."""
    logs: dict[str, tuple[str, ...]] = {}
    for name, categories in given:
        known = logs.get(name)
        every = categories == () or known == ()
        logs[name] = () if every else tuple(dict.fromkeys((*(known or ()), *categories)))
    return logs


def _progress_bar(args: argparse.Namespace) -> bool:
    """Whether to draw a progress bar on stderr: not ``--quiet``, and stderr a terminal
    that goes back with a carriage return. ``TERM=dumb`` (Emacs's shell and compilation
    buffers) shows each redraw's carriage return as ``^M`` on one growing line."""
    return not args.quiet and sys.stderr.isatty() and os.environ.get("TERM") != "dumb"


def _export(args: argparse.Namespace) -> int:
    from cosim.export.command import export_scenario

    return export_scenario(
        args.scenario, ssp=args.ssp, osp=args.osp, fmu_dir=args.fmu_dir, force=args.force
    )


def _view(args: argparse.Namespace) -> int:
    from cosim.viz.recording import view_run

    return view_run(args.run_dir, args.web or args.open, args.open, args.web_port, args.file_port)


def _conditions(args: argparse.Namespace) -> OperatingConditions:
    from cosim.analysis.analyze import operating_conditions

    return operating_conditions(
        args.vehicle,
        args.variant,
        args.thrust,
        args.roll_torque,
        args.mass_position,
        args.current_east,
        sweep_parameter=getattr(args, "param", None),
    )


def _equilibria(args: argparse.Namespace) -> int:
    from cosim.analysis.analyze import print_equilibria

    return print_equilibria(_conditions(args), as_json=args.json)


def _sweep(args: argparse.Namespace) -> int:
    from cosim.analysis.analyze import sweep_command

    conditions = _conditions(args)
    return sweep_command(conditions, args.param, args.start, args.stop, args.steps, args.out)


def _phase_portrait(args: argparse.Namespace) -> int:
    from cosim.analysis.analyze import phase_portrait_command

    return phase_portrait_command(_conditions(args), args.out)


def _margins(args: argparse.Namespace) -> int:
    from cosim.analysis.margins_text import margins_command

    scale = dict(args.scale or [])
    return margins_command(
        args.vehicle, args.design_speed, args.step, args.speed, scale, args.plot, args.loop
    )


def _study(args: argparse.Namespace) -> int:
    """``auv-cosim sweep``: 0 if any run completed (failed runs are rows of the table), 1
    if none did, 128 + the signal number if a stop signal ended it."""
    _check_counts(args)
    if args.dashboard:  # the local cluster's (checked before it starts)
        if args.scheduler is not None:
            raise CosimError(
                "--dashboard: a --scheduler cluster serves its own dashboard (its scheduler's "
                "--dashboard-address); leave --dashboard out"
            )
        from cosim.study.execution import check_dashboard

        check_dashboard()
    if args.scheduler is None:  # before a worker or the fork server starts
        check_local_study()
    local = args.scheduler is None and not args.resume
    from cosim.study import fork_server

    if not local:
        try:
            return _run_study(args, local)
        finally:  # a resumed study's local cluster, opened once it knew the runs left,
            # has closed: its workers' fork server ends now, as a fresh study's does
            # (early_client's end_server), not with the command
            if args.scheduler is None and args.own_process:
                fork_server.stop()
    # the workers' fork server imports beside this process (cosim.study.fork_server) and
    # warms up once on the study it is handed (cosim.study.server_warm)
    fork_server.start(warm=True)
    try:
        return _run_study(args, local)
    finally:  # a study refused before its hand-over: the server is to wait no longer
        fork_server.hand_over(None)


def _run_study(args: argparse.Namespace, local: bool) -> int:
    """:func:`_study` once its flags are checked (and its fork server started if
    ``local``)."""
    from cosim.study.spec import MAX_RUNS, check_size, load_study, run_count, study_label

    max_runs = args.max_runs if args.max_runs is not None else MAX_RUNS
    spec = load_study(args.study)
    check_size(spec, study_label(args.study), max_runs)  # before dask is imported
    from cosim.study.collector import gc_diagnosis_registered
    from cosim.study.dask_settings import check_dask_settings
    from cosim.study.fork_server import libyaml_parsing

    with libyaml_parsing():  # distributed's defaults file, read as it is imported
        from cosim.study.execution import early_client, tls_security
    from cosim.study.signals import StudyStopped, stop_study_on_signals

    # a local cluster of no more workers than runs: each would start for nothing
    workers = max(1, min(_workers(args), run_count(spec))) if local else _workers(args)
    security = tls_security(args.tls_ca_file, args.tls_cert, args.tls_key)
    check_dask_settings()  # before the cluster starts (its workers would fail to)
    # a local cluster starts while the study's modules are imported and the study checked
    # (a remote scheduler is reached, and refused, after the checks); a resumed study may
    # have nothing left to run, and then starts none
    try:
        with stop_study_on_signals(ignore_after=args.own_process):
            early = (
                early_client(workers, args.dashboard, end_server=args.own_process)
                if local
                else nullcontext(None)
            )
            diagnosis = gc_diagnosis_registered() if args.scheduler is None else nullcontext()
            with diagnosis, early as client:
                from cosim.study.runner import Cluster, report, run_study

                cluster = Cluster(workers, args.scheduler, security, args.dashboard, client)
                outcome = run_study(
                    args.study,
                    args.out,
                    cluster=cluster,
                    resume=args.resume,
                    fmu_dir=args.fmu_dir,
                    progress=_progress_bar(args),
                    overlay=args.overlay,
                    max_runs=max_runs,
                    fmu_log=_fmu_logs(args.fmu_log or []),
                )
    except StudyStopped as stop:
        print(f"auv-cosim sweep: {stop}", file=sys.stderr)
        return stop.exit_code
    print(report(outcome))
    if outcome.total and not outcome.complete:
        print(
            f"auv-cosim sweep: no run completed ({outcome.failed} failed: see the error "
            f"column of {outcome.paths['table']})",
            file=sys.stderr,
        )
        return 1
    return 0


def _check_counts(args: argparse.Namespace) -> None:
    """``sweep``'s counts given (--workers, --max-runs, --overlay), refused before the
    workers' fork server, the cluster or a build starts (seconds, where --overlay 0 was
    refused after them); the study's modules imported only for a count given."""
    if args.workers is not None and args.workers < 1 and args.scheduler is None:
        raise CosimError(f"--workers {args.workers}: expected at least 1 worker process")
    if args.max_runs is not None:
        from cosim.study.spec import check_max_runs

        check_max_runs(args.max_runs)
    if args.overlay is not None:
        from cosim.study.overlay import check_count

        check_count(args.overlay)


def _workers(args: argparse.Namespace) -> int:
    """The local workers the options ask for, capped at the cores this process may use
    (said so); beyond :data:`~cosim.study.execution.MAX_WORKERS_PER_CORE` a core refused,
    oversubscribed or not, before the count is cut to the study's runs (as
    ``cosim.sweep`` refuses it)."""
    if args.scheduler is not None and args.workers is not None:
        raise CosimError("give --workers (a local cluster) or --scheduler, not both")
    from cosim.study.execution import MAX_WORKERS_PER_CORE, usable_cores

    cores = usable_cores()
    workers = args.workers if args.workers is not None else cores
    if workers > MAX_WORKERS_PER_CORE * cores and args.oversubscribe:
        raise CosimError(
            f"--workers {workers}: expected at most {MAX_WORKERS_PER_CORE * cores} worker "
            f"processes ({MAX_WORKERS_PER_CORE} per core), even with --oversubscribe"
        )
    if workers > cores and not args.oversubscribe and args.scheduler is None:
        print(
            f"auv-cosim sweep: --workers {workers} capped at the {cores} "
            f"core{'s' if cores > 1 else ''} this process may use "
            f"(--oversubscribe starts {workers})",
            file=sys.stderr,
        )
        workers = cores
    return workers


def _report(args: argparse.Namespace) -> int:
    from cosim.viz.report import write_report

    index = write_report(args.run_dir)
    print(f"report: {index}")
    return 0


def _reproduce(args: argparse.Namespace) -> int:
    import time

    from cosim.reproduction import reproduce

    if not args.values.is_file():
        raise CosimError(
            f"--values {args.values}: no such file (reproduce regenerates docs/reproduction.md "
            "of a checkout of the repository: run it from the checkout's root, or give "
            "--values FILE and --out DIR)"
        )
    started = time.perf_counter()
    page = reproduce(args.out, args.values, scenarios=not args.skip_scenarios)
    print(f"wrote {page} in {time.perf_counter() - started:.0f} s")
    return 0


def _add_coupling_options(p: argparse.ArgumentParser) -> None:
    """``auv-cosim run``'s coupling options (docs/coupling.md)."""
    p.add_argument(
        "--algorithm",
        choices=["jacobi", "gauss-seidel", "adaptive"],
        help="how the FMUs take turns: jacobi (all step from the values exchanged at the "
        "step's start), gauss-seidel (one after another, each taking the values just "
        "computed), adaptive (gauss-seidel with an error-controlled step) [the scenario's]",
    )
    p.add_argument(
        "--extrapolation",
        choices=["none", "linear", "quadratic"],
        help="what an exchanged value does across a step: held (none) or extrapolated from "
        "its last values (docs/coupling.md) [the scenario's]",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        help="adaptive only: the relative error a step may make, > 0 and < 1 "
        f"[the scenario's, {_DEFAULT_TOLERANCE} unless it sets one]",
    )
    p.add_argument(
        "--check-step",
        action="store_true",
        help="also run at half and a quarter of the step: the estimated coupling error "
        "(summary.json, docs/coupling.md)",
    )


# what every command's exit code says, at the end of its --help (README.md, docs/runs.md)
EXIT_CODES = (
    "exit codes: 0 done; 1 failed or refused (one line on stderr says why); 2 a command "
    "line it cannot parse; 3 a run complete but its recording cut short (a full disk); "
    "130, 143, 129 stopped by Ctrl-C, SIGTERM, SIGHUP (a run or a study keeps its partial "
    "results); 141 the reader of its output stopped (| head)"
)


class _Parser(argparse.ArgumentParser):
    """argparse's parser taking "-5e-1" for a negative number, as it takes "-5" and "-0.5":
    before Python 3.13 it read a negative number in exponent form as an unknown option
    ("--roll-torque -5e-1": "expected one argument"). By hand because argparse has no
    setting for it; this project's parsers have no option that looks like a number, so
    the matcher decides nothing else. Sub-parsers are made of this class too."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("epilog", EXIT_CODES)  # the end of every command's --help
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = _NEGATIVE_NUMBER
        self._given: list[str] = []  # the arguments this parser was given, for error()
        self._command_parser = False  # a command's (run, analyze margins), not auv-cosim's

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        self._given = [str(arg) for arg in (sys.argv[1:] if args is None else args)]
        parsed, unknown = super().parse_known_args(args, namespace)
        if unknown and self._command_parser:
            # refused by the command's own parser, after its usage: left to auv-cosim's,
            # "auv-cosim: error: unrecognized arguments" came after the list of commands
            self.error(f"unrecognized arguments: {' '.join(unknown)}{_closest(self, unknown)}")
        return parsed, unknown

    def add_subparsers(self, **kwargs: Any) -> Any:
        """argparse's, making each command's parser refuse what it does not know itself."""
        kwargs.setdefault("parser_class", _CommandParser)
        return super().add_subparsers(**kwargs)

    def _print_message(self, message: str, file: Any = None) -> None:
        """argparse's, but a help or a version that standard output refuses (``--help >
        /dev/full``, ``--help | head -0``) raises, as a command's own output does: argparse
        drops a failed write, and the command exited 0 having printed nothing. What goes to
        stderr (a usage error) is dropped as argparse drops it: nowhere is left to say so."""
        if file is None or file is sys.stderr:
            super()._print_message(message, file)
            return
        try:
            file.write(message)
            file.flush()
        except BrokenPipeError:
            raise
        except OSError as exc:
            raise _OutputRefusedError(f"{self.prog}: {one_line(_reason(exc))}") from exc

    def error(self, message: str) -> NoReturn:
        """argparse's usage error, and how to give a file whose name starts with - (read
        as an option: "the following arguments are required: scenario")."""
        dashed = [arg for arg in self._given if arg.startswith("-") and
                  arg not in self._option_string_actions and os.path.lexists(arg)]  # fmt: skip
        if dashed:
            message += (
                f" ({dashed[0]!r} is a file, read as an option: give it as ./{dashed[0]} "
                "or after --)"
            )
        super().error(message)


class _CommandParser(_Parser):
    """The parser of one command (``run``, ``analyze margins``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._command_parser = True


def _closest(parser: argparse.ArgumentParser, unknown: Sequence[str]) -> str:
    """`` (--stop-tme: did you mean '--stop-time'?)`` for the first unknown option close to
    one of ``parser``'s, else ``""``."""
    for word in unknown:
        option = word.split("=")[0]
        close = did_you_mean(option, parser._option_string_actions) if option[:2] == "--" else ""
        if close:
            return f" ({option}: {close[2:-1]})"
    return ""


class _OutputRefusedError(Exception):
    """A help or a version that standard output refused, as the line that says so
    ("auv-cosim run: standard output: No space left on device")."""


class _Version(argparse.Action):
    """``--version``: the package's version (:mod:`cosim.version`), looked up only when
    asked for (argparse's own action takes the string when the parser is built, which
    every command would pay for with importlib.metadata's import)."""

    def __init__(self, option_strings: Sequence[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *args: Any) -> None:
        from cosim.version import version as own_version

        version = own_version() or "(version unknown: no pyproject.toml, not installed)"
        # on stdout, as argparse's own version action does
        parser._print_message(f"auv-cosim {version}\n", sys.stdout)
        parser.exit()


# "-inf" and "-nan" too: the checks then name them ("thrust = -inf: expected a finite ...")
_NEGATIVE_NUMBER = re.compile(r"^-((\d+\.?\d*|\.\d+)(e[+-]?\d+)?|inf|infinity|nan)$", re.IGNORECASE)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="auv-cosim",
        description=(
            "Co-simulate the REMUS 100 with internal actuators as three FMI 2.0 FMUs "
            "(AuvPlant, AuvAutopilot, AuvGuidance)."
        ),
    )
    parser.add_argument("--version", action=_Version)
    # not required: without one, main() prints the whole help (the commands), not argparse's
    # "the following arguments are required: COMMAND"
    parser.set_defaults(func=None, usage_help=parser.print_help)
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    _add_build_parser(sub)
    _add_validate_parser(sub)
    _add_scenarios_parser(sub)
    _add_run_parser(sub)
    _add_sweep_parser(sub)
    _add_export_parser(sub)
    _add_view_parser(sub)
    _add_analyze_parser(sub)
    _add_reproduce_parser(sub)

    p = sub.add_parser(
        "report", help="plot a run's time histories into RUN_DIR/report/ (PNGs + index.html)"
    )
    p.add_argument(
        "run_dir",
        type=_path_arg,
        metavar="RUN_DIR",
        help="a run folder holding results.csv (`auv-cosim run SCENARIO` writes "
        "runs/<scenario-id>)",
    )
    p.set_defaults(func=_report)
    _describe(sub)
    return parser


def _add_build_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim build``."""
    p = sub.add_parser("build", help="build AuvPlant.fmu, AuvAutopilot.fmu and AuvGuidance.fmu")
    p.add_argument(
        "--out", "--fmu-dir", type=_path_arg, default=DEFAULT_FMU_DIR,
        help="output folder (the other commands' --fmu-dir) [%(default)s]",
    )  # fmt: skip
    p.add_argument("--force", action="store_true", help="rebuild even if up to date")
    p.add_argument(
        "--portable",
        action="store_true",
        help="FMUs to hand on or publish: they record no Python of this machine (no path "
        "of it inside), so the same sources and tools build the same bytes anywhere",
    )
    p.set_defaults(func=_build)


def _add_validate_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim validate``."""
    p = sub.add_parser(
        "validate",
        help="validate the built FMUs as they are (fmpy + our own checks), any FMU files, "
        "or scenarios without running them",
    )
    p.add_argument(
        "fmus", nargs="*", type=_path_arg, metavar="FMU|SCENARIO",
        help="FMU files to check for what a run needs of them (any FMI 2.0 co-simulation "
        "FMU: fmpy's validation, a binary for this platform, one step), or scenario files "
        "(.toml) or ids to check as a run would, against the FMUs of --fmu-dir, stepping "
        "nothing [the built FMUs]",
    )  # fmt: skip
    p.add_argument(
        "--fmu-dir",
        type=_path_arg,
        help=f"the built FMUs' folder, checked as built [{DEFAULT_FMU_DIR}]",
    )
    p.set_defaults(func=_validate)


def _add_export_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim export``."""
    p = sub.add_parser("export", help="export a scenario as SSP or OSP system structure")
    p.add_argument("scenario", type=_scenario_arg, help="scenario id or .toml path")
    target = p.add_mutually_exclusive_group(required=True)  # neither or both: usage, exit 2
    target.add_argument("--ssp", type=_path_arg, help="write an SSP 1.0 archive to this file")
    target.add_argument(
        "--osp", type=_path_arg, help="write OspSystemStructure.xml + FMUs to this folder"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace an --ssp file no export wrote, or one changed since",
    )
    p.add_argument("--fmu-dir", type=_path_arg, default=DEFAULT_FMU_DIR, help=FMU_DIR_HELP)
    p.set_defaults(func=_export)


def _describe(sub: argparse._SubParsersAction) -> None:
    """Each command's one line in its parent's help (``auv-cosim --help``) also opens its
    own ``--help``, which began with the usage line and the options."""
    for action in sub._choices_actions:
        parser = sub.choices[action.dest]
        if parser.description is None:
            parser.description = action.help


def _add_scenarios_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("scenarios", help="list the built-in scenarios, or copy one to edit")
    p.add_argument(
        "--copy",
        nargs=2,
        metavar=("ID", "FILE"),
        help="copy the built-in scenario ID (its file, with comments) to FILE, a new .toml "
        "file to edit and run with `auv-cosim run FILE`; never writes over a file",
    )
    p.set_defaults(func=_scenarios)


# where the FMUs' messages go, in ``run --help`` (cosim.engine.slave keeps them, docs/runs.md)
FMU_MESSAGES = (
    "The FMUs' warnings and errors are listed after the run and kept in summary.json "
    "(fmu_messages, docs/runs.md); a failed call's line gives the FMU's reason. Their "
    "debug messages are shown, on stderr, for the instances named by --fmu-log (or by the "
    "scenario's debug_logging and log_categories keys)."
)


def _add_run_parser(sub: argparse._SubParsersAction) -> None:
    what = "run a built-in scenario id or a scenario TOML file"
    p = sub.add_parser("run", help=what, description=f"{what}. {FMU_MESSAGES}")
    p.add_argument(
        "scenario",
        type=_scenario_arg,
        nargs="?",
        help="scenario id (see `auv-cosim scenarios`) or .toml path (none with --resume)",
    )
    p.add_argument("--out", type=_path_arg, help="run folder [runs/<scenario-id>]")
    _add_checkpoint_options(p)
    p.add_argument(
        "--overwrite", action="store_true", help="replace an earlier run in the run folder"
    )
    p.add_argument(
        "--stop-time",
        type=_seconds("--stop-time"),
        metavar="SECONDS",
        help="simulated time to run, s (a number, > 0) [the scenario's]",
    )
    p.add_argument(
        "--step",
        type=_seconds("--step"),
        metavar="SECONDS",
        help="the communication step: how often the FMUs exchange values, s (> 0) [the scenario's]",
    )
    _add_coupling_options(p)
    recording = p.add_mutually_exclusive_group()  # a file to write, or none
    recording.add_argument(
        "--rrd", type=_path_arg, help="recording file [<run folder>/recording.rrd]"
    )
    recording.add_argument("--no-rrd", action="store_true", help="do not write a Rerun recording")
    p.add_argument(
        "--connect",
        metavar="URL",
        help="also stream to a running Rerun viewer: `rerun` listens on "
        "rerun+http://127.0.0.1:9876/proxy (docs/live-runs.md)",
    )
    p.add_argument("--fmu-dir", type=_path_arg, default=DEFAULT_FMU_DIR, help=FMU_DIR_HELP)
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--fmu-log",
        type=_fmu_log_arg,
        action="append",
        metavar="INSTANCE[:CATEGORY,...]",
        help="turn the instance's debug logging on before initialisation (fmi2SetDebugLogging: "
        "every category, or these of its LogCategories) and show its messages of every "
        "status on stderr, each as `INSTANCE: [STATUS] CATEGORY: text`; repeat it for "
        "another instance (docs/runs.md)",
    )
    _add_live_options(p)
    p.set_defaults(func=_run)


def _add_checkpoint_options(p: argparse.ArgumentParser) -> None:
    """``run``'s checkpoints: ``--checkpoint-every`` and ``--resume`` (docs/runs.md)."""
    p.add_argument(
        "--checkpoint-every",
        type=_seconds("--checkpoint-every"),
        metavar="SECONDS",
        help="write the run's state to <run folder>/checkpoint.json every SECONDS (> 0) "
        "of simulated time and where a signal stops it [none]",
    )
    p.add_argument(
        "--resume",
        type=_path_arg,
        metavar="OUT",
        help="continue the run in the folder OUT from its checkpoint.json (no scenario)",
    )


def _add_analyze_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim analyze`` and its analyses: equilibria, sweep, phase-portrait, margins."""
    p = sub.add_parser(
        "analyze", help="equilibria, continuation sweeps, phase portraits, loop margins"
    )
    p.set_defaults(func=None, usage_help=p.print_help)  # `analyze` alone: its help (main)
    asub = p.add_subparsers(dest="analysis", metavar="ANALYSIS")
    a = asub.add_parser("equilibria", help="all equilibria in the search box, with stability")
    _add_model_options(a)
    a.add_argument(
        "--json", action="store_true", help="print JSON (SI, with its units) instead of a table"
    )
    a.set_defaults(func=_equilibria)
    a = asub.add_parser("sweep", help="continuation of equilibrium branches over a parameter")
    a.add_argument(
        "param",
        choices=["roll_torque", "mass_position", "mu", "eta"],
        help="roll_torque (N.m), mass_position (m), mu or eta (fin arm and area factors, 1)",
    )
    a.add_argument("start", type=float, metavar="FROM", help="the first value, in its unit")
    a.add_argument("stop", type=float, metavar="TO", help="the last value, in its unit")
    a.add_argument(
        "--steps", type=int, default=200, help="continuation steps, 2 to 100000 [%(default)s]"
    )
    a.add_argument(
        "--out", type=_path_arg, default=Path("analysis"), help="output folder [%(default)s]"
    )
    _add_model_options(a, "lateral for roll_torque and mass_position, else horizontal")
    a.set_defaults(func=_sweep)
    a = asub.add_parser("phase-portrait", help="open-loop horizontal trajectories (Fig. 5.4)")
    a.add_argument(
        "--out", type=_path_arg, default=Path("analysis"), help="output folder [%(default)s]"
    )
    _add_model_options(a)
    a.set_defaults(func=_phase_portrait)
    _add_margins_parser(asub)
    _describe(asub)


def _add_margins_parser(asub: argparse._SubParsersAction) -> None:
    """``auv-cosim analyze margins``: the shipped LQR loop's margins (docs/model.md#lqr)."""
    a = asub.add_parser(
        "margins", help="gain, phase and delay margins and poles of the LQR or depth loop"
    )
    a.add_argument(
        "--loop",
        choices=["lqr", "depth"],
        default="lqr",
        help="the LQR heading loop, or the depth PD (Table 6.2) [%(default)s]",
    )
    a.add_argument(
        "--vehicle", default="remus100", help="parameter set name or .toml file [%(default)s]"
    )
    a.add_argument(
        "--design-speed",
        type=float,
        default=1.525,
        help="U0 of the design, m/s, > 0 [%(default)s]",
    )
    a.add_argument(
        "--step", type=float, default=0.01, help="sample time h of the design, s, > 0 [%(default)s]"
    )
    a.add_argument(
        "--speed", type=float, help="surge speed the loop runs at, m/s, > 0 [the design speed]"
    )
    a.add_argument(
        "--scale",
        type=_scale_arg,
        action="append",
        metavar="NAME=FACTOR",
        help="multiply a vehicle parameter of the plant (not the design) by FACTOR, e.g. "
        "m_v=1.2; repeatable",
    )
    a.add_argument(
        "--plot", type=_path_arg, metavar="FILE", help="also draw the loop's Bode diagram (PNG)"
    )
    a.set_defaults(func=_margins)


def _add_live_options(p: argparse.ArgumentParser) -> None:
    """``auv-cosim run``'s live options: pacing, the control endpoint, keys."""
    p.add_argument(
        "--real-time",
        nargs="?",
        const=1.0,
        type=float,
        metavar="FACTOR",
        help="pace the run at FACTOR x real time, FACTOR > 0 [1.0] (docs/live-runs.md)",
    )
    p.add_argument(
        "--control",
        metavar="[HOST:]PORT",
        help="JSON-lines control endpoint, host 127.0.0.1 unless given; no authentication",
    )
    p.add_argument("--interactive", action="store_true", help="steer with keys (needs --real-time)")


def _add_view_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim view``: the native viewer, or the web viewer served on 127.0.0.1."""
    p = sub.add_parser("view", help="open a run's or a study's recording in the Rerun viewer")
    p.add_argument(
        "run_dir",
        type=_path_arg,
        help="a run folder (recording.rrd), a study folder (overlay.rrd) or a .rrd file",
    )
    p.add_argument(
        "--web",
        action="store_true",
        help="serve it to the web viewer on 127.0.0.1, print the URL that opens it (Ctrl-C stops)",
    )
    p.add_argument("--open", action="store_true", help="--web, and open the URL in a browser")
    p.add_argument(
        "--web-port", type=int, default=WEB_PORT, help="web viewer page, 0 any free [%(default)s]"
    )
    p.add_argument(
        "--file-port",
        "--grpc-port",  # its name while rerun's gRPC proxy served the recording
        dest="file_port",
        type=int,
        default=FILE_PORT,
        help="the recording's HTTP server, 0 any free [%(default)s]",
    )
    p.set_defaults(func=_view)


def _add_sweep_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim sweep``: a study on a local or remote Dask cluster."""
    p = sub.add_parser("sweep", help="a parameter sweep or Monte Carlo study on Dask")
    p.add_argument("study", type=_path_arg, help="study .toml file (docs/studies.md)")
    p.add_argument(
        "--workers",
        type=int,
        help="local worker processes, >= 1, at most the cores unless --oversubscribe "
        "[one per core]",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="tcp:// or tls:// of a Dask cluster, not with --workers [a local cluster]",
    )
    p.add_argument(
        "--out", type=_path_arg, help="study folder [studies/<study file name without .toml>]"
    )
    p.add_argument("--resume", action="store_true", help="skip the runs already in runs.csv")
    p.add_argument(
        "--max-runs",
        type=int,
        metavar="N",
        help="refuse a study of more runs than N, 1 to 10000000 [100000]",
    )
    p.add_argument(
        "--oversubscribe",
        action="store_true",
        help="start every --workers process even beyond the cores, at most 16 per core "
        "[capped at the cores]",
    )
    p.add_argument("--fmu-dir", type=_path_arg, default=DEFAULT_FMU_DIR, help=FMU_DIR_HELP)
    p.add_argument(
        "--dashboard",
        action="store_true",
        help="local Dask dashboard on 127.0.0.1:8787 (needs bokeh)",
    )
    p.add_argument("--tls-ca-file", type=_path_arg, help="CA certificate for a tls:// scheduler")
    p.add_argument("--tls-cert", type=_path_arg, help="client certificate for a tls:// scheduler")
    p.add_argument("--tls-key", type=_path_arg, help="client private key for a tls:// scheduler")
    p.add_argument(
        "--overlay",
        type=int,
        metavar="N",
        help="draw N runs (1 to 20) spread over the study in overlay.rrd [the study "
        "file's overlay, else none]",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.add_argument(
        "--fmu-log",
        type=_fmu_log_arg,
        action="append",
        metavar="INSTANCE[:CATEGORY,...]",
        help="turn the instance's debug logging on in every run (as `run --fmu-log`) and "
        "write each run's messages to runs/<run id>/fmu-log.txt in the study folder; "
        "repeat it for another instance (docs/studies.md)",
    )
    p.set_defaults(func=_study)


def _add_reproduce_parser(sub: argparse._SubParsersAction) -> None:
    """``auv-cosim reproduce``: regenerate docs/reproduction.md."""
    p = sub.add_parser("reproduce", help="check the dissertation's numbers: docs/reproduction.md")
    p.add_argument("--out", type=_path_arg, default=DOCS_DIR, help="docs folder [%(default)s]")
    p.add_argument(
        "--values",
        type=_path_arg,
        default=DOCS_DIR / "dissertation-values.toml",
        help="the dissertation's printed values [%(default)s]",
    )
    p.add_argument(
        "--skip-scenarios",
        action="store_true",
        help="no closed-loop runs (Ch. 6; with them the whole run takes minutes, 11 on a busy "
        "2-core machine): their rows and figures stay as the page has them",
    )
    p.set_defaults(func=_reproduce)


VARIANTS = {"full": 0, "lateral": 1, "horizontal": 2}  # the plant's variant codes


def _scale_arg(text: str) -> tuple[str, float]:
    """``NAME=FACTOR`` of ``--scale``; a usage error names what is not."""
    name, sep, factor = text.partition("=")
    try:
        if sep and name:
            return name, float(factor)
    except ValueError:
        pass
    raise argparse.ArgumentTypeError(f"{text!r}: expected NAME=FACTOR, e.g. m_v=1.2")


def _variant(text: str) -> int:
    """``--variant``: a name, as a scenario file gives it, or its code (the help's
    default says "lateral", which the flag refused when it took codes only)."""
    code = VARIANTS.get(text.strip().lower())
    if code is None and text.strip() in {str(c) for c in VARIANTS.values()}:
        code = int(text)
    if code is None:
        names = ", ".join(f"{name} ({c})" for name, c in VARIANTS.items())
        raise argparse.ArgumentTypeError(f"{text!r}: expected one of {names}")
    return code


def _add_model_options(a: argparse.ArgumentParser, variant_default: str = "horizontal") -> None:
    """An analysis's operating conditions (:func:`~cosim.analysis.analyze.operating_conditions`);
    ``variant_default``: the variant it picks without ``--variant``, for its help."""
    a.add_argument(
        "--vehicle", default="remus100", help="parameter set name or .toml file [%(default)s]"
    )
    a.add_argument(
        "--variant",
        type=_variant,
        metavar="VARIANT",
        help="full (0), lateral (1) or horizontal (2), as a scenario's plant.variant "
        f"[{variant_default}]",
    )
    a.add_argument(
        "--thrust", type=float, default=9.0, help="propeller thrust T, N, > 0 [%(default)s]"
    )
    a.add_argument(
        "--roll-torque", type=float, default=0.0, help="roll torque on the hull, N.m [%(default)s]"
    )
    a.add_argument(
        "--mass-position",
        type=float,
        default=0.0,
        help="the moving mass's position y_v on its rail, m, at most the vehicle's stroke "
        "either way [%(default)s]",
    )
    a.add_argument(
        "--current-east",
        type=float,
        default=0.0,
        help=f"current towards east, m/s, at most {MAX_SPEED:g} either way [%(default)s]",
    )


def _matplotlib_cache() -> Path:
    """:func:`cosim.user_cache.matplotlib_cache` (imported here: the command's start imports
    no more than it needs)."""
    from cosim.user_cache import matplotlib_cache

    return matplotlib_cache()


def _named(args: argparse.Namespace) -> str:
    """How a line of the command names it: ``auv-cosim run``, and an analysis with its
    command, ``auv-cosim analyze margins``."""
    analysis = getattr(args, "analysis", None)
    return f"auv-cosim {args.command}{f' {analysis}' if analysis else ''}"


def main(argv: Sequence[str] | None = None) -> int:
    """Run one command. With ``argv`` None (the process's own command line), ``run``
    records stop signals from the moment its arguments are read (:mod:`cosim.engine.signals`):
    one arriving before the run caught them ends it before its first step, one arriving
    after it, while the interpreter shuts down, cannot turn a finished run's exit code
    into a death by signal. A Ctrl-C before that ends any command in one line, 130."""
    if signal.getsignal(signal.SIGINT) is _interrupted_while_starting:
        signal.signal(signal.SIGINT, signal.default_int_handler)  # KeyboardInterrupt on
    _null_for_closed_streams()
    _printable_anything()
    if argv is None:
        sys.stdout = _StandardOutput(sys.stdout)
    try:
        args = build_parser().parse_args(argv)
        if args.func is None:  # `auv-cosim` or `auv-cosim analyze` alone: the choices, as
            args.usage_help(sys.stderr)  # a usage error, on stderr as argparse's own are
            return 2
        # in this block: a Ctrl-C during the import of the signals' module is a start's
        args.held_stop = _hold_stop_signals() if argv is None and args.command == "run" else None
        args.own_process = argv is None  # the process ends with the command
    except BrokenPipeError:  # --help or --version to a reader that stopped (`| head`)
        return _reader_gone()
    except _OutputRefusedError as exc:  # --help or --version to a standard output refusing it
        print(shortened(str(exc)), file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print("auv-cosim: interrupted (Ctrl-C) while starting", file=sys.stderr)
        return 130
    if args.held_stop is not None and args.connect is not None:
        _quiet_viewer_transport_log()
    if argv is None:
        warnings.showwarning = one_line_warnings(_named(args))
        matplotlib_folder_in_one_line()
        matplotlib_folder_absolute(_matplotlib_cache)
        matplotlib_off_screen()
    code = _command(args, argv)
    if argv is None and args.command == "sweep":  # its process ends without its teardown
        command_end.end_with(code)
    return code


def _command(args: argparse.Namespace, argv: Sequence[str] | None) -> int:
    """The parsed command run, its failures in one line: :func:`main`'s exit code."""
    # a study's imports and cluster with the collector off (cosim.study.collector); not in a
    # caller's process, whose objects the collector's resumption would freeze for good
    collecting = paused() if argv is None and args.command == "sweep" else nullcontext()
    try:
        with collecting:
            return int(args.func(args) or 0)
    except CosimError as exc:
        print(f"{_named(args)}: {shortened(one_line(str(exc)))}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{_named(args)}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # a reader that stopped (`| head`): nothing more to say to it
        return _reader_gone()
    except MemoryError as exc:
        reason = f"MemoryError{f': {exc}' if str(exc) else ''}"
        print(f"{_named(args)}: {shortened(out_of_memory(reason))}", file=sys.stderr)
        return 1
    except (ValueError, OSError, RuntimeError) as exc:
        print(f"{_named(args)}: {shortened(one_line(_reason(exc)))}", file=sys.stderr)
        return 1
    finally:
        if args.held_stop is not None:
            _ignore_stop_signals_to_the_end()
        if argv is None:  # the process ends with the command
            # The interpreter's last garbage collection at exit walks every object of the
            # libraries imported (~0.5 s with dask, matplotlib and numba loaded) to find
            # nothing the command still needs: what exists now is moved out of its reach.
            gc.freeze()


def _reason(exc: Exception) -> str:
    """An unexpected failure in one line: a file the system refused as "PATH: why" (``File
    name too long``, ``Permission denied``), anything else as "Type: message". Out of file
    descriptors, the file is any the process opened next (a library's module: it named
    ``email/_header_value_parser.py``), and the limit is what to name."""
    if isinstance(exc, OSError) and exc.errno == errno.EMFILE:
        return f"{exc.strerror or 'too many open files'}{_open_files_limit()}"
    if isinstance(exc, OSError) and exc.filename is not None and exc.strerror:
        return f"{exc.filename}: {exc.strerror}"
    if isinstance(exc, UnicodeEncodeError) and (said := unencodable(exc)) is not None:
        return said
    return f"{type(exc).__name__}: {exc}"


def _open_files_limit() -> str:
    """`` (this process may have N files open: raise the limit with `ulimit -n`)``, or
    ``""`` where the system does not say (Windows)."""
    try:
        import resource
    except ImportError:
        return ""
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    return f" (this process may have {soft} files open: raise the limit with `ulimit -n`)"


def _null_for_closed_streams() -> None:
    """A standard descriptor closed when the process started (``2>&-``, a supervisor that
    closes them) is the null device instead, and so are ``sys.stdout`` and ``sys.stderr``,
    which Python then sets to None (``sys.stdin`` stays None: a closed stdin is said to be
    one, ``--interactive``). Else ``sys.stderr.isatty()`` fails before a run or a study
    begins (exit 1, not a word), ``print(..., file=sys.stderr)`` writes errors and warnings
    on stdout, and the free descriptor goes to the next file opened (a run folder's lock
    file), where a child's or a library's messages for stderr would end up."""
    for fd, name in enumerate(("stdin", "stdout", "stderr")):
        if getattr(sys, name) is not None:
            continue
        try:
            os.fstat(fd)
        except OSError:  # free: the null device takes it (the lowest free descriptor)
            null = os.open(os.devnull, os.O_RDWR)
            if null != fd:
                os.dup2(null, fd)
                os.close(null)
        if fd:
            setattr(sys, name, open(os.devnull, "w", encoding="utf-8"))  # noqa: SIM115


_BYTES_OR_ESCAPE = "auv-cosim-bytes-or-escape"  # the error handler of _bytes_or_escape


def _printable_anything() -> None:
    """stdout and stderr write what their encoding cannot (a path given in bytes that are
    no UTF-8, which Python reads as surrogates: ``--out $'run\\xff'``) as a backslash
    escape: a strict stdout (a UTF-8 locale's) refused the report of a run that had
    completed, and the command said "UnicodeEncodeError" and exited 1. A stdout that
    passes such bytes through (a C locale's, Python's UTF-8 mode off) still does, and
    escapes what else its encoding has not (ö in ASCII, quoted from a scenario file):
    that too said "UnicodeEncodeError". stderr, which Python has escape everything
    (``backslashreplace``), passes a name's bytes through as well where stdout does: a
    refusal on stderr named ``fahrt-über.toml`` "fahrt-\\udcc3\\udcbcber.toml" in a C
    locale."""
    codecs.register_error(_BYTES_OR_ESCAPE, _bytes_or_escape)
    printable = {"strict": "backslashreplace", "surrogateescape": _BYTES_OR_ESCAPE}
    if getattr(sys.stdout, "errors", None) == "surrogateescape":  # names' bytes pass
        printable["backslashreplace"] = _BYTES_OR_ESCAPE
    for stream in (sys.stdout, sys.stderr):
        errors = getattr(stream, "errors", None)
        if errors in printable and hasattr(stream, "reconfigure"):
            stream.reconfigure(errors=printable[errors])


def _bytes_or_escape(exc: UnicodeError) -> tuple[str | bytes, int]:
    """``surrogateescape`` for the surrogates Python read a name's bytes as (those bytes),
    ``backslashreplace`` for any other character the encoding has not."""
    if isinstance(exc, UnicodeEncodeError):
        bad = exc.object[exc.start : exc.end]
        if all("\udc80" <= c <= "\udcff" for c in bad):
            return bytes(ord(c) - 0xDC00 for c in bad), exc.end
    return codecs.backslashreplace_errors(exc)


class _StandardOutput:
    """``sys.stdout`` whose failures name it: a write refused (a full disk, ``> /dev/full``)
    raised an OSError naming no file, which said "OSError: [Errno 28] No space left on
    device" after a run whose folder had been written (as if that disk were full).
    BrokenPipeError (a reader gone, ``| head``) passes as it is."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def write(self, text: str) -> int:
        with _named_standard_output():
            return self._stream.write(text)

    def flush(self) -> None:
        with _named_standard_output():
            self._stream.flush()

    def __getattr__(self, name: str) -> Any:  # everything else is the stream's
        return getattr(self._stream, name)


@contextmanager
def _named_standard_output() -> Iterator[None]:
    try:
        yield
    except BrokenPipeError:
        raise
    except OSError as exc:
        raise OSError(exc.errno, exc.strerror, "standard output") from None


def _reader_gone() -> int:
    """The exit code of a command whose reader stopped reading (``| head``): 141, as a
    command ended by SIGPIPE, with nothing more written to that reader."""
    _quiet_stdout()
    return 128 + 13  # SIGPIPE's number, which Windows' signal module does not define


def _quiet_stdout() -> None:
    """stdout to the null device: the interpreter's flush of what is still buffered for a
    reader that is gone would print a second BrokenPipeError at exit (Python's docs,
    "Note on SIGPIPE")."""
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, sys.stdout.fileno())


# rerun-sdk's own log lines about a viewer that went away ("ERROR re_grpc_client::write:
# Write messages call failed", "Failed to flush previous sink"): the run says so itself, in
# one warning line (cosim.viz.recording.RerunSink); the rest of the SDK logs as it would.
VIEWER_TRANSPORT_LOG = "warn,re_grpc_client=off,re_sdk::recording_stream=off"


def _quiet_viewer_transport_log() -> None:
    """Give rerun-sdk :data:`VIEWER_TRANSPORT_LOG` as its log filter (``RUST_LOG``, read
    once as rerun is first imported, after this) unless the user set one."""
    os.environ.setdefault("RUST_LOG", VIEWER_TRANSPORT_LOG)


def _hold_stop_signals() -> StopRequest:
    """Stop signals recorded from now on, not acted on: the run takes up one that came
    before it caught them (the import of its modules: a Ctrl-C then was lost, the run went
    on to its end), and one after it is ignored. SIGHUP stays ignored under nohup."""
    from cosim.engine.signals import STOP_SIGNALS, StopRequest, stop_signals

    held = StopRequest()
    caught = stop_signals()  # asks whether nohup ignored SIGHUP before it is changed here

    def hold(signum: int, _frame: Any) -> None:
        held.record(signum)

    for signum in STOP_SIGNALS:
        signal.signal(signum, hold if signum in caught else signal.SIG_IGN)
    return held


def _ignore_stop_signals_to_the_end() -> None:
    """The stop signals ignored by the system from here until the process ends, where
    :func:`_hold_stop_signals` recorded them for no one to read: Python's finalization
    puts the default action back for a signal a Python function handles, so a Ctrl-C
    arriving while the interpreter shut down killed the process (-2 to its parent, not
    130 or 0); an ignored signal stays ignored through it."""
    from cosim.engine.signals import STOP_SIGNALS

    for signum in STOP_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)


if __name__ == "__main__":
    sys.exit(main())
