"""scripts/cross_check_files.py: the files the FMI cross-check asks of an exported FMU
(``<Model>.fmu``, ``_in.csv``, ``_ref.csv``, ``_ref.opt`` in the vendor folder's layout),
passing fmpy's checker of vendor folders, and an importer's run of each FMU alone (fmpy's
cross-check simulation, at output points of its own) within the cross-check's band of the
reference. ``tests/cosim/fmus/test_compliance_checker.py`` runs the FMU Compliance
Checker on them where it is built."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any

import pytest
from fmpy import read_model_description
from fmpy.cross_check.validate_vendor_repo import read_csv
from fmpy.util import read_ref_opt_file
from process_group import run_in_group
from process_state import running
from repo_paths import ROOT

SCRIPT = ROOT / "scripts" / "cross_check_files.py"
RUN_S = 600.0  # s: the scenario's run and two fmpy runs of 10 s (a few seconds)

IMPORTER = """
import sys
from fmpy import simulate_fmu
from fmpy.cross_check import validate_result
from fmpy.cross_check.validate_vendor_repo import read_csv
from fmpy.util import read_ref_opt_file

folder, model = sys.argv[1], sys.argv[2]
opts = read_ref_opt_file(f"{folder}/{model}_ref.opt")
reference = read_csv(f"{folder}/{model}_ref.csv")
# as fmpy.cross_check's simulate() runs an FMU (its __main__ parses arguments on import)
result = simulate_fmu(f"{folder}/{model}.fmu", validate=False, step_size=opts["StepSize"],
                      stop_time=opts["StopTime"], input=read_csv(f"{folder}/{model}_in.csv"),
                      output=reference.dtype.names[1:])
print(validate_result(result, reference, opts["StartTime"], opts["StopTime"]))
"""


@pytest.mark.slow
def test_each_fmu_of_a_scenario_gets_files_an_importer_reproduces(
    fmu_dir: Path, tmp_path: Path, run_python: Any
) -> None:
    """bs-3 for 10 s at 0.1 s: the plant's and the autopilot's folders, each passing fmpy's
    checks (the script exits 0 only then); the inputs are the FMU's inputs, the reference
    its outputs, the options the run's; fmpy's cross-check run of the FMU with the inputs
    (which outputs every 0.08 s, not at the reference's points) is within the band."""
    command = [sys.executable, SCRIPT, "bs-3", "--out", tmp_path, "--stop-time", "10"]
    done = run_in_group([*command, "--fmu-dir", fmu_dir], timeout=RUN_S, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    folders = sorted((tmp_path / "fmus" / "2.0" / "cs" / "linux64" / "auv-cosim").glob("*/*"))
    assert [f.name for f in folders] == ["AuvAutopilot", "AuvPlant"]
    for folder in folders:
        model = folder.name
        variables = read_model_description(str(folder / f"{model}.fmu")).modelVariables
        inputs = read_csv(str(folder / f"{model}_in.csv"))
        reference = read_csv(str(folder / f"{model}_ref.csv"))
        assert inputs.dtype.names[1:] == tuple(v.name for v in variables if v.causality == "input")
        assert reference.dtype.names[1:] == tuple(
            v.name for v in variables if v.causality == "output"
        )
        assert len(inputs) == len(reference) == 101
        options = read_ref_opt_file(str(folder / f"{model}_ref.opt"))
        assert (options["StartTime"], options["StopTime"], options["StepSize"]) == (0, 10, 0.1)
        imported = run_python(IMPORTER, folder, model)
        assert imported.returncode == 0, imported.stderr[-3000:]
        assert imported.stdout.strip().splitlines()[-1] == "None"


def test_a_step_that_does_not_divide_the_stop_time_is_refused_in_one_line(
    fmu_dir: Path, tmp_path: Path
) -> None:
    command = [sys.executable, SCRIPT, "bs-3", "--out", tmp_path, "--step", "0.7"]
    done = run_in_group([*command, "--fmu-dir", fmu_dir], timeout=RUN_S, cwd=tmp_path)
    assert (done.returncode, done.stderr) == (
        1,
        "--step 0.7: expected a positive step that divides the stop time 60.0 s\n",
    )
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("stop_time", ["nan", "inf", "-5"])
def test_a_stop_time_that_is_no_positive_finite_time_is_refused_naming_it(
    fmu_dir: Path, tmp_path: Path, stop_time: str
) -> None:
    """Guards the script's check of its step and stop time: ``--stop-time nan`` (or inf)
    ended in a traceback (``round`` of nan), and ``--stop-time -5`` was blamed on ``--step
    0.1``. The stop time is refused in one line naming it, before any file is written."""
    command = [sys.executable, SCRIPT, "bs-3", "--out", tmp_path / "xc", f"--stop-time={stop_time}"]
    done = run_in_group([*command, "--fmu-dir", fmu_dir], timeout=RUN_S, cwd=tmp_path)
    assert (done.returncode, done.stderr) == (
        1,
        f"--stop-time {float(stop_time)}: expected a positive finite time (s)\n",
    )
    assert not (tmp_path / "xc").exists()


@pytest.mark.slow
def test_a_step_between_the_runs_points_is_refused_in_one_line(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """Guards the inputs file against rows missing: at ``--step 0.015`` the run of bs-3 (at
    0.01 s) has inputs every 0.03 s only, and ``_in.csv`` had 101 rows to the reference's
    201 (the importer interpolating the rest), without a word. Such a step is refused
    before the run, naming the scenario's step."""
    command = [sys.executable, SCRIPT, "bs-3", "--out", tmp_path / "xc", "--step", "0.015"]
    done = run_in_group([*command, "--fmu-dir", fmu_dir], timeout=RUN_S, cwd=tmp_path)
    assert (done.returncode, done.stderr) == (
        1,
        "--step 0.015: expected a multiple of the scenario's step, 0.01 s (the inputs "
        "are known at its points only)\n",
    )
    assert not (tmp_path / "xc").exists()


def test_a_checker_that_does_not_finish_is_one_problem_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A checker that outlived its time ended the script in a traceback (subprocess's
    TimeoutExpired), the other FMUs unchecked; it is one problem line naming the FMU and
    the time it was given, and the checker is ended with whatever it started."""
    spec = importlib.util.spec_from_file_location("cross_check_files", SCRIPT)
    assert spec is not None and spec.loader is not None
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    monkeypatch.setattr(script, "CHECKER_S", 0.5)
    started = tmp_path / "started"
    checker = tmp_path / "fmuCheck.linux64"
    checker.write_text(f"#!/bin/sh\nsleep 60 &\necho $! > {started}\nwait\n")
    checker.chmod(0o755)
    problems = script.checker_problems(checker, tmp_path / "AuvPlant", 0.1, 1.0)
    assert problems == ["AuvPlant: the checker did not finish within 0.5 s"]
    assert running(int(started.read_text())) is None  # ended with the checker (its group)
