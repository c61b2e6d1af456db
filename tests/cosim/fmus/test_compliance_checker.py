"""The FMU Compliance Checker (github.com/modelica-tools/FMUComplianceChecker, on FMI
Library 2.x) on the built FMUs, as a tool vendor or the FMI cross-check runs it: its
default run (the model description parsed and checked, the FMU instantiated, initialised,
stepped to the default experiment's stop time reading every output at each of its 500
output points, terminated and freed) and a run with an input file from
``scripts/cross_check_files.py`` against the reference fmpy writes there.

The checker is not built here: CI has no copy of its sources. Build it as docs/hosts.md
says and name its executable in ``FMU_COMPLIANCE_CHECKER`` (or put ``fmuCheck.linux64``
on PATH); without it these tests skip. The rules it applies to the model description are
checked everywhere by ``test_fmi_compliance.py``.
"""

from __future__ import annotations

import csv
import math
import os
import shutil
import sys
from pathlib import Path

import pytest
from fmpy import read_model_description
from process_group import run_in_group
from repo_paths import ROOT

from cosim.fmus.build import FMUS

CHECKER_S = 600.0  # s: one run of the checker (60 s of the plant: about 2 s)
CLEAN = "Checker reported:\n\t0 Warning(s)\n\t0 Error(s)"


def _checker() -> Path | None:
    named = os.environ.get("FMU_COMPLIANCE_CHECKER") or shutil.which("fmuCheck.linux64")
    return Path(named) if named and os.access(named, os.X_OK) else None


CHECKER = _checker()
needs_checker = pytest.mark.skipif(
    CHECKER is None,
    reason="the FMU Compliance Checker is not built: set FMU_COMPLIANCE_CHECKER to its "
    "fmuCheck.linux64 (docs/hosts.md says how to build it)",
)


def check(fmu: Path, out: Path, *options: str) -> tuple[str, list[list[str]]]:
    """The checker's log and its CSV rows (the header first) for ``fmu`` with
    ``options``; fails the test where it exits non-zero."""
    log, result = out / f"{fmu.stem}.log", out / f"{fmu.stem}.csv"
    command = [str(CHECKER), "-l", "3", *options, "-e", str(log), "-o", str(result), str(fmu)]
    environ = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}  # as a user's shell
    done = run_in_group(command, timeout=CHECKER_S, env=environ)
    text = log.read_text() if log.exists() else done.stderr
    assert done.returncode == 0, text[-3000:]
    with result.open(newline="") as rows:
        return text, list(csv.reader(rows))


@needs_checker
@pytest.mark.parametrize("name", sorted(FMUS))
def test_the_checkers_default_run_finds_nothing_and_every_output_is_finite(
    name: str, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """No warning or error of the checker's, none of the FMU's above Warning (the plant,
    started at the surface by its own start values, says its hull leaves the water); the
    result has every output, in the order of the model description, from t = 0 to the
    default stop time at its 500 output points, every value finite. (The checker drops a
    point where its summed time falls a rounding error short of its output grid: 9.24 s of
    the 0.12 s steps to 60 s.)"""
    text, rows = check(fmu_paths[name], tmp_path)
    md = read_model_description(str(fmu_paths[name]))
    assert CLEAN in text, text[-3000:]
    assert "logStatusError" not in text and "logStatusFatal" not in text, text[-3000:]
    outputs = [v.name for v in md.modelVariables if v.causality == "output"]
    assert rows[0] == ["time", *outputs]
    times = [float(r[0]) for r in rows[1:]]
    assert times[0] == 0.0 and len(times) in (500, 501)
    assert math.isclose(times[-1], float(md.defaultExperiment.stopTime))
    assert [r[0] for r in rows[1:] if not all(math.isfinite(float(x)) for x in r)] == []


@needs_checker
@pytest.mark.slow
def test_the_checker_with_the_cross_check_inputs_reproduces_their_reference(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """``scripts/cross_check_files.py --checker``: the checker (FMI Library, C) steps each
    FMU of bs-3 alone with its ``_in.csv`` and gives fmpy's ``_ref.csv`` within the
    cross-check's criterion."""
    script = ROOT / "scripts" / "cross_check_files.py"
    command = [sys.executable, script, "bs-3", "--out", tmp_path / "xc", "--stop-time", "10"]
    command += ["--fmu-dir", fmu_dir, "--checker", CHECKER]
    done = run_in_group(command, timeout=CHECKER_S, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.count("within the cross-check's band") == 2, done.stdout
