"""Run folders are owned: refused before the first step when they cannot be
used, reused only with --overwrite (which removes the earlier run's files first), and the
recording may not point at another output. On the test FMUs of tests/fmus, in process."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
from scenario_factory import loop_toml

from cosim.cli import main
from cosim.engine import master
from cosim.outputs.folder import LOCK_FILE, RunFolder, RunFolderError
from cosim.outputs.folder import MANIFEST_FILE as MANIFEST


@pytest.fixture
def no_stepping(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if a run gets as far as the master."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("the run was not refused before the master started")

    monkeypatch.setattr(master, "run", refuse)


def contents(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def one_line(capsys: pytest.CaptureFixture[str]) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    return err


@pytest.mark.slow
def test_a_finished_run_folder_is_reused_only_with_overwrite(loop_file: Path, tmp_path, capsys):
    """Regression: `run bs-3 --out d; run bs-1 --out d --no-rrd` left bs-3's recording beside
    bs-1's results."""
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out)]) == 0
    first = contents(out)
    assert set(first) == {"results.csv", "scenario.toml", "summary.json", "recording.rrd", MANIFEST}
    other = tmp_path / "other.toml"
    other.write_text(loop_file.read_text().replace('id = "loop"', 'id = "other"'))
    capsys.readouterr()

    assert main(["run", str(other), "--out", str(out), "--no-rrd"]) == 1
    err = one_line(capsys)
    assert "holds an earlier run (scenario 'loop', status 'complete')" in err
    assert "--overwrite" in err
    assert contents(out) == first  # refused: nothing touched

    assert main(["run", str(other), "--out", str(out), "--no-rrd", "--overwrite"]) == 0
    assert set(contents(out)) == {"results.csv", "scenario.toml", "summary.json", MANIFEST}
    assert json.loads((out / "summary.json").read_text())["scenario"] == "other"


def test_overwrite_keeps_files_that_no_run_wrote(loop_file: Path, tmp_path: Path):
    out = tmp_path / "d"
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    (out / "notes.txt").write_text("mine\n")
    (out / "report").mkdir()  # what `auv-cosim report` adds: the earlier run's
    assert main(["run", str(loop_file), "--out", str(out), "--overwrite"]) == 0
    assert (out / "notes.txt").read_text() == "mine\n"
    assert (out / "report").is_dir()  # derived from the earlier run: kept, and said so
    assert (out / "recording.rrd").is_file()


@pytest.mark.parametrize(
    ("make", "flags", "message"),
    [
        (lambda t: t / "afile", [], "--out {out}: exists and is not a folder"),
        (lambda t: Path("/proc/auv-cosim-test/x"), [], "--out {out}: cannot create the run folder"),
        (lambda t: t / "full", [], "is not empty (mine.txt) and holds no earlier run"),
        (lambda t: t / "r", ["--rrd", "{out}/results.csv"], "that is the run's results.csv"),
        (lambda t: t / "r", ["--rrd", "{out}/summary.json"], "that is the run's summary.json"),
        (lambda t: t / "r", ["--rrd", "{tmp}"], "is a folder; expected the path of a .rrd file"),
    ],
)
def test_unusable_outputs_are_refused_before_the_first_step(
    loop_file: Path, tmp_path: Path, capsys, no_stepping: None, make, flags, message
):
    """Regression: `--out /proc/x`, `--out` an existing file ran the whole simulation, then
    rc 1; `--rrd runs/x/results.csv` overwrote the CSV."""
    (tmp_path / "afile").write_text("not a folder\n")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "mine.txt").write_text("mine\n")
    out = make(tmp_path)
    options = [f.format(out=out, tmp=tmp_path) for f in flags]
    assert main(["run", str(loop_file), "--out", str(out), *options]) == 1
    assert message.format(out=out) in one_line(capsys)
    assert (tmp_path / "afile").read_text() == "not a folder\n"
    assert not (tmp_path / "r").exists()  # a refused run leaves no folder behind
    assert sorted(p.name for p in (tmp_path / "full").iterdir()) == ["mine.txt"]


@pytest.mark.parametrize(
    ("flag", "value", "message"),
    [
        ("--stop-time", "inf", "--stop-time inf: expected a finite number of seconds > 0"),
        ("--stop-time", "nan", "--stop-time nan: expected a finite number of seconds > 0"),
        ("--step", "-0.1", "--step -0.1: expected a finite number of seconds > 0"),
        ("--stop-time", "1e12", "is 1e+13 communication steps of 0.1 s (coupling.step); at most"),
        # the count overflows a float: it was printed as "inf communication steps"
        ("--stop-time", "1e308", "is over 1e+308 communication steps of 0.1 s (coupling.step)"),
    ],
)
def test_bad_times_on_the_command_line_are_one_line(
    loop_file: Path, tmp_path: Path, capsys, no_stepping: None, flag: str, value: str, message
):
    """Regression: `--stop-time inf` / `1e12` ended in a Python traceback."""
    assert main(["run", str(loop_file), "--out", str(tmp_path / "r"), f"{flag}={value}"]) == 1
    assert message in one_line(capsys)
    assert not (tmp_path / "r").exists()


def test_a_locked_folder_is_refused_naming_the_process(loop_file: Path, tmp_path: Path, capsys):
    out = tmp_path / "d"
    holder = RunFolder.claim(out)
    try:
        assert (out / LOCK_FILE).is_file()
        with pytest.raises(RunFolderError, match=r"is in use by process \d+ \("):
            RunFolder.claim(out)
        assert main(["run", str(loop_file), "--out", str(out)]) == 1
        assert f"run folder {out} is in use by process" in one_line(capsys)
    finally:
        holder.release()
    assert not (out / LOCK_FILE).exists()
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0


@pytest.mark.parametrize("plant", ["symlink", "dangling symlink", "hard link"])
def test_a_lock_file_planted_as_a_link_is_refused_and_its_target_left(
    plant: str, tmp_path: Path
) -> None:
    """A run folder received from someone else (a tarball, a shared /tmp folder) holding
    its lock file as a link to one of the user's files: claiming it truncated that file
    and wrote the run's pid and command line into it (a dangling link made a new file
    where it pointed). The link is refused, naming it; the file it names is untouched."""
    out, victim = tmp_path / "downloaded", tmp_path / "victim.txt"
    out.mkdir()
    if plant != "dangling symlink":
        victim.write_text("precious line\n")
    if plant == "hard link":
        (out / LOCK_FILE).hardlink_to(victim)
    else:
        (out / LOCK_FILE).symlink_to(Path("..") / victim.name)
    with pytest.raises(RunFolderError, match=f"{LOCK_FILE}: .*link") as refused:
        RunFolder.claim(out)
    assert str(out) in str(refused.value) and "\n" not in str(refused.value)
    if plant == "dangling symlink":
        assert not victim.exists()
    else:
        assert victim.read_text() == "precious line\n"


def test_links_planted_at_the_temporary_names_are_not_written_through(
    loop_file: Path, tmp_path: Path
) -> None:
    """A run folder someone else can write (or a tarball of one) holding links named like
    the run's temporary files (``.summary.json.<pid>.tmp``: the pid is in the lock file
    while the run goes): ``--overwrite`` wrote the summary over the file a link named, and
    then failed ("summary.json: it is not a regular file any more"). A link at a name the
    run writes goes; the files they name are untouched and the run completes."""
    out, victim = tmp_path / "shared", tmp_path / "victim.txt"
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd"]) == 0
    victim.write_text("precious line\n")
    for name in ("summary.json", "scenario.toml", MANIFEST):
        (out / f".{name}.{os.getpid()}.tmp").symlink_to(victim)
    assert main(["run", str(loop_file), "--out", str(out), "--no-rrd", "--overwrite"]) == 0
    assert victim.read_text() == "precious line\n"
    assert not any((out / name).is_symlink() for name in ("summary.json", MANIFEST))
    assert json.loads((out / "summary.json").read_text())["status"] == "complete"


def test_a_command_line_holding_bytes_not_utf8_runs(
    loop_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
):
    """An argument that is no UTF-8 (a folder named in Latin-1: Python reads the byte
    0xff as the surrogate U+DCFF) failed every run at the lock file, which holds the
    command line: "UnicodeEncodeError: 'utf-8' codec can't encode character '\\udcff'",
    exit 1, and an empty lock file left in the folder; past it, a strict stdout (a UTF-8
    locale's) refused the report of the completed run naming that folder, exit 1 again."""
    import os
    import sys

    out = tmp_path / os.fsdecode(b"run-\xff")
    argv = ["run", str(loop_file), "--out", str(out), "--no-rrd"]
    monkeypatch.setattr(sys, "argv", ["auv-cosim", *argv])  # what the lock file records
    holder = RunFolder.claim(out)
    named = r"in use by process \d+ \(auv-cosim run .* --out \S*run-\ufffd "  # as given
    try:
        with pytest.raises(RunFolderError, match=named):
            RunFolder.claim(out)
    finally:
        holder.release()
    assert main(argv) == 0, capsys.readouterr().err
    assert json.loads((out / "summary.json").read_text())["status"] == "complete"
    assert not (out / LOCK_FILE).exists()


def test_the_vehicles_key_figures_are_printed_only_for_a_run_that_has_them(
    loop_file: Path,
    fmu_paths: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
):
    # Guards the report of FMUs other than ours: a line of three "n/a" said nothing.
    assert main(["run", str(loop_file), "--out", str(tmp_path / "loop"), "--no-rrd"]) == 0
    assert "yaw_settling_time_s" not in capsys.readouterr().out
    bs3 = ["run", "bs-3", "--stop-time", "0.5", "--out", str(tmp_path / "bs-3"), "--no-rrd"]
    assert main([*bs3, "--fmu-dir", str(fmu_paths["AuvPlant"].parent)]) == 0
    # half a second into the turn: a figure that is absent says why, not "n/a"
    printed = capsys.readouterr().out
    assert "yaw_settling_time_s = not settled: the yaw is not within 1 deg of its" in printed


def test_an_adaptive_runs_report_counts_the_steps_an_fmu_discarded(
    test_fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    path = tmp_path / "loop.toml"
    text = loop_toml(algorithm="adaptive", fmu_dir=test_fmu_dir)
    path.write_text(
        text.replace("[instances.plant.start]", "[instances.plant.start]\nlongest_step = 0.045")
    )
    assert main(["run", str(path), "--out", str(tmp_path / "d"), "--no-rrd"]) == 0
    taken = json.loads((tmp_path / "d" / "summary.json").read_text())["coupling"]
    assert taken["discarded_steps"] >= 1
    assert f"{taken['discarded_steps']} of them discarded by an FMU" in capsys.readouterr().out


def test_a_default_run_folder_the_system_refuses_is_not_named_as_out(
    loop_file: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys, no_stepping
) -> None:
    """A scenario id too long for a file name, run without --out, was refused as "--out
    runs/aaa...: File name too long", naming an option the user never gave."""
    long_id = "a" * 300
    scenario = tmp_path / "long.toml"
    scenario.write_text(loop_file.read_text().replace('id = "loop"', f'id = "{long_id}"'))
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scenario), "--no-rrd"]) == 1
    err = one_line(capsys)
    assert err.startswith(
        f"auv-cosim run: runs/{long_id} (the default run folder, from the scenario's id; "
        "--out names another): cannot create the run folder: File name too long"
    ), err


@pytest.mark.slow
@pytest.mark.parametrize("named", ["folder", "scenario file"])
def test_a_recorded_run_with_a_path_not_utf8_completes(
    named: str, loop_file: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run folder or a scenario file named in Latin-1 (the byte 0xf6, Python reads it as
    the surrogate U+DCF6), the recording on: the run failed before its first step,
    "cannot start the Rerun recording: 'utf-8' codec can't encode character '\\udcf6'"
    (the recording's name, from the folder) or "UnicodeEncodeError" (scenario.toml's
    first line names the file). The files written name it with the byte escaped."""
    import os

    odd = os.fsdecode(b"gr\xf6\xdfe")
    out = tmp_path / (odd if named == "folder" else "out")
    scenario = loop_file
    if named == "scenario file":
        scenario = loop_file.rename(loop_file.with_name(f"{odd}.toml"))
    assert main(["run", str(scenario), "--out", str(out)]) == 0, capsys.readouterr().err
    assert json.loads((out / "summary.json").read_text("utf-8"))["status"] == "complete"
    first_line = (out / "scenario.toml").read_text("utf-8").splitlines()[0]
    assert (r"gr\xf6\xdfe" in first_line) == (named == "scenario file"), first_line
    assert (out / "recording.rrd").stat().st_size > 0


@pytest.mark.slow
def test_a_recording_that_fails_to_start_leaves_the_folder_free_for_the_next_run(
    loop_file: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A recording that failed as it started (its name, from a folder named in Latin-1,
    was refused by rerun) left its first part, recording.rrd, in a folder the run had
    made; the same command again was refused, "the folder is not empty (recording.rrd)
    and holds no earlier run". A run that never stepped removes what it made."""
    from cosim.viz.recording import RerunSink

    def refused(*args: object, **kwargs: object) -> None:
        raise ValueError("the recording's name is refused")

    out = tmp_path / "out"
    argv = ["run", str(loop_file), "--out", str(out)]
    with monkeypatch.context() as patched:
        patched.setattr(RerunSink, "_log_static", refused)
        assert main(argv) == 1
    assert "cannot start the Rerun recording" in capsys.readouterr().err
    assert not out.exists()
    assert main(argv) == 0, capsys.readouterr().err
