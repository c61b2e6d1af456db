"""Random FMI 2.0 call sequences (``fmi_machine.py``, a Hypothesis state machine over
ctypes) on the plant and the autopilot, in a fresh process so that a crash or a hang
fails the test rather than killing the test process: every status in range, every
refusal logged, no NaN read after fmi2OK, no forbidden call, foreign state or garbled
bytes answered fmi2OK. The sequences that found defects are replayed first; the random
ones are derandomised (the same on every run)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from c_hosts import (
    SANITIZED_ENVIRONMENT,
    asan_preload,
    run_clean,
    sanitized_runtime,
    with_runtime,
)

MACHINE = Path(__file__).parent / "fmi_machine.py"
RUNTIMES = {"runtime": "", "pythonfmu": "pythonfmu"}
FUZZED = ("AuvPlant", "AuvAutopilot")
RUN = """
import os, sys
os.environ["AUV_FMU_RUNTIME"] = sys.argv[1]
sys.path.insert(0, os.path.dirname(sys.argv[2]))
import fmi_machine
fmi_machine.main(sys.argv[3], sys.argv[4], int(sys.argv[5]), int(sys.argv[6]))
"""


def check(done) -> None:
    """The machine replayed and ran its examples to the end: no failure, no crash, no
    sanitizer report."""
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-6000:]
    assert done.stdout.strip().endswith("fuzz: ok"), done.stdout[-2000:]
    assert "Sanitizer" not in done.stderr and "runtime error" not in done.stderr, done.stderr


def test_random_call_sequences_break_no_fmi_rule(fmu_paths, run_python):
    """A few short sequences with the FMUs' own runtime, in the fast tier."""
    done = run_python(RUN, "", MACHINE, *(fmu_paths[name] for name in FUZZED), 5, 25)
    check(done)


@pytest.mark.slow
@pytest.mark.parametrize("runtime", sorted(RUNTIMES))
def test_many_random_call_sequences_break_no_fmi_rule(runtime, fmu_paths, run_python):
    """Many longer sequences, with the FMUs' runtime and with pythonfmu's binary."""
    paths = (fmu_paths[name] for name in FUZZED)
    done = run_python(RUN, RUNTIMES[runtime], MACHINE, *paths, 150, 60, timeout=1800)
    check(done)


@pytest.mark.slow
def test_random_call_sequences_trip_no_sanitizer(extracted, tmp_path, clean_home):
    """The found sequences and a few random ones against the runtime built with ASan and
    UBSan, loaded by a Python that preloads ASan's library."""
    runtime = sanitized_runtime(tmp_path)
    folders = [with_runtime(extracted[name], runtime, tmp_path / name) for name in FUZZED]
    environment = {**SANITIZED_ENVIRONMENT, "LD_PRELOAD": asan_preload()}
    command = [sys.executable, "-c", RUN, "", MACHINE, *folders, 8, 40]
    check(run_clean(command, clean_home, timeout=1800, **environment))
