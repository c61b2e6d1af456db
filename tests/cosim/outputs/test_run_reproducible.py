"""The same run twice, from processes whose environments differ in what must not matter
(hash seed, locale, time zone, BLAS/OpenMP thread counts, working folder): the same
results.csv bytes, and a summary.json differing only in the keys docs/runs.md says vary
("The same run twice")."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT

import cosim

# What docs/runs.md says differs between two runs of one scenario in one place
VARIES = {"pid", "wall_clock_s", "real_time_factor", "startup_s", "startup_total_s"}
THREADS = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")
ENVIRONMENTS = {
    "a": {"PYTHONHASHSEED": "1", "LC_ALL": "C", "TZ": "UTC", **dict.fromkeys(THREADS, "1")},
    "b": {"PYTHONHASHSEED": "4242", "LC_ALL": "C.UTF-8", "TZ": "Etc/GMT-9"}
    | dict.fromkeys(THREADS, "2"),
}


def _run(name: str, fmu_dir: Path, tmp_path: Path) -> Path:
    """bs-3 for 2 s from a working folder of its own, in environment ``name``."""
    cwd = tmp_path / f"cwd-{name}"
    cwd.mkdir()
    out = tmp_path / f"run-{name}"
    packages = str(Path(cosim.__file__).resolve().parents[1])
    env = {**os.environ, **ENVIRONMENTS[name], "PYTHONPATH": packages}
    command = [sys.executable, "-m", "cosim", "run", "bs-3", "--stop-time", "2", "--no-rrd"]
    command += ["--quiet", "--fmu-dir", str(fmu_dir), "--out", str(out)]
    done = run_in_group(command, timeout=300, cwd=cwd, env=env)
    assert done.returncode == 0, done.stderr
    return out


@pytest.mark.slow
def test_a_run_writes_the_same_files_whatever_the_environment(fmu_paths, tmp_path):
    fmu_dir = fmu_paths["AuvPlant"].parent
    first, second = (_run(name, fmu_dir, tmp_path) for name in ENVIRONMENTS)
    assert (first / "results.csv").read_bytes() == (second / "results.csv").read_bytes()
    summaries = [json.loads((run / "summary.json").read_text("utf-8")) for run in (first, second)]
    differing = {key for key in summaries[0] if summaries[0][key] != summaries[1].get(key)}
    assert differing <= VARIES, f"summary.json keys differing: {sorted(differing - VARIES)}"
    assert set(summaries[0]) == set(summaries[1])


def test_the_keys_said_to_vary_are_the_ones_docs_runs_md_names():
    section = (ROOT / "docs" / "runs.md").read_text("utf-8").split("## The same run twice")[1]
    section = section.split("\n## ")[0]
    assert all(f"`{key}`" in section for key in VARIES)
    assert all(f"`{name}`" in section for name in THREADS)
