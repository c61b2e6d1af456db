"""Study files: every key checked, a clear error naming the file and the key, data only."""

from __future__ import annotations

from pathlib import Path

import pytest
from sweep_helpers import GRID_STUDY

from cosim.study.spec import (
    Normal,
    StudyError,
    Uniform,
    check_size,
    load_study,
    study_from_dict,
)

MINIMAL = {"scenario": "bs-3", "grid": {"plant.v_0": [-0.1, 0.1]}}


def test_the_grid_example_reads_with_its_defaults(tmp_path: Path) -> None:
    path = tmp_path / "study.toml"
    path.write_text(GRID_STUDY, encoding="utf-8")
    spec = load_study(path)
    assert spec.factors == ["plant.v_0", "controller.k0"]
    assert spec.stop_time == 20.0 and spec.keep == "none" and spec.metrics.collect is None
    assert spec.random.n == 0 and spec.random.sampling == "random"


def test_random_factors_sit_beside_n_and_seed() -> None:
    spec = study_from_dict(
        {
            "scenario": "bs-3",
            "random": {
                "n": 5,
                "seed": 3,
                "sampling": "latin-hypercube",
                "plant.current_east": {"uniform": [0, 0.3]},
                "plant.yaw_0": {"normal": [0.0, 0.1]},
            },
        },
        "s.toml",
    )
    assert spec.random.factors == {
        "plant.current_east": Uniform(uniform=(0.0, 0.3)),
        "plant.yaw_0": Normal(normal=(0.0, 0.1)),
    }
    assert spec.factors == ["plant.current_east", "plant.yaw_0"]


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"gird": {}}, "unknown key 'gird'"),
        ({"factors": {"plant.v_0": [0.1]}}, "unknown key 'factors'"),
        ({"uniform": [1, 2]}, "unknown key 'uniform'"),
        ({"scenario": None}, "key 'scenario' is missing"),
        ({"stop_time": "20"}, "key 'stop_time' = '20': expected a number"),
        ({"stop_time": -1.0}, "key 'stop_time' = -1.0"),
        ({"keep": "some"}, "key 'keep' = 'some'"),
        ({"grid": {"plant.v_0": [0.1, 0.1]}}, "lists a value twice"),
        ({"grid": {"plant.v_0": []}}, "key 'grid.plant.v_0' = []"),
        # one value where the grid takes a list: pydantic's "Input should be a valid list"
        (
            {"grid": {"plant.v_0": -0.1}},
            "key 'grid.plant.v_0' = -0.1: expected a list of values, [-0.1]",
        ),
        ({"grid": {"plant.v_0": [[1]]}}, "expected a number, an integer, true/false or a string"),
        ({"grid": {"v_0": [1.0]}}, "factor 'v_0': expected <instance>.<variable>"),
        ({"grid": {}}, "the study varies nothing"),
        ({"random": {"n": 4, "seed": 1}}, "n = 4 but no factor to sample"),
        ({"random": {"n": 0, "plant.u_0": {"uniform": [1, 2]}}}, "has factors but n = 0"),
        ({"random": {"n": 2, "plant.u_0": {"uniform": [2, 1]}}}, "low < high"),
        ({"random": {"n": 2, "plant.u_0": {"normal": [0, 0]}}}, "std > 0"),
        ({"random": {"n": 2, "plant.u_0": {"beta": [1, 2]}}}, "expected { uniform"),
        ({"random": {"n": 2, "sampling": "sobol", "plant.u_0": {"uniform": [1, 2]}}}, "sobol"),
        ({"random": {"n": 2, "plant.v_0": {"uniform": [1, 2]}}}, "both in [grid] and in [random]"),
        # a key no name is close to: the table's keys are named (the sample count is n)
        (
            {"random": {"samples": 4, "plant.u_0": {"uniform": [1, 2]}}},
            "unknown key 'random.samples': [random] takes n, sampling, seed and factors "
            "as 'instance.variable' keys",
        ),
        ({"metrics": {"colect": ["final.plant.yaw"]}}, "(did you mean 'collect'?)"),
        ({"metrics": {"metric": ["final.plant.yaw"]}}, "[metrics] takes collect"),
        ({"metrics": {"collect": []}}, "key 'metrics.collect' = []"),
        # a metric listed twice was merged without a word, a grid value twice refused
        ({"metrics": {"collect": ["final.plant.yaw", "final.plant.yaw"]}}, "lists a value twice"),
    ],
)
def test_bad_study_names_the_file_and_the_key(change: dict, expected: str) -> None:
    data = {**MINIMAL, **change}
    data = {k: v for k, v in data.items() if v is not None}
    with pytest.raises(StudyError) as info:
        study_from_dict(data, "study file my-study.toml")
    assert str(info.value).startswith("study file my-study.toml: ")
    assert expected in str(info.value)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"scenario": 3}, "key 'scenario' = 3: expected a text"),
        ({"overlay": []}, "key 'overlay' = []: expected at least 1 item"),
        ({"grid": {"plant.v_0": []}}, "key 'grid.plant.v_0' = []: expected at least 1 item"),
        ({"keep": "some"}, "key 'keep' = 'some': expected 'all', 'failed' or 'none'"),
        ({"stop_time": -1.0}, "key 'stop_time' = -1.0: expected a number greater than 0"),
    ],
)
def test_a_study_refusal_says_what_is_expected_in_the_houses_words(
    change: dict, expected: str
) -> None:
    """A study's value of the wrong type or size was refused in pydantic's words ("Input
    should be a valid string", "List should have at least 1 item after validation, not
    0"); the refusal says what is expected as every other refusal does, naming the key and
    the value."""
    with pytest.raises(StudyError) as info:
        study_from_dict({**MINIMAL, **change}, "study file my-study.toml")
    assert str(info.value) == f"study file my-study.toml: {expected}"


def test_a_study_file_is_data_never_code(tmp_path: Path) -> None:
    # an expression is a string (the scenario then refuses it for a Real), never evaluated
    path = tmp_path / "study.toml"
    marker = tmp_path / "evaluated"
    expression = f"__import__('pathlib').Path({str(marker)!r}).touch() or 0.1"
    path.write_text(f'scenario = "bs-3"\n[grid]\n"plant.v_0" = ["{expression}"]\n', "utf-8")
    assert load_study(path).grid["plant.v_0"] == [expression]
    assert not marker.exists()
    path.write_text('scenario = "bs-3"\nstop_time = "2 * 10"\n[grid]\n"plant.v_0" = [0.1]\n')
    with pytest.raises(StudyError, match="stop_time"):
        load_study(path)


def test_unreadable_and_invalid_files_are_named(tmp_path: Path) -> None:
    with pytest.raises(StudyError, match=r"missing\.toml: no such file; expected a study"):
        load_study(tmp_path / "missing.toml")  # the path once (it was named twice)
    with pytest.raises(StudyError, match="cannot read it"):
        load_study(tmp_path)  # a folder
    bad = tmp_path / "bad.toml"
    bad.write_text("scenario = \n", encoding="utf-8")
    with pytest.raises(StudyError, match=r"bad\.toml: not valid TOML"):
        load_study(bad)


def test_a_study_given_through_a_pipe_is_refused_saying_why(tmp_path: Path) -> None:
    """``auv-cosim sweep <(make-study)``: the study file is read twice (its size is
    checked before the cluster starts), and the second read of the pipe found it empty:
    "key 'scenario' is missing"; a FIFO with no writer hung the command for ever."""
    import os

    read, write = os.pipe()
    try:
        os.write(write, b'scenario = "bs-3"\n[grid]\n"plant.v_0" = [0.1]\n')
        os.close(write)
        with pytest.raises(StudyError, match="cannot read it: a pipe or a device, not a file"):
            load_study(Path(f"/dev/fd/{read}"))
    finally:
        os.close(read)


def test_a_study_file_with_a_byte_order_mark_reads_as_a_scenario_file_does(
    tmp_path: Path,
) -> None:
    """A study file saved with a byte-order mark (some Windows editors write one) was
    "not valid TOML (at line 1, column 1)"; a file that is not UTF-8 ended in a traceback,
    then in the codec's words ("cannot read it: 'utf-8' codec can't decode byte 0xb0 in
    position 21"), not saying it was no UTF-8 nor where."""
    marked = tmp_path / "marked.toml"
    marked.write_bytes(b"\xef\xbb\xbf" + b'scenario = "bs-3"\n[grid]\n"plant.v_0" = [0.1]\n')
    assert load_study(marked).scenario == "bs-3"
    latin = tmp_path / "latin.toml"
    latin.write_bytes('scenario = "bs-3" # \u00b0\n'.encode("latin-1"))
    with pytest.raises(StudyError) as info:
        load_study(latin)
    assert str(info.value) == (
        f"study file {latin}: not UTF-8 text: byte 0xb0 at line 1, column 21; save it as UTF-8"
    )


def test_factors_written_as_toml_dotted_keys_are_the_quoted_factors(tmp_path: Path) -> None:
    """TOML reads an unquoted ``plant.v_0 = [...]`` (or a ``[grid.plant]`` table) as a
    table ``plant`` holding ``v_0``: the study refused it ("key 'grid.plant' = {'v_0':
    [...]}: Input should be a valid list", "unknown key 'random.plant'") though it is the
    same file as the quoted keys; a name written both ways is refused, not one dropped."""
    path = tmp_path / "study.toml"
    path.write_text(
        'scenario = "bs-3"\n[grid]\nplant.v_0 = [-0.1, 0.1]\n[grid.controller]\nk0 = [0.2]\n'
        "[random]\nn = 2\nplant.yaw_0 = { normal = [0.0, 0.1] }\n"
        "events.turn.time.uniform = [5.0, 10.0]\n",
        encoding="utf-8",
    )
    spec = load_study(path)
    assert spec.grid == {"plant.v_0": [-0.1, 0.1], "controller.k0": [0.2]}
    assert spec.random.factors == {
        "plant.yaw_0": Normal(normal=(0.0, 0.1)),
        "events.turn.time": Uniform(uniform=(5.0, 10.0)),
    }
    path.write_text('scenario = "bs-3"\n[grid]\n"plant.v_0" = [0.1]\nplant.v_0 = [0.2]\n')
    with pytest.raises(StudyError, match=r"factor 'plant.v_0' is given twice \(as a quoted"):
        load_study(path)


def test_a_factor_with_two_laws_is_refused_showing_its_table() -> None:
    """``{ uniform = [0, 1], normal = [0, 1] }`` was refused as "unknown key
    'random.plant.u_0'", as if the factor's name were wrong, not its two laws."""
    law = {"uniform": [0, 1], "normal": [0, 1]}
    with pytest.raises(StudyError) as info:
        study_from_dict({"scenario": "bs-3", "random": {"n": 2, "plant.u_0": law}}, "s.toml")
    assert str(info.value) == (
        f"s.toml: key 'random.plant.u_0' = {law!r}: "
        "expected { uniform = [low, high] } or { normal = [mean, std] }"
    )


def test_a_study_nested_too_deeply_to_read_is_refused_as_not_valid_toml(tmp_path: Path) -> None:
    """Arrays thousands deep in a study file: "RecursionError: maximum recursion depth
    exceeded", naming neither the file nor what was wrong."""
    deep = tmp_path / "deep.toml"
    deep.write_text('scenario = "bs-3"\nx = ' + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(StudyError, match=r"deep\.toml: not valid TOML: arrays or inline tables "):
        load_study(deep)


HUGE = 10**400  # an int beyond the floats (TOML and a Python dict both hold one)


@pytest.mark.parametrize(
    ("change", "key"),
    [
        ({"stop_time": HUGE}, "stop_time"),
        ({"stop_time": -HUGE}, "stop_time"),
        ({"random": {"n": 2, "plant.u_0": {"uniform": [0, HUGE]}}}, "random.plant.u_0"),
        ({"random": {"n": 2, "plant.u_0": {"normal": [0, HUGE]}}}, "random.plant.u_0"),
        ({"grid": {"plant.v_0": [0.1, HUGE]}}, "grid.plant.v_0"),
    ],
)
def test_an_int_beyond_the_floats_is_refused_as_cosim_run_refuses_it(
    change: dict, key: str
) -> None:
    """``cosim.sweep({..., "stop_time": 10**400})`` ended in "OverflowError: int too
    large to convert to float" (and a grid value of 10**400 so as its factor was read),
    where ``cosim.run(stop_time=10**400)`` is refused in one line: now the study's key is
    named with the value shortened, as a finite number is expected."""
    with pytest.raises(StudyError) as info:
        study_from_dict({**MINIMAL, **change}, "study s.toml")
    message = str(info.value)
    assert message.startswith(f"study s.toml: key '{key}")
    assert message.endswith("characters) is not a finite number"), message
    assert len(message) < 300


def test_a_study_of_more_runs_than_the_floats_hold_is_refused_by_its_size() -> None:
    """``[random] n = 10**400`` ended in "OverflowError: int too large to convert to
    float" as the refusal of its size was written: now that refusal, the count shown in
    powers of ten."""
    random = {"n": HUGE, "plant.u_0": {"uniform": [0, 1]}}
    spec = study_from_dict({**MINIMAL, "random": random}, "s")
    with pytest.raises(StudyError, match=r"^s: 2e\+400 runs \(2 grid points x 1e\+400 samples\)"):
        check_size(spec, "s")
