"""The suite's time limits (pyproject.toml, tests/conftest.py): pytest-timeout's per-test
limit does not count a shared fixture's set-up, which has a limit of its own. Before,
a session fixture set up under load (the Windows CPython under Wine: 498 s at load 20) ate
the 900 s of the test that first asked for it, which then timed out through no fault of its
own.

Each case is a pytest run in a process of its own (this repository's ini file and
conftest.py, small limits), ended with its process group."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT

SLOW_FIXTURE = """
import time
import pytest

@pytest.fixture(scope="session")
def shared():
    time.sleep(3)

def test_asks_for_it(shared):
    pass
"""


def _pytest(folder: Path, *options: str):
    (folder / "test_case.py").write_text(SLOW_FIXTURE)
    command = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "conftest",
               "-c", str(ROOT / "pyproject.toml"), "--rootdir", str(folder),
               *options, str(folder / "test_case.py")]  # fmt: skip
    env = {"PYTHONPATH": f"{ROOT}:{ROOT / 'tests'}", "PATH": "/usr/bin:/bin"}
    return run_in_group(command, timeout=300, env=env, cwd=folder)


@pytest.mark.slow
def test_a_slow_shared_fixture_is_not_counted_in_the_test_s_time_limit(tmp_path):
    done = _pytest(tmp_path, "--timeout", "1")
    assert re.search(r"^1 passed", done.stdout, re.M), done.stdout[-3000:] + done.stderr[-3000:]


@pytest.mark.slow
def test_a_fixture_past_its_set_up_limit_fails_the_test_naming_it(tmp_path):
    done = _pytest(tmp_path, "-o", "fixture_setup_timeout=1")
    assert re.search(r"^1 error", done.stdout, re.M), done.stdout[-3000:] + done.stderr[-3000:]
    assert "AssertionError: fixture shared: set-up not done after 1 s" in done.stdout
