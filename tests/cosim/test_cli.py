"""The command line's own options, apart from any command."""

import argparse
import fcntl
import importlib.metadata
import os
import pty
import re
import select
import struct
import sys
import termios
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from process_group import run_in_group, started_in_group
from relative_home import PREAMBLE

from cosim.cli import build_parser, main


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


@pytest.mark.cluster
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
    a newcomer gets the list of commands (a usage error all the same, exit 2), on stderr
    as every usage error: on stdout it was what ``out=$(auv-cosim $COMMAND)`` read as the
    output of a command whose variable was empty."""
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "", out
    assert err.startswith("usage: auv-cosim") and all(f"    {c}" in err for c in choices), err


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


@pytest.mark.parametrize("argv", [["scenarios"], ["--version"], ["--help"], ["run", "--help"]])
def test_a_reader_that_stops_reading_gets_no_traceback(argv: list[str], tmp_path: Path) -> None:
    """`auv-cosim scenarios | head -0`: the command wrote into a closed pipe and printed
    "BrokenPipeError: [Errno 32] Broken pipe" on stderr (and more at exit). ``--version``
    said "auv-cosim: BrokenPipeError: [Errno 32] Broken pipe" and exited 1, and a help
    exited 0 as if the reader had had it all: each ends as a command ended by SIGPIPE."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", *argv],
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
        proc.stderr.close()
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
        ["export", "bs-3", "--ssp", "-"],
        ["export", "bs-3", "--osp", "-"],
        ["run", "bs-3", "--rrd", "-"],
        ["run", "bs-3", "--out", "-"],
        ["analyze", "phase-portrait", "--out", "-"],
        ["build", "--out", "-"],
        ["sweep", "-"],
        ["report", "-"],
        ["view", "-"],
        ["validate", "-"],
        ["run", "-"],
        ["export", "-", "--ssp", "out.ssp"],
    ],
)
def test_a_dash_for_standard_input_or_output_is_a_usage_error(
    argv: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    """``export bs-3 --ssp -`` (a pipeline's "to standard output") wrote a 3 MB archive
    into a file named ``-`` in the working folder and said "SSP archive: ./-", and ``run
    bs-3 --rrd -`` a recording there; ``run -`` (a scenario piped in) said "unknown
    scenario '-'". No file or folder option reads or writes a stream: ``-`` is refused
    before anything runs, saying so and how to name a file called ``-``."""
    with pytest.raises(SystemExit) as exit_:
        build_parser().parse_args(argv)
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "'-': expected a" in err and "standard input" in err and "./-" in err, err


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


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["--stop-time", "60s"], "argument --stop-time: '60s': expected a number of seconds, "
         "without a unit (--stop-time 60)"),
        (["--step", "10ms"], "argument --step: '10ms': expected a number of seconds, "
         "without a unit (--step 0.01)"),
        (["--stop-time", "2 min"], "(--stop-time 120)"),
        (["--stop-time", "sixty"], "argument --stop-time: 'sixty': expected a number of seconds"),
    ],
)  # fmt: skip
def test_a_time_typed_with_its_unit_is_refused_with_the_number_to_type(
    argv: list[str], expected: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """``--stop-time 60s``, a newcomer's first try, got argparse's "invalid float value:
    '60s'": the message now says the option takes seconds as a plain number and gives it,
    before anything runs."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as exit_:
        main(["run", "bs-3", *argv])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert expected in err and "invalid float value" not in err, err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("command", ["view", "report"])
def test_a_scenario_id_given_for_its_run_folder_names_the_folder(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """``auv-cosim view bs-3`` (the id, not the folder ``runs/bs-3`` the run wrote) said
    only that there was no ``bs-3/recording.rrd``; ``report bs-3`` that bs-3 "is not a
    folder". Both now name the run's folder."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "runs" / "bs-3").mkdir(parents=True)
    assert main([command, "bs-3"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "(did you mean 'runs/bs-3'?)" in err, err


@pytest.mark.parametrize("command", ["view", "report"])
def test_a_runs_report_folder_given_for_the_run_names_the_run(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """``report runs/bs-3/report`` (the folder ``report`` wrote, beside the run's files)
    said only that it held no results.csv, or no recording."""
    monkeypatch.chdir(tmp_path)
    run = tmp_path / "runs" / "bs-3"
    (run / "report").mkdir(parents=True)
    (run / "results.csv").write_text("time\n0.0\n", encoding="utf-8")
    assert main([command, "runs/bs-3/report"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "did you mean 'runs/bs-3'?" in err, err


@pytest.mark.parametrize("command", ["view", "report"])
@pytest.mark.parametrize("given", ["lqr-1", "runs/lqr-1"])
def test_a_scenario_not_run_yet_is_named_with_the_command_that_runs_it(
    command: str, given: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    """``view``/``report`` before ``run`` (a newcomer's order of the README's commands)
    said there was no recording, or no folder, without saying what makes one."""
    monkeypatch.chdir(tmp_path)
    assert main([command, given]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no run of lqr-1 yet: `auv-cosim run lqr-1` writes " in err
    assert "runs/lqr-1" in err and "is not a folder" not in err, err


def test_run_help_gives_every_coupling_options_default(capsys: pytest.CaptureFixture[str]) -> None:
    """``run --help`` said "master algorithm" and nothing of what the run uses without the
    option (the scenario's own choice), nor the default tolerance; a newcomer meets
    "jacobi" and "gauss-seidel" there first."""
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    for option in ("--stop-time", "--step", "--algorithm", "--extrapolation", "--tolerance"):
        help_text = text.split(f" {option} ", 1)[1].split(" --", 1)[0]
        assert "[the scenario's" in help_text, (option, help_text)
    from cosim.scenario.spec import DEFAULT_TOLERANCE

    assert "one after another" in text and f"[the scenario's, {DEFAULT_TOLERANCE:g}" in text
    assert "rerun+http://127.0.0.1:9876/proxy" in text  # what --connect takes


def test_run_help_says_where_the_fmus_messages_go(capsys: pytest.CaptureFixture[str]) -> None:
    """``run --help`` said nothing of what the FMUs log: an integrator looked for a log
    file or stderr. It names where their warnings and errors go (the run's report and
    summary.json's fmu_messages) and how to see their debug messages (--fmu-log)."""
    with pytest.raises(SystemExit):
        main(["run", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "warnings and errors" in text and "summary.json (fmu_messages" in text, text
    assert "debug messages are shown, on stderr, for the instances named by --fmu-log" in text


@pytest.mark.parametrize(
    "command",
    ["build", "validate", "scenarios", "run", "sweep", "export", "view", "analyze", "reproduce",
     "report"],
)  # fmt: skip
def test_a_commands_help_says_what_the_command_does(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """``auv-cosim report --help`` (and every other command's) began with the usage line
    and the options: the one line ``auv-cosim --help`` gives the command is its first
    paragraph too."""
    from cosim.cli import build_parser

    parser = build_parser()
    listed = parser.format_help()
    with pytest.raises(SystemExit):
        parser.parse_args([command, "--help"])
    paragraphs = capsys.readouterr().out.split("\n\n")
    first = " ".join(paragraphs[1].split())
    assert not first.startswith(("positional arguments", "options")), paragraphs
    assert first.split(" (")[0].split(":")[0][:30] in " ".join(listed.split()), (first, listed)


def _with_stderr_closed(cwd: Path, *argv: str) -> tuple[int, str]:
    """``auv-cosim ARGV 2>&-`` in a fresh interpreter (a session of its own, ended as a
    group whatever happens): its exit code and stdout."""
    import sys

    command = ["sh", "-c", 'exec "$@" 2>&-', "sh", sys.executable, "-m", "cosim.cli", *argv]
    done = run_in_group(command, timeout=300, stderr=None, cwd=cwd)
    return done.returncode, done.stdout


def test_with_stderr_closed_an_error_is_not_written_on_stdout(tmp_path: Path) -> None:
    """``auv-cosim run nosuch --quiet 2>&-``: Python sets ``sys.stderr`` to None for a
    closed descriptor 2, and ``print(..., file=None)`` writes on stdout: the error landed
    in what a script reads as the command's output."""
    code, out = _with_stderr_closed(tmp_path, "run", "no-such-scenario", "--quiet")
    assert (code, out) == (1, "")


@pytest.mark.slow
def test_a_run_with_stderr_closed_runs(fmu_paths: dict[str, Path], tmp_path: Path) -> None:
    """``auv-cosim run bs-3 2>&-`` (a supervisor that closes stderr) exited 1 before its
    first step, saying nothing anywhere: the progress bar's ``sys.stderr.isatty()`` on a
    stderr that Python had set to None."""
    import json

    fmu_dir = fmu_paths["AuvPlant"].parent
    argv = ["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", "out", "--stop-time", "0.05"]
    code, out = _with_stderr_closed(tmp_path, *argv, "--no-rrd")
    assert code == 0, out
    assert out.startswith("scenario bs-3: complete"), out
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["status"] == "complete"


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs Linux's /dev/full")
@pytest.mark.parametrize(
    "argv",
    [["--version"], ["scenarios"], ["validate", "bs-3"], ["--help"], ["run", "--help"]],
)
def test_a_full_standard_output_is_named_as_such(argv: list[str], tmp_path: Path) -> None:
    """``auv-cosim validate bs-3 > out.txt`` on a full disk said "OSError: [Errno 28] No
    space left on device", naming no file (a run's report: as if its folder's disk were
    full), and ``--version`` printed a traceback. ``--help > FILE`` on a full disk exited
    0 and said nothing (argparse drops a failed write), leaving the file empty."""
    import sys

    with open("/dev/full", "w") as full:
        command = [sys.executable, "-m", "cosim.cli", *argv]
        done = run_in_group(command, timeout=120, stdout=full, cwd=tmp_path)
    command = "auv-cosim" if argv[0].startswith("-") else f"auv-cosim {argv[0]}"
    assert done.returncode == 1, done.stderr
    assert done.stderr == f"{command}: standard output: No space left on device\n"


def test_out_of_file_descriptors_names_the_limit_not_a_file(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``ulimit -n 32; auv-cosim sweep ...`` said "auv-cosim sweep: /usr/lib/python3.11/
    email/_header_value_parser.py: Too many open files": the module being imported when
    the descriptors ran out, which is not the problem; the limit is."""
    import errno
    import resource

    from cosim import cli

    module = "/usr/lib/python3.11/email/_header_value_parser.py"

    def scenarios(args: object) -> int:
        raise OSError(errno.EMFILE, "Too many open files", module)

    monkeypatch.setattr(cli, "_scenarios", scenarios)
    assert main(["scenarios"]) == 1
    soft, _ = resource.getrlimit(resource.RLIMIT_NOFILE)
    assert capsys.readouterr().err == (
        f"auv-cosim scenarios: Too many open files (this process may have {soft} files open: "
        "raise the limit with `ulimit -n`)\n"
    )


def test_an_event_or_fault_after_the_stop_time_is_warned_of_naming_both_times(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """An event at t = 90 s and a fault starting at 70 s in a run that stops at 0.05 s
    (``--stop-time``, or the file's own) ran complete without a word and neither was ever
    applied; an event at the stop time itself fires at the last point, and is no doubt."""

    bs3 = (Path(__file__).parents[2] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    path = tmp_path / "late.toml"
    path.write_text(
        bs3 + '\n[[events]]\nname = "turn"\ntime = 90.0\nset = { "controller.yaw_setpoint" = 0.3 }'
        '\n[[events]]\ntime = 0.05\nset = { "controller.yaw_setpoint" = 0.2 }'
        '\n[[faults]]\nname = "jam"\nkind = "mass-jam"\nstart = 70.0\n'
    )
    lines = [m for m in _warned_over_50_ms(path, fmu_paths, tmp_path) if "stop time" in m]
    assert lines == [
        "events.turn.time = 90 s is after the stop time (0.05 s): the run ends before the "
        "event, which is never applied",
        "faults.jam.start = 70 s is after the stop time (0.05 s): the run ends before the "
        "fault, which never acts",
    ]


def _warned_over_50_ms(path: Path, fmu_paths: dict[str, Path], tmp_path: Path) -> list[str]:
    """The warnings' messages of the scenario file ``path`` run for 0.05 s into
    ``tmp_path / "run"`` (it must complete)."""
    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", str(path), "--stop-time", "0.05", "--no-rrd", "--quiet", "--fmu-dir", fmu_dir,
            "--out", str(tmp_path / "run")]  # fmt: skip
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(argv) == 0
    return [str(w.message) for w in caught]


@pytest.mark.parametrize(("algorithm", "warned"), [("gauss-seidel", True), ("adaptive", False)])
def test_a_fault_between_two_communication_points_is_warned_of(
    fmu_paths: dict[str, Path], tmp_path: Path, algorithm: str, warned: bool
) -> None:
    """A fault from 0.021 s to 0.025 s with a step of 0.01 s (a sweep of its stop that
    comes close to its start) is active at no communication point (start <= t_n < stop):
    it never acted, without a word, while the recording logged that it started and never
    that it stopped. An adaptive run, whose points are step / 1024 apart, applies it."""
    import json

    bs3 = (Path(__file__).parents[2] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    path = tmp_path / "blip.toml"
    path.write_text(
        bs3.replace('algorithm = "gauss-seidel"', f'algorithm = "{algorithm}"')
        + '\n[[faults]]\nname = "blip"\nkind = "thruster-off"\nstart = 0.021\nstop = 0.025\n'
    )
    lines = [m for m in _warned_over_50_ms(path, fmu_paths, tmp_path) if "faults.blip" in m]
    expected = [
        "faults.blip: start = 0.021 s and stop = 0.025 s lie between two communication "
        "points (0.01 s apart): the fault is active at none, and never acts"
    ]
    assert lines == (expected if warned else [])
    flags = (tmp_path / "run" / "results.csv").read_text().splitlines()
    column = flags[0].split(",").index("fault.blip")
    assert any(row.split(",")[column] != "0" for row in flags[1:]) is not warned
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert [f["name"] for f in summary["faults"]] == ["blip"]


UNWRITABLE_HOME = """
import os, sys
for name in ("XDG_CONFIG_HOME", "XDG_CACHE_HOME", "MPLCONFIGDIR"):
    os.environ.pop(name, None)
os.environ["HOME"], os.environ["TMPDIR"] = sys.argv[1], sys.argv[2]
sys.argv = ["auv-cosim", *sys.argv[3:]]
from cosim.cli import main

sys.exit(main())
"""


@pytest.mark.slow
def test_a_home_that_cannot_be_written_costs_matplotlib_one_line(run_python, tmp_path):
    """With a HOME that cannot be written (a service account's, ``HOME=/nonexistent``),
    a command that draws printed matplotlib's two lines ("mkdir -p failed for path ...",
    "Matplotlib created a temporary cache directory ...") beside its own one-line
    warnings. It says one line, naming the folder and what to set, and leaves no
    temporary folder behind."""
    blocker = tmp_path / "a-file"  # a home below a file: no user, root included, writes it
    blocker.write_text("")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    out = tmp_path / "portrait"
    done = run_python(
        UNWRITABLE_HOME, blocker / "home", scratch, "analyze", "phase-portrait", "--out", out
    )
    assert done.returncode == 0, done.stderr[-2000:]
    said = [line for line in done.stderr.splitlines() if "matplotlib" in line.lower()]
    assert len(said) == 1, done.stderr
    assert said[0].startswith(
        "auv-cosim analyze phase-portrait: warning: matplotlib's folder cannot be written "
        f"(the default path ({blocker}/home/.config/matplotlib)): using a temporary one ("
    )
    assert said[0].endswith("set MPLCONFIGDIR (or HOME) to a writable folder")
    assert (out / "phase_portrait.png").is_file()
    assert [p.name for p in scratch.iterdir() if not p.name.startswith("auv-cosim-scratch")] == []


RELATIVE_HOME = (
    PREAMBLE
    + """sys.argv = ["auv-cosim", *sys.argv[3:]]
from cosim.cli import main

sys.exit(main())
"""
)


@pytest.mark.slow
def test_a_relative_home_puts_nothing_into_the_working_folder(run_python, tmp_path):
    """With ``HOME=home`` (relative), ``auv-cosim analyze phase-portrait --out DIR`` made
    ``home/.config/matplotlib`` and ``home/.cache/matplotlib/fontlist-*.json`` in the
    folder it was run from: matplotlib takes a relative HOME as it is, where auv-cosim's
    own caches ignore it. matplotlib's folder is then the one auv-cosim's caches fall back
    to, absolute, and the working folder is left as it was."""
    scratch, work, out = tmp_path / "tmp", tmp_path / "work", tmp_path / "portrait"
    scratch.mkdir()
    work.mkdir()
    done = run_python(RELATIVE_HOME, scratch, work, "analyze", "phase-portrait", "--out", out)
    assert done.returncode == 0, done.stderr[-2000:]
    assert (out / "phase_portrait.png").is_file()
    assert sorted(str(p.relative_to(work)) for p in work.rglob("*")) == []
    assert "matplotlib" not in done.stderr, done.stderr  # a folder it could write
    assert list(scratch.glob("auv-cosim-cache-*/matplotlib/fontlist-*.json")), list(
        scratch.rglob("*")
    )


MATPLOTLIB_WITHOUT_HOME = """
import os, pwd, sys, warnings
for name in ("HOME", "XDG_CONFIG_HOME", "XDG_CACHE_HOME", "MPLCONFIGDIR"):
    os.environ.pop(name, None)
os.environ["TMPDIR"] = sys.argv[1]


def no_entry(number):  # as for `docker run -u 12345`: a uid /etc/passwd does not list
    raise KeyError(f"getpwuid(): uid not found: {number}")


pwd.getpwuid = no_entry
from cosim.errors import matplotlib_folder_in_one_line, one_line_warnings

warnings.showwarning = one_line_warnings("auv-cosim analyze")
matplotlib_folder_in_one_line()
import matplotlib

matplotlib.get_cachedir()
"""


def test_matplotlib_without_a_home_folder_says_there_is_none(run_python, tmp_path):
    """A uid with no passwd entry and HOME unset (``docker run -u 12345``): the command's
    line about matplotlib's folder read "matplotlib's folder cannot be written (resolving
    the home directory)", matplotlib's words for what went wrong, not which folder. It
    says there is no home folder, and what to set."""
    done = run_python(MATPLOTLIB_WITHOUT_HOME, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    said = [line for line in done.stderr.splitlines() if "matplotlib" in line.lower()]
    assert len(said) == 1, done.stderr
    assert "no home folder" in said[0] and "resolving" not in said[0], said[0]
    assert said[0].endswith("set MPLCONFIGDIR (or HOME) to a writable folder")


def test_python_dash_m_cosim_is_the_command() -> None:
    """``python -m cosim`` said "No module named cosim.__main__" (only ``python -m
    cosim.cli`` worked), where the command's scripts folder is not on PATH."""
    done = run_in_group([sys.executable, "-m", "cosim", "--version"], timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout == f"auv-cosim {importlib.metadata.version('auv-cosim')}\n"


ASCII_LOCALE = {"LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}  # names: ASCII


def _in_ascii_locale(argv: list[str], cwd: Path) -> tuple[int, str, str]:
    """``python -m cosim *argv`` where Python reads file names and writes text as ASCII
    (``LC_ALL=C`` with its UTF-8 mode off): exit code, stdout, stderr."""
    import os

    env = {key: value for key, value in os.environ.items() if key not in ("LANG", "LC_CTYPE")}
    done = run_in_group(
        [sys.executable, "-m", "cosim", *argv], timeout=120, cwd=cwd, env={**env, **ASCII_LOCALE}
    )
    return done.returncode, done.stdout, done.stderr


@pytest.mark.parametrize(
    ("text", "stream", "said"),
    [
        # a value beyond ASCII in a refusal printed on stdout
        ('id = "s"\nstop_time = "zwölf"\n', "out", r"key 'stop_time' = 'zw\xf6lf': "),
        # a path beyond ASCII that the system must be given
        ('id = "s"\nstop_time = 1.0\n[coupling]\nstep = 0.1\n[instances.plant]\n'
         'fmu = "Größe/AuvPlant.fmu"\n', "err",
         r"Gr\xf6\xdfe' holds '\xf6', which this locale's encoding (ascii) has not: set "
         "PYTHONUTF8=1 (or a UTF-8 locale, LC_ALL=C.UTF-8)"),
    ],
)  # fmt: skip
def test_text_beyond_ascii_in_an_ascii_locale_is_said_in_one_line(
    tmp_path: Path, text: str, stream: str, said: str
) -> None:
    """Where Python reads and writes text as ASCII, a scenario file whose text goes beyond
    it ended in "UnicodeEncodeError: 'ascii' codec can't encode characters in position
    12-13: ordinal not in range(128)": printing a refusal that quotes it, or giving a path
    from it to the system. The refusal is printed, the letter escaped, and a path the
    system cannot be given is named with the setting that lets Python give it."""
    (tmp_path / "s.toml").write_text(text, encoding="utf-8")
    code, out, err = _in_ascii_locale(["validate", "s.toml"], tmp_path)
    assert code == 1 and "UnicodeEncodeError" not in out + err, out + err
    shown = {"out": out, "err": err}[stream]
    assert said in shown and shown.count("\n") == 1, shown


@pytest.mark.parametrize("command", ["run", "validate"])
def test_a_file_name_beyond_ascii_is_named_by_its_bytes_in_an_ascii_locale(
    command: str, tmp_path: Path
) -> None:
    """Where Python reads names as ASCII (``LC_ALL=C``, its UTF-8 mode off) a refusal of
    ``fahrt-über.toml`` on stderr (``run``) named "fahrt-\\udcc3\\udcbcber.toml": the
    stand-ins Python read the name's bytes as, escaped, where stdout (``validate``) gives
    the bytes back, which a UTF-8 terminal shows as the name typed."""
    import os

    name = "fahrt-über.toml"
    (tmp_path / name).write_text('stop_time = "zwölf"\n', encoding="utf-8")
    env = {key: value for key, value in os.environ.items() if key not in ("LANG", "LC_CTYPE")}
    done = run_in_group(
        [sys.executable, "-m", "cosim", command, name], timeout=120, cwd=tmp_path,
        env={**env, **ASCII_LOCALE}, text=False,
    )  # fmt: skip
    refusal = done.stderr if command == "run" else done.stdout
    assert done.returncode == 1, done.stderr
    assert name.encode() in refusal and b"\\udc" not in refusal, refusal
    assert refusal.count(b"\n") == 1 and rb"'zw\xf6lf'" in refusal, refusal


@pytest.mark.parametrize("command", ["run", "validate", "export"])
def test_a_file_named_with_a_leading_dash_is_named_with_how_to_give_it(
    command: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A scenario file named ``-fahrt.toml`` given as it is was read as an option:
    "the following arguments are required: scenario" (run) or "unrecognized arguments:
    -fahrt.toml" (validate), neither naming the file. The usage error says how to give it."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "-fahrt.toml").write_text('id = "fahrt"\n', encoding="utf-8")
    with pytest.raises(SystemExit) as ended:
        main([command, "-fahrt.toml", *(["--ssp", "x.ssp"] if command == "export" else [])])
    assert ended.value.code == 2
    err = capsys.readouterr().err
    assert (
        "'-fahrt.toml' is a file, read as an option: give it as ./-fahrt.toml or after --"
        in err.splitlines()[-1]
    ), err


@pytest.mark.parametrize("command", ["run", "validate"])
def test_a_path_holding_a_line_break_is_refused_in_one_line(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A scenario file named with a line break (``neu\\nzeile.toml``, a name a script
    made) was refused on two lines, "scenario file .../neu" and "zeile.toml: key 'id':
    ...": a reader of the first line saw no reason. Control characters in a refusal are
    escaped, as Python writes them."""
    path = tmp_path / "neu\nzeile.toml"
    path.write_text('stop_time = "zwölf"\n', encoding="utf-8")
    assert main([command, str(path)]) == 1
    said = capsys.readouterr()
    refusal = said.out if command == "validate" else said.err
    assert refusal.count("\n") == 1, refusal
    assert "neu\\nzeile.toml" in refusal and "zwölf" in refusal


# the exit codes a command can end with, each shown by a test of this file or of
# tests/cosim/engine/test_run_signals.py: a script tells them apart
EXIT_CODES = ("0", "1", "2", "3", "130", "141", "143", "129")


def _every_parser(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """``parser`` and every command's and analysis's parser under it."""
    yield parser
    for action in parser._subparsers._group_actions if parser._subparsers else ():
        for sub in dict.fromkeys(action.choices.values()):
            yield from _every_parser(sub)


def test_every_help_and_the_readme_list_the_exit_codes(monkeypatch: pytest.MonkeyPatch) -> None:
    """A script telling a failed run from a bad command line or an interrupted one read
    the codes in the README only, without 141 (a reader that stopped, ``| head``), which
    every command ends with as a command ended by SIGPIPE; no ``--help`` said any. Every
    command's help ends with them, and the README and docs/runs.md name each."""
    monkeypatch.setenv("COLUMNS", "80")  # argparse's width, as in an 80-column terminal
    helps = {parser.prog: parser.format_help() for parser in _every_parser(build_parser())}
    assert len(helps) > 10, list(helps)
    for prog, text in helps.items():
        last = " ".join(text.strip().split("\n\n")[-1].split())
        assert last.startswith("exit codes:"), (prog, last)
        assert all(re.search(rf"\b{code}\b", last) for code in EXIT_CODES), (prog, last)
        assert max(map(len, text.splitlines())) <= 80, prog
    root = Path(__file__).parents[2]
    for page in ("README.md", "docs/runs.md"):
        text = " ".join((root / page).read_text(encoding="utf-8").split())
        said = re.search(r"Exit codes[^:]*:(.{0,600})", text)
        assert said is not None, page
        assert all(re.search(rf"\b{code}\b", said[1]) for code in EXIT_CODES), (page, said[1])


def _scenarios_listed(tmp_path: Path, terminal_columns: int | None, columns: str | None) -> str:
    """What ``auv-cosim scenarios`` prints to a terminal of ``terminal_columns`` (a pty), or
    to a pipe (None), with ``COLUMNS`` set to ``columns`` (None: unset)."""
    env = {k: v for k, v in os.environ.items() if k != "COLUMNS"}
    if columns is not None:
        env["COLUMNS"] = columns
    command = [sys.executable, "-m", "cosim.cli", "scenarios"]
    if terminal_columns is None:
        done = run_in_group(command, timeout=120, cwd=tmp_path, env=env)
        assert done.returncode == 0, done.stderr
        return done.stdout
    parent, child = pty.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, terminal_columns, 0, 0))
    shown = b""
    try:
        with started_in_group(command, stdout=child, cwd=tmp_path, env=env) as proc:
            while proc.poll() is None or select.select([parent], [], [], 0.2)[0]:
                if select.select([parent], [], [], 0.2)[0]:
                    shown += os.read(parent, 4096)
            assert proc.returncode == 0
    finally:
        os.close(parent)
        os.close(child)
    return shown.decode().replace("\r\n", "\n")


@pytest.mark.parametrize(("terminal_columns", "columns"), [(40, None), (None, "40"), (120, "40")])
def test_the_scenario_list_fits_a_narrow_terminal(
    terminal_columns: int | None, columns: str | None, tmp_path: Path
) -> None:
    """``auv-cosim scenarios`` in a terminal 40 columns wide (or with ``COLUMNS=40``, which
    takes precedence, as for the help) printed lines of up to 113 characters, which the
    terminal wrapped into the next scenario's id column. Each summary is wrapped within the
    width, under its own column or, when that is too narrow, on lines below its id."""
    from cosim.scenario.spec import builtin_scenarios

    listed = _scenarios_listed(tmp_path, terminal_columns, columns)
    lines = listed.splitlines()
    assert all(len(line) < 40 for line in lines), [line for line in lines if len(line) >= 40]
    ids = [line.split()[0] for line in lines if not line.startswith(" ")]
    scenarios = builtin_scenarios()
    assert ids == list(scenarios)
    assert listed.split() == [word for i, s in scenarios.items() for word in [i, *s.split()]]


def test_the_scenario_list_to_a_pipe_is_a_line_per_scenario(tmp_path: Path) -> None:
    """``auv-cosim scenarios | grep bs-`` (no ``COLUMNS``): one line per scenario, its id
    and its whole summary, whatever the width of the terminal the command runs in."""
    from cosim.scenario.spec import builtin_scenarios

    lines = _scenarios_listed(tmp_path, None, None).splitlines()
    scenarios = builtin_scenarios()
    assert [line.split(maxsplit=1) for line in lines] == [[i, s] for i, s in scenarios.items()]


def _run_in_a_terminal(argv: list[str], term: str, tmp_path: Path) -> bytes:
    """What ``auv-cosim *argv`` writes to a terminal (a pty, 80 columns) whose ``TERM`` is
    ``term``, its stdout and stderr both."""
    parent, child = pty.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    env = {**os.environ, "TERM": term}
    command = [sys.executable, "-m", "cosim.cli", *argv]
    shown = b""
    try:
        with started_in_group(command, stdout=child, stderr=child, cwd=tmp_path, env=env) as proc:
            while proc.poll() is None or select.select([parent], [], [], 0.2)[0]:
                if select.select([parent], [], [], 0.2)[0]:
                    shown += os.read(parent, 65536)
            assert proc.returncode == 0, shown
    finally:
        os.close(parent)
        os.close(child)
    return shown


@pytest.mark.slow
@pytest.mark.parametrize(("term", "bar"), [("dumb", False), ("xterm-256color", True)])
def test_a_dumb_terminal_gets_no_progress_bar(
    term: str, bar: bool, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """Emacs's shell and compilation buffers say ``TERM=dumb``: a terminal that shows a
    carriage return rather than going back with it, where each of the bar's redraws
    stood on the line as ``^M``, dozens in one run. There, as with ``--quiet``, no bar:
    only the lines of the report."""
    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", "bs-3", "--stop-time", "2", "--no-rrd", "--fmu-dir", fmu_dir, "--out", "run"]
    shown = _run_in_a_terminal(argv, term, tmp_path)
    assert shown.startswith(b"scenario bs-3: complete") != bar, shown
    assert (b"\r" in shown.replace(b"\r\n", b"\n")) == bar, shown


@pytest.mark.parametrize("builder", ["ended", pytest.param("between", marks=pytest.mark.slow)])
def test_ctrl_c_while_the_first_run_builds_its_fmus_is_an_interruption(
    builder: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Ctrl-C during a first run's FMU build reaches pythonfmu's builder too (the
    terminal signals the whole process group), which dies of it: the run ended with exit
    code 1 and "pythonfmu could not build AuvPlant.fmu (exit code -2): ... |
    KeyboardInterrupt", a failure to report rather than the interruption it was. Between
    two builds, the build went on and a run of 0 steps was written. Either way it is the
    interruption: exit code 130, one line saying so, no run folder."""
    import signal

    from cosim.errors import CosimError
    from cosim.fmus import build

    built = build.pythonfmu_build

    def interrupted_build(*args: Any, **kwargs: Any) -> Path:
        os.kill(os.getpid(), signal.SIGINT)  # the terminal's Ctrl-C, to this process ...
        if builder == "between":  # ... after the builder ended
            return built(*args, **kwargs)
        raise CosimError(  # ... and to the builder, which it ends
            "pythonfmu could not build AuvPlant.fmu (exit code -2): | KeyboardInterrupt"
        )

    monkeypatch.setattr(build, "pythonfmu_build", interrupted_build)
    out = tmp_path / "run"
    argv = ["run", "bs-3", "--fmu-dir", str(tmp_path / "fmus"), "--out", str(out), "--quiet"]
    assert main([*argv, "--no-rrd"]) == 130
    said = capsys.readouterr().err.strip()
    assert said == "auv-cosim run: interrupted (Ctrl-C) before the first step", said
    assert not out.exists()


def test_build_takes_the_fmu_folder_by_the_name_the_other_commands_give_it() -> None:
    """run, validate, export and sweep name the FMUs' folder ``--fmu-dir``; ``build`` calls
    it ``--out`` and refused ``--fmu-dir`` as an unrecognised argument: it takes both."""
    parser = build_parser()
    assert parser.parse_args(["build", "--fmu-dir", "fmus"]).out == Path("fmus")
    assert parser.parse_args(["build", "--out", "fmus"]).out == Path("fmus")
