"""Dask settings from the environment that Dask cannot use are refused in one line before a
study's cluster starts (cosim/study/dask_settings.py), not met as Dask's tracebacks."""

from __future__ import annotations

import os

import dask.config
import pytest

from cosim.study.dask_settings import check_dask_settings
from cosim.study.spec import StudyError

# the command with a variable set before Dask reads its configuration (as it is imported)
WITH_VARIABLE = """
import os, sys
name, value = sys.argv[1].split("=", 1)
os.environ[name] = value
sys.argv = ["auv-cosim", *sys.argv[2:]]
from cosim.cli import main

sys.exit(main())
"""
STUDY = """
scenario = "bs-3"
stop_time = 0.2
[grid]
"plant.v_0" = [-0.10, 0.10]
"""


@pytest.mark.slow
@pytest.mark.cluster
@pytest.mark.parametrize(
    ("variable", "expected"),
    [
        ("DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc", "expected a duration"),
        ("DASK_DISTRIBUTED__WORKER__MEMORY__TARGET=lots", "expected a fraction"),
    ],
)
def test_sweep_refuses_a_dask_setting_dask_cannot_use_in_one_line(
    run_python, tmp_path, fmu_dir, variable, expected
) -> None:
    """``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc auv-cosim sweep`` printed Dask's
    KeyError traceback ("Invalid time unit: abc") as the client connected, and a memory
    target of ``lots`` "RuntimeError: Nanny failed to start" after every worker's
    traceback: now one line naming the variable, its value and what was expected, exit 1
    (the study could not run), nothing written."""
    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    args = ["sweep", study, "--out", out, "--fmu-dir", fmu_dir, "--workers", "1", "--quiet"]
    done = run_python(WITH_VARIABLE, variable, *args)
    name, value = variable.split("=")
    assert done.returncode == 1, done.stderr[-2000:]
    lines = done.stderr.splitlines()
    assert len(lines) == 1, done.stderr[-2000:]
    assert lines[0].startswith(f"auv-cosim sweep: {name}={value!r}: {expected}"), lines
    assert not out.exists()


@pytest.mark.parametrize(
    ("key", "value", "expected"),
    [
        ("distributed.comm.timeouts.tcp", "30 parsecs", "expected a duration"),
        ("distributed.scheduler.worker-ttl", [5], "expected a duration"),
        ("distributed.comm.shard", "big", "expected a size"),
        ("distributed.worker.memory.pause", 1.5, "expected a fraction"),
        ("distributed.worker.memory.spill", True, "expected a fraction"),
        ("distributed.scheduler.allowed-failures", "3", "expected a whole number"),
    ],
)
def test_a_setting_dask_cannot_use_is_named_with_its_value(
    monkeypatch: pytest.MonkeyPatch, key: str, value: object, expected: str
) -> None:
    """A setting from a Dask configuration file (no variable set it) is named by its key."""
    for name in [n for n in os.environ if n.startswith("DASK_")]:
        monkeypatch.delenv(name)
    with dask.config.set({key: value}), pytest.raises(StudyError) as raised:
        check_dask_settings()
    assert str(raised.value).startswith(f"Dask setting {key}=")
    assert expected in str(raised.value)


def test_the_variable_that_set_a_setting_is_named(monkeypatch: pytest.MonkeyPatch) -> None:
    """Dask takes ``_`` for ``-`` in a variable's name: the refusal names the variable."""
    monkeypatch.setenv("DASK_DISTRIBUTED__SCHEDULER__WORKER_TTL", "soon")
    refusal = r"^DASK_DISTRIBUTED__SCHEDULER__WORKER_TTL='soon'"
    with (
        dask.config.set({"distributed.scheduler.worker-ttl": "soon"}),
        pytest.raises(StudyError, match=refusal),
    ):
        check_dask_settings()


@pytest.mark.parametrize(
    "settings",
    [
        {},  # Dask's defaults
        {"distributed.comm.timeouts.connect": 10, "distributed.worker.memory.target": False},
        {"distributed.scheduler.idle-timeout": None, "distributed.comm.offload": False},
        {"distributed.comm.shard": "1 GiB", "distributed.worker.memory.terminate": 1},
    ],
)
def test_settings_dask_reads_pass(settings: dict[str, object]) -> None:
    """Dask's defaults, numbers of seconds, None (no limit) and False (off) all pass."""
    with dask.config.set(settings):
        check_dask_settings()
