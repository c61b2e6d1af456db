"""A run's own files are known by what they hold, not by their inode: ``--overwrite`` (and
the default folder's replacement of an earlier run of the same scenario file) removes a
file only if it is still exactly what the earlier run wrote (size, time and content, as
its manifest records them), checked again when it is removed. Anything else -- a user's
file written in place of one, one moved in while the new run prepares, a user's file that
merely looks like a temporary file of ours -- stays. On the test FMUs of tests/fmus, in
process."""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from scenario_factory import loop_toml

from cosim import runner
from cosim.cli import main
from cosim.engine import master
from cosim.outputs.folder import MANIFEST_FILE


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every path below ``folder`` (relative, hidden ones too) -> its bytes (None: folder)."""
    return {
        str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes()
        for p in sorted(folder.rglob("*"))
    }


def one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


def users_version(path: Path) -> bytes:
    """What a user might write in place of a run's file (a summary stays a summary)."""
    if path.name == "summary.json":
        return json.dumps({**json.loads(path.read_text()), "note": "my edits"}).encode()
    return b"the user's own " + path.name.encode() + b"\n"


def rewrite_in_place(path: Path) -> None:
    """Same inode, other content."""
    data = users_version(path)
    with path.open("r+b") as f:
        f.truncate(0)
        f.write(data)


def delete_and_write_again(path: Path) -> None:
    """A new file under the name (the file system usually gives the inode back)."""
    data = users_version(path)
    path.unlink()
    path.write_bytes(data)


def same_size_and_time(path: Path) -> None:
    """One digit changed in place (a summary stays JSON), the modification time put back:
    only the content tells."""
    status = path.stat()
    data = bytearray(path.read_bytes())
    digits = [i for i, byte in enumerate(data) if 0x30 <= byte <= 0x39]  # ASCII digits only
    at = next((i for i in digits if i >= len(data) // 2), digits[0])
    data[at] = ord(str((int(chr(data[at])) + 1) % 10))
    with path.open("r+b") as f:
        f.write(data)
    os.utime(path, ns=(status.st_atime_ns, status.st_mtime_ns))


CHANGES: dict[str, Callable[[Path], None]] = {
    "rewritten in place": rewrite_in_place,
    "deleted and written again": delete_and_write_again,
    "same size and time, one byte changed": same_size_and_time,
}


@pytest.mark.parametrize("name", ["results.csv", "scenario.toml", "summary.json", "recording.rrd"])
@pytest.mark.parametrize("change", list(CHANGES))
def test_a_users_file_in_place_of_a_runs_file_is_never_removed(
    loop_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], name: str, change: str
) -> None:
    """--overwrite trusted inode numbers: a user who deleted results.csv and wrote their own
    got the same inode back (10 of 10 tries) and lost the file."""
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out)]) == 0
    CHANGES[change](out / name)
    before = tree(out)
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--overwrite"]) == 1
    assert f"{name} is not a file the earlier run wrote" in one_line(capsys)
    assert tree(out) == before


def test_a_file_moved_in_while_the_run_prepares_is_kept(
    loop_file: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A file moved into the folder after the claim, while the FMUs were built, was
    removed as the earlier run's (the check was at the claim only)."""
    out, mine = tmp_path / "d", tmp_path / "mine.csv"
    assert main(["run", str(loop_file), "--out", str(out)]) == 0
    mine.write_text("time,mine\n0,1\n")
    checked = runner._checked_scenario

    def moving_in(*args: Any, **kwargs: Any) -> Any:
        loaded = checked(*args, **kwargs)
        os.replace(mine, out / "results.csv")  # after the claim, before anything is removed
        return loaded

    monkeypatch.setattr(runner, "_checked_scenario", moving_in)
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--overwrite"]) == 1
    assert "results.csv changed since the run began" in one_line(capsys)
    assert (out / "results.csv").read_text() == "time,mine\n0,1\n"
    assert {"scenario.toml", "summary.json", "recording.rrd"} <= set(os.listdir(out))


@pytest.mark.parametrize(
    "name",
    [
        ".summary.json.mine.tmp",
        ".summary.json.1.tmp",
        ".summary.json..tmp",
        ".scenario.toml.mine.tmp",
        f".{MANIFEST_FILE}.x.tmp",
    ],
)
def test_a_users_file_named_like_a_temporary_file_of_ours_is_kept(
    loop_file: Path, tmp_path: Path, name: str
) -> None:
    """--overwrite removed a user's .summary.json.mine.tmp (any name matching
    .summary.json.*.tmp): only the earlier run's own process's temporary files go."""
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    (out / name).write_text("mine\n")
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 0
    assert (out / name).read_text() == "mine\n"


@pytest.mark.parametrize(
    ("damage", "message"),
    [
        (lambda text: text[: len(text) // 2], "is unreadable"),
        (lambda text: "", "is unreadable"),
        (lambda text: "[1, 2]", "is unreadable"),
        (lambda text: json.dumps({"files": []}), "was written by an older auv-cosim"),
    ],
    ids=["truncated", "empty", "not ours", "older format"],
)
def test_a_damaged_manifest_is_named_as_such_not_as_missing(
    loop_file: Path, tmp_path: Path, capsys, damage: Callable[[str], str], message: str
) -> None:
    """A truncated manifest was reported as missing ("holds a summary.json but no
    .auv-cosim-run.json")."""
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    manifest = out / MANIFEST_FILE
    manifest.write_text(damage(manifest.read_text()))
    before = tree(out)
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 1
    err = one_line(capsys)
    assert f"its {MANIFEST_FILE} {message}" in err and "but no" not in err
    assert tree(out) == before


def test_the_default_folder_is_replaced_silently_only_for_the_same_scenario_file(
    test_fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """runs/turn of exp/a/turn.toml was silently replaced by a run of exp/b/turn.toml,
    another file with the same id."""
    monkeypatch.setattr(runner, "RUNS_DIR", tmp_path / "runs")
    files = []
    for name, gain in (("a", 2.0), ("b", 3.0)):
        (tmp_path / "exp" / name).mkdir(parents=True)
        path = tmp_path / "exp" / name / "turn.toml"
        text = loop_toml(fmu_dir=test_fmu_dir)
        path.write_text(text.replace("k = 2.0", f"k = {gain}"))
        files.append(path)
    assert main(["run", str(files[0]), "--no-rrd"]) == 0
    before = tree(tmp_path / "runs" / "turn")
    capsys.readouterr()
    assert main(["run", str(files[1]), "--no-rrd"]) == 1
    err = one_line(capsys)
    assert "another scenario file with the same id 'turn'" in err and "--overwrite" in err
    # no --out was given: the folder is named as the default one, not as "--out ..."
    assert "(the default run folder of 'turn')" in err and "--out runs" not in err, err
    assert tree(tmp_path / "runs" / "turn") == before
    assert main(["run", str(files[0]), "--no-rrd"]) == 0  # the same file: replaced silently


def test_the_default_folder_refused_for_a_users_file_names_that_file(
    loop_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """The default folder is reused without --overwrite only while it holds nothing but
    the earlier run (docs/runs.md); with a file of the user's beside it (notes.txt) the
    command that ran twice was refused, saying only that the folder holds an earlier run,
    which it had held the time before too. The line names the file that made the
    difference, and the folder is left as it was."""
    monkeypatch.setattr(runner, "RUNS_DIR", tmp_path / "runs")
    assert main(["run", str(loop_file), "--no-rrd"]) == 0
    folder = tmp_path / "runs" / "loop"
    (folder / "notes.txt").write_text("my notes\n")
    before = tree(folder)
    capsys.readouterr()
    assert main(["run", str(loop_file), "--no-rrd"]) == 1
    err = one_line(capsys)
    assert "the folder holds an earlier run (scenario 'loop', status 'complete')" in err, err
    assert "and notes.txt, which no run wrote" in err and "--overwrite" in err, err
    assert tree(folder) == before


def test_a_live_runs_rewritten_scenario_is_the_runs_own(
    loop_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """After a live run that took overrides, its rewritten scenario.toml was missing from
    the manifest: the folder could not be replaced even with --overwrite ("status
    incomplete")."""
    run = master.run

    def with_an_override(*args: Any, **kwargs: Any) -> Any:
        result = run(*args, **kwargs)
        result.overrides.append(
            {"name": "k", "time": 0.5, "set": {"controller.k": 3.0}, "source": "test"}
        )
        return result

    out = tmp_path / "d"
    monkeypatch.setattr(master, "run", with_an_override)
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    assert "controller.k" in (out / "scenario.toml").read_text()  # the replay was written
    monkeypatch.setattr(master, "run", run)
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 0
    assert "removed results.csv, scenario.toml, summary.json" in capsys.readouterr().err
