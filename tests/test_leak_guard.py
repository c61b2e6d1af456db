"""The suite's guard against tests that leave their pytest process changed
(tests/conftest.py): a test that leaves SIGINT ignored, a signal blocked or a child process
running fails at its teardown, naming what it left, and the tests after it are not blamed.
Before, a slow test left SIGINT ignored in its xdist worker; a later test's child inherited
it, ignored Ctrl-C and timed out after 60 s, far from the test that caused it.
``--leak-check`` (tests/leak_check.py) lists what else a test leaves behind.

The cases are one pytest run in a process of its own (this repository's ini file and
conftest.py), ended with its process group."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from process_group import run_in_group, started_in_group
from process_state import new_children
from repo_paths import ROOT

CASES = """
import os
import signal
import subprocess

def test_ignores_sigint():
    signal.signal(signal.SIGINT, signal.SIG_IGN)

def test_blocks_sigterm():
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGTERM})

def test_leaves_a_child():
    subprocess.Popen(["sleep", "60"])

def test_after_them():
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.SIGTERM not in signal.pthread_sigmask(signal.SIG_BLOCK, [])

def test_sets_a_variable():
    os.environ["LEAK_GUARD_CASE"] = "left"

def test_ends_its_child():
    child = subprocess.Popen(["sleep", "60"])
    child.kill()
    child.wait()
"""


def _pytest(folder: Path, *options: str):
    (folder / "test_case.py").write_text(CASES)
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "conftest",
               "-c", str(ROOT / "pyproject.toml"), "--rootdir", str(folder),
               *options, str(folder / "test_case.py")]  # fmt: skip
    env = {"PYTHONPATH": f"{ROOT}:{ROOT / 'tests'}", "PATH": "/usr/bin:/bin", "COLUMNS": "1000"}
    return run_in_group(command, timeout=300, env=env, cwd=folder, preexec_fn=_sigint_default)


def _sigint_default() -> None:
    """In the child before its exec: SIGINT as an interactive shell leaves it, so that
    the cases' Python starts with its own handler even where this suite was started with
    SIGINT ignored (a background job), which would hide the case that ignores it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.slow  # a child left running is waited for 5 s
def test_a_test_leaving_signals_or_a_child_fails_naming_what_it_left(tmp_path: Path) -> None:
    report = tmp_path / "leaks.jsonl"
    done = _pytest(tmp_path, "--leak-check", "--leak-report", str(report))
    errors = dict(re.findall(r"^ERROR test_case.py::(\w+) - Failed: (.*)$", done.stdout, re.M))
    assert set(errors) == {"test_ignores_sigint", "test_blocks_sigterm", "test_leaves_a_child"}
    assert re.fullmatch(
        r"the test left SIGINT's handler: \S*default_int_handler -> SIG_IGN; SIGINT newly ignored",
        errors["test_ignores_sigint"],
    )
    assert errors["test_blocks_sigterm"] == "the test left SIGTERM newly blocked"
    assert errors["test_leaves_a_child"].startswith("the test left child process ")
    assert errors["test_leaves_a_child"].endswith(" running: [S] sleep 60")
    assert "6 passed, 3 errors" in done.stdout, done.stdout
    listed = [json.loads(line) for line in report.read_text().splitlines()]
    variable = [r for r in listed if r["test"].endswith("::test_sets_a_variable")]
    assert variable and variable[0]["environ"] == {"LEAK_GUARD_CASE": "None -> left"}
    assert not [r for r in listed if r["test"].endswith("::test_ends_its_child")]


def test_a_fork_server_of_a_python_run_with_warning_options_is_the_process_s() -> None:
    """The multiprocessing helpers a study leaves (fork server, resource tracker) are the
    process's, not a test's, also under ``python -W error::DeprecationWarning ...``: the
    options are passed on to the helpers and push ``import main`` past the 160 characters
    of a command line the guard shows, which failed every study test at its teardown."""
    flags = ["-W", "error::DeprecationWarning", "-W", "error::FutureWarning"]
    flags += ["-W", "error::PendingDeprecationWarning"]
    code = "from multiprocessing.forkserver import main; print(flush=True); input()"
    with started_in_group(
        [sys.executable, "-B", *flags, "-c", code], stdin=subprocess.PIPE
    ) as helper:
        assert helper.stdout is not None and helper.stdout.readline() == "\n"  # exec'd
        assert helper.pid not in new_children({})
