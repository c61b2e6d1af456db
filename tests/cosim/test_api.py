"""The Python API (cosim.run, load_scenario, sweep, build_fmus): the same runs, files and
errors as the command line, results as DataFrames, no folder unless asked for."""

from __future__ import annotations

import ast
import csv
import dataclasses
import inspect
import json
import os
import pickle
import pkgutil
import re
import shutil
import socket
import subprocess
import sys
import tempfile
import tomllib
from collections.abc import Callable
from copy import deepcopy
from decimal import Decimal
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import tomli_w
from process_group import run_in_group
from repo_paths import ROOT
from users_mypy import users_mypy

import cosim
from cosim.errors import CosimError
from cosim.runner import NotStartedError
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import SCENARIO_FOLDER, Scenario, load_scenario, scenario_from_toml
from cosim.scenario.unit_doubts import UnitWarning
from cosim.scratch import SCRATCH_DIR
from cosim.study.spec import StudyError

ACCEPTANCE = (
    "import cosim; r = cosim.run('bs-3', stop_time=5.0, start={'plant.v_0': -0.05}); "
    "print(r.results['plant.yaw'].iloc[-1])"
)


def _user_folder(tmp_path: Path, fmu_dir: Path) -> Path:
    """A working folder as a user has it after ``auv-cosim build``: build/fmus up to date."""
    fmus = tmp_path / "build" / "fmus"
    fmus.mkdir(parents=True)
    for path in fmu_dir.glob("*.fmu*"):
        shutil.copyfile(path, fmus / path.name)
    return tmp_path


def _environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(Path(cosim.__file__).resolve().parents[1])
    return env


def _results_column(results_csv: Path, column: str) -> list[float]:
    with results_csv.open(encoding="utf-8", newline="") as f:
        return [float(row[column]) for row in csv.DictReader(f)]


@pytest.mark.slow
def test_api_run_matches_the_command_line_bit_for_bit(tmp_path: Path, fmu_dir: Path) -> None:
    """The acceptance one-liner prints the very yaw ``auv-cosim run`` writes for a
    scenario file with the same start value."""
    folder = _user_folder(tmp_path, fmu_dir)
    data = tomllib.loads((SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8"))
    data["instances"]["plant"]["start"]["v_0"] = -0.05
    (folder / "case.toml").write_text(tomli_w.dumps(data), encoding="utf-8")
    cli = [sys.executable, "-m", "cosim.cli", "run", "case.toml", "--stop-time", "5.0"]
    cli += ["--out", "cli-run", "--no-rrd", "--quiet"]
    for command in (cli, [sys.executable, "-c", ACCEPTANCE]):
        done = subprocess.run(command, cwd=folder, env=_environment(), capture_output=True,
                              text=True, timeout=600, check=False)  # fmt: skip
        assert done.returncode == 0, done.stderr
    printed = float(done.stdout.strip().splitlines()[-1])
    written = _results_column(folder / "cli-run" / "results.csv", "plant.yaw")[-1]
    assert printed.hex() == written.hex()
    assert printed != 0.0


@pytest.mark.slow
def test_run_keeps_results_in_memory_and_leaves_no_folder(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    scratch = tmp_path / "scratch"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    monkeypatch.chdir(tmp_path)
    run = cosim.run("bs-3", stop_time=0.5, fmu_dir=fmu_dir)
    assert run.out_dir is None and run.complete
    left = [p.name for p in scratch.rglob("auv-cosim-*") if p.name != SCRATCH_DIR]
    assert left == [] and not (tmp_path / "runs").exists()  # (fmpy's unzipped FMUs stay)
    results = run.results
    assert results.index.name == "time" and results.shape == (51, len(run.scenario.columns))
    assert list(results.columns) == list(run.scenario.columns)
    assert results.index[-1] == pytest.approx(0.5)
    assert run.summary["complete"] is True and run.summary["rows"] == 51
    assert run.summary["final_values"]["plant.yaw"] == results["plant.yaw"].iloc[-1]
    times, values = results.index.to_numpy(), results.to_numpy()
    assert times.dtype == values.dtype == np.float64


def test_a_runs_results_frame_carries_each_columns_unit(fmu_dir: Path) -> None:
    """``run.results.attrs["units"]`` gives the unit of the time index and of every column,
    as summary.json's ``units`` does, so a frame passed on keeps its units with it (as the
    table of ``cosim.sweep`` does from runs.parquet)."""
    run = cosim.run("bs-3", stop_time=0.05, fmu_dir=fmu_dir)
    units = run.results.attrs["units"]
    assert units == run.summary["units"]
    assert list(units) == [run.results.index.name, *run.results.columns]
    assert (units["time"], units["plant.yaw"], units["controller.thrust"]) == ("s", "rad", "N")


@pytest.mark.slow
def test_a_run_shows_the_command_lines_progress_only_when_asked(
    fmu_dir: Path, capfd: pytest.CaptureFixture
) -> None:
    """A long run in a notebook showed nothing until it ended (the progress bar was the
    command line's only); ``progress=True`` shows it, and without it nothing is printed."""
    cosim.run("bs-3", stop_time=0.5, fmu_dir=fmu_dir)
    assert capfd.readouterr().err == ""
    cosim.run("bs-3", stop_time=0.5, fmu_dir=fmu_dir, progress=True)
    shown = capfd.readouterr().err
    assert "bs-3: loading FMUs" in shown and "/51 [" in shown, shown


@pytest.mark.slow
def test_run_with_out_writes_the_command_lines_folder(tmp_path: Path, fmu_dir: Path) -> None:
    run = cosim.run("bs-3", stop_time=0.3, out=tmp_path / "run", fmu_dir=fmu_dir)
    assert run.out_dir == tmp_path / "run"
    names = {p.name for p in run.out_dir.iterdir()}
    assert {"results.csv", "summary.json", "scenario.toml", "recording.rrd"} <= names
    for column in ("plant.yaw", "controller.thrust"):
        written = _results_column(run.out_dir / "results.csv", column)
        assert written == run.results[column].tolist()
    with pytest.raises(CosimError, match="overwrite"):  # an earlier run is kept, as on the CLI
        cosim.run("bs-3", stop_time=0.3, out=tmp_path / "run", fmu_dir=fmu_dir)


@pytest.mark.slow
def test_a_run_folder_given_relative_is_still_found_after_chdir(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``cosim.run(..., out="runs/x").out_dir`` was ``runs/x`` as given: after ``os.chdir``
    (``%cd`` in a notebook) ``run.out_dir`` named a folder that is not there, and the
    notebook's ``inline_viewer(run.out_dir)`` found no recording. It is absolute."""
    monkeypatch.chdir(tmp_path)
    run = cosim.run("bs-3", stop_time=0.1, out="runs/x", recording=False, fmu_dir=fmu_dir)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert run.out_dir == tmp_path / "runs" / "x"
    assert (run.out_dir / "results.csv").is_file()


@pytest.mark.slow
def test_a_run_kept_in_memory_names_no_output_file(tmp_path: Path, fmu_dir: Path) -> None:
    """Without ``out=`` nothing is written, yet ``run.summary["outputs"]`` named
    results.csv, scenario.toml and summary.json (in a temporary folder already removed):
    a user opening them found nothing. It names none."""
    run = cosim.run("bs-3", stop_time=0.1, fmu_dir=fmu_dir)
    assert run.summary["outputs"] == {}
    kept = cosim.run("bs-3", stop_time=0.1, fmu_dir=fmu_dir, out=tmp_path / "kept")
    assert kept.out_dir is not None
    assert all((kept.out_dir / name).is_file() for name in kept.summary["outputs"].values())
    assert "results" in kept.summary["outputs"]


def test_a_run_error_crosses_a_process_pool(fmu_dir: Path) -> None:
    """A RunError raised in a ProcessPoolExecutor worker did not unpickle in the parent
    (``__init__() missing 1 required positional argument: 'run'``): the pool broke
    (BrokenProcessPool) instead of the caller catching the RunError. It pickles with its
    message and partial run, as does the runner's NotStartedError with its exit code."""
    start = {"plant.u_0": 100.0, "plant.v_0": 100.0, "plant.r_0": 50.0}  # leaves the range
    with (
        pytest.warns(UnitWarning, match="r_0 = 50 rad/s is more than a full turn a second"),
        pytest.raises(cosim.RunError) as raised,
    ):
        cosim.run("bs-3", stop_time=1.0, start=start, fmu_dir=fmu_dir)
    copy = pickle.loads(pickle.dumps(raised.value))
    assert type(copy) is cosim.RunError and str(copy) == str(raised.value)
    assert copy.run.results.equals(raised.value.run.results) and not copy.run.complete
    stopped = pickle.loads(pickle.dumps(NotStartedError("interrupted (Ctrl-C)", 130)))
    assert (str(stopped), stopped.exit_code) == ("interrupted (Ctrl-C)", 130)


@pytest.mark.slow
def test_a_run_shows_in_one_line_not_its_whole_table(fmu_dir: Path, tmp_path: Path) -> None:
    """A notebook cell ending in ``cosim.run(...)`` printed the dataclass repr: the scenario
    with every instance, the DataFrame and the whole summary, 5,000 characters over many
    lines. It is one line naming the scenario, whether it completed, the table's shape
    and the folder; a run kept in a folder too, named as what it is (a SavedRun's said
    ``Run(...)``, the class it is not)."""
    run = cosim.run("bs-3", stop_time=0.1, fmu_dir=fmu_dir)
    columns = len(run.scenario.columns)
    expected = f"(scenario='bs-3', complete=True, results=<11 rows x {columns} columns>, "
    assert repr(run) == "Run" + expected + "out_dir=None)"
    kept = cosim.run("bs-3", stop_time=0.1, fmu_dir=fmu_dir, out=tmp_path / "run", recording=False)
    assert type(kept) is cosim.SavedRun
    assert repr(kept) == "SavedRun" + expected + f"out_dir={tmp_path / 'run'!r})"


def test_runs_and_studies_go_into_lists_and_sets_by_identity(fmu_dir: Path) -> None:
    """Run and Study compared their fields: ``run in runs``, ``runs.index(run)`` and
    ``a == b`` raised pandas' "The truth value of a DataFrame is ambiguous", and
    ``{run}`` or a cache keyed by a run "unhashable type". They compare and hash as
    objects do, by identity (their tables compare with ``.results.equals``)."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    table = pd.DataFrame({"plant.yaw": [0.0, 0.1]}, index=pd.Index([0.0, 0.01], name="time"))
    first = cosim.Run(scenario, table, {"complete": True}, None)
    second = cosim.Run(scenario, table.copy(), {"complete": True}, None)
    assert first == first and first != second and [first, second].index(second) == 1
    assert len({first, second, first}) == 2
    study = cosim.Study(table, None)
    assert study in [cosim.Study(table.copy(), None), study] and len({study, study}) == 1
    copy = pickle.loads(pickle.dumps(study))  # a process pool's result: the same table
    assert copy.table.equals(study.table) and copy != study


def test_errors_are_the_command_lines(tmp_path: Path, capsys: pytest.CaptureFixture) -> None:
    """The same exception type and one-line message as ``auv-cosim run`` prints, naming
    the API's keyword where the command line names its flag."""
    from cosim.cli import main

    assert main(["run", "bs-3", "--stop-time", "-1", "--out", str(tmp_path / "r")]) == 1
    printed = capsys.readouterr().err.strip()
    with pytest.raises(CosimError) as raised:
        cosim.run("bs-3", stop_time=-1.0, out=tmp_path / "r")
    assert printed == "auv-cosim run: --stop-time -1.0: expected a finite number of seconds > 0"
    assert str(raised.value) == "stop_time=-1.0: expected a finite number of seconds > 0"
    with pytest.raises(ScenarioError, match="expected a built-in id"):
        cosim.run("no-such-scenario")


@pytest.mark.parametrize(
    ("arguments", "named"),
    [
        ({"stop_time": -1.0}, "stop_time=-1.0: expected"),
        ({"stop_time": float("inf")}, "stop_time=inf: expected"),
        ({"step": 0.0}, "step=0.0: expected"),
        ({"out": "userdir"}, "out='userdir': the folder is not empty"),
    ],
)
def test_api_refusals_name_its_keywords_not_the_command_lines_flags(
    arguments: dict, named: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A refused option of cosim.run is named as the caller wrote it (stop_time=, step=,
    out=), not as the command line's --stop-time, --step, --out."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "userdir").mkdir()
    (tmp_path / "userdir" / "notes.txt").write_text("mine", encoding="utf-8")
    with pytest.raises(CosimError) as raised:
        cosim.run("bs-3", **arguments)
    assert str(raised.value).startswith(named) and "--" not in str(raised.value)


def test_api_refusal_of_an_earlier_run_names_overwrite_true(tmp_path: Path, fmu_dir: Path) -> None:
    """The folder of an earlier run is refused with the API's way to replace it."""
    cosim.run("bs-3", stop_time=0.1, out=tmp_path / "r", recording=False, fmu_dir=fmu_dir)
    with pytest.raises(CosimError, match=r"pass overwrite=True to replace it") as raised:
        cosim.run("bs-3", stop_time=0.1, out=tmp_path / "r", recording=False, fmu_dir=fmu_dir)
    assert str(raised.value).startswith(f"out={str(tmp_path / 'r')!r}: ")


@pytest.mark.parametrize("argument", ["nope.toml", "sub/bs-3", "folder", "/nowhere/x.toml"])
def test_a_scenario_path_that_is_no_file_is_named_so(
    argument: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture
) -> None:
    """An argument meant as a file (ending in .toml, holding a path separator, or naming
    a folder) that is no file is refused saying so and where it was looked for, not as an
    unknown built-in id; the path once, a relative one with the folder it is relative to
    (the message named it twice, as given and as absolute: ``missing.toml (looked for
    /home/me/missing.toml)``). The API names its keyword, ``scenario=`` (it said "not a
    file: folder", naming no argument), ``auv-cosim run`` its argument as given."""
    from cosim.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "folder").mkdir()
    what = "not a file" if argument == "folder" else "no such file"
    where = "" if argument.startswith("/") else f" (relative to {tmp_path})"
    for call in (cosim.run, cosim.load_scenario):
        with pytest.raises(ScenarioError) as raised:
            call(argument)
        said = f"scenario={argument!r}: {what}{where}; expected a scenario .toml file"
        assert str(raised.value).startswith(said), raised.value
    expected = f"{what}: {argument}{where}; expected a scenario"
    assert main(["run", argument]) == 1
    assert capsys.readouterr().err.strip().startswith(f"auv-cosim run: {expected}")


def test_numpy_numbers_are_taken_for_times_and_counts(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A numpy number for a time or a count (``stop_time=np.int64(1)`` from ``np.arange``,
    ``workers=np.int64(1)``) was refused as "stop_time=np.int64(1): expected a number of
    seconds (float or int)", though a start value takes one as its Python value; so
    are these now."""
    import cosim.study.runner

    run = cosim.run("bs-3", stop_time=np.int64(1), step=np.float32(0.015625), fmu_dir=fmu_dir)
    assert (run.summary["stop_time"], run.summary["step"]) == (1.0, 0.015625)
    given: dict[str, object] = {}

    def ran(*args: object, cluster: object, **options: object) -> None:
        given.update(options, workers=cluster.workers)  # type: ignore[attr-defined]
        raise StudyError("not run")

    monkeypatch.setattr(cosim.study.runner, "run_study", ran)
    counts = {"workers": np.int64(1), "max_runs": np.int32(5), "overlay": np.uint8(2)}
    with pytest.raises(StudyError, match="not run"):
        cosim.sweep({"scenario": "bs-3"}, out=tmp_path / "study", **counts)
    assert {name: given[name] for name in counts} == {"workers": 1, "max_runs": 5, "overlay": 2}
    assert all(type(given[name]) is int for name in counts)


def test_numpy_scalar_start_values_are_taken_as_their_python_values(fmu_dir: Path) -> None:
    """A numpy float32, int64 or bool_ start value (as a numpy computation gives it) is
    the Python number of the same value, not refused for its type."""
    run = cosim.run(
        "bs-3",
        stop_time=0.1,
        fmu_dir=fmu_dir,
        start={"plant.v_0": np.float32(-0.1), "plant.variant": np.int64(1)},
    )
    start = run.scenario.instances["plant"].start
    assert start["v_0"] == float(np.float32(-0.1)) and type(start["v_0"]) is float
    assert start["variant"] == 1 and type(start["variant"]) is int
    assert run.results["plant.v"].iloc[0] == float(np.float32(-0.1))
    with pytest.raises(CosimError, match=r"start\['plant.v_0'\]=np.complex128"):
        cosim.run("bs-3", start={"plant.v_0": np.complex128(1)}, fmu_dir=fmu_dir)


@pytest.mark.parametrize("overrides", [{}, {"stop_time": 1.0}])
def test_a_start_value_refused_before_the_run_names_where_it_came_from(
    overrides: dict, fmu_dir: Path
) -> None:
    """A start value the run refuses before loading any FMU (a max_substep of hours per
    step) is named with the start values it came from, like every other start-value
    refusal, so the shipped file does not read as faulty."""
    with pytest.raises(ScenarioError) as raised:
        cosim.run("bs-3", start={"plant.max_substep": 1e-9}, fmu_dir=fmu_dir, **overrides)
    message = str(raised.value)
    assert "bs-3.toml (with the start values {'plant.max_substep': 1e-09})" in message
    assert "key 'instances.plant.start.max_substep': plant.max_substep = 1e-09 s" in message


@pytest.mark.parametrize("variable", ["v_0", "variant"])  # a Real, an Integer
def test_a_huge_start_value_is_refused_in_one_short_line_naming_it(
    variable: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """``with_start({"plant.v_0": 10**400})`` raised OverflowError ("int too large to
    convert to float"), past ``except CosimError``, and a scenario file holding that
    number ended ``auv-cosim run`` in the same traceback; an Integer's refusal printed
    all 401 digits, twice. A ScenarioError naming the key, the number shortened."""
    huge = 10**400
    with pytest.raises(ScenarioError) as raised:
        load_scenario("bs-3", fmu_dir=fmu_dir).with_start({f"plant.{variable}": huge})
    data = tomllib.loads((SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8"))
    data["instances"]["plant"]["start"][variable] = huge
    path = tmp_path / "huge.toml"
    path.write_text(tomli_w.dumps(data), encoding="utf-8")
    with pytest.raises(ScenarioError) as from_file:
        load_scenario(path, fmu_dir=fmu_dir)
    for message in (str(raised.value), str(from_file.value)):
        assert f"key 'instances.plant.start.{variable}': 1000" in message, message
        assert "\n" not in message and len(message) < 400, message


def test_with_start_is_checked_like_the_scenario_file(fmu_dir: Path) -> None:
    base = load_scenario("bs-3", fmu_dir=fmu_dir)
    changed = base.with_start({"plant.v_0": np.float64(-0.05), "controller.k0": 0.3})
    assert changed.instances["plant"].start["v_0"] == -0.05
    assert changed.instances["controller"].start["k0"] == 0.3
    assert base.instances["plant"].start["v_0"] == -0.10  # a copy
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    from_file = scenario_from_toml(
        text.replace("v_0 = -0.10", "v_0 = -0.05").replace(
            "yaw_setpoint", "k0 = 0.3\nyaw_setpoint"
        ),
        fmu_dir=fmu_dir,
    )
    assert changed.instances == from_file.instances
    refused = {
        "plant.no_such": "has no variable 'no_such'",
        "plant.variant": "1.5 is not an integer",  # given 1.5 below
        "plant.yaw": "output .initial .calculated.*; only parameters, inputs and variables",
        "nowhere.v_0": "expected '<instance>.<variable>'",
        "v_0": "expected '<instance>.<variable>'",
    }
    for ref, message in refused.items():
        value = 1.5 if ref == "plant.variant" else 0.1
        with pytest.raises(ScenarioError, match=message) as raised:
            base.with_start({ref: value})
        assert "\n" not in str(raised.value)


def test_a_loaded_scenario_refuses_edits_and_points_at_with_start(fmu_dir: Path) -> None:
    """A loaded scenario's instances and start values are read-only: an edit would bypass
    the scenario checks and be dropped by the next override; the refusal names
    with_start, which gives a checked copy."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    start = scenario.instances["plant"].start
    with pytest.raises(TypeError, match=r"plant\.start\['v_0'\] = 'fast': .*with_start"):
        start["v_0"] = "fast"  # type: ignore[index]
    with pytest.raises(TypeError, match="with_start"):
        start.update(v_0=0.1)  # type: ignore[attr-defined]
    with pytest.raises(TypeError, match="with_start"):
        del scenario.instances["plant"]  # type: ignore[attr-defined]
    assert scenario.instances["plant"].start["v_0"] == -0.10
    assert pickle.loads(pickle.dumps(scenario.instances)).keys() == scenario.instances.keys()


def test_a_loaded_scenarios_step_multiples_and_event_values_refuse_edits(fmu_dir: Path) -> None:
    """``scenario.coupling.step_multiples`` and an event's ``set`` were plain dicts: an edit
    went through unchecked and took effect in ``cosim.run(scenario)``, then vanished in
    ``cosim.run(scenario, stop_time=...)`` (an override re-reads the file's data). Read-only
    like the start values, naming what to change instead."""
    scenario = load_scenario("zigzag-20", fmu_dir=fmu_dir)
    multiples = scenario.coupling.step_multiples
    with pytest.raises(TypeError, match=r"step_multiples\['controller'\] = 5: .*read-only"):
        multiples["controller"] = 5  # type: ignore[index]
    event_values = scenario.events[0].set
    with pytest.raises(TypeError, match=r"set\['controller.yaw_setpoint'\] = 1.0: .*read-only"):
        event_values["controller.yaw_setpoint"] = 1.0  # type: ignore[index]
    with pytest.raises(TypeError, match="read-only"):
        event_values.clear()  # type: ignore[attr-defined]
    assert scenario == load_scenario("zigzag-20", fmu_dir=fmu_dir)
    assert pickle.loads(pickle.dumps(scenario.coupling)) == scenario.coupling


def test_a_scenario_copied_by_dataclasses_replace_is_refused_not_run_unchecked(
    fmu_dir: Path,
) -> None:
    """``dataclasses.replace(scenario, stop_time=1.0)`` (what a frozen dataclass's "cannot
    assign to field" sends a user to) skipped every check: a record naming no variable
    ended in a bare KeyError, and ``cosim.run(copy, start=...)`` silently ran the file's
    60 s again (with_start starts from the checked file data). Refused in one line naming
    the checked way; a copy by pickle or copy.deepcopy stays checked."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    replaced = dataclasses.replace(scenario, stop_time=1.0)
    calls: list[Callable[[], object]] = [
        lambda: cosim.run(replaced, fmu_dir=fmu_dir),
        lambda: cosim.run(replaced, start={"plant.v_0": -0.05}, fmu_dir=fmu_dir),
        lambda: replaced.with_start({"plant.v_0": -0.05}),
        lambda: replaced.with_overrides(step=0.02),
    ]
    for call in calls:
        with pytest.raises(ScenarioError, match=r"dataclasses\.replace.*with_overrides") as raised:
            call()
        assert "\n" not in str(raised.value)
    for copy in (pickle.loads(pickle.dumps(scenario)), deepcopy(scenario)):
        assert copy.with_start({"plant.v_0": -0.05}).stop_time == scenario.stop_time


def test_fmu_dir_with_a_loaded_scenario_is_refused_not_ignored(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """A loaded scenario's FMUs are the ones it was loaded with: ``cosim.run(scenario,
    fmu_dir=other)`` ran those, silently ignoring ``other``. Refused, naming both; the
    same folder (as given or absolute) and no fmu_dir at all are fine."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    other = tmp_path / "other-fmus"
    for start in (None, {"plant.v_0": -0.05}):
        with pytest.raises(CosimError, match=r"fmu_dir=.*other-fmus.*loaded with") as raised:
            cosim.run(scenario, stop_time=0.1, start=start, fmu_dir=other)
        assert str(fmu_dir) in str(raised.value) and "\n" not in str(raised.value)
    assert not other.exists()
    assert cosim.run(scenario, stop_time=0.1, fmu_dir=str(fmu_dir)).complete


def test_a_file_named_in_a_start_value_given_in_python_is_relative_to_the_working_folder(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``cosim.run("bs-3", start={"plant.vehicle": "my-vehicle.toml"})`` looked for the file
    in the installed package's scenarios folder (the built-in scenario's), not in the
    caller's working folder, as every other path the API takes is: "names no file (looked
    for .../cosim/scenarios/my-vehicle.toml)". A file's own start values stay relative to
    the file."""
    shutil.copyfile(
        SCENARIO_FOLDER.parents[1] / "plant_fmu/model/vehicles/remus100-long-fins.toml",
        tmp_path / "my-vehicle.toml",
    )
    monkeypatch.chdir(tmp_path)
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    changed = scenario.with_start({"plant.vehicle": "my-vehicle.toml"})
    assert changed.instances["plant"].start["vehicle"] == str(tmp_path / "my-vehicle.toml")
    assert changed.with_start({"plant.v_0": -0.05}).instances["plant"].start["vehicle"] == str(
        tmp_path / "my-vehicle.toml"
    )


def test_connected_input_refuses_a_start_value(fmu_dir: Path) -> None:
    base = load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError, match=r"connections\.remove"):
        base.with_start({"plant.thrust": 5.0})


def test_the_api_names_complete_in_ipython_before_their_first_use(
    run_python: Callable[..., subprocess.CompletedProcess],
) -> None:
    """The API is imported on first use (``cosim.__getattr__``), but ``dir(cosim)`` lacked
    it: ``cosim.<Tab>`` in Jupyter offered Any, TYPE_CHECKING, annotations and importlib,
    and ``cosim.r<Tab>`` nothing. dir() lists every public name, without importing them."""
    done = run_python(
        """
        import sys
        import cosim
        print(sorted(dir(cosim)))
        print("cosim.api" in sys.modules)
        """
    )
    assert done.returncode == 0, done.stderr
    listed, imported = done.stdout.splitlines()[-2:]
    assert set(cosim.__all__) <= set(ast.literal_eval(listed)), listed
    assert imported == "False"  # listing them imports nothing


def test_public_names_have_numpy_docstrings() -> None:
    public = ["Run", "RunError", "RunInterrupted", "SavedRun", "Study", "SweepInterrupted",
              "build_fmus"]  # fmt: skip
    errors = ["CosimError", "Scenario", "ScenarioError", "StudyError"]
    calls = ["load_scenario", "resume", "run", "sweep"]
    assert sorted(cosim.__all__) == sorted([*public, *errors, *calls])
    # inspect.getdoc: CPython 3.13 strips a docstring's indentation as it compiles, 3.11 not
    for name in (*calls, "build_fmus"):
        doc = inspect.getdoc(getattr(cosim, name)) or ""
        assert "Returns\n-------" in doc and "Raises\n------" in doc, name
    for name in ("Run", "SavedRun", "Study"):
        assert "Attributes\n----------" in (inspect.getdoc(getattr(cosim, name)) or "")


API_DOC = ROOT / "docs" / "api.md"


def _documented_calls(text: str) -> list[ast.Call]:
    """The calls ``cosim.<name>(...)`` in the Python examples of ``text``."""
    blocks = re.findall(r"```python\n(.*?)```", text, re.DOTALL)
    calls = [node for block in blocks for node in ast.walk(ast.parse(block))]
    return [
        call
        for call in calls
        if isinstance(call, ast.Call)
        and isinstance(call.func, ast.Attribute)
        and isinstance(call.func.value, ast.Name)
        and call.func.value.id == "cosim"
    ]


def test_the_names_docs_api_documents_are_the_packages_and_its_calls_bind() -> None:
    """docs/api.md had a caller catch ``cosim.errors.CosimError``,
    ``cosim.scenario.checks.ScenarioError`` and ``cosim.study.spec.StudyError``: the
    package exported none of them, nor the Scenario ``load_scenario`` returns, so
    ``except cosim.CosimError`` raised AttributeError and a user's annotations named
    modules inside the package. Every ``cosim.<name>`` the page names is exported (and
    every exported name documented there), every dotted name resolves, every call its
    examples make binds to the signature, and every ``keyword=`` it names is a keyword."""
    text = API_DOC.read_text(encoding="utf-8")
    top_level = set(re.findall(r"\bcosim\.([A-Za-z]\w*)\b(?![./])", text))
    assert top_level == set(cosim.__all__), sorted(top_level ^ set(cosim.__all__))
    for dotted in re.findall(r"\bcosim(?:\.[A-Za-z_]\w*)+", text):
        assert pkgutil.resolve_name(dotted) is not None, dotted
    for call in _documented_calls(text):
        signature = inspect.signature(getattr(cosim, call.func.attr))  # type: ignore[attr-defined]
        signature.bind(*call.args, **{k.arg: k.value for k in call.keywords if k.arg})
    keywords = {
        name
        for function in (cosim.run, cosim.sweep, cosim.load_scenario, cosim.build_fmus)
        for name in inspect.signature(function).parameters
    }
    assert set(re.findall(r"`([a-z_]+)=", text)) <= keywords
    exported = (cosim.CosimError, cosim.Scenario, cosim.ScenarioError, cosim.StudyError)
    assert exported == (CosimError, Scenario, ScenarioError, StudyError)


@pytest.mark.slow
def test_run_survives_importing_every_module(
    run_python: Callable[..., subprocess.CompletedProcess],
) -> None:
    """Importing a submodule sets an attribute on its package: no module may be named
    like a function of the API, whatever is imported first."""
    names = [m.name for m in pkgutil.walk_packages(cosim.__path__, "cosim.")]
    assert not [n for n in names if n.rpartition(".")[2] in cosim.__all__]
    done = run_python(
        "import importlib, sys\n"
        "import cosim\n"
        "for name in sys.argv[1:]:\n"
        "    importlib.import_module(name)\n"
        "import cosim.api\n"
        "def home(n): return importlib.import_module(cosim._HOMES.get(n, 'cosim.api'))\n"
        "assert all(getattr(cosim, n) is getattr(home(n), n) for n in cosim.__all__)\n"
        "assert callable(cosim.run) and cosim.run.__module__ == 'cosim.api'\n"
        "print('ok', len(sys.argv) - 1)\n",
        *names,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.startswith("ok")


@pytest.mark.cluster
@pytest.mark.slow
def test_sweep_of_a_dict_returns_its_table(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture
) -> None:
    """... and shows the command line's progress bar of the runs when asked."""
    monkeypatch.chdir(tmp_path)
    study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [-0.1, 0.1]}}
    result = cosim.sweep(study, workers=1, fmu_dir=fmu_dir, progress=True)
    assert "runs: 100%" in capfd.readouterr().err
    assert result.out_dir is None and list(tmp_path.iterdir()) == []
    table = result.table
    assert isinstance(table, pd.DataFrame) and len(table) == 2
    assert sorted(table["plant.v_0"]) == [-0.1, 0.1]
    assert (table["status"] == "complete").all()
    assert table["final.plant.v"].iloc[0] != table["final.plant.v"].iloc[1]
    assert repr(result) == f"Study(table=<2 rows x {table.shape[1]} columns>, out_dir=None)"
    assert result.statistics is None and result.sensitivity is None  # no Monte Carlo


@pytest.mark.cluster
@pytest.mark.slow
def test_a_monte_carlo_sweep_returns_its_statistics_without_a_folder(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Without ``out`` the study folder is removed, and with it the statistics and
    sensitivity tables a Monte Carlo study writes there: a notebook had the runs only."""
    monkeypatch.chdir(tmp_path)
    draws = {"n": 3, "seed": 2, "plant.current_east": {"uniform": [0.0, 0.3]}}
    study = {"scenario": "bs-3", "stop_time": 0.5, "random": draws,
             "metrics": {"collect": ["final.plant.east", "final.plant.yaw"]}}  # fmt: skip
    result = cosim.sweep(study, workers=1, fmu_dir=fmu_dir)
    assert result.out_dir is None and list(tmp_path.iterdir()) == []
    assert result.statistics is not None and result.sensitivity is not None
    east = result.statistics.set_index("metric").loc["final.plant.east"]
    assert east["runs"] == 3
    assert east["p95"] == pytest.approx(result.table["final.plant.east"].quantile(0.95))
    assert set(result.sensitivity["factor"]) == {"plant.current_east"}


@pytest.mark.cluster
@pytest.mark.slow
def test_a_sweep_leaves_its_callers_environment_as_it_was(
    run_python: Callable[..., subprocess.CompletedProcess], fmu_dir: Path
) -> None:
    """The workers' environment (Dask's pre-spawn one: one BLAS and OpenMP thread...) is
    theirs: after cosim.sweep a notebook's own environment, which every process it starts
    inherits, had OMP_NUM_THREADS=1, MKL_NUM_THREADS=1 and OPENBLAS_NUM_THREADS=1 left in it.
    A second sweep in the same process (Dask's pre-spawn environment read once) too."""
    done = run_python(
        """
        import json, os, sys
        import cosim

        if __name__ == "__main__":
            before = dict(os.environ)
            study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [-0.1, 0.1]}}
            for _ in range(2):
                cosim.sweep(study, workers=1, fmu_dir=sys.argv[1])
            after = dict(os.environ)
            changed = {k: (before.get(k), after.get(k)) for k in {*before, *after}
                       if before.get(k) != after.get(k)}
            print(json.dumps(changed))
        """,
        fmu_dir,
    )
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout.strip().splitlines()[-1]) == {}


@pytest.mark.skipif(not hasattr(os, "getuid"), reason="needs POSIX resource limits")
def test_a_sweep_leaves_its_callers_open_files_limit_as_it_was(
    run_python: Callable[..., subprocess.CompletedProcess],
) -> None:
    """A local study raises the soft limit on open files to what its workers need (``ulimit
    -n``; the command's process ends with it): a service or notebook calling cosim.sweep
    kept the raised limit after the call, refused or not, and so did every process it
    started later."""
    done = run_python(
        """
        import resource
        import cosim

        if __name__ == "__main__":
            _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
            resource.setrlimit(resource.RLIMIT_NOFILE, (32, hard))
            try:
                cosim.sweep({"scenario": "no-such-scenario", "grid": {"plant.v_0": [0.1]}},
                            workers=1)
            except cosim.CosimError as error:
                print("refused:", error)
            print(resource.getrlimit(resource.RLIMIT_NOFILE)[0])
        """
    )
    assert done.returncode == 0, done.stderr
    refused, soft = done.stdout.strip().splitlines()[-2:]
    assert refused.startswith("refused:") and "no-such-scenario" in refused, done.stdout
    assert soft == "32", f"the soft limit on open files was left at {soft}, not 32"


@pytest.mark.cluster
@pytest.mark.slow
def test_a_sweep_into_a_folder_named_in_bytes_not_utf8_returns_its_table(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """``out`` named in Latin-1 (the byte 0xff, read as the surrogate U+DCFF): the study
    ran, then reading its runs.parquet back failed, "UnicodeEncodeError" (pyarrow encodes
    a name it is given as strict UTF-8)."""
    out = tmp_path / os.fsdecode(b"study-\xff")
    study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [-0.1, 0.1]}}
    table = cosim.sweep(study, workers=1, fmu_dir=fmu_dir, out=out).table
    assert sorted(table["plant.v_0"]) == [-0.1, 0.1]
    assert (table["status"] == "complete").all()


@pytest.mark.slow
def test_a_study_dict_takes_numpy_arrays_and_paths(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A grid as numpy gives it (``np.linspace``, float32 values) and the scenario as a
    pathlib.Path were refused ("cannot be written as TOML: Object of type 'ndarray' is not
    TOML serializable"), though cosim.run takes both kinds; they count as their lists,
    numbers and paths."""
    monkeypatch.chdir(tmp_path)
    shutil.copyfile(SCENARIO_FOLDER / "bs-3.toml", tmp_path / "case.toml")
    study = {
        "scenario": Path("case.toml"),
        "stop_time": np.float32(0.5),
        "grid": {"plant.v_0": np.linspace(-0.1, 0.1, 2), "controller.k0": (np.float32(0.5),)},
    }
    table = cosim.sweep(study, workers=1, fmu_dir=fmu_dir).table
    assert sorted(table["plant.v_0"]) == [-0.1, 0.1]
    assert table["controller.k0"].tolist() == [0.5, 0.5]
    assert (table["status"] == "complete").all()


def test_a_none_in_a_study_dict_is_named_by_its_key() -> None:
    """``{"stop_time": None}`` was refused as "cannot be written as TOML: Object of type
    'NoneType' is not TOML serializable", naming no key; the key is named, and what to do."""
    with pytest.raises(StudyError) as raised:
        cosim.sweep({"scenario": "bs-3", "stop_time": None, "grid": {"plant.v_0": [0.1]}})
    message = str(raised.value)
    assert message.startswith("study (given as a dict): key 'stop_time' = None:"), message
    assert "leave the key out" in message and "\n" not in message


def test_built_fmus_given_a_relative_folder_are_found_after_chdir(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``cosim.build_fmus("build/fmus")`` returned ``build/fmus/AuvPlant.fmu`` as given:
    after ``os.chdir`` the paths named files that are not there. They are absolute, like
    ``Run.out_dir``."""
    folder = _user_folder(tmp_path, fmu_dir)
    monkeypatch.chdir(folder)
    built = cosim.build_fmus("build/fmus")
    monkeypatch.chdir(tmp_path.parent)
    assert built["AuvPlant"] == folder / "build" / "fmus" / "AuvPlant.fmu"
    assert all(path.is_file() for path in built.values())


def test_build_fmus_is_the_build_command(tmp_path: Path, fmu_dir: Path) -> None:
    folder = _user_folder(tmp_path, fmu_dir)
    built = cosim.build_fmus(folder / "build" / "fmus")  # up to date: nothing rebuilt
    assert set(built) >= {"AuvPlant", "AuvAutopilot"}
    assert all(
        path.is_file() and path.parent == folder / "build" / "fmus" for path in built.values()
    )


def test_importing_the_plotting_modules_keeps_the_callers_backend(
    run_python: Callable[..., subprocess.CompletedProcess], tmp_path: Path
) -> None:
    """A notebook's plots stay inline after a sweep or a report: the modules that draw
    figures never switch matplotlib's backend, and still write their PNGs."""
    done = run_python(
        "import sys, matplotlib\n"
        "matplotlib.use('svg')\n"
        "import matplotlib.pyplot as plt\n"
        "import cosim.analysis.plots, cosim.study.plots, cosim.viz.report\n"
        "assert matplotlib.get_backend() == 'svg', matplotlib.get_backend()\n"
        "from cosim.study.plots import plot_scatter_matrix\n"
        "rows = [{'a': float(i), 'b': float(i * i)} for i in range(5)]\n"
        "out = __import__('pathlib').Path(sys.argv[1])\n"
        "path = plot_scatter_matrix(rows, ['a', 'b'], out, {})\n"
        "assert path.read_bytes()[:4] == b'\\x89PNG' and plt.get_fignums() == []\n",
        str(tmp_path / "matrix.png"),
    )
    assert done.returncode == 0, done.stderr


A_FILE = Path(__file__)  # a file where a folder is expected
HUGE = 10**400
BAD_ARGUMENTS = [
    ("run", {"scenario": "bs-3", "stop_time": Decimal("1.0")}, "stop_time=Decimal('1.0')"),
    ("run", {"scenario": "bs-3", "stop_time": HUGE}, "stop_time=1000"),
    ("run", {"scenario": "bs-3", "step": HUGE}, "step=1000"),
    ("run", {"scenario": "bs-3", "stop_time": True}, "stop_time=True"),
    ("run", {"scenario": "bs-3", "start": [("plant.v_0", 0.1)]}, "start=[('plant.v_0', 0.1)]"),
    ("run", {"scenario": "bs-3", "start": {"plant.v_0": HUGE}}, "start['plant.v_0']=1000"),
    ("run", {"scenario": "bs-3", "start": {"plant.v_0": Decimal("0.1")}}, "Decimal('0.1')"),
    ("run", {"scenario": "bs-3", "start": {"plant.vehicle": "re\0mus"}}, "NUL"),
    ("run", {"scenario": "bs-3\0x"}, "scenario='bs-3\\x00x'"),
    ("run", {"scenario": 42}, "scenario=42"),
    ("run", {"scenario": "bs-3", "out": "a\0b"}, "out='a\\x00b'"),
    ("run", {"scenario": "bs-3", "fmu_dir": A_FILE}, "fmu_dir="),
    ("run", {"scenario": "bs-3", "algorithm": "euler"}, "algorithm='euler'"),
    ("run", {"scenario": "bs-3", "overwrite": "no"}, "overwrite='no'"),
    ("run", {"scenario": "bs-3", "recording": 3}, "recording=3"),
    ("run", {"scenario": "bs-3", "progress": "yes"}, "progress='yes'"),
    ("load_scenario", {"scenario": "bs\0"}, "scenario='bs\\x00'"),
    ("load_scenario", {"scenario": "bs-3", "fmu_dir": A_FILE}, "fmu_dir="),
    ("sweep", {"study": {"scenario": "bs-3"}, "workers": "2"}, "workers='2'"),
    ("sweep", {"study": {"scenario": "bs-3"}, "workers": 0}, "workers=0"),
    ("sweep", {"study": {"scenario": "bs-3"}, "workers": 16}, "workers=16: more than the 2 cores"),
    ("sweep", {"study": {"scenario": "bs-3"}, "workers": HUGE, "oversubscribe": True}, "workers="),
    ("sweep", {"study": [1, 2]}, "study=[1, 2]: expected a study file (str or pathlib.Path) or a "),
    ("sweep", {"study": "a\0.toml"}, "study='a\\x00.toml'"),
    # a study's scenario holding a NUL: its refusal carried the NUL itself, unescaped
    ("sweep", {"study": {"scenario": "\0/0", "grid": {"plant.v_0": [0.1]}}}, "file: \\x00/0"),
    ("sweep", {"study": {"scenario": "bs-3"}, "overlay": "2"}, "overlay='2'"),
    ("sweep", {"study": {"scenario": "bs-3"}, "resume": "yes"}, "resume='yes'"),
    ("sweep", {"study": {"scenario": "bs-3"}, "progress": 1}, "progress=1"),
    ("sweep", {"study": {"scenario": "bs-3"}, "scheduler": 8786}, "scheduler=8786"),
    ("build_fmus", {"out": A_FILE}, "out="),
    ("build_fmus", {"force": "yes"}, "force='yes'"),
]


@pytest.mark.parametrize(("function", "arguments", "named"), BAD_ARGUMENTS)
def test_every_bad_argument_is_one_typed_line_naming_it(
    function: str, arguments: dict, named: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Decimal, huge ints, a list for a mapping, NUL bytes, a file as fmu_dir and a
    string for workers gave OverflowError, AttributeError, FileExistsError or TypeError
    tracebacks, or were taken; cosim.sweep(workers=16) started 16 processes on 2 cores."""
    monkeypatch.setattr("cosim.study.execution.usable_cores", lambda: 2)
    call = getattr(cosim, function)
    positional = [arguments.pop(k) for k in ("scenario", "study") if k in arguments]
    with pytest.raises(CosimError) as raised:
        call(*positional, **arguments)
    message = str(raised.value)
    assert "\n" not in message and named in message and "expected" in message, message
    assert len(message) < 300, message


@pytest.mark.parametrize(
    ("arguments", "named"),
    [({"resume": True}, "resume=True needs out="), ({"overlay": 2}, "overlay=2 needs out=")],
)
def test_sweep_without_out_refuses_resume_and_overlay_before_running(
    arguments: dict, named: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """resume and overlay act on the study folder: without out= there is none, so the
    call is refused before any run (not an overlay computed and thrown away, nor a
    refusal naming a temporary folder and a command-line flag)."""
    import cosim.study.runner

    def ran(*args: object, **kwargs: object) -> None:
        raise AssertionError("the study ran")

    monkeypatch.setattr(cosim.study.runner, "run_study", ran)
    with pytest.raises(StudyError) as raised:
        cosim.sweep({"scenario": "bs-3"}, workers=1, **arguments)
    assert str(raised.value).startswith(named) and "--" not in str(raised.value)


@pytest.mark.parametrize(
    ("resume", "held", "named"),
    [
        (False, "study.json", "already holds a study: add resume=True to continue it, or give "
         "another out="),
        (True, None, "resume=True: "),
        (False, "notes.txt", "out='"),
    ],
)  # fmt: skip
def test_a_refused_study_folder_names_the_keywords_not_the_flags(
    resume: bool, held: str | None, named: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """cosim.sweep(out=...) into a folder holding a study said "add --resume to continue
    it, or give another --out": the command line's flags, which a script does not have."""
    out = tmp_path / "study"
    out.mkdir()
    if held is not None:
        (out / held).write_text("{}\n")
    study = {"scenario": "bs-3", "stop_time": 0.1, "grid": {"plant.v_0": [0.1]}}
    with pytest.raises(StudyError) as raised:
        cosim.sweep(study, workers=1, out=out, resume=resume, fmu_dir=fmu_dir)
    assert named in str(raised.value) and "--" not in str(raised.value), raised.value


@pytest.mark.parametrize(
    ("arguments", "named"),
    [
        ({"max_runs": 2}, "(max_runs=N raises the cap)"),
        ({"max_runs": 20_000_000}, "max_runs=20000000: expected 1 to 10000000"),
        ({"overlay": 50, "out": "study"}, "overlay=50: expected a number of runs from 1 to 20"),
    ],
)
def test_a_study_too_large_names_the_keyword_that_raises_the_cap(
    arguments: dict, named: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """cosim.sweep of a study over its cap said "(--max-runs N raises the cap)", a flag
    the API did not have; overlay=50 was "--overlay 50"."""
    if "out" in arguments:
        arguments = {**arguments, "out": tmp_path / arguments["out"]}
    study = {"scenario": "bs-3", "stop_time": 0.1, "grid": {"plant.v_0": [0.1, 0.2, 0.3]}}
    with pytest.raises(StudyError) as raised:
        cosim.sweep(study, workers=1, fmu_dir=fmu_dir, **arguments)
    assert named in str(raised.value) and "--" not in str(raised.value), raised.value


WRONG_TYPE = [
    ("sweep", {"study": {"scenario": "bs-3"}, "overlay": 0}, StudyError, "overlay=0"),
    ("sweep", {"study": 5}, StudyError, "study=5"),
    ("sweep", {"study": {"scenario": "bs-3"}, "oversubscribe": "yes"}, StudyError, "'yes'"),
    ("sweep", {"study": {"scenario": "bs-3"}, "out": A_FILE}, StudyError, "out="),
    ("sweep", {"study": {"scenario": "bs-3"}, "fmu_dir": A_FILE}, StudyError, "fmu_dir="),
    ("load_scenario", {"scenario": 5}, ScenarioError, "scenario=5"),
    ("load_scenario", {"scenario": "bs-3", "fmu_dir": A_FILE}, ScenarioError, "fmu_dir="),
]


EMPTY_PATHS = [
    ("run", {"scenario": ""}, CosimError, "scenario=''"),
    ("run", {"scenario": "bs-3", "out": ""}, CosimError, "out=''"),
    ("run", {"scenario": "bs-3", "fmu_dir": ""}, CosimError, "fmu_dir=''"),
    ("load_scenario", {"scenario": ""}, ScenarioError, "scenario=''"),
    ("load_scenario", {"scenario": "bs-3", "fmu_dir": ""}, ScenarioError, "fmu_dir=''"),
    ("sweep", {"study": ""}, StudyError, "study=''"),
    ("sweep", {"study": {"scenario": "bs-3"}, "out": ""}, StudyError, "out=''"),
    ("sweep", {"study": {"scenario": "bs-3"}, "fmu_dir": ""}, StudyError, "fmu_dir=''"),
    ("build_fmus", {"out": ""}, CosimError, "out=''"),
]


@pytest.mark.parametrize(("function", "arguments", "error", "named"), EMPTY_PATHS)
def test_an_empty_path_is_refused_not_read_as_the_working_folder(
    function: str,
    arguments: dict,
    error: type[CosimError],
    named: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An empty string (an unset environment variable's default) was read as ".":
    ``fmu_dir=""`` and ``build_fmus("")`` built the FMUs into the working folder, and
    ``cosim.run("")`` said "not a file: .", naming no argument. Refused, naming it, with
    nothing written."""
    monkeypatch.chdir(tmp_path)
    call = getattr(cosim, function)
    positional = [arguments.pop(k) for k in ("scenario", "study") if k in arguments]
    with pytest.raises(error) as raised:
        call(*positional, **arguments)
    message = str(raised.value)
    assert message.startswith(f"{named}: expected a non-empty path"), message
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("function", "arguments", "error", "named"), WRONG_TYPE)
def test_bad_arguments_raise_the_type_the_docstring_names(
    function: str, arguments: dict, error: type[CosimError], named: str
) -> None:
    """sweep documents StudyError and load_scenario ScenarioError for a bad argument: a
    caller catching the documented type catches these too."""
    call = getattr(cosim, function)
    positional = [arguments.pop(k) for k in ("scenario", "study") if k in arguments]
    with pytest.raises(error, match="expected") as raised:
        call(*positional, **arguments, **({"workers": 1} if function == "sweep" else {}))
    assert named in str(raised.value)


@pytest.mark.parametrize(
    "value", [np.array([0.1, 0.2]), np.array([0.1]), Decimal("0.1")], ids=["array", "one", "dec"]
)
def test_with_start_takes_the_values_cosim_run_takes_and_refuses_the_others(
    value: object, fmu_dir: Path
) -> None:
    """``with_start`` raised ValueError ("can only convert an array of size 1 to a Python
    scalar") for an array, past ``except CosimError``, and took an array of one element or
    a Decimal as a float, which ``cosim.run(start=...)`` refuses: one rule for both, a
    bool, int, float or str or a numpy scalar of one, else a ScenarioError naming it."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError) as raised:
        scenario.with_start({"plant.v_0": value})  # type: ignore[dict-item]
    message = str(raised.value)
    assert "start value 'plant.v_0'" in message and "expected a bool, int, float" in message
    with pytest.raises(CosimError, match="expected a bool, int, float or str"):
        cosim.run(scenario, start={"plant.v_0": value})  # type: ignore[dict-item]


def test_with_start_of_a_non_mapping_is_a_scenario_error(fmu_dir: Path) -> None:
    """with_start([1]) raised a bare TypeError from dict(); it is the documented
    ScenarioError naming the value and what was expected."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError, match=r"start values \[1\]: expected a mapping"):
        scenario.with_start([1])  # type: ignore[arg-type]


def test_a_study_given_as_a_dict_is_named_as_such_not_by_a_temporary_file() -> None:
    """A refused key of a study dict is named in the dict, not in the temporary
    study.toml the dict is written to (a file the caller never wrote)."""
    with pytest.raises(StudyError) as raised:
        cosim.sweep({"scenario": "bs-3", "grd": {}}, workers=1)
    message = str(raised.value)
    assert message.startswith("study (given as a dict): unknown key 'grd'"), message
    assert "study.toml" not in message and tempfile.gettempdir() not in message


UNGUARDED = """
import cosim
study = cosim.sweep({"scenario": "bs-3", "stop_time": 0.1, "grid": {"plant.v_0": [0.0]}})
print(study.table)
"""


@pytest.mark.slow
def test_sweep_at_the_top_level_of_a_script_says_in_one_line_what_is_needed(
    tmp_path: Path,
) -> None:
    """cosim.sweep in a script without `if __name__ == "__main__":` flooded the terminal
    with Dask's spawn traceback from every worker process."""
    script = tmp_path / "study_script.py"
    script.write_text(UNGUARDED, encoding="utf-8")
    done = subprocess.run(
        [sys.executable, str(script)], cwd=tmp_path, env=_environment(), capture_output=True,
        text=True, timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode != 0
    last = done.stderr.strip().splitlines()[-1]
    assert 'put the call under `if __name__ == "__main__":`' in last, done.stderr
    assert f"top level of {script} (line 3)" in last
    assert "bootstrapping phase" not in done.stderr and "Nanny" not in done.stderr


def test_a_scenario_loaded_by_a_relative_path_keeps_its_files_after_chdir(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A scenario read as ``case.toml`` with ``fmu_dir="build/fmus"`` (both relative, as
    a notebook gives them) kept those paths relative: after ``os.chdir`` (``%cd`` in
    Jupyter) ``with_start`` looked for its vehicle file in the new folder ("names no
    file"), and its built-in FMUs were looked up, and built, there. Its files stay the
    ones it was read with."""
    folder = _user_folder(tmp_path / "user", fmu_dir)
    data = tomllib.loads((SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8"))
    data["instances"]["plant"]["start"]["vehicle"] = "my-vehicle.toml"
    (folder / "case.toml").write_text(tomli_w.dumps(data), encoding="utf-8")
    shutil.copyfile(
        SCENARIO_FOLDER.parents[1] / "plant_fmu/model/vehicles/remus100-long-fins.toml",
        folder / "my-vehicle.toml",
    )
    monkeypatch.chdir(folder)
    scenario = cosim.load_scenario("case.toml", fmu_dir="build/fmus")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    changed = scenario.with_start({"plant.v_0": -0.05}).with_overrides(stop_time=1.0)
    assert changed.instances["plant"].start["vehicle"] == str(folder / "my-vehicle.toml")
    for name, instance in changed.instances.items():
        assert instance.fmu_path == folder / "build" / "fmus" / f"{instance.fmu}.fmu", name
    assert list(elsewhere.iterdir()) == [], "nothing is built or written in the new folder"


USER_SCRIPT = """\
import numpy as np

import cosim


def main() -> None:
    run = cosim.run("bs-3", start={"plant.v_0": np.float32(-0.05), "plant.variant": np.int64(1)})
    loaded: cosim.Scenario = cosim.load_scenario("bs-3")
    scenario = loaded.with_start({"controller.k0": np.float32(0.3)})
    try:
        print(run.results, cosim.run(scenario, start={"plant.v_0": -0.05}).summary)
    except (cosim.ScenarioError, cosim.StudyError, cosim.CosimError) as error:
        print(error)
"""


def _users_mypy(script_text: str, tmp_path: Path, cache: Path) -> tuple[str, int]:
    """``mypy --strict`` of a user's script ``script_text`` (:func:`users_mypy`)."""
    script = tmp_path / "user.py"
    script.write_text(script_text, encoding="utf-8")
    return users_mypy([script], tmp_path, cache)


@pytest.mark.slow
def test_a_users_mypy_strict_takes_the_numpy_start_values_the_docs_show(
    tmp_path: Path, users_mypy_cache: Path
) -> None:
    """docs/api.md: a numpy scalar start value (``np.float32(-0.05)``) counts as its Python
    value, and cosim.run takes it; the annotations said bool, int, float or str only, so a
    user's ``mypy --strict`` refused the documented call ("Dict entry 0 has incompatible
    type")."""
    report, status = _users_mypy(USER_SCRIPT, tmp_path, users_mypy_cache)
    assert status == 0, report


@pytest.mark.slow
def test_a_users_mypy_catches_a_mistyped_algorithm_in_with_overrides(
    tmp_path: Path, users_mypy_cache: Path
) -> None:
    """``Scenario.with_overrides`` takes the algorithm, extrapolation and error estimate
    ``cosim.run`` takes, typed as their names: a typo is the user's mypy error before it
    is the run's refusal (they were typed ``str``, so mypy passed ``"jacobbi"``)."""
    script = (
        "import cosim\n\n\ndef main() -> None:\n"
        '    cosim.load_scenario("bs-3").with_overrides(algorithm="jacobbi")\n'
    )
    report, status = _users_mypy(script, tmp_path, users_mypy_cache)
    assert status == 1 and 'Argument "algorithm" to "with_overrides"' in report, report


@pytest.mark.slow
def test_a_users_mypy_catches_a_string_given_for_sweeps_security(
    tmp_path: Path, users_mypy_cache: Path
) -> None:
    """``cosim.sweep``'s ``security`` is a ``distributed.Security``: typed ``Any``, a user's
    ``mypy --strict`` passed the folder of the certificates given in its place."""
    script = (
        "import cosim\n\n\ndef main() -> None:\n"
        '    cosim.sweep("study.toml", scheduler="tls://10.0.0.5:8786", security="certs/")\n'
    )
    report, status = _users_mypy(script, tmp_path, users_mypy_cache)
    assert status == 1 and 'Argument "security" to "sweep"' in report, report


@pytest.mark.parametrize("scheduler", [8786, b"tcp://127.0.0.1:8786"])
def test_a_scheduler_that_is_no_address_text_is_one_line_naming_it(scheduler: object) -> None:
    """``scheduler=`` given the scheduler's port alone or its address in bytes: refused
    before a study starts, naming the value and the address a scheduler has."""
    with pytest.raises(cosim.StudyError) as refused:
        cosim.sweep({"scenario": "bs-3"}, scheduler=scheduler)
    message = str(refused.value)
    assert message.startswith(f"scheduler={scheduler!r}: expected the address"), message
    assert "tcp://HOST:PORT" in message and "\n" not in message


@pytest.mark.parametrize("key", [1, ("plant", "v_0"), "plant.v_0\0"])
def test_a_start_key_that_is_no_name_is_one_line_naming_it(key: object) -> None:
    """``start=`` keyed by a number, a tuple or a name holding NUL: a CosimError naming
    the key and the form a start value's name takes, before any FMU is loaded."""
    with pytest.raises(CosimError) as refused:
        cosim.run("bs-3", stop_time=0.1, start={key: 0.0})  # type: ignore[dict-item]
    message = str(refused.value)
    assert message.startswith("start key ") and "'<instance>.<variable>'" in message, message
    assert "\n" not in message


@pytest.mark.parametrize("security", ["certs/", {"tls_ca_file": "ca.pem"}])
def test_a_security_that_is_no_dask_security_is_one_typed_line_naming_it(
    security: object,
) -> None:
    """A study on a ``tls://`` scheduler that accepts connections, given the certificates'
    folder or a dict of Security's keywords for ``security``: an AttributeError from
    inside ("'str' object has no attribute 'get_connection_args'"), not a StudyError."""
    with socket.create_server(("127.0.0.1", 0)) as server:  # accepts: the probe gets further
        address = f"tls://127.0.0.1:{server.getsockname()[1]}"
        with pytest.raises(cosim.StudyError) as refused:
            cosim.sweep({"scenario": "bs-3"}, scheduler=address, security=security)
    message = str(refused.value)
    assert message.startswith(f"security={security!r}: expected a distributed.Security"), message
    assert "\n" not in message


INTERRUPTED_LOOP = """
import glob, json, os, signal, sys, tempfile, threading, time
import cosim
from cosim.errors import CosimError

def interrupt_after_the_first_rows():
    pattern = "auv-cosim-scratch*/*/auv-cosim-*/run/results.csv"
    while not any(len(open(p).readlines()) > 2 for p in glob.glob(pattern)):
        time.sleep(0.05)
    os.kill(os.getpid(), signal.SIGINT)  # what a notebook's stop button sends its kernel

if __name__ == "__main__":
    tempfile.tempdir = os.getcwd()  # an in-memory run's: auv-cosim-scratch-<uid>/*/auv-cosim-*/run
    threading.Thread(target=interrupt_after_the_first_rows, daemon=True).start()
    started = 0
    try:
        for stop_time in (3000.0, 1.0, 1.0):
            started += 1
            try:
                cosim.run("bs-3", stop_time=stop_time, fmu_dir=sys.argv[1])
            except CosimError:  # a failed run: go on with the next
                continue
    except cosim.RunInterrupted as stop:
        print(json.dumps({"started": started, "message": str(stop),
                          "signal": stop.run.summary["signal"], "rows": len(stop.run.results)}))
"""


@pytest.mark.slow
def test_ctrl_c_ends_a_loop_that_goes_on_after_a_failed_run(tmp_path: Path, fmu_dir: Path) -> None:
    """Ctrl-C during cosim.run raised a RunError, a CosimError: a loop over runs that goes
    on after a failed one (``except CosimError: continue``) swallowed the stop and started
    the next run. It is a KeyboardInterrupt now, with the partial results."""
    script = tmp_path / "interrupted_loop.py"
    script.write_text(INTERRUPTED_LOOP, encoding="utf-8")
    command = [sys.executable, str(script), str(fmu_dir)]
    done = run_in_group(command, timeout=600, cwd=tmp_path, env=_environment())
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    assert done.stdout.strip(), "the loop ran to its end: the stop was swallowed"
    caught = json.loads(done.stdout.strip().splitlines()[-1])
    assert caught["started"] == 1 and caught["signal"] == "SIGINT" and caught["rows"] > 1
    assert caught["message"].endswith("(partial results in the error's run.results)")


INTERRUPTED_SWEEP = """
import glob, json, os, signal, sys, tempfile, threading, time
import cosim

def interrupt_after_the_first_row(pattern):
    while not any(len(open(p).readlines()) > 1 for p in glob.glob(pattern)):
        time.sleep(0.05)
    os.kill(os.getpid(), signal.SIGINT)  # what a notebook's stop button sends its kernel

if __name__ == "__main__":
    out, fmu_dir = sys.argv[1] or None, sys.argv[2]
    tempfile.tempdir = os.getcwd()  # an in-memory study's folder (cosim.scratch)
    pattern = os.path.join(out or "auv-cosim-scratch*/*/auv-cosim-*/study", "runs.csv")
    threading.Thread(target=interrupt_after_the_first_row, args=(pattern,), daemon=True).start()
    grid = {"plant.v_0": [round(-0.1 + 0.02 * i, 2) for i in range(10)]}
    try:
        cosim.sweep({"scenario": "bs-3", "stop_time": 30.0, "grid": grid}, workers=1,
                    out=out, fmu_dir=fmu_dir)
    except cosim.SweepInterrupted as error:
        table = error.study.table
        print(json.dumps({"message": str(error), "rows": len(table),
                          "complete": bool((table["status"] == "complete").all()),
                          "out_dir": None if error.study.out_dir is None
                          else str(error.study.out_dir)}))
"""


@pytest.mark.cluster
@pytest.mark.slow
@pytest.mark.parametrize("out", [None, "study"], ids=["in-memory", "out"])
def test_an_interrupted_sweep_raises_one_line_with_the_finished_rows(
    tmp_path: Path, fmu_dir: Path, out: str | None
) -> None:
    """Ctrl-C (a notebook's stop button) during cosim.sweep raised a bare KeyboardInterrupt
    from inside Dask, and the rows of the runs already finished were lost with it."""
    script = tmp_path / "interrupted_sweep.py"
    script.write_text(INTERRUPTED_SWEEP, encoding="utf-8")
    command = [sys.executable, str(script), out or "", str(fmu_dir)]
    done = run_in_group(command, timeout=600, cwd=tmp_path, env=_environment())
    assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
    caught = json.loads(done.stdout.strip().splitlines()[-1])
    assert 1 <= caught["rows"] < 10 and caught["complete"]
    runs = f"{caught['rows']} finished run{'s' * (caught['rows'] != 1)}"  # 1 run: singular
    kept = f"{runs} kept in the error's study.table"
    assert caught["message"].startswith(f"interrupted (Ctrl-C): {kept}")
    if out is None:
        left = [p for p in tmp_path.rglob("auv-cosim-*") if p.name != SCRATCH_DIR]
        assert caught["out_dir"] is None and not left
    else:
        assert caught["out_dir"] == str(tmp_path / out)
        assert f"{tmp_path / out / 'runs.csv'} (resume=True" in caught["message"]
        with (tmp_path / out / "runs.csv").open(encoding="utf-8") as file:
            assert len(file.readlines()) == 1 + caught["rows"]


EARLY_INTERRUPTED_SWEEP = """
import json, os, re, signal, sys, threading, time
import psutil
import cosim
from cosim import sweep  # cosim.api imported (~0.07 s): the call is what is timed

# multiprocessing's helpers, which last as long as the process that started them
HELPERS = re.compile(r"from multiprocessing\\.(forkserver|resource_tracker) import main")
# distributed's own offload thread (distributed.utils' module-level executor), which once
# started lasts as long as the process, as those helpers do
LIBRARY_THREADS = ("Dask-Offload",)

if __name__ == "__main__":
    offset, fmu_dir = float(sys.argv[1]), sys.argv[2]
    go = threading.Event()
    timer = threading.Thread(target=lambda: go.wait() and time.sleep(offset) or
                             os.kill(os.getpid(), signal.SIGINT))
    study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [-0.1]}}
    timer.start()
    try:
        go.set()  # a stop sent while the sweep imports Dask and starts its cluster
        sweep(study, workers=1, fmu_dir=fmu_dir)
        caught = "finished"
    except cosim.SweepInterrupted as error:
        caught = f"SweepInterrupted: {error}"
    except KeyboardInterrupt as error:
        caught = f"{type(error).__name__}: {error}"
    timer.join()

    def left():
        threads = [t.name for t in threading.enumerate() if t is not threading.main_thread()
                   and not t.name.startswith(LIBRARY_THREADS)]
        children = []
        for child in psutil.Process().children(recursive=True):
            try:
                command = " ".join(child.cmdline())
            except psutil.NoSuchProcess:  # ended as it was looked at
                continue
            if not HELPERS.search(command):
                children.append(command)
        return threads, children

    # what the sweep started ends soon after it returns: looked for until it has ended (a
    # guard against a hang, not a measure: a fixed wait guessed how long that takes)
    deadline = time.monotonic() + 60.0
    while any(left()) and time.monotonic() < deadline:
        time.sleep(0.05)
    threads, children = left()
    print(json.dumps({"caught": caught, "threads": threads, "children": children}))
"""


@pytest.mark.cluster
@pytest.mark.slow
def test_ctrl_c_in_a_sweeps_first_second_raises_sweep_interrupted(
    tmp_path: Path, fmu_dir: Path
) -> None:
    """Ctrl-C in the first second of cosim.sweep (its imports, before the study's stop
    handler was installed) raised a bare KeyboardInterrupt from inside an import, not the
    SweepInterrupted a notebook catches; whenever it comes, the sweep ends with no process
    or thread of its own left."""
    script = tmp_path / "early_interrupted_sweep.py"
    script.write_text(EARLY_INTERRUPTED_SWEEP, encoding="utf-8")
    outcomes = []
    for offset in (0.001, 0.05, 0.2, 0.5, 1.0):
        command = [sys.executable, str(script), str(offset), str(fmu_dir)]
        done = run_in_group(command, timeout=600, cwd=tmp_path, env=_environment())
        assert done.returncode == 0 and "Traceback" not in done.stderr, done.stderr
        outcome = json.loads(done.stdout.strip().splitlines()[-1])
        assert outcome["caught"].startswith(("SweepInterrupted: ", "finished")), (offset, outcome)
        assert outcome["threads"] == [] and outcome["children"] == [], (offset, outcome)
        outcomes.append(outcome["caught"])
    stopped = "SweepInterrupted: interrupted (Ctrl-C): 0 finished runs kept in"
    assert outcomes[0].startswith(stopped), outcomes


@pytest.mark.cluster
@pytest.mark.slow
def test_a_sweep_with_failed_runs_says_so_in_one_warning(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study whose runs failed returned its table silently: a notebook showed NaN metrics
    (or plotted fewer points) with no word of the failures the command line reports."""
    monkeypatch.chdir(tmp_path)
    study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [-0.1, 99.0]}}
    with pytest.warns(UserWarning) as caught:
        result = cosim.sweep(study, workers=1, fmu_dir=fmu_dir)
    failed = result.table.loc[result.table["status"] == "failed"]
    assert list(failed["plant.v_0"]) == [99.0]
    messages = [str(w.message) for w in caught if str(w.message).startswith("cosim.sweep:")]
    assert len(messages) == 1 and "\n" not in messages[0]
    first = f"the first run {failed['run'].iloc[0]} (plant.v_0 = 99.0): plant: fmi2DoStep"
    assert messages[0].startswith(f"cosim.sweep: 1 of 2 runs failed, {first}")
    assert caught[0].filename == __file__  # the warning points at the caller's line


def test_a_scenario_shows_in_one_line_with_its_start_values(fmu_dir: Path) -> None:
    """A notebook cell ending in a loaded scenario printed the dataclass's repr: every
    connection, recorded column and coupling setting, thousands of characters."""
    vehicle = (ROOT / "plant_fmu/model/vehicles/remus100.toml").read_text(encoding="utf-8")
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir).with_start(
        {"plant.u_0": 1.2, "plant.vehicle": vehicle}
    )
    shown = repr(scenario)
    assert "\n" not in shown and "Connection(" not in shown and len(shown) < 3 * 160, shown
    assert shown.startswith("Scenario(id='bs-3', source=") and "stop_time=60.0" in shown
    assert "'plant.u_0': 1.2" in shown and "'controller.heading_mode': 3" in shown
    assert f"connections=<{len(scenario.connections)}>" in shown


def test_a_study_dict_naming_a_file_in_bytes_not_utf8_is_refused_saying_so(
    tmp_path: Path,
) -> None:
    """``cosim.sweep({"scenario": <a file named in Latin-1>})`` was refused as "cannot be
    written as TOML: 'utf-8' codec can't encode character '\\udcf6' in position 14:
    surrogates not allowed": the key and the name as the user knows it (``gr\\xf6sse``)
    went unsaid, and so did what to do."""
    scenario = tmp_path / os.fsdecode(b"gr\xf6sse.toml")
    shutil.copyfile(SCENARIO_FOLDER / "bs-3.toml", scenario)
    study = {"scenario": scenario, "stop_time": 0.5, "grid": {"plant.v_0": [0.1]}}
    with pytest.raises(StudyError) as refused:
        cosim.sweep(study, workers=1, out=tmp_path / "study")
    assert str(refused.value) == (
        f"study (given as a dict): key 'scenario' = {str(scenario)!r}: a name in bytes that "
        f"are no UTF-8 ({tmp_path}/gr\\xf6sse.toml), which a study's TOML cannot hold: "
        "rename the file"
    )


def test_a_stopped_studys_table_keeps_an_all_digit_run_id_as_its_text(tmp_path: Path) -> None:
    """A run id is 16 hexadecimal digits, now and then all of them decimal: the table a
    stopped study hands back read such an id from runs.csv as the integer 123456789012345,
    which names no run folder and no `overlay` entry (the leading 0 lost)."""
    import signal

    from cosim.api import _stopped

    (tmp_path / "runs.csv").write_text(
        "run,plant.v_0,status\n0123456789012345,-0.1,complete\n", encoding="utf-8"
    )
    error = _stopped(signal.SIGINT, tmp_path, kept=True)
    assert list(error.study.table["run"]) == ["0123456789012345"]
