"""Scenario files, study files and command lines written from their documented schema
(``tests/scenario_fuzz.py``), each value valid most of the time and pushed to an edge
otherwise, given to ``auv-cosim run``, ``cosim.load_scenario``, ``cosim.run`` and
``cosim.sweep``. The property, beyond ``test_hostile_input.py``'s (one line, no
traceback): an input runs to its stop time, or is refused with exit code 1 (2 for a
command line argparse cannot parse) BEFORE any FMU is instantiated, with nothing left in
the output folder; the Python API raises :class:`~cosim.errors.CosimError` (its
``ScenarioError`` and ``StudyError``), never another exception.

The fast tier runs a few dozen examples of each; the slow tier more.
``SCHEMA_EXAMPLES=5000 python -m pytest tests/cosim/test_schema_fuzz.py -m slow`` hunts
with more (``--hypothesis-seed`` to vary them)."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import re
import tempfile
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from unittest import mock

import pytest
import tomli_w
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st
from scenario_fuzz import scenarios, studies

import cosim
from cosim.cli import main
from cosim.engine.slave import Slave
from cosim.errors import CosimError, one_line_warnings

HUNTING = "SCHEMA_EXAMPLES" in os.environ
SLOW_EXAMPLES = int(os.environ.get("SCHEMA_EXAMPLES", "300"))


def fuzz(examples: int) -> settings:
    """Hypothesis's settings for ``examples`` examples: the same ones on every run of the
    suite, random ones when hunting."""
    return settings(
        max_examples=examples,
        deadline=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
        derandomize=not HUNTING,
    )


@contextlib.contextmanager
def loads_counted() -> Iterator[list[str]]:
    """The names of the FMU instances instantiated (``Slave.load``) in the block."""
    loaded: list[str] = []
    original = Slave.load

    def load(slave: Slave, stop_time: float) -> None:
        loaded.append(slave.instance.name)
        original(slave, stop_time)

    with mock.patch.object(Slave, "load", load):
        yield loaded


def command(argv: list[str]) -> tuple[int, str, list[str]]:
    """``auv-cosim *argv`` in this process: its exit code, its stderr (warnings one line
    each, as the command shows them) and the instances it instantiated."""
    err = io.StringIO()
    with (
        warnings.catch_warnings(),
        contextlib.redirect_stderr(err),
        contextlib.redirect_stdout(io.StringIO()),
        loads_counted() as loaded,
    ):
        warnings.simplefilter("always")
        warnings.showwarning = one_line_warnings(f"auv-cosim {argv[0]}")
        try:
            code = main(argv)
        except SystemExit as exit_:  # argparse's usage error
            code = int(exit_.code or 0)
    return code, err.getvalue(), loaded


TYPE_NAME = re.compile(r"\b[A-Z]\w*(Error|Exception): ")
KEY = re.compile(r"key '([^']*)'")  # the key a refusal names (for the statistics)


def check_outcome(code: int, err: str, loaded: list[str], out: Path) -> None:
    """A complete run with finite results, or a refusal before any FMU was instantiated:
    exit 1 (2 for argparse's usage error) and one line, nothing in ``out``."""
    assert "Traceback" not in err, err
    lines = [  # the command's lines, not the FMUs' debug log a scenario may turn on
        line
        for line in err.splitlines()
        if line.startswith(("auv-cosim", "usage: "))
        and not line.startswith("auv-cosim run: warning: ")
    ]
    event(f"exit {code}")
    if code == 0:
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        assert summary["status"] == "complete", summary
        with (out / "results.csv").open(newline="", encoding="utf-8") as rows:
            cells = [cell for row in list(csv.reader(rows))[1:] for cell in row]
        assert all(math.isfinite(float(cell)) for cell in cells), err
        assert not lines, err
        return
    said = [line for line in lines if not line.startswith("usage: ")]
    assert len(said) == 1, err
    keys = KEY.findall(said[0])
    event(f"refused at {re.sub('[0-9]+', 'N', keys[0]) if keys else said[0][:30]}")
    assert said[0].startswith("auv-cosim run"), err
    assert not TYPE_NAME.search(said[0]), said[0]
    if code == 1 and (out / "summary.json").is_file():  # a run that failed on its way
        event("a run that failed")
        summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
        assert summary["status"] != "complete", summary
        return
    assert code in (1, 2), err
    assert not loaded, f"refused after instantiating {loaded}: {said[0]}"
    assert not out.exists() or not any(out.iterdir()), sorted(out.iterdir())


def toml_text(data: dict[str, Any]) -> str | None:
    """``data`` as TOML, or None where TOML cannot hold it (a mixed array's table)."""
    try:
        return tomli_w.dumps(data)
    except (TypeError, ValueError):
        return None


def run_file(data: dict[str, Any], fmu_dir: Path, *flags: str) -> None:
    """``auv-cosim run`` on ``data`` written as a scenario file, checked by
    :func:`check_outcome`."""
    text = toml_text(data)
    if text is None:
        event("not TOML")
        return
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.toml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        out = Path(tmp) / "run"
        argv = ["run", str(path), "--no-rrd", "--quiet", "--out", str(out)]
        code, err, loaded = command([*argv, "--fmu-dir", str(fmu_dir), *flags])
        check_outcome(code, err, loaded, out)


@fuzz(12)
@given(data=scenarios())
def test_a_generated_scenario_runs_or_is_refused_before_its_fmus_load(
    fmu_dir: Path, data: dict[str, Any]
) -> None:
    """A scenario file of valid and edge values: a complete run, or one line and exit 1
    before any FMU is instantiated, the run folder left empty."""
    run_file(data, fmu_dir)


@pytest.mark.slow
@fuzz(SLOW_EXAMPLES)
@given(data=scenarios())
def test_many_generated_scenarios_run_or_are_refused_before_their_fmus_load(
    fmu_dir: Path, data: dict[str, Any]
) -> None:
    """The fast tier's property, over more scenario files."""
    run_file(data, fmu_dir)


def api_run(data: dict[str, Any], fmu_dir: Path) -> None:
    """``cosim.load_scenario`` and ``cosim.run`` on ``data`` written as a scenario file:
    both load it, or raise a CosimError before any FMU is instantiated, ``out`` unmade."""
    text = toml_text(data)
    if text is None:
        return
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = Path(tmp) / "fuzz.toml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        out = Path(tmp) / "run"
        try:
            cosim.load_scenario(path, fmu_dir=fmu_dir)
        except CosimError as exc:
            event("load_scenario refused")
            assert "\n" not in str(exc), str(exc)
        with loads_counted() as loaded:
            try:
                run = cosim.run(path, out=out, recording=False, fmu_dir=fmu_dir)
            except cosim.RunError as exc:  # a run that failed on its way: its partial run
                assert not exc.run.complete, exc.run.summary
                return
            except CosimError as exc:
                event("run refused")
                assert not loaded, f"refused after instantiating {loaded}: {exc}"
                assert not out.exists(), sorted(out.iterdir())
                return
        event("ran")
        assert run.complete, run.summary


@fuzz(12)
@given(data=scenarios())
def test_the_api_loads_a_generated_scenario_or_raises_a_cosim_error(
    fmu_dir: Path, data: dict[str, Any]
) -> None:
    """``cosim.load_scenario`` and ``cosim.run`` on a scenario file of valid and edge
    values: loaded and run, or a CosimError (never a KeyError, TypeError, ValueError or
    pydantic's ValidationError) before any FMU is instantiated."""
    api_run(data, fmu_dir)


@pytest.mark.slow
@fuzz(SLOW_EXAMPLES)
@given(data=scenarios())
def test_the_api_loads_many_generated_scenarios_or_raises_cosim_errors(
    fmu_dir: Path, data: dict[str, Any]
) -> None:
    """The fast tier's API property, over more scenario files."""
    api_run(data, fmu_dir)


# ``auv-cosim run``'s options (``--help``), each with good values and edge ones; the live
# ones (--control, --interactive, --connect, --real-time) wait on the world and are left out
NUMBER_TEXT = ["0", "-0", "-1", "nan", "inf", "-inf", "1e308", "1e-320", "", " ", "0x10",
               "1_0", "٣", "10 s", "1e", "--", "0.01", "0.02", "0.025", "0.05"]  # fmt: skip
OPTION_VALUES: dict[str, st.SearchStrategy[list[str]]] = {
    "--stop-time": st.sampled_from(NUMBER_TEXT).map(lambda v: [v]),
    "--step": st.sampled_from(NUMBER_TEXT).map(lambda v: [v]),
    "--tolerance": st.sampled_from(NUMBER_TEXT).map(lambda v: [v]),
    "--checkpoint-every": st.sampled_from(NUMBER_TEXT).map(lambda v: [v]),
    "--algorithm": st.sampled_from(["jacobi", "gauss-seidel", "adaptive", "", "Jacobi"]).map(
        lambda v: [v]
    ),
    "--extrapolation": st.sampled_from(["none", "linear", "quadratic", "cubic"]).map(lambda v: [v]),
    "--fmu-log": st.sampled_from(
        ["plant", "controller:logAll", "nosuch", ":", "plant:", "a:b,,c"]
    ).map(lambda v: [v]),
    "--rrd": st.sampled_from(["{tmp}/x.rrd", "", "/", "{tmp}/名前.rrd", "{tmp}"]).map(
        lambda v: [v]
    ),
    "--resume": st.sampled_from(["nosuch", "", "/"]).map(lambda v: [v]),
    "--check-step": st.just([]),
    "--no-rrd": st.just([]),
    "--overwrite": st.just([]),
    "--quiet": st.just([]),
    "--bogus": st.just([]),
    "-h": st.just([]),
}


@st.composite
def flag_lists(draw: st.DrawFn) -> list[str]:
    """Zero to four of ``auv-cosim run``'s options with their values, a short stop time
    first (a later ``--stop-time`` wins)."""
    argv = ["--stop-time", "0.05"]
    for option in draw(st.lists(st.sampled_from(sorted(OPTION_VALUES)), max_size=4)):
        argv += [option, *draw(OPTION_VALUES[option])]
    return argv


def run_flags(flags: list[str], fmu_dir: Path) -> None:
    """``auv-cosim run bs-3 FLAGS`` into a fresh folder, checked by :func:`check_outcome`
    (--help: its text and exit 0)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        flags = [flag.replace("{tmp}", tmp) for flag in flags]
        if "--no-rrd" not in flags and "--rrd" not in flags:
            flags.append("--no-rrd")
        argv = ["run", "bs-3", "--out", str(out), "--fmu-dir", str(fmu_dir), *flags]
        code, err, loaded = command(argv)
        if "-h" in flags and code == 0:
            return
        check_outcome(code, err, loaded, out)


@fuzz(12)
@given(flags=flag_lists())
def test_run_options_in_any_combination_run_or_are_refused_before_the_fmus_load(
    fmu_dir: Path, flags: list[str]
) -> None:
    """``auv-cosim run bs-3`` with options of good and edge values in any combination: a
    complete run, or exit 1 (2: argparse's) and one line before any FMU is instantiated."""
    run_flags(flags, fmu_dir)


@pytest.mark.slow
@fuzz(SLOW_EXAMPLES)
@given(flags=flag_lists())
def test_many_run_option_combinations_run_or_are_refused_before_the_fmus_load(
    fmu_dir: Path, flags: list[str]
) -> None:
    """The fast tier's option property, over more combinations."""
    run_flags(flags, fmu_dir)


class Planned(BaseException):
    """Raised where an accepted study would start its runs (no cluster is started)."""


def api_sweep(data: dict[str, Any], fmu_dir: Path) -> None:
    """``cosim.sweep`` of the study ``data``: planned (stopped where its runs would start),
    or a StudyError of one line before any FMU is instantiated, no study folder left."""
    from cosim.study import runner
    from cosim.study.spec import StudyError

    def planned(*args: Any) -> None:
        raise Planned

    with (
        tempfile.TemporaryDirectory() as tmp,
        warnings.catch_warnings(),
        mock.patch.object(runner, "_execute", planned),
        loads_counted() as loaded,
    ):
        warnings.simplefilter("ignore")
        out = Path(tmp) / "study"
        try:
            cosim.sweep(data, workers=1, out=out, fmu_dir=fmu_dir)
        except Planned:
            event("planned")
        except StudyError as exc:
            event("refused")
            assert "\n" not in str(exc), str(exc)
            assert not out.exists(), sorted(out.iterdir())
        assert not loaded, loaded


def cli_sweep(data: dict[str, Any], fmu_dir: Path) -> None:
    """``auv-cosim sweep`` of the study ``data`` written as a file (if TOML holds it):
    planned, or exit 1 and one line, no study folder left. Neither the workers' fork server
    nor a cluster is started: the command's early cluster is none here."""
    from cosim.study import execution, fork_server, runner

    text = toml_text(data)
    if text is None:
        return

    def planned(*args: Any) -> None:
        raise Planned

    with (
        tempfile.TemporaryDirectory() as tmp,
        mock.patch.object(fork_server, "start", lambda warm=False: False),
        mock.patch.object(execution, "early_client", lambda *args, **kw: contextlib.nullcontext()),
        mock.patch.object(runner, "_execute", planned),
    ):
        path = Path(tmp) / "study.toml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        out = Path(tmp) / "study"
        argv = ["sweep", str(path), "--quiet", "--out", str(out), "--fmu-dir", str(fmu_dir)]
        try:
            code, err, loaded = command(argv)
        except Planned:
            return
        assert "Traceback" not in err, err
        lines = [line for line in err.splitlines() if not line.startswith("auv-cosim sweep: warn")]
        assert code == 1 and len(lines) == 1 and lines[0].startswith("auv-cosim sweep: "), err
        assert not TYPE_NAME.search(lines[0]), lines[0]
        assert not loaded and not out.exists(), loaded


@fuzz(12)
@given(data=studies())
def test_a_generated_study_is_planned_or_raises_a_study_error(
    fmu_dir: Path, data: dict[str, Any]
) -> None:
    """``cosim.sweep`` and ``auv-cosim sweep`` of a study of valid and edge values:
    planned, or a StudyError (never another exception; exit 1 and one line from the
    command) with no study folder left."""
    api_sweep(data, fmu_dir)
    cli_sweep(data, fmu_dir)


@pytest.mark.slow
@fuzz(SLOW_EXAMPLES)
@given(data=studies())
def test_many_generated_studies_are_planned_or_raise_study_errors(
    fmu_dir: Path, data: dict[str, Any]
) -> None:
    """The fast tier's study property, over more studies."""
    api_sweep(data, fmu_dir)
    cli_sweep(data, fmu_dir)


LONG_NAME = "é" * 300  # 600 bytes: past the 255 a file system takes for a name


@pytest.mark.parametrize("scenario", [LONG_NAME, f"{LONG_NAME}.toml", f"./{LONG_NAME}"])
def test_a_scenario_name_too_long_for_the_file_system_is_a_scenario_error(
    scenario: str, fmu_dir: Path
) -> None:
    """``cosim.load_scenario("é" * 300)`` raised OSError ("File name too long", naming the
    built-in scenarios' folder the caller never named), where the API promises a
    ScenarioError."""
    from cosim.scenario.checks import ScenarioError

    with pytest.raises(ScenarioError) as refused:
        cosim.load_scenario(scenario, fmu_dir=fmu_dir)
    assert "File name too long" in str(refused.value), refused.value
    assert "cosim/scenarios" not in str(refused.value), refused.value


@pytest.mark.parametrize("scenario", ["\x00/0", LONG_NAME, f"a/{LONG_NAME}"])
def test_a_study_s_scenario_the_system_cannot_look_up_is_a_study_error(
    scenario: str, fmu_dir: Path
) -> None:
    """A study whose scenario holds a NUL character or a name too long for the file system
    escaped ``cosim.sweep`` as ValueError ("embedded null byte") and OSError ("File name
    too long") before any run: both are a StudyError naming the scenario."""
    from cosim.study.spec import StudyError

    study = {"scenario": scenario, "grid": {"plant.v_0": [0.1]}}
    with (
        tempfile.TemporaryDirectory() as tmp,
        loads_counted() as loaded,
        pytest.raises(StudyError) as refused,
    ):
        cosim.sweep(study, workers=1, out=Path(tmp) / "study", fmu_dir=fmu_dir)
    assert "\n" not in str(refused.value) and not loaded, refused.value
