"""The command line's own options, apart from any command."""

import importlib.metadata
import re
from pathlib import Path

import pytest

from cosim.cli import main


def test_version_is_the_installed_packages(capsys: pytest.CaptureFixture[str]) -> None:
    """A user reporting a problem is asked for the version: ``--version`` prints it and
    exits 0 without a command."""
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == f"auv-cosim {importlib.metadata.version('auv-cosim')}\n"


def test_a_megabyte_value_in_a_failure_is_named_by_its_start(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A 1 MB mission reaches the guidance, which refuses it: the one line that says so
    (and the FMU's own log message in it) is kilobytes, not megabytes."""
    scenario = tmp_path / "huge.toml"
    scenario.write_text(
        'stop_time = 0.1\n[coupling]\nstep = 0.01\n[instances.g]\nfmu = "AuvGuidance"\n'
        f'[instances.g.start]\nwaypoints = "{"x" * 1_000_000}"\n'
    )
    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", str(scenario), "--out", str(tmp_path / "run"), "--no-rrd", "--fmu-dir", fmu_dir]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and len(err) < 3000, len(err)
    assert "waypoint 1 ('xxx" in err and "characters left out" in err


def test_a_name_the_system_refuses_is_one_line_naming_it(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A path component over 255 bytes (ENAMETOOLONG, which pathlib's exists() raises
    rather than answering) as --out, --rrd, a run folder or a study's --out: the path and
    the system's reason, never "OSError: [Errno 36]" or a traceback."""
    long = tmp_path / ("a" * 300)
    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    run = ["run", "bs-3", "--stop-time", "0.1", "--quiet", "--fmu-dir", fmu_dir]
    study = str(Path(__file__).parents[2] / "docs" / "study-example.toml")
    for argv in (
        [*run, "--out", str(long), "--no-rrd"],
        [*run, "--out", str(tmp_path / "run"), "--rrd", f"{long}.rrd"],
        ["sweep", study, "--out", str(long), "--fmu-dir", fmu_dir],
        ["report", str(long)],
        ["view", str(long)],
    ):
        assert main(argv) == 1, argv
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "File name too long" in err and str(long) in err, err
        assert "OSError" not in err and "Errno" not in err, err


@pytest.mark.parametrize(
    ("argv", "choices"),
    [([], ["run", "sweep", "view"]), (["analyze"], ["equilibria", "phase-portrait"])],
)
def test_a_command_without_its_subcommand_prints_the_choices(
    argv: list[str], choices: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """`auv-cosim` alone answered only "the following arguments are required: COMMAND":
    a newcomer gets the list of commands (a usage error all the same, exit 2)."""
    assert main(argv) == 2
    out = capsys.readouterr().out
    assert out.startswith("usage: auv-cosim") and all(f"    {c}" in out for c in choices), out


def test_no_rrd_and_rrd_together_are_a_usage_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--no-rrd --rrd x.rrd`` asks for a recording and for none: refused as a usage
    error naming both, before anything runs (it was taken, and x.rrd never written)."""
    out = tmp_path / "r"
    with pytest.raises(SystemExit) as exit_:
        main(["run", "bs-3", "--no-rrd", "--rrd", str(tmp_path / "x.rrd"), "--out", str(out)])
    assert exit_.value.code == 2
    assert "argument --rrd: not allowed with argument --no-rrd" in capsys.readouterr().err
    assert not (tmp_path / "x.rrd").exists() and not out.exists()


def test_a_path_of_the_wrong_kind_is_not_suggested_as_itself(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`report` of a file said "is not a folder (did you mean '<that file>'?)"."""
    script = tmp_path / "t.sh"
    script.write_text("echo\n", encoding="utf-8")
    assert main(["report", str(script)]) == 1
    err = capsys.readouterr().err
    assert f"{script} is not a folder" in err and "did you mean" not in err


def test_a_reader_that_stops_reading_gets_no_traceback(tmp_path: Path) -> None:
    """`auv-cosim scenarios | head -0`: the command wrote into a closed pipe and printed
    "BrokenPipeError: [Errno 32] Broken pipe" on stderr (and more at exit)."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", "scenarios"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=tmp_path,
    )  # fmt: skip
    assert proc.stdout is not None and proc.stderr is not None
    proc.stdout.close()  # the reader is gone before the first line
    try:
        err = proc.stderr.read().decode()
        code = proc.wait(timeout=60)
    finally:
        proc.kill()
        proc.wait()
    assert err == "" and code == 141, (code, err)


def test_a_warning_is_one_line_naming_the_command(tmp_path: Path) -> None:
    """A warning of ours ("Rerun viewer: gRPC connection severed ...") reached the user as
    Python shows it: the file and line that warned, then that source line. It names the
    subcommand, as an error does ("auv-cosim: warning:" left a user of several commands
    in a script guessing which one warned)."""
    import subprocess
    import sys

    code = (
        "import sys, warnings\n"
        "from cosim import cli\n"
        "def scenarios(args):\n"
        "    warnings.warn('Rerun viewer: the stream\\n  ended', stacklevel=2)\n"
        "    return 0\n"
        "cli._scenarios = scenarios\n"
        "sys.argv = ['auv-cosim', 'scenarios']\n"
        "sys.exit(cli.main())\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=tmp_path
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == "auv-cosim scenarios: warning: Rerun viewer: the stream ended\n"


def test_every_help_pointer_names_a_page_that_exists(capsys: pytest.CaptureFixture[str]) -> None:
    """``sweep --help`` sent the reader to "README, Studies", a section the README does not
    have; every ``docs/<page>.md`` a help text names is a page of the repository, and
    every --fmu-dir says what the folder is, not only its default."""
    from cosim.cli import build_parser

    parser = build_parser()
    commands = ["run", "sweep", "export", "view", "report", "build", "validate", "reproduce"]
    pages = set()
    for command in commands:
        with pytest.raises(SystemExit):
            parser.parse_args([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert "README" not in text, (command, text)
        pages |= set(re.findall(r"docs/[\w-]+\.md", text))
        if "--fmu-dir FMU_DIR [build/fmus]" in text:
            pytest.fail(f"{command} --help: --fmu-dir says only its default")
    root = Path(__file__).parents[2]
    assert "docs/studies.md" in pages
    assert all((root / page).is_file() for page in pages), pages


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["run", "bs-3.toml"], "no such file: bs-3.toml (the built-in scenario is the id 'bs-3'"),
        (["sweep", "studdy.toml"], "study file studdy.toml: no such file (did you mean "),
    ],
)
def test_a_missing_file_is_named_with_what_was_probably_meant(
    argv: list[str],
    expected: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``run bs-3.toml`` (the built-in id typed as a file name) gave no hint, and a
    mistyped study file "cannot read it: [Errno 2] No such file or directory"."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "study.toml").write_text('scenario = "bs-3"\n[grid]\n"plant.v_0" = [0.1]\n')
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err and "Errno" not in err, err


@pytest.mark.parametrize(
    "argv",
    [
        ["run", "bs-3", "--fmu-dir", ""],
        ["run", "bs-3", "--out", ""],
        ["build", "--out", ""],
        ["sweep", "study.toml", "--fmu-dir", ""],
        ["report", ""],
    ],
)
def test_an_empty_path_is_a_usage_error_not_the_working_folder(
    argv: list[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """An empty path (an unset shell variable: ``--fmu-dir "$FMUS"``) is refused naming
    the option, as the API refuses it, before anything is built or written: it was read
    as the working folder, and ``--fmu-dir ""`` built the FMUs into it."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "expected a non-empty path ('.' names the working folder)" in err, err
    assert not list(tmp_path.iterdir())
