"""Fixtures of the run-output tests: the master tests' loop as a scenario file."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_factory import write_loop_file


@pytest.fixture
def loop_file(test_fmu_dir: Path, tmp_path: Path) -> Path:
    """``tmp_path/loop.toml``: the loop of the test FMUs (tests/fmus), id "loop"."""
    return write_loop_file(tmp_path, test_fmu_dir)
