"""``auv-cosim run``: load a scenario, run the master, write the outputs, report.

:func:`run_scenario` is the programmatic entry (tests, benchmarks); :func:`run_from_cli`
adapts the command line's arguments to it and prints where the outputs went and the key
figures. A failed run keeps its partial results (``summary.json`` says ``"complete":
false`` and why) and exits non-zero with a one-line reason.
"""

from __future__ import annotations

import argparse
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import CosimError
from cosim.run import master
from cosim.run.master import RunResult
from cosim.run.results import key_figures, write_outputs
from cosim.run.scenario import DEFAULT_FMU_DIR, Scenario, load_scenario

RUNS_DIR = Path("runs")
RECORDING_FILE = "recording.rrd"
MESSAGES_SHOWN = 3  # FMU log lines (warnings and worse) printed per instance


@dataclass
class RunOutcome:
    """A finished (or stopped) run and where its outputs are."""

    result: RunResult
    out_dir: Path
    paths: dict[str, Path]  # results, scenario, summary and (if written) recording


def run_scenario(
    scenario: str | Path | Scenario,
    out_dir: Path | None = None,
    *,
    stop_time: float | None = None,
    step: float | None = None,
    algorithm: str | None = None,
    rrd: Path | None = None,
    no_rrd: bool = False,
    connect: str | None = None,
    fmu_dir: Path = DEFAULT_FMU_DIR,
    progress: bool = False,
) -> RunOutcome:
    """Run a scenario (id, file or loaded) and write its outputs to ``out_dir``
    (default ``runs/<id>``). The recording goes to ``rrd`` if given, else to
    ``<out_dir>/recording.rrd`` unless the scenario's ``output.rrd`` is false; ``no_rrd``
    writes none. ``connect`` also streams it to a running Rerun viewer.

    Raises :class:`CosimError` if the scenario is invalid or the FMUs cannot be set up;
    a failure during the run is reported in ``outcome.result`` (``complete`` false).
    """
    if not isinstance(scenario, Scenario):
        scenario = load_scenario(scenario, fmu_dir=fmu_dir)
    if stop_time is not None or step is not None or algorithm is not None:
        scenario = scenario.with_overrides(stop_time=stop_time, step=step, algorithm=algorithm)
    out_dir = out_dir if out_dir is not None else RUNS_DIR / scenario.id
    if no_rrd:
        rrd_path = None
    elif rrd is not None:  # asked for explicitly: wins over the scenario's output.rrd
        rrd_path = rrd
    else:
        rrd_path = out_dir / RECORDING_FILE if scenario.rrd else None
    sink = _open_sink(scenario, rrd_path, connect)
    bar: list[Any] = []  # the progress bar, opened when the stepping starts

    def on_rows(times: np.ndarray, values: np.ndarray) -> None:
        if sink is not None:
            sink.add_rows(times, values)
        if progress:
            if not bar:
                bar.append(_progress_bar(scenario))
            bar[0].update(len(times))

    try:
        result = master.run(scenario, on_rows=on_rows if sink is not None or progress else None)
    finally:
        for b in bar:
            b.close()
        if sink is not None:
            sink.close()
    paths = write_outputs(result, out_dir)
    if rrd_path is not None and sink is not None:
        paths["recording"] = rrd_path
    return RunOutcome(result, out_dir, paths)


def run_from_cli(args: argparse.Namespace) -> int:
    """``auv-cosim run``: 0 if the run completed, 130 if interrupted, 1 on failure."""
    quiet = bool(args.quiet)
    outcome = run_scenario(
        args.scenario,
        args.out,
        stop_time=args.stop_time,
        step=args.step,
        algorithm=args.algorithm,
        rrd=args.rrd,
        no_rrd=args.no_rrd,
        connect=args.connect,
        fmu_dir=args.fmu_dir,
        progress=not quiet and sys.stderr.isatty(),
    )
    result = outcome.result
    print(_report(outcome))
    if result.complete:
        return 0
    print(f"auv-cosim run: {result.error} (partial results in {outcome.out_dir})", file=sys.stderr)
    return 130 if result.interrupted else 1


def _report(outcome: RunOutcome) -> str:
    result = outcome.result
    scenario = result.scenario
    t_end = float(result.times[-1])
    lines = [
        f"scenario {scenario.id}: {'complete' if result.complete else 'INCOMPLETE'}, "
        f"t = {t_end:g} of {scenario.stop_time:g} s, {len(result.times) - 1} steps of "
        f"{scenario.coupling.step:g} s ({scenario.coupling.algorithm}), "
        f"{result.wall_clock_s:.2f} s wall clock"
        + (f" ({t_end / result.wall_clock_s:.1f}x real time)" if result.wall_clock_s > 0 else "")
    ]
    lines += [f"  {name:<10} {path}" for name, path in outcome.paths.items()]
    figures = key_figures(result)
    lines.append("  " + ", ".join(f"{k} = {_fmt(v)}" for k, v in figures.items()))
    for name, messages in result.messages.items():
        lines += [f"  {name} logged: {message}" for message in messages[:MESSAGES_SHOWN]]
        if len(messages) > MESSAGES_SHOWN:
            lines.append(f"  {name} logged {len(messages) - MESSAGES_SHOWN} more (summary.json)")
    return "\n".join(lines)


def _fmt(value: float | None) -> str:
    return "n/a" if value is None else f"{value:.4g}"


def _open_sink(scenario: Scenario, rrd_path: Path | None, connect: str | None) -> Any:
    """The Rerun sink (cosim.viz.recording), or None if nothing is to be recorded."""
    if rrd_path is None and connect is None:
        return None
    try:
        from cosim.viz.recording import RerunSink
    except ImportError as exc:
        warnings.warn(
            f"no Rerun recording: cannot import cosim.viz.recording ({exc})", stacklevel=2
        )
        return None
    try:
        return RerunSink(rrd_path, connect, scenario.id, scenario.to_toml(), list(scenario.record))
    except (OSError, ValueError) as exc:
        raise CosimError(f"cannot start the Rerun recording: {exc}") from None


def _progress_bar(scenario: Scenario) -> Any:
    from tqdm import tqdm

    return tqdm(total=scenario.n_steps + 1, unit="step", desc=scenario.id, leave=False)
