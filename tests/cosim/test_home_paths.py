"""A path starting with ``~`` where no shell expanded it (``--out=~/x``, a study file's
scenario) is the home folder's, as the Python API's paths are (cosim/scenario/arguments.py:
home_expanded); a ``~user`` with no home folder is refused, never made a folder named ``~``
in the working folder."""

from __future__ import annotations

from pathlib import Path

import pytest

import cosim
from cosim.cli import build_parser, main
from cosim.study.runner import _scenario_ref
from cosim.study.spec import StudyError

NO_USER = "~no-such-user-of-auv-cosim"


@pytest.fixture
def home(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """HOME set to a folder of the test's own, and the working folder another."""
    home, work = tmp_path / "home", tmp_path / "work"
    home.mkdir()
    work.mkdir()
    monkeypatch.setenv("HOME", str(home))
    monkeypatch.chdir(work)
    return home


@pytest.mark.parametrize(
    "argv",
    [
        ["sweep", "study.toml", "--out=~/studies/a"],
        ["run", "bs-3", "--out=~/studies/a"],
        ["build", "--out=~/studies/a"],
    ],
)
def test_an_option_written_with_equals_takes_the_home_folder(home: Path, argv: list[str]) -> None:
    """``--out=~/x`` reaches the command unexpanded (a shell expands ``~`` only at the
    start of a word): it named a folder ``~`` in the working folder."""
    assert build_parser().parse_args(argv).out == home / "studies" / "a"


def test_an_option_with_a_home_folder_no_user_has_is_refused(
    home: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--out=~nosuchuser/x`` is a usage error naming it, nothing made."""
    with pytest.raises(SystemExit) as ended:
        main(["run", "bs-3", f"--out={NO_USER}/x", "--no-rrd"])
    assert ended.value.code == 2
    err = capsys.readouterr().err
    assert f"no home folder for {NO_USER!r}" in err, err
    assert list(Path.cwd().iterdir()) == []


def test_a_study_files_scenario_under_the_home_folder_is_found(home: Path, tmp_path: Path) -> None:
    """``scenario = "~/my.toml"`` in a study file was looked for as ``./~/my.toml``."""
    (home / "my.toml").write_text("", encoding="utf-8")
    assert _scenario_ref("~/my.toml", tmp_path) == str(home / "my.toml")
    assert _scenario_ref("bs-3", tmp_path) == "bs-3"


def test_a_study_files_scenario_under_no_home_folder_is_refused(home: Path, tmp_path: Path) -> None:
    """A study's scenario ``~nosuchuser/s.toml`` is refused saying there is no home
    folder for that user (it said "no such file" of a path in the working folder)."""
    study = {"scenario": f"{NO_USER}/s.toml", "grid": {"plant.v_0": [0.0, 0.1]}}
    with pytest.raises(StudyError, match=f"scenario = '{NO_USER}/s.toml': no home folder for"):
        cosim.sweep(study, out=tmp_path / "out", workers=1)
