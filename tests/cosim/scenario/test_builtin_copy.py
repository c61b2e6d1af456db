"""A built-in scenario copied to a file of one's own (``auv-cosim scenarios --copy ID
FILE``): the file as shipped, with its comments, which loads as the built-in does; a
mistyped id gets its likely meaning, and an existing file is never written over."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.cli import main
from cosim.scenario.spec import SCENARIO_FOLDER, ScenarioError

BS3 = SCENARIO_FOLDER / "bs-3.toml"


def test_a_copied_builtin_is_the_shipped_file_and_the_command_says_how_to_run_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """There was no way to get a built-in scenario's file but to find it in the installed
    package; ``auv-cosim scenarios --copy`` was refused as an unknown option."""
    copy = tmp_path / "my-bs3.toml"
    assert main(["scenarios", "--copy", "bs-3", str(copy)]) == 0
    assert copy.read_bytes() == BS3.read_bytes()
    out = capsys.readouterr().out
    assert f"auv-cosim run {copy}" in out, out


def test_a_mistyped_builtin_id_to_copy_gets_its_likely_meaning(tmp_path: Path) -> None:
    from cosim.scenario.builtin_copy import copy_builtin

    with pytest.raises(ScenarioError, match=r"unknown scenario 'bs3' \(did you mean 'bs-3'\?\)"):
        copy_builtin("bs3", tmp_path / "my.toml")
    assert list(tmp_path.iterdir()) == []


def test_a_copy_never_writes_over_an_existing_file(tmp_path: Path) -> None:
    """A student's edited copy, copied to again by a command run twice, would lose the
    edits: the copy is refused naming the file, which keeps its content."""
    from cosim.scenario.builtin_copy import copy_builtin

    mine = tmp_path / "my.toml"
    mine.write_text("# my edits\n")
    with pytest.raises(ScenarioError, match=r"my\.toml exists: .*another file name"):
        copy_builtin("bs-3", mine)
    assert mine.read_text() == "# my edits\n"


@pytest.mark.parametrize("name", ["my-bs3", "my-bs3.txt"])
def test_a_copy_not_named_toml_is_refused_saying_so(tmp_path: Path, name: str) -> None:
    """``auv-cosim run my-bs3`` reads a name without .toml as a built-in id: the copy is
    refused before it makes a file that a run would not find."""
    from cosim.scenario.builtin_copy import copy_builtin

    with pytest.raises(ScenarioError, match=r"expected a file name ending in \.toml"):
        copy_builtin("bs-3", tmp_path / name)
    assert list(tmp_path.iterdir()) == []
