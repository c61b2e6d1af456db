"""pyproject.toml's dependency floors hold: a user whose environment already has older
libraries (pip keeps whatever satisfies the declared ranges) gets a working auv-cosim.
scripts/check_floors.py installs every direct dependency at its floor (uv's
``--resolution lowest-direct``) and runs bs-3 there and here, and a small study there."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT, script_module

UNAVAILABLE = script_module("check_floors").UNAVAILABLE


@pytest.mark.slow
@pytest.mark.cluster
def test_a_short_bs_3_at_the_dependency_floors_is_byte_identical_and_a_study_runs(
    tmp_path: Path,
) -> None:
    """At the floors pyproject declared, numba 0.60 failed every import of the compiled
    kernels, pandas 2.0 (built for numpy 1) failed writing any results table, and
    numpy 1.26, scipy 1.11 or pyarrow 14 could not install beside rerun-sdk 0.41: the
    floors install, run bs-3 to the same bytes as this environment, and run a study. A
    skip where the registry cannot be reached."""
    script = [sys.executable, ROOT / "scripts" / "check_floors.py", "--stop-time", "2"]
    done = run_in_group([*script, "--venv", tmp_path / "venv"], timeout=1500, cwd=tmp_path)
    if done.returncode == UNAVAILABLE:
        pytest.skip(done.stderr.strip()[-300:])
    assert done.returncode == 0, done.stderr[-3000:]
    assert "byte-identical" in done.stdout
