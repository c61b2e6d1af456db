"""scripts/host_pythons.py refuses bad arguments in one line before it builds or installs
anything (each of its rows makes virtual environments from the package registry)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT

SCRIPT = ROOT / "scripts" / "host_pythons.py"


@pytest.mark.parametrize(
    ("arguments", "said"),
    [
        (["--stop", "-5"], "--stop: -5.0 is not a positive finite number of seconds"),
        (["--stop", "nan"], "--stop: nan is not a positive finite number of seconds"),
        (["--work", "{file}"], "is not a folder"),
        (["--python", "/nonexistent/python3"], "--python: '/nonexistent/python3' is not an"),
    ],
)
def test_a_bad_argument_is_refused_before_anything_is_made(
    tmp_path: Path, arguments: list[str], said: str
) -> None:
    """`--stop -5` went on to build FMUs and install numpy into new environments, and
    `--work` naming a file ended in a NotADirectoryError traceback."""
    a_file = tmp_path / "a-file"
    a_file.write_text("")
    work = ["--work", str(tmp_path / "work")] if "--work" not in arguments else []
    given = [a.format(file=a_file) for a in arguments] + work
    done = run_in_group([sys.executable, str(SCRIPT), *given], timeout=60)
    assert done.returncode == 2, done.stderr
    assert said in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "work").exists()
