"""cosim.whole_file: a file written whole through a temporary file beside it, which is this
process's own, never a link someone planted at its predictable name."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cosim.whole_file import write_whole


@pytest.mark.parametrize("plant", ["symlink", "dangling symlink", "hard link"])
def test_a_link_planted_at_the_temporary_name_is_not_written_through(
    plant: str, tmp_path: Path
) -> None:
    """The temporary file ``.<name>.<pid>.tmp`` has a name anyone can predict (the pid is
    in the run folder's lock file): a link planted there (a folder from elsewhere, a folder
    others can write) had the new content written over the file it named, or created
    where a dangling one pointed. The link goes; the file it names is untouched."""
    target, victim = tmp_path / "summary.json", tmp_path / "victim.txt"
    if plant != "dangling symlink":
        victim.write_text("precious line\n")
    planted = tmp_path / f".{target.name}.{os.getpid()}.tmp"
    if plant == "hard link":
        planted.hardlink_to(victim)
    else:
        planted.symlink_to(victim.name)
    write_whole(target, lambda tmp: tmp.write_text("the new summary\n"))
    assert target.read_text() == "the new summary\n" and not target.is_symlink()
    if plant == "dangling symlink":
        assert not victim.exists()
    else:
        assert victim.read_text() == "precious line\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        {target.name} | ({victim.name} if plant != "dangling symlink" else set())
    )


def test_a_failed_write_leaves_neither_file(tmp_path: Path) -> None:
    """A write that fails leaves the target as it was and no temporary file."""
    target = tmp_path / "results.csv"
    target.write_text("old\n")

    def fail(tmp: Path) -> None:
        tmp.write_text("half")
        raise OSError(28, "No space left on device")

    with pytest.raises(OSError, match=str(target)):
        write_whole(target, fail)
    assert target.read_text() == "old\n" and [p.name for p in tmp_path.iterdir()] == [target.name]
