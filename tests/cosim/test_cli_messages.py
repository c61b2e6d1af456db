"""The shape of every refusal the command gives a user: a table of bad inputs (flags,
files, values out of range, unknown names) walked through ``auv-cosim`` in-process, each
refused with its documented exit code (1 refused, 2 a command line argparse cannot parse)
and one line on stderr in the command's form, naming the bad value, with no traceback,
no Python type name (``ValueError: ...``) and no repr of a path or a class; and the
refusals that once named the wrong thing (a file's key for a flag, the wrong flag)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import cosim
from cosim.cli import main
from cosim.errors import CosimError

REPO = Path(__file__).parents[2]
# What no refusal shows a user: a traceback, a Python type's name before the message, the
# repr of a path or a class, a None where a value was expected.
NOISE = re.compile(
    r"Traceback|\b[A-Z]\w*(Error|Exception): |PosixPath\(|WindowsPath\(|<class |\bNone\b"
)

BS3_CONNECTIONS = "[connections]                     # same-named outputs -> inputs, except:\n"
BS3_CONNECTIONS += 'remove = ["plant.fin_angle"]'  # bs-3's connections table
BAD_START = '[instances.plant.start]\nvariant = "lateral"'  # bs-3's plant start table
NO_FACTOR = 'scenario = "bs-3"\n[random]\nn = 0\n'  # a study that varies nothing
STUDY = 'scenario = "bs-3"\nstop_time = 1.0\n[grid]\n"plant.v_0" = [-0.1, 0.1]\n'
NOT_VALUES = 'summary = "not a reference value"\n'  # a TOML file, not the printed values

# (command line, the files it needs in the working folder, exit code, what stderr names);
# "{fmus}" is the session's built FMUs.
BAD_INPUTS: list[tuple[str, dict[str, str], int, str]] = [
    ("run no-such-scenario", {}, 1, "unknown scenario 'no-such-scenario'"),
    ("run bs-3 --step 0 --fmu-dir {fmus}", {}, 1, "--step 0.0: expected"),
    ("run lqr-1 --step 0.004 --fmu-dir {fmus}", {}, 1,
     "0.01 s is not a whole number of controller's steps of 0.004 s"),
    ("run bs-3 --stop-time nan --fmu-dir {fmus}", {}, 1, "--stop-time nan: expected"),
    ("run bs-3 --tolerance -1 --fmu-dir {fmus}", {}, 1, "--tolerance -1.0: expected"),
    ("run bs-3 --tolerance 0.01 --fmu-dir {fmus}", {}, 1, "--tolerance 0.01: applies"),
    ("run bs-3 --real-time 0 --no-rrd --fmu-dir {fmus}", {}, 1, "--real-time 0.0: expected"),
    ("run bs-3 --control abc --no-rrd --fmu-dir {fmus}", {}, 1, "'abc'"),
    ("run bs-3 --interactive --no-rrd --fmu-dir {fmus}", {}, 1, "--interactive needs"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|u_0 = '1.5 m/s'"}, 1,
     "'1.5 m/s' is not a number"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|u_0 = 1e9"}, 1,
     "1000000000.0 is outside"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|v_00 = 0.1"}, 1,
     "no variable 'v_00' (did you mean 'v_0'?)"),
    # a time with its unit, or quoted: pydantic's "Input should be a valid number" said
    # neither what was wrong with it nor what to write
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:stop_time = 60.0|stop_time = '60 s'"},
     1, "'stop_time' = '60 s': expected a number, in SI units, without a unit or quotes: 60"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:step = 0.01|step = '0.01'"}, 1,
     "'coupling.step' = '0.01': expected a number, in SI units, without a unit or quotes: 0.01"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|vehicle = 'nosuch'"}, 1,
     "unknown vehicle 'nosuch'"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": f"bs-3:{BAD_START}|[instances.plant.st]"},
     1, "'instances.plant.st'"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|yaw_0 = 1e300"}, 1,
     "'instances.plant.start.yaw_0': 1e+300 is outside [-1000000.0, 1000000.0]"),
    # a depth set-point above the surface: the range alone did not say which way depth counts
    ("run bad.toml --fmu-dir {fmus}",
     {"bad.toml": "bs-3:yaw_setpoint = 0.0|depth_setpoint = -3.0"}, 1,
     "-3.0 is outside [0.0, inf], the range depth_setpoint takes (depths are down positive, "
     "0 m at the surface)"),
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|max_substep = 0"}, 1,
     "'instances.plant.start.max_substep': 0.0 is outside (0.0, inf]"),
    # the smallest subnormal: step / max_substep overflowed to inf ("OverflowError: cannot
    # convert float infinity to integer", a traceback) before the sub-step limit was checked
    ("run bad.toml --fmu-dir {fmus}", {"bad.toml": "bs-3:u_0 = 1.50|max_substep = 5e-324"}, 1,
     "'instances.plant.start.max_substep': plant.max_substep = 5e-324 s would take inf "
     "sub-steps"),
    ("validate bad.toml nothing.fmu --fmu-dir {fmus}", {"bad.toml": "bs-3:"}, 1,
     "FMUs: nothing.fmu"),
    ("export bs-3 --osp taken --fmu-dir {fmus}", {"taken": ""}, 1,
     "cannot write --osp taken: it exists and is not a folder"),
    # a file where a folder of the path goes: the system's "File exists" named nothing
    ("export bs-3 --osp taken/x --fmu-dir {fmus}", {"taken": ""}, 1,
     "cannot write --osp taken/x: taken is a file, not a folder"),
    ("export bs-3 --ssp taken/x.ssp --fmu-dir {fmus}", {"taken": ""}, 1,
     "cannot write --ssp taken/x.ssp: taken is a file, not a folder"),
    ("export bs-3 --ssp theirs.ssp --fmu-dir {fmus}", {"theirs.ssp": "x"}, 1,
     "cannot write --ssp theirs.ssp: it exists and is not an archive"),
    ("export bs-3 --ssp bs-3.zip --fmu-dir {fmus}", {}, 1,
     "cannot write --ssp bs-3.zip: an SSP archive's name ends in '.ssp'"),
    ("view no-such-run", {}, 1, "no-such-run"),
    ("report no-such-run", {}, 1, "no-such-run"),
    ("report taken", {"taken": ""}, 1, "taken is not a folder"),
    ("scenarios --copy bs-9 copy.toml", {}, 1, "unknown scenario 'bs-9'"),
    ("scenarios --copy bs-3 copy.txt", {}, 1, "copy.txt: expected a file name ending"),
    ("build --out taken", {"taken": ""}, 1, "into taken: expected a folder"),
    ("analyze equilibria --thrust nan", {}, 1, "--thrust nan: expected a finite number"),
    ("analyze phase-portrait --roll-torque 1", {}, 1, "--roll-torque 1.0: it acts through"),
    ("analyze equilibria --variant 1 --mass-position 1", {}, 1, "--mass-position 1.0: expected"),
    ("analyze equilibria --current-east 1e3", {}, 1, "--current-east 1000.0: expected"),
    ("analyze sweep mu 1 2 --thrust 0", {}, 1, "--thrust 0.0: expected a thrust > 0"),
    ("analyze equilibria --vehicle nosuch", {}, 1, "unknown vehicle 'nosuch'"),
    ("analyze sweep mu 1 1", {}, 1, "sweep range 1.0 .. 1.0"),
    ("analyze sweep mu 1 2 --steps 1", {}, 1, "--steps 1: expected"),
    ("analyze margins --scale nosuch=1.2", {}, 1, "--scale nosuch=1.2: unknown parameter"),
    ("sweep no-such-study.toml", {}, 1, "no-such-study.toml: no such file"),
    ("sweep study.toml --workers 0 --fmu-dir {fmus}", {"study.toml": STUDY}, 1, "--workers 0"),
    ("sweep study.toml --max-runs 0 --fmu-dir {fmus}", {"study.toml": STUDY}, 1, "--max-runs 0"),
    ("sweep study.toml --overlay 0 --fmu-dir {fmus}", {"study.toml": STUDY}, 1, "--overlay 0"),
    ("sweep study.toml --scheduler nowhere", {"study.toml": STUDY}, 1, "--scheduler nowhere"),
    ("sweep none.toml --workers 1", {"none.toml": NO_FACTOR}, 1, "the study varies nothing"),
    ("reproduce --values no-such.toml", {}, 1, "--values no-such.toml: no such file"),
    ("reproduce --values values.toml", {"values.toml": NOT_VALUES}, 1, "values.toml"),
    ("run bs-3 --algorithm foo", {}, 2, "invalid choice: 'foo'"),
    ("run bs-3 --stop-time 60s", {}, 2, "'60s': expected a number of seconds"),
    ("run -", {}, 2, "'-': expected a scenario id or file"),
    ("view run --file-port abc", {}, 2, "invalid int value: 'abc'"),
    ("analyze sweep nosuch 0 1", {}, 2, "invalid choice: 'nosuch'"),
    ("export bs-3", {}, 2, "one of the arguments --ssp --osp is required"),
    # a misspelt option: the command's own usage and the option it comes closest to, not
    # auv-cosim's list of commands
    ("run bs-3 --stop-tme 5", {}, 2, "--stop-tme 5 (--stop-tme: did you mean '--stop-time'?)"),
    ("report runs/bs-3 --outt x", {}, 2, "unrecognized arguments: --outt x"),
    ("analyze margins --loopp depth", {}, 2, "(--loopp: did you mean '--loop'?)"),
]  # fmt: skip


def _file_text(spec: str) -> str:
    """A file's text: ``"bs-3:OLD|NEW"`` is the built-in scenario with OLD replaced by NEW
    (``"bs-3:"`` as it is), anything else the text itself."""
    if not spec.startswith("bs-3:"):
        return spec
    text = (REPO / "cosim" / "scenarios" / "bs-3.toml").read_text(encoding="utf-8")
    if "|" not in spec:
        return text
    old, new = spec.removeprefix("bs-3:").split("|")
    assert old in text, old
    return text.replace(old, new, 1)


def _exit_code(argv: list[str]) -> int | str | None:
    """The command's exit code: what ``main`` returns, or argparse's exit for a usage
    error (which ``auv-cosim`` makes the process's)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return exc.code


@pytest.mark.parametrize(("command", "files", "code", "names"), BAD_INPUTS)
def test_every_bad_input_is_one_line_naming_it_with_its_exit_code(
    command: str,
    files: dict[str, str],
    code: int,
    names: str,
    fmu_paths: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Each bad input of the table is refused before any work with its exit code (1 a
    refusal, 2 a command line that does not parse, after the command's usage) and one line
    on stderr, "auv-cosim COMMAND: ...", that names the bad value, with no traceback, no
    Python type name, no path or class repr and no None; nothing on stdout."""
    from cosim.study import fork_server

    # a sweep refused when its study file is read: the workers' fork server it starts
    # first (to import beside the reading) is not started here, where no run follows
    monkeypatch.setattr(fork_server, "start", lambda warm=False: False)
    monkeypatch.chdir(tmp_path)
    for name, spec in files.items():
        (tmp_path / name).write_text(_file_text(spec), encoding="utf-8")
    fmus = str(fmu_paths["AuvPlant"].parent)
    argv = [word.replace("{fmus}", fmus) for word in command.split()]
    assert _exit_code(argv) == code
    out, err = capsys.readouterr()
    lines = err.splitlines()
    said = lines[-1] if lines else ""
    assert out == "", out
    if code == 1:  # an analysis is named with its command: "auv-cosim analyze margins: "
        assert len(lines) == 1, err
        command = " ".join(argv[:2]) if argv[0] == "analyze" else argv[0]
        assert said.startswith(f"auv-cosim {command}: "), said
    else:
        assert lines[0].startswith("usage: auv-cosim "), err
        assert re.match(rf"auv-cosim {argv[0]}( \w+)?: error: ", said), said
    assert names in said, said
    assert not NOISE.search(said), said


def test_a_tolerance_out_of_range_names_the_option_not_the_scenario_key(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--tolerance -1`` was refused as the scenario file's "key 'coupling.tolerance' =
    -1.0: Input should be greater than 0", blaming a file the user had not written where
    ``--step -1`` names the flag; both the command line and the API now name the option
    as given and the range it takes."""
    fmus = str(fmu_paths["AuvPlant"].parent)
    out = str(tmp_path / "r")
    for value in ("-1", "1", "nan"):
        argv = ["run", "bs-3", "--algorithm", "adaptive", "--tolerance", value, "--out", out]
        assert main([*argv, "--fmu-dir", fmus]) == 1
        said = capsys.readouterr().err.strip()
        expected = f"auv-cosim run: --tolerance {float(value)}: expected a relative error"
        assert said == f"{expected} > 0 and < 1", said
    with pytest.raises(CosimError) as refused:
        cosim.run("bs-3", algorithm="adaptive", tolerance=-1.0, fmu_dir=fmus)
    assert str(refused.value) == "tolerance=-1.0: expected a relative error > 0 and < 1"
    assert not (tmp_path / "r").exists()


def test_a_tolerance_for_a_fixed_step_run_names_the_algorithm_option(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--tolerance 0.01`` on bs-3 (Gauss-Seidel at a fixed step) was refused as the
    scenario file's key "'coupling.tolerance': applies to algorithm = 'adaptive' only";
    the refusal now names the option given and the one that makes it apply."""
    fmus = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", "bs-3", "--tolerance", "0.01", "--out", str(tmp_path / "r")]
    assert main([*argv, "--fmu-dir", fmus]) == 1
    assert capsys.readouterr().err.strip() == (
        "auv-cosim run: --tolerance 0.01: applies to --algorithm adaptive only, and bs-3 "
        "runs 'gauss-seidel'"
    )
    with pytest.raises(CosimError) as refused:
        cosim.run("bs-3", tolerance=0.01, fmu_dir=fmus)
    assert str(refused.value) == (
        "tolerance=0.01: applies to algorithm='adaptive' only, and bs-3 runs 'gauss-seidel'"
    )


@pytest.mark.parametrize(
    ("options", "said"),
    [
        ("--step 1e-9", "--step 1e-09: scenario file {bs3}: key 'stop_time': 60.0 s is 6e+10 "
         "communication steps of 1e-09 s (coupling.step); at most 1e+08 are run"),
        ("--stop-time 1e12", "--stop-time 1000000000000.0: 1000000000000.0 s is 1e+14 "
         "communication steps of 0.01 s (coupling.step); at most 1e+08 are run"),
        ("--step 200 --stop-time 200", "--step 200.0: plant.max_substep = "
         "0.01 s would take 2e+04 sub-steps per communication step of 200.0 s; at most 10000 "
         "are allowed (max_substep >= 0.02 s)"),
        ("--algorithm adaptive --step 1e-9", "--step 1e-09, --algorithm adaptive: scenario "
         "file {bs3}: key 'stop_time': 60.0 s is 6e+10 communication steps"),
    ],
)  # fmt: skip
def test_a_scenario_an_override_makes_unrunnable_is_refused_naming_the_override(
    options: str,
    said: str,
    fmu_paths: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``auv-cosim run bs-3 --step 1e-9`` was refused as "scenario file bs-3.toml (with the
    override coupling.step = 1e-09): key 'stop_time': ...", blaming a key of a file the
    user had not changed for the flag they typed; each refusal an override causes now
    starts with the flags as given, and an overridden key is named by its flag alone."""
    fmus = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", "bs-3", *options.split(), "--out", str(tmp_path / "r"), "--fmu-dir", fmus]
    assert main(argv) == 1
    bs3 = REPO / "cosim" / "scenarios" / "bs-3.toml"
    err = capsys.readouterr().err.strip()
    assert err.startswith("auv-cosim run: " + said.format(bs3=bs3)), err
    assert not (tmp_path / "r").exists()


def test_a_files_own_key_refused_at_preflight_is_not_blamed_on_an_option(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A file's ``max_substep = 5e-324`` run with ``--stop-time 0.05`` was refused as
    "--stop-time 0.05: scenario file ...: key 'instances.plant.start.max_substep': ...",
    blaming a flag that had nothing to do with it; the refusal now starts with the file
    and names its key, as it does without the flag."""
    bad = tmp_path / "sub.toml"
    bad.write_text(_file_text("bs-3:u_0 = 1.50|max_substep = 5e-324"), encoding="utf-8")
    fmus = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", str(bad), "--stop-time", "0.05", "--out", str(tmp_path / "r")]
    assert main([*argv, "--fmu-dir", fmus]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(
        f"auv-cosim run: scenario file {bad}: key 'instances.plant.start.max_substep': "
        "plant.max_substep = 5e-324 s would take inf sub-steps"
    ), err
    assert not (tmp_path / "r").exists()


def test_a_scenario_an_override_makes_unrunnable_names_the_python_keyword(
    fmu_paths: dict[str, Path],
) -> None:
    """``cosim.run(..., step=1e-9)`` names the keyword it was given, as the command line
    names its flag."""
    with pytest.raises(CosimError) as refused:
        cosim.run("bs-3", step=1e-9, fmu_dir=fmu_paths["AuvPlant"].parent)
    assert str(refused.value).startswith("step=1e-09: scenario file "), refused.value


def test_an_analysis_condition_out_of_range_names_the_flag_not_the_keyword(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``auv-cosim analyze equilibria --thrust -1`` said "thrust = -1.0 N: expected a
    thrust > 0", the model's Python keyword for the flag the user typed; the command line
    names its flag and Python callers keep their keyword."""
    from cosim.analysis.bifurcation import OperatingConditions
    from plant_fmu.model.parameters import load_vehicle

    assert main(["analyze", "equilibria", "--thrust", "-1"]) == 1
    said = capsys.readouterr().err.strip()
    assert said.startswith(
        "auv-cosim analyze equilibria: --thrust -1.0: expected a thrust > 0 ("
    ), said
    with pytest.raises(CosimError, match=r"^thrust = -1\.0 N: expected a thrust > 0"):
        OperatingConditions(load_vehicle("remus100"), thrust=-1.0)


def test_a_build_folder_that_cannot_be_made_names_the_builds_own_option(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``auv-cosim build --out FILE`` ended "name a folder you can write with --fmu-dir
    (fmu_dir= in Python)", options ``build`` and ``cosim.build_fmus`` do not take: both
    name their own, ``--out`` and ``out=``."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "taken").write_text("a file, not a folder", encoding="utf-8")
    assert main(["build", "--out", "taken/fmus"]) == 1
    said = capsys.readouterr().err.strip()
    assert said.endswith("name a folder you can write with --out (out= in Python)"), said
    with pytest.raises(CosimError) as refused:
        cosim.build_fmus("taken/fmus")
    assert str(refused.value).endswith("with --out (out= in Python)"), refused.value


def test_printed_values_that_do_not_read_are_named_by_their_file(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``auv-cosim reproduce --values FILE`` with a TOML file that holds no printed values
    said "ReferenceValueError: reference value 'summary': ...": a Python type's name, and
    not the file it read."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "values.toml").write_text(NOT_VALUES, encoding="utf-8")
    assert main(["reproduce", "--values", "values.toml", "--skip-scenarios"]) == 1
    assert capsys.readouterr().err.strip() == (
        "auv-cosim reproduce: reference values 'values.toml': entry 'summary': expected a "
        "table with value, unit, source and description, got 'not a reference value'"
    )


@pytest.mark.parametrize(
    ("name", "text", "said"),
    [
        ("bad.toml", "bs-3:[coupling]\nstep = 0.01|coupling = 0.01\n[c]\nstep = 0.01",
         "scenario file bad.toml: key 'coupling' = 0.01: expected a table"),
        # [[connections]] (TOML's array of tables, as other tools write connections)
        ("bad.toml", f"bs-3:{BS3_CONNECTIONS}|[[connections]]\nfrom = 'plant.yaw'\n"
         "to = 'controller.yaw'\n[[connections]]\nfrom = 'plant.r'\nto = 'controller.r'",
         "scenario file bad.toml: key 'connections' = [{'from': 'plant.yaw', 'to': "
         "'controller.yaw'}, {'from': 'plant.r', 'to': 'controller.r'}]: expected a table "
         "([connections] with add = [{ from = \"a.y\", to = \"b.u\" }], not "
         "[[connections]]: docs/scenario-example.toml)"),
        ("bad.toml", "id = 'bad'\nstop_time = 1.0\n[coupling]\nstep = 0.01\n[[instances]]\n"
         "fmu = 'AuvPlant'",
         "scenario file bad.toml: key 'instances' = [{'fmu': 'AuvPlant'}]: expected a table "
         "([instances.NAME] with fmu = ..., not [[instances]]: docs/scenario-example.toml)"),
        ("study.toml", "metrics = ['yaw_settling_time_s']\n" + STUDY,
         "study file study.toml: key 'metrics' = ['yaw_settling_time_s']: expected a table"),
    ],
)  # fmt: skip
def test_a_value_where_a_table_goes_is_refused_without_a_class_name(
    name: str,
    text: str,
    said: str,
    fmu_paths: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``coupling = 0.01`` in a scenario, ``metrics = [...]`` in a study: refused as
    pydantic's "Input should be a valid dictionary or instance of CouplingSpec", a class
    of the code the user never wrote and a Python word for a TOML table; ``[[connections]]``
    and ``[[instances]]`` (arrays of tables, as other tools write them) are told how this
    file writes them."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / name).write_text(_file_text(text), encoding="utf-8")
    fmus = str(fmu_paths["AuvPlant"].parent)
    command = "run" if name == "bad.toml" else "sweep"
    assert main([command, name, "--fmu-dir", fmus]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"auv-cosim {command}: {said}"), err
    assert "instance of" not in err and "dictionary" not in err, err


@pytest.mark.parametrize("overlay", ["0", "21"])
def test_an_overlay_out_of_range_is_refused_before_the_cluster_starts(
    overlay: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """``auv-cosim sweep STUDY --overlay 0`` started the workers' fork server and a local
    Dask cluster and built the FMUs (20 s on a busy machine) before refusing the flag, as
    ``--workers 0`` is refused at once."""
    from cosim.study import fork_server

    def started(warm: bool = False) -> None:
        raise AssertionError("the workers' fork server started before --overlay was checked")

    monkeypatch.setattr(fork_server, "start", started)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "study.toml").write_text(STUDY, encoding="utf-8")
    assert main(["sweep", "study.toml", "--overlay", overlay]) == 1
    assert capsys.readouterr().err.strip() == (
        f"auv-cosim sweep: --overlay {overlay}: expected a number of runs from 1 to 20"
    )


def test_a_factor_value_a_scenario_refuses_is_named_once(
    fmu_paths: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """A grid value the scenario refuses was said twice: "factor values {'plant.v_0':
    'x'}: scenario file bs-3 with {'plant.v_0': 'x'}: key ...". It is said once, before
    what the scenario refuses of it, as the study file writes it (the values were a
    Python dict's repr, braces and all)."""
    from cosim.study import fork_server

    monkeypatch.setattr(fork_server, "start", lambda warm=False: False)  # refused before any run
    monkeypatch.chdir(tmp_path)
    (tmp_path / "study.toml").write_text(STUDY.replace("0.1]", "'x']"), encoding="utf-8")
    fmus = str(fmu_paths["AuvPlant"].parent)
    assert main(["sweep", "study.toml", "--fmu-dir", fmus]) == 1
    assert capsys.readouterr().err.strip() == (
        "auv-cosim sweep: the run with plant.v_0 = 'x': scenario file bs-3: key "
        "'instances.plant.start.v_0': 'x' is not a number (v_0 is Real): expected a number "
        "of m/s"
    )
