"""The workers' fork server imports what a study's runs use, and not what they do not: the
server's imports are the longer chain before a study's first run (docs/performance.md),
so each module a default run never uses delays every study. pyarrow (~0.025 s of CPU)
writes results.csv, which a study's runs write only with ``keep``; it is imported at the
first rows written, and writes them as before."""

from __future__ import annotations

import ast
import sys

import pytest
from process_group import run_in_group

PRELOAD_THEN_CSV = """
import importlib, sys
import numpy as np
from cosim.study.fork_server import PRELOAD
for name in PRELOAD[:-1]:  # the last one makes the server's exit skip the teardown
    importlib.import_module(name)
found = "pyarrow" in sys.modules
from cosim.outputs.results import csv_lines
written = csv_lines(np.array([0.0, 0.5]), np.array([[0.1, float("inf")], [2.5e-7, 1.0]]))
print(repr([found, written.decode()]))
"""


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="no fork server on Windows")
def test_the_fork_server_leaves_pyarrow_out_and_rows_are_written_as_before() -> None:
    done = run_in_group([sys.executable, "-c", PRELOAD_THEN_CSV], timeout=600)
    assert done.returncode == 0, done.stderr.strip().splitlines()[-3:]
    found, written = ast.literal_eval(done.stdout.strip().splitlines()[-1])
    assert not found, "the fork server imported pyarrow, which a study's runs do not use"
    assert written == "0,0.1,inf\n0.5,2.5e-7,1\n", "results.csv's rows changed"


PRELOAD_MODULES = """
import importlib, sys
from cosim.study.fork_server import PRELOAD
for name in PRELOAD[:-1]:  # the last one makes the server's exit skip the teardown
    importlib.import_module(name)
print(repr(sorted(name for name in ("scipy.optimize", "control") if name in sys.modules)))
"""


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="no fork server on Windows")
def test_the_fork_server_leaves_scipy_optimize_and_control_out() -> None:
    """The scenario's checks (cosim.scenario.design_doubts: a root of a delay margin) use
    scipy.optimize, ~0.4 s of CPU to import, only when a fault asks for it: imported with
    the module, it lengthened every study's start by that much."""
    done = run_in_group([sys.executable, "-c", PRELOAD_MODULES], timeout=600)
    assert done.returncode == 0, done.stderr.strip().splitlines()[-3:]
    assert ast.literal_eval(done.stdout.strip().splitlines()[-1]) == []
