"""A TOML file read or refused in one line, the same for every reader of a user's file:
the problem said without the file's name, which each reader puts before it."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import load_scenario
from cosim.scenario.toml_file import UnreadableTomlError, read_toml_file
from cosim.study.spec import StudyError, load_study

UNREADABLE = {  # file content -> how the problem starts
    "invalid": (b"stop_time = 0,26\n", "not valid TOML: "),
    "latin-1": ("a = 'caf\u00e9'\n".encode("latin-1"), "not UTF-8 text: byte 0xe9 at line 1"),
    "utf-16": ("a = 1\n".encode("utf-16"), "not UTF-8 text but UTF-16"),
}


def test_a_file_with_a_byte_order_mark_reads_as_its_table(tmp_path: Path) -> None:
    path = tmp_path / "bom.toml"
    path.write_bytes(b"\xef\xbb\xbfstop_time = 2.0\n")
    assert read_toml_file(path) == {"stop_time": 2.0}


@pytest.mark.parametrize("kind", sorted(UNREADABLE))
def test_an_unreadable_file_is_one_line_without_its_name(tmp_path: Path, kind: str) -> None:
    content, start = UNREADABLE[kind]
    path = tmp_path / "bad.toml"
    path.write_bytes(content)
    with pytest.raises(UnreadableTomlError) as caught:
        read_toml_file(path)
    assert str(caught.value).startswith(start)
    assert "\n" not in str(caught.value) and str(path) not in str(caught.value)


def test_a_folder_cannot_be_read(tmp_path: Path) -> None:
    with pytest.raises(UnreadableTomlError, match=r"^cannot read it: "):
        read_toml_file(tmp_path)


@pytest.mark.parametrize("kind", sorted(UNREADABLE))
def test_scenario_and_study_files_say_the_same_of_the_same_slip(tmp_path: Path, kind: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_bytes(UNREADABLE[kind][0])
    with pytest.raises(ScenarioError) as scenario:
        load_scenario(path)
    with pytest.raises(StudyError) as study:
        load_study(path)
    assert str(scenario.value) == f"scenario file {path}: {_problem(path)}"
    assert str(study.value) == f"study file {path}: {_problem(path)}"


def _problem(path: Path) -> str:
    with pytest.raises(UnreadableTomlError) as caught:
        read_toml_file(path)
    return str(caught.value)
