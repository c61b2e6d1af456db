"""A mistyped name in a scenario or study file is refused with the name it was probably
meant to be; a name close to nothing, or as close to two names, gets no guess."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import load_scenario, scenario_from_toml, scenario_id
from cosim.study.spec import StudyError, study_from_dict

BS3_LIKE = """
stop_time = 1.0
[coupling]
step = 0.01
[instances.plant]
fmu = "AuvPlant"
[instances.controller]
fmu = "AuvAutopilot"
"""


@pytest.mark.parametrize(
    ("change", "guess"),
    [
        (("stop_time = 1.0", "stop_tme = 1.0"),
         "unknown key 'stop_tme' (did you mean 'stop_time'?)"),
        (("step = 0.01", "step = 0.01\nalgoritm = 'jacobi'"),
         "unknown key 'coupling.algoritm' (did you mean 'algorithm'?)"),
        (('fmu = "AuvPlant"', 'fmu = "AUVPlant"'),
         "'AUVPlant' (did you mean 'AuvPlant'?) is neither"),
        (('fmu = "AuvPlant"', 'fmu = "AuvPlant"\nstart = { u0 = 1.5 }'),
         "has no variable 'u0' (did you mean 'u_0'?)"),
        (("step = 0.01", "step = 0.01\n[output]\nrecord = ['plant.yawn']"),
         "has no variable 'yawn' (did you mean 'yaw'?)"),
        (("step = 0.01", "step = 0.01\n[output]\nrecord = ['plnt.yaw']"),
         "with an instance in ['plant', 'controller'] (did you mean 'plant'?)"),
        # a letter for a digit: too short for difflib, and docs/api.md's own example
        (('fmu = "AuvPlant"', 'fmu = "AuvPlant"\nstart = { v_O = -0.05 }'),
         "has no variable 'v_O' (did you mean 'v_0'?)"),
        (('fmu = "AuvPlant"', 'fmu = "AuvPlant"\nstart = { yaw_o = 0.1 }'),
         "has no variable 'yaw_o' (did you mean 'yaw_0'?)"),
        (("stop_time = 1.0", 'stop_time = 1.0\nmanoeuvre = "zig-zag"'),
         "'zig-zag' is not a manoeuvre (did you mean 'zigzag'?)"),
    ],
)  # fmt: skip
def test_a_mistyped_scenario_name_is_refused_with_its_likely_meaning(
    change: tuple[str, str], guess: str, fmu_dir: Path
) -> None:
    text = BS3_LIKE.replace(*change, 1)
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert guess in str(refused.value)


def test_a_mistyped_instance_in_a_start_value_is_refused_with_its_likely_meaning(
    fmu_dir: Path,
) -> None:
    scenario = scenario_from_toml(BS3_LIKE, fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError, match=r"\(did you mean 'plant'\?\)$"):
        scenario.with_start({"plnt.v_0": 0.1})


def test_a_mistyped_scenario_id_is_refused_with_its_likely_meaning() -> None:
    with pytest.raises(ScenarioError, match=r"unknown scenario 'bs3' \(did you mean 'bs-3'\?\)"):
        load_scenario("bs3")


def test_a_name_close_to_nothing_or_to_two_gets_no_guess(fmu_dir: Path) -> None:
    text = BS3_LIKE.replace("stop_time = 1.0", "stop_time = 1.0\nwobble = 3", 1)
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert "unknown key 'wobble': the file's top level takes " in str(refused.value)
    assert "did you mean" not in str(refused.value)
    with pytest.raises(ScenarioError) as refused:
        load_scenario("bs-9")  # bs-1, bs-2 or bs-3?
    assert "did you mean" not in str(refused.value)


@pytest.mark.parametrize(
    ("change", "refusal"),
    [
        # "stop" was met with "did you mean 'step'?", a key of [coupling], not of the top level
        (("stop_time = 1.0", "stop = 1.0"),
         "unknown key 'stop': the file's top level takes connections, coupling, events, "),
        # as close to 'step' as to the top level's 'stop': no guess was made
        (("step = 0.01", "stp = 0.01"), "unknown key 'coupling.stp' (did you mean 'step'?)"),
        (("step = 0.01", "step = 0.01\nmethod = 'jacobi'"),
         "unknown key 'coupling.method': [coupling] takes algorithm, error_estimate, "),
        (('fmu = "AuvPlant"', 'model = "AuvPlant"'),
         "unknown key 'instances.plant.model': [instances.plant] takes debug_logging, fmu, "
         "log_categories and start"),
    ],
)  # fmt: skip
def test_an_unknown_key_is_matched_against_its_own_table_or_gets_its_keys(
    change: tuple[str, str], refusal: str, fmu_dir: Path
) -> None:
    text = BS3_LIKE.replace(*change, 1)
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert refusal in str(refused.value)


def test_a_mistyped_study_key_is_refused_with_its_likely_meaning() -> None:
    with pytest.raises(StudyError, match=r"unknown key 'metricz' \(did you mean 'metrics'\?\)"):
        study_from_dict({"scenario": "bs-3", "grid": {"plant.v_0": [0.1]}, "metricz": {}}, "s")


def test_a_mistyped_path_is_refused_with_the_likely_one(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run folder to view or report, or a scenario file, a letter off what exists."""
    run_dir = tmp_path / "runs" / "bs-3"
    run_dir.mkdir(parents=True)
    (tmp_path / "mine.toml").write_text("")
    for argv, meant in (
        (["view", str(tmp_path / "runs" / "bs3")], run_dir),
        (["report", str(tmp_path / "runs" / "bs3")], run_dir),
        (["run", str(tmp_path / "mine.tom")], tmp_path / "mine.toml"),
    ):
        assert main(argv) == 1
        assert f"(did you mean '{meant}'?)" in capsys.readouterr().err, argv


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (("[instances.controller]", '[instances."my.controller"]'),
         "key 'instances.my.controller' = 'my.controller': expected a name of ASCII letters "
         "(A-Z, a-z), digits and _, not starting with a digit"),
        (("stop_time = 1.0", 'stop_time = 1.0\nid = "-x"'),
         "key 'id' = '-x': expected a name of ASCII letters (A-Z, a-z), digits, _, . and -, "
         "not starting with"),
        (("stop_time = 1.0", 'stop_time = 1.0\n[[events]]\nname = "a turn"\ntime = 1.0'),
         "key 'events[0].name' = 'a turn': expected a name of ASCII letters (A-Z, a-z), "
         "digits, - and _"),
    ],
)  # fmt: skip
def test_a_name_that_is_not_plain_is_refused_in_words_not_a_pattern(
    change: tuple[str, str], expected: str, fmu_dir: Path
) -> None:
    """A dotted instance name was refused with pydantic's "String should match pattern
    '^[A-Za-z_][A-Za-z0-9_]*$'" under the key 'instances.my.controller.[key]'."""
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(BS3_LIKE.replace(*change, 1), fmu_dir=fmu_dir)
    assert expected in str(refused.value) and "[key]" not in str(refused.value)
    assert "pattern" not in str(refused.value)


@pytest.mark.parametrize(
    ("change", "name"),
    [
        (("[instances.controller]", '[instances."regler_ü"]'), "'instances.regler_ü'"),
        (("stop_time = 1.0", 'stop_time = 1.0\nid = "größe"'), "'id'"),
        (("stop_time = 1.0", 'stop_time = 1.0\n[[events]]\nname = "wende-ç"\ntime = 1.0'),
         "'events[0].name'"),
    ],
)  # fmt: skip
def test_a_name_with_a_letter_beyond_ascii_is_refused_saying_ascii(
    change: tuple[str, str], name: str, fmu_dir: Path
) -> None:
    """An instance, id or event named with an umlaut or a cedilla was refused as
    "expected a name of letters, digits and _": ü is a letter, so the user read the rule
    as kept. Names stay ASCII (a column of results.csv, a folder, an SSP identifier); the
    refusal says so."""
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(BS3_LIKE.replace(*change, 1), fmu_dir=fmu_dir)
    assert f"key {name}" in str(refused.value), refused.value
    assert "expected a name of ASCII letters (A-Z, a-z), digits" in str(refused.value)


def test_a_file_name_with_a_letter_beyond_ascii_asks_for_an_id(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A scenario file named ``fahrt-ü.toml`` without an ``id`` was refused as "the file
    name 'fahrt-ü' is not a plain name (letters, digits, _ . -, ...)"."""
    path = tmp_path / "fahrt-ü.toml"
    path.write_text(BS3_LIKE, encoding="utf-8")
    with pytest.raises(ScenarioError) as refused:
        load_scenario(path, fmu_dir=fmu_dir)
    assert "the file name 'fahrt-ü' is not a plain name (ASCII letters (A-Z, a-z), digits," in (
        str(refused.value)
    )


def test_a_file_name_with_a_space_says_which_id_to_set(fmu_dir: Path, tmp_path: Path) -> None:
    """A scenario file a student saved as ``my lab.toml`` was refused ending "...: set
    id", which said neither where nor to what; the line now gives a plain name to use."""
    path = tmp_path / "my lab.toml"
    path.write_text(BS3_LIKE, encoding="utf-8")
    with pytest.raises(ScenarioError) as refused:
        load_scenario(path, fmu_dir=fmu_dir)
    assert str(refused.value).endswith(
        'rename the file my-lab.toml, or set id = "my-lab" at its top'
    ), refused.value


MISPLACED = "a top-level key: TOML puts every key below a [table] or [[table]] header into it"


@pytest.mark.parametrize(
    ("text", "key"),
    [
        (BS3_LIKE.replace("stop_time = 1.0\n", "") + "stop_time = 1.0\n",
         "instances.controller.stop_time"),
        (BS3_LIKE + '[[faults]]\nkind = "mass-jam"\nstart = 0.5\nstop_time = 1.0\n',
         "faults[0].stop_time"),
    ],
)  # fmt: skip
def test_a_top_level_key_written_below_a_table_is_named_as_such(
    text: str, key: str, fmu_dir: Path
) -> None:
    """``stop_time = 60.0`` appended to the README's turn.toml, after its ``[[faults]]``,
    was refused as "unknown key 'faults[0].stop_time'" (and "key 'stop_time' is missing"
    when moved there): TOML reads it into the table above, which the message now says."""
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    message = str(refused.value)
    assert f"unknown key {key!r} ({MISPLACED}; write stop_time before the first header)" in (
        message
    ), message


@pytest.mark.parametrize(
    ("study", "key"),
    [
        ({"grid": {"plant.v_0": [0.1], "stop_time": 2.0}}, "grid.stop_time"),
        ({"grid": {"plant.v_0": [0.1]}, "random": {"n": 0, "keep": "all"}}, "random.keep"),
    ],
)
def test_a_top_level_study_key_written_below_a_table_is_named_as_such(
    study: dict[str, object], key: str
) -> None:
    """``stop_time = 2.0`` below ``[grid]`` was "key 'grid.stop_time' = 2.0: Input should
    be a valid list": a factor, to pydantic; to the user a top-level key in the wrong
    place."""
    with pytest.raises(StudyError) as refused:
        study_from_dict({"scenario": "bs-3", **study}, "s")
    name = key.rpartition(".")[2]
    assert f"key {key!r} ({MISPLACED}; write {name} before the first header)" in str(
        refused.value
    ), refused.value


@pytest.mark.parametrize(
    ("change", "refusal"),
    [
        # a coupling key written at the top of the file, above [coupling]
        (("stop_time = 1.0", "stop_time = 1.0\nstep = 0.02"),
         "unknown key 'step' (a key of [coupling]: write it below the [coupling] header)"),
        (("stop_time = 1.0", "stop_time = 1.0\nalgorithm = 'jacobi'"),
         "unknown key 'algorithm' (a key of [coupling]: write it below the [coupling] "),
        # a start value written in the instance's own table, not in its [.start] table
        (('fmu = "AuvAutopilot"', 'fmu = "AuvAutopilot"\nyaw_setpoint = 0.5'),
         "unknown key 'instances.controller.yaw_setpoint': [instances.controller] takes "
         "debug_logging, fmu, log_categories and start (a start value goes below "
         "[instances.controller.start])"),
        # a coupling key written among an instance's start values
        (('fmu = "AuvAutopilot"', 'fmu = "AuvAutopilot"\nstart = { step = 0.02 }'),
         "has no variable 'step' (a key of [coupling]: write it below the [coupling] header)"),
    ],
)  # fmt: skip
def test_a_key_written_in_the_wrong_table_names_the_table_it_belongs_to(
    change: tuple[str, str], refusal: str, fmu_dir: Path
) -> None:
    """A student who put ``step = 0.02`` at the top of a copied scenario was told only what
    the top level takes; one who put ``yaw_setpoint`` below ``[instances.controller]``
    only that the table takes fmu and start: neither said where the key goes."""
    text = BS3_LIKE.replace(*change, 1)
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert refusal in str(refused.value), refused.value


@pytest.mark.parametrize(
    ("written", "meant"),
    [("LQR", "lqr"), ("backsteping", "backstepping"), ("sliding mode", "sliding_mode"),
     ("Backstepping", "backstepping")],
)  # fmt: skip
def test_a_mistyped_controller_name_is_refused_with_its_likely_meaning(
    written: str, meant: str, fmu_dir: Path
) -> None:
    """``heading_mode = "LQR"`` was refused listing every mode, without saying that the
    lower-case 'lqr' is the one meant."""
    text = BS3_LIKE.replace(
        'fmu = "AuvAutopilot"', f'fmu = "AuvAutopilot"\nstart = {{ heading_mode = "{written}" }}'
    )
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert f"{written!r} is not a heading_mode (did you mean {meant!r}?): expected one of " in (
        str(refused.value)
    ), refused.value


def test_a_scenario_file_named_without_its_toml_gets_the_file_as_its_likely_meaning(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``auv-cosim run lab1`` beside the student's own ``lab1.toml`` was refused as an
    unknown built-in id, listing the built-in ids and not the file."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "lab1.toml").write_text("stop_time = 1.0\n")
    with pytest.raises(
        ScenarioError, match=r"unknown scenario 'lab1' \(did you mean 'lab1\.toml'\?\)"
    ):
        load_scenario("lab1")


@pytest.mark.parametrize(
    ("change", "refusal"),
    [
        # a decimal comma, as a spreadsheet in many languages writes a number
        (("step = 0.01", "step = 0,01"),
         "(at line 4, column 9): write a decimal point, not a comma: 0.01"),
        # a name left unquoted
        (('fmu = "AuvPlant"', "fmu = AuvPlant"),
         '(at line 6, column 7): a string is quoted: "AuvPlant"'),
        # a unit typed after the number
        (("stop_time = 1.0", "stop_time = 60 s"),
         "(at line 2, column 16): a number stands alone, in SI units (here 60)"),
        # a key given twice: a gain added below one the copied file already sets
        (("step = 0.01", "step = 0.01\nstep = 0.02"),
         "(at line 5, column 12): 'step' is given twice in its table; keep one"),
    ],
)  # fmt: skip
def test_a_toml_slip_is_named_with_the_fix(
    change: tuple[str, str], refusal: str, fmu_dir: Path
) -> None:
    """``u_0 = 1,5``, ``heading_mode = backstepping``, ``stop_time = 60 s`` and a key given
    twice were refused with tomllib's words alone ("Expected newline or end of document
    after a statement", "Invalid value", "Cannot overwrite a value"), which do not say what
    to write instead."""
    text = BS3_LIKE.replace(*change, 1)
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert str(refused.value).endswith(refusal), refused.value


@pytest.mark.parametrize(
    ("change", "guess"),
    [
        (("step = 0.01", "step = 0.01\nalgorithm = 'gauss_seidel'"), "'gauss-seidel'"),
        (("step = 0.01", "step = 0.01\nalgorithm = 'Jacobi'"), "'jacobi'"),
        (("stop_time = 1.0", "stop_time = 1.0\n[[faults]]\nkind = 'thruster_off'"),
         "'thruster-off'"),
    ],
)  # fmt: skip
def test_a_mistyped_choice_of_the_file_is_refused_with_its_likely_meaning(
    change: tuple[str, str], guess: str, fmu_dir: Path
) -> None:
    """``kind = "thruster_off"`` was refused with pydantic's "Input should be 'stuck', ...
    or 'plane-stuck'", not saying which one was meant."""
    text = BS3_LIKE.replace(*change, 1)
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_dir)
    assert f"(did you mean {guess}?)" in str(refused.value), refused.value


def test_a_file_name_in_bytes_that_are_no_utf8_is_named_as_the_file_is(tmp_path: Path) -> None:
    """A scenario file named in Latin-1 (``l\\xf6.toml``) was refused naming the file by its
    bytes but its name as Python's repr of them, ``'l\\udcf6'``: the name the line gives is
    the file's own, its bytes written as the command line writes the file's path."""
    path = Path(os.fsdecode(bytes(tmp_path) + b"/l\xf6.toml"))
    path.write_text(BS3_LIKE, encoding="utf-8")
    with pytest.raises(ScenarioError) as refused:
        scenario_id(path)
    message = str(refused.value)
    shown = ascii(message)  # pytest's workers send a report only in UTF-8
    assert f"scenario file {path}: key 'id'" in message, shown
    assert f"the file name '{path.stem}' is not a plain name" in message, shown
    assert "\\udcf6" not in message, shown
