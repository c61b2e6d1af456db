"""The files the FMI cross-check (github.com/modelica/fmi-cross-check) asks of an exported
FMU, for each FMU of a built-in scenario, and their check.

    python scripts/cross_check_files.py SCENARIO --out DIR [--fmu-dir build/fmus]
        [--step 0.1] [--stop-time SECONDS] [--checker PATH/fmuCheck.linux64]

For each instance's FMU (the first instance of each), in the cross-check's layout
``DIR/fmus/2.0/cs/linux64/auv-cosim/<version>/<Model>/``:

* ``<Model>.fmu``, a copy;
* ``<Model>_in.csv``: the inputs that instance received in the scenario's run (the
  connected output driving it, else its recorded value), every ``--step`` s (a whole
  number of the scenario's steps, where the run has them);
* ``<Model>_ref.opt``: StartTime, StopTime, StepSize (the communication step) and RelTol
  (which our FMUs ignore: they have no error-controlled integrator);
* ``<Model>_ref.csv``: every output of the FMU run alone by fmpy with these inputs and
  its own start values, as an importing tool runs it (the rules give it no parameters:
  the scenario's start values are not the FMU's, so this is not the scenario's run).

Each folder is then checked by fmpy's checker of vendor folders (file sizes, the
modelDescription.xml against the schema, the option file, the CSVs' time and names);
with ``--checker``, the FMU Compliance Checker (another importer, on FMI Library) steps
each FMU with ``<Model>_in.csv`` and its result is compared with ``<Model>_ref.csv`` by
the cross-check's own criterion (fmpy's ``validate_result``) and to the largest
difference relative to max(1, |value|). Exit status 0 when every check passed, 1 when
one failed (each problem one line on stderr).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd
from fmpy import read_model_description, simulate_fmu
from fmpy.cross_check import validate_result
from fmpy.cross_check.validate_vendor_repo import read_csv, validate_test_fmu

import cosim
from cosim.paths import DEFAULT_FMU_DIR
from cosim.scenario.spec import Scenario

REL_TOL = 1e-4  # the option file's RelTol: required by the rules, ignored by our FMUs
CHECKER_S = 600.0  # s: one checker run (60 s of the plant at 0.1 s takes about 2 s)


def instance_inputs(scenario: Scenario, results: pd.DataFrame, instance: str) -> pd.DataFrame:
    """The inputs ``instance`` received in a run of ``scenario`` (its ``results``, indexed
    by time): each connected input its source's column, each other input its own."""
    sources = {
        c.target_variable: c.source for c in scenario.connections if c.target_instance == instance
    }
    columns = {}
    for variable in scenario.instances[instance].interface.variables.values():
        if variable.causality == "input":
            column = sources.get(variable.name, f"{instance}.{variable.name}")
            columns[variable.name] = results[column].to_numpy(dtype=float)
    return pd.DataFrame(columns, index=results.index)


def write_model_folder(
    fmu: Path, inputs: pd.DataFrame, folder: Path, step: float, stop_time: float
) -> None:
    """One FMU's cross-check files in ``folder``, its reference run by fmpy."""
    model = fmu.stem
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(fmu, folder / fmu.name)
    sampled = inputs[np.isclose(np.remainder(inputs.index + step / 2, step), step / 2)]
    sampled = sampled[sampled.index <= stop_time + step / 2]
    sampled.index = np.round(sampled.index / step) * step  # times on the step grid, exactly
    sampled.to_csv(folder / f"{model}_in.csv", index_label="time")
    (folder / f"{model}_ref.opt").write_text(
        f"StartTime, 0.0\nStopTime, {stop_time!r}\nStepSize, {step!r}\nRelTol, {REL_TOL!r}\n"
    )
    outputs = [
        v.name for v in read_model_description(str(fmu)).modelVariables if v.causality == "output"
    ]
    result = simulate_fmu(
        str(fmu),
        stop_time=stop_time,
        step_size=step,
        output_interval=step,
        input=read_csv(str(folder / f"{model}_in.csv")),
        output=outputs,
    )
    pd.DataFrame({name: result[name] for name in result.dtype.names}).to_csv(
        folder / f"{model}_ref.csv", index=False
    )


def checker_problems(checker: Path, folder: Path, step: float, stop_time: float) -> list[str]:
    """The FMU Compliance Checker's run of ``folder``'s FMU with its inputs against its
    reference: each problem one line; prints the largest relative difference."""
    model = folder.name
    with tempfile.TemporaryDirectory() as scratch:
        csv, log = Path(scratch) / "cc.csv", Path(scratch) / "cc.log"
        flags = ["-l", "3", "-h", repr(step), "-s", repr(stop_time), "-n", "0"]
        files = ["-i", folder / f"{model}_in.csv", "-o", csv, "-e", log, folder / f"{model}.fmu"]
        done = _run_checker([str(part) for part in (checker, *flags, *files)])
        if done is None:
            return [f"{model}: the checker did not finish within {CHECKER_S:g} s"]
        text = log.read_text() if log.exists() else done.stderr
        if done.returncode != 0 or "\t0 Warning(s)\n\t0 Error(s)" not in text:
            return [
                f"{model}: the checker reported (exit {done.returncode}): {text.strip()[-500:]}"
            ]
        result, reference = read_csv(str(csv)), read_csv(str(folder / f"{model}_ref.csv"))
    problem = validate_result(result=result, reference=reference, t_start=0.0, t_stop=stop_time)
    if problem is not None:
        return [f"{model}: {problem}"]
    if len(result) == len(reference):
        worst = max(
            float(np.max(np.abs(result[n] - reference[n]) / np.maximum(1.0, np.abs(reference[n]))))
            for n in reference.dtype.names
        )
        print(f"{model}: the checker's result is within the cross-check's band; largest "
              f"difference {worst:.1e} of max(1, |value|)")  # fmt: skip
    return []


def _run_checker(command: list[str]) -> subprocess.CompletedProcess[str] | None:
    """``command`` run to its end in a process group of its own; None if it did not end
    within :data:`CHECKER_S` (the group is killed either way: subprocess.run's timeout
    kills the checker only, not what it started)."""
    proc = subprocess.Popen(
        command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
    )
    try:
        out, err = proc.communicate(timeout=CHECKER_S)
    except subprocess.TimeoutExpired:
        return None
    finally:
        with contextlib.suppress(ProcessLookupError):  # the group may have ended on its own
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    return subprocess.CompletedProcess(command, proc.returncode, out, err)


def step_problem(scenario: Scenario, step: float, stop_time: float) -> str | None:
    """Why ``step`` (s) cannot be the cross-check's step for a run of ``scenario`` to
    ``stop_time`` (s), one line; None if it can: it must divide the stop time, and be a
    whole number of the scenario's steps (the inputs are known at its points only)."""
    steps = stop_time / step if step > 0 else 0.0
    if steps < 1 or not np.isclose(round(steps), steps):
        return f"--step {step}: expected a positive step that divides the stop time {stop_time} s"
    h = scenario.coupling.step
    if not np.isclose(round(step / h), step / h, rtol=0.0, atol=1e-9):
        return (
            f"--step {step}: expected a multiple of the scenario's step, {h} s (the inputs "
            "are known at its points only)"
        )
    return None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("scenario", help="a built-in scenario id or a scenario .toml")
    parser.add_argument("--out", type=Path, required=True, help="the vendor folder to write")
    parser.add_argument("--fmu-dir", type=Path, default=Path(DEFAULT_FMU_DIR))
    parser.add_argument("--step", type=float, default=0.1, help="s, the communication step")
    parser.add_argument("--stop-time", type=float, default=None, help="s [the scenario's]")
    parser.add_argument("--checker", type=Path, default=None, help="fmuCheck.linux64 to try")
    args = parser.parse_args(argv)
    scenario = cosim.load_scenario(args.scenario, fmu_dir=args.fmu_dir)
    stop_time = float(scenario.stop_time if args.stop_time is None else args.stop_time)
    if not (math.isfinite(stop_time) and stop_time > 0):  # (a scenario's is: checked)
        print(f"--stop-time {stop_time}: expected a positive finite time (s)", file=sys.stderr)
        return 1
    problem = step_problem(scenario, args.step, stop_time)
    if problem is not None:
        print(problem, file=sys.stderr)
        return 1
    run = cosim.run(scenario, stop_time=stop_time, recording=False)
    base = args.out / "fmus" / "2.0" / "cs" / "linux64" / "auv-cosim" / cosim.__version__
    problems: list[str] = []
    done: set[Path] = set()
    for name, instance in run.scenario.instances.items():
        if instance.fmu_path in done:
            continue
        done.add(instance.fmu_path)
        folder = base / instance.fmu_path.stem
        inputs = instance_inputs(run.scenario, run.results, name)
        write_model_folder(instance.fmu_path, inputs, folder, args.step, stop_time)
        problems += validate_test_fmu(str(folder))
        if args.checker is not None:
            problems += checker_problems(args.checker, folder, args.step, stop_time)
        print(folder)
    for problem in problems:
        print(problem, file=sys.stderr)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
