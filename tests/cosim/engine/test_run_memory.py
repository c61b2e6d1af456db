"""A run's memory does not grow with its stop time (a regression: vert-2 --stop-time 3600 took
250 MB while stepping and 1.21 GB while writing its results.csv).

scripts/bench_memory.py measures the reported pair (vert-2 at 3600 s against 60 s, with the
recording: within 50 MB); here a shorter pair, the recording left out (rerun's file footer
index grows slowly with every send, see cosim/viz/recording.py), with the same bound in
proportion: 50 MB per 3540 s of stop time."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
from repo_paths import ROOT

SHORT, LONG = 20.0, 200.0  # s of vert-2
BOUND_MB = 50.0 * (LONG - SHORT) / (3600.0 - 60.0)


def _bench_memory():
    spec = importlib.util.spec_from_file_location("bench_memory", ROOT / "scripts/bench_memory.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_peak_memory_does_not_grow_with_the_stop_time(fmu_paths, tmp_path: Path):
    fmu_dir = fmu_paths["AuvAutopilot"].parent
    peak = _bench_memory().peak_rss_mb
    short = peak("vert-2", SHORT, tmp_path / "short", fmu_dir, "--no-rrd")
    long = peak("vert-2", LONG, tmp_path / "long", fmu_dir, "--no-rrd")
    assert long - short < BOUND_MB, f"{short:.1f} MB at {SHORT:g} s, {long:.1f} MB at {LONG:g} s"
    assert short > 50.0  # measured what it should: a whole run with its FMUs
