"""``--overwrite`` (and the default folder's replacement of an earlier run) removes only
the regular files the earlier run wrote, as its manifest names them with their inodes:
never a folder, never a file a summary.json merely lists, never through a link, never a
file outside the run folder; it says what it removed. A recording file is locked like the
run folder. On the test FMUs of tests/fmus, in process."""

from __future__ import annotations

import fcntl
import json
import os
from pathlib import Path

import pytest

from cosim import runner
from cosim.cli import main

BEING_WRITTEN = b"RRF2\x00\n\tauv-cosim being written\n"  # how a recording of ours starts


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every path below ``folder`` (relative) -> its bytes (None for a folder)."""
    return {
        str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes()
        for p in sorted(folder.rglob("*"))
    }


def test_a_summary_listing_other_paths_removes_none_of_them(
    loop_file: Path, tmp_path: Path, capsys
):
    """A crafted summary.json's outputs ("Documents/x", "../x", an absolute path) made
    --overwrite remove the whole Documents/ folder inside the run folder. A summary.json
    edited since the run is no longer the run's: the folder is refused, untouched."""
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    summary = json.loads((out / "summary.json").read_text())
    outside = tmp_path / "outside.txt"
    outside.write_text("outside\n")
    summary["outputs"].update(
        {"a": "Documents/x", "b": "../outside.txt", "c": str(outside), "d": "notes.txt"}
    )
    (out / "summary.json").write_text(json.dumps(summary))
    (out / "Documents").mkdir()
    (out / "Documents" / "x").write_text("mine\n")
    (out / "Documents" / "thesis.tex").write_text("mine\n")
    (out / "notes.txt").write_text("mine\n")
    users = tree(out)
    capsys.readouterr()

    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "summary.json is not a file the earlier run wrote" in err
    assert tree(out) == users
    assert (out / "notes.txt").read_text() == "mine\n"
    assert outside.read_text() == "outside\n"


def test_a_summary_without_the_runs_manifest_is_refused_untouched(
    loop_file: Path, tmp_path: Path, capsys
):
    """A foreign or hand-made summary.json cost the user's results.csv and report/."""
    out = tmp_path / "d"
    out.mkdir()
    listed = {"results": "results.csv", "report": "report"}
    summary = {"scenario": "loop", "status": "complete", "outputs": listed}
    (out / "summary.json").write_text(json.dumps(summary))
    (out / "results.csv").write_text("the user's own results\n")
    (out / "report").mkdir()
    (out / "report" / "index.html").write_text("<p>mine</p>\n")
    before = tree(out)
    capsys.readouterr()

    assert main(["run", str(loop_file), "--out", str(out), "--overwrite"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no .auv-cosim-run.json" in err, err
    assert tree(out) == before


def test_a_recording_in_a_subfolder_goes_alone(loop_file: Path, tmp_path: Path):
    """After a run with --rrd OUT/data/rec.rrd, --overwrite deleted OUT/data/ with the
    user's other files in it."""
    out = tmp_path / "d"
    rrd = out / "data" / "rec.rrd"
    assert main(["run", str(loop_file), "--out", str(out), "--rrd", str(rrd)]) == 0
    (out / "data" / "mine.csv").write_text("mine\n")
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 0
    assert (out / "data" / "mine.csv").read_text() == "mine\n"
    assert not rrd.exists()  # the earlier run's own recording is gone


def test_a_symlinked_run_folder_keeps_the_users_files(loop_file: Path, tmp_path: Path):
    real, link = tmp_path / "real", tmp_path / "link"
    real.mkdir()
    link.symlink_to(real, target_is_directory=True)
    assert main(["run", str(loop_file), "--out", str(link), "--no-rrd"]) == 0
    (real / "mine.txt").write_text("mine\n")
    assert main(["run", str(loop_file), "--out", str(link), "--no-rrd", "--overwrite"]) == 0
    assert (real / "mine.txt").read_text() == "mine\n"
    assert json.loads((real / "summary.json").read_text())["status"] == "complete"


def test_an_output_replaced_by_a_link_is_neither_removed_nor_followed(
    loop_file: Path, tmp_path: Path, capsys
):
    out, precious = tmp_path / "d", tmp_path / "precious.csv"
    precious.write_text("precious\n")
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    (out / "results.csv").unlink()
    (out / "results.csv").symlink_to(precious)
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "results.csv is not a file the earlier run wrote" in err
    assert precious.read_text() == "precious\n"
    assert (out / "results.csv").is_symlink()


def test_overwrite_says_what_it_removed_and_keeps_a_report(loop_file: Path, tmp_path: Path, capsys):
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out)]) == 0
    (out / "report").mkdir()
    (out / "report" / "index.html").write_text("<p>report</p>\n")
    capsys.readouterr()
    assert main(["run", str(loop_file), "--out", str(out), "--overwrite"]) == 0
    err = capsys.readouterr().err
    assert err == (
        f"auv-cosim run: replaced the earlier run in {out}: removed recording.rrd, "
        "results.csv, scenario.toml, summary.json; kept report/\n"
    )
    assert (out / "report" / "index.html").read_text() == "<p>report</p>\n"


@pytest.fixture
def runs_dir(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    monkeypatch.setattr(runner, "RUNS_DIR", tmp_path / "runs")
    return tmp_path / "runs"


def test_the_default_folder_can_be_run_twice(loop_file: Path, runs_dir: Path, capsys):
    """The README's first command, pasted twice, exited 1 asking for --overwrite."""
    assert main(["run", str(loop_file), "--no-rrd"]) == 0
    assert main(["run", str(loop_file), "--no-rrd"]) == 0
    err = capsys.readouterr().err
    assert err == (
        f"auv-cosim run: replaced the earlier run in {runs_dir / 'loop'}: removed "
        "results.csv, scenario.toml, summary.json\n"
    )


def test_the_default_folder_keeps_its_protection(loop_file: Path, runs_dir: Path, capsys):
    assert main(["run", str(loop_file), "--no-rrd"]) == 0
    (runs_dir / "loop" / "notes.txt").write_text("mine\n")
    capsys.readouterr()
    assert main(["run", str(loop_file), "--no-rrd"]) == 1  # something not of the run
    assert "pass --overwrite" in capsys.readouterr().err
    (runs_dir / "loop" / "notes.txt").unlink()
    summary = json.loads((runs_dir / "loop" / "summary.json").read_text())
    summary["scenario"] = "another"
    (runs_dir / "loop" / "summary.json").write_text(json.dumps(summary))
    assert main(["run", str(loop_file), "--no-rrd"]) == 1  # another scenario's run
    assert "pass --overwrite" in capsys.readouterr().err


def test_a_recording_being_written_is_refused(loop_file: Path, tmp_path: Path, capsys):
    """Two runs writing one --rrd at once both ended "complete" with a corrupt file."""
    rrd = tmp_path / "shared.rrd"
    rrd.write_bytes(BEING_WRITTEN)
    fd = os.open(rrd, os.O_RDWR)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # as the run writing it holds it
        command = ["run", str(loop_file), "--out", str(tmp_path / "d"), "--rrd", str(rrd)]
        assert main([*command, "--overwrite"]) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "another run is writing this recording" in err
        assert rrd.read_bytes() == BEING_WRITTEN
        assert not (tmp_path / "d").exists()
    finally:
        os.close(fd)
    assert main([*command, "--overwrite"]) == 0  # once the other run is done
