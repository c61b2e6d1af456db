"""Hostile scenario and study files: the built-in scenarios and docs/study-example.toml,
mutated structurally (a key or a table dropped, a value of another type, NaN, inf, -0.0,
1e308, huge integers, empty strings, control characters in names, duplicated instances
or connections, a connection to itself, units typed into strings, lists where tables go,
nested junk) and given to ``auv-cosim run`` in-process. The property: exit 0 with a
complete run and no NaN in its results, or a non-zero exit with exactly one line on stderr
in the command's error form, and never an exception escaping the command.

``HOSTILE_EXAMPLES=2000 python -m pytest tests/cosim/test_hostile_input.py`` hunts with
more examples than the committed count."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import math
import os
import re
import tempfile
import tomllib
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import tomli_w
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from cosim.cli import main
from cosim.errors import CosimError, one_line_warnings
from cosim.scenario.spec import SCENARIO_FOLDER

REPO = Path(__file__).parents[2]
STUDY_EXAMPLE = REPO / "docs" / "study-example.toml"
SCENARIOS = sorted(SCENARIO_FOLDER.glob("*.toml"))
EXAMPLES = int(os.environ.get("HOSTILE_EXAMPLES", "60"))
HUNT = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    derandomize="HOSTILE_EXAMPLES" not in os.environ,  # the committed test: the same files
)

ODD = [math.nan, math.inf, -math.inf, -0.0, 0.0, 1e308, -1e308, 5e-324, 2**63 - 1, -(2**63),
       0, -1, 1, True, False, "", " ", "\x00", "\x1b[31mred", "\u202eevil", "é", "名前",
       "10 s", "1.5 m/s", "30 deg", "nan", "inf", "plant", "plant.yaw",
       "controller.yaw_setpoint", "plant.plant", "../../etc/passwd", "a" * 300]  # fmt: skip
SCALARS = st.one_of(
    st.sampled_from(ODD),
    st.floats(),
    st.integers(min_value=-(2**63), max_value=2**63 - 1),
    st.text(max_size=12),
)
# start values of the plant, the autopilot and the guidance, given odd values
START_NAMES = ["m", "m_v", "W", "B", "I_zz", "x_g", "mass_stroke", "max_substep", "u_0",
               "yaw_0", "variant", "vehicle", "heading_mode", "depth_mode", "k0",
               "design_speed", "design_step", "waypoints", "acceptance_radius",
               "thrust"]  # fmt: skip
JUNK = st.recursive(
    SCALARS,
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=6), inner),
    max_leaves=8,
)


def _places(data: Any, at: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """Every key path into ``data``'s tables and lists (the root is ``()``)."""
    yield at
    items = (
        data.items()
        if isinstance(data, dict)
        else enumerate(data)
        if isinstance(data, list)
        else ()
    )
    for key, value in items:
        yield from _places(value, (*at, key))


def _get(data: Any, at: tuple[Any, ...]) -> Any:
    for key in at:
        data = data[key]
    return data


@st.composite
def mutated(draw: st.DrawFn, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with one to three structural mutations."""
    data = json.loads(json.dumps(data))  # a deep copy (TOML data is JSON data, but dates)
    for _ in range(draw(st.integers(1, 3))):
        at = draw(st.sampled_from(list(_places(data))))
        _mutate(draw, data, at)
    return data


def _mutate(draw: st.DrawFn, data: dict[str, Any], at: tuple[Any, ...]) -> None:
    """One mutation at ``at``: drop it, replace it, add a key, duplicate an entry or a
    table, or connect a variable to itself."""
    where = _get(data, at)
    op = draw(st.sampled_from(["drop", "replace", "add", "duplicate", "self", "start"]))
    if op in ("drop", "replace") and at:
        parent = _get(data, at[:-1])
        if op == "drop":
            del parent[at[-1]]
        else:
            parent[at[-1]] = draw(JUNK)
    elif op == "add" and isinstance(where, dict):
        where[
            draw(
                st.sampled_from(["", " ", "\x07", "plant", "x.y", "time", "é"])
                | st.text(max_size=6)
            )
        ] = draw(JUNK)
    elif op == "duplicate" and isinstance(where, list) and where:
        where.append(json.loads(json.dumps(draw(st.sampled_from(where)))))
    elif op == "duplicate" and isinstance(where, dict) and where:
        key = draw(st.sampled_from(sorted(where)))
        where[f"{key}2"] = json.loads(json.dumps(where[key]))
    elif op == "start" and isinstance(data.get("instances"), dict) and data["instances"]:
        instance = data["instances"][draw(st.sampled_from(sorted(data["instances"])))]
        start = instance.setdefault("start", {}) if isinstance(instance, dict) else None
        if isinstance(start, dict):
            start[draw(st.sampled_from(START_NAMES))] = draw(SCALARS)
    elif op == "self":
        ref = draw(st.sampled_from(["plant.yaw", "controller.yaw_setpoint", "plant.fin_angle"]))
        add = data.setdefault("connections", {})
        if isinstance(add, dict) and isinstance(add.setdefault("add", []), list):
            add["add"].append({"from": ref, "to": ref})


def _toml(data: dict[str, Any]) -> str | None:
    """``data`` as TOML, or None for what TOML cannot hold (a None, a table in a mixed
    array)."""
    try:
        return tomli_w.dumps(data)
    except (TypeError, ValueError):
        return None


def _short(data: dict[str, Any]) -> dict[str, Any]:
    """A scenario's data stopping after five communication steps (a whole run is slow)."""
    step = data.get("coupling", {}).get("step", 0.01)
    data["stop_time"] = 5 * step if isinstance(step, float) else 0.05
    return data


def _cli(*argv: str) -> tuple[int, str]:
    """``auv-cosim *argv`` in this process: its exit code and stderr, with warnings shown
    as the command shows them (one line each)."""
    err = io.StringIO()
    with (
        warnings.catch_warnings(),
        contextlib.redirect_stderr(err),
        contextlib.redirect_stdout(io.StringIO()),
    ):
        warnings.simplefilter("always")
        warnings.showwarning = one_line_warnings(f"auv-cosim {argv[0]}")
        try:
            code = main(list(argv))
        except SystemExit as exit_:  # argparse's usage error
            code = int(exit_.code or 0)
    return code, err.getvalue()


def check_outcome(code: int, err: str, out: Path, command: str) -> None:
    """The property: a complete run without NaN, or one line of error, no traceback."""
    assert "Traceback" not in err, err
    # the command's fallback for an exception no check expected ("ValueError: ..."): an
    # input that reached code which does not name it as the file's key
    assert re.search(rf"^auv-cosim {command}: \w+(Error|Exception): ", err, re.M) is None, err
    lines = [
        line for line in err.splitlines() if not line.startswith(f"auv-cosim {command}: warning: ")
    ]
    if code == 0:
        summary = json.loads((out / "summary.json").read_text())
        assert summary["status"] == "complete", summary
        with (out / "results.csv").open(newline="") as rows:
            cells = [cell for row in list(csv.reader(rows))[1:] for cell in row]
        bad = [cell for cell in cells if not math.isfinite(float(cell))]
        assert not bad or "nan" in err.lower() or "inf" in err.lower(), bad[:5]
        assert not lines, err
        return
    if code == 2 and lines and lines[0].startswith("usage: "):  # argparse's usage error
        errors = (f"auv-cosim {command}: error: ", "auv-cosim: error: ")  # the command's, the top's
        lines = [line for line in lines if line.startswith(errors)]
        assert len(lines) == 1, err
        return
    assert len(lines) == 1 and lines[0].startswith(f"auv-cosim {command}: "), err


def run_scenario_text(text: str | bytes, fmu_dir: Path, *flags: str) -> None:
    """``auv-cosim run`` on a file holding ``text``, checked by :func:`check_outcome`."""
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "hostile.toml"
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8", errors="surrogatepass")
        out = Path(tmp) / "run"
        argv = [
            "run",
            str(path),
            "--no-rrd",
            "--quiet",
            "--out",
            str(out),
            "--fmu-dir",
            str(fmu_dir),
        ]
        code, err = _cli(*argv, *flags)
        event(f"exit {code}")
        check_outcome(code, err, out, "run")


SCENARIO_DATA = [tomllib.loads(path.read_text()) for path in SCENARIOS]


@pytest.mark.slow
@HUNT
@given(
    data=st.sampled_from(SCENARIO_DATA).flatmap(
        lambda d: mutated(_short(json.loads(json.dumps(d))))
    )
)
def test_a_mutated_scenario_runs_or_is_refused_in_one_line(
    fmu_paths: dict[str, Path], data: dict[str, Any]
) -> None:
    """A built-in scenario, mutated: a complete run or one line naming what is wrong."""
    text = _toml(data)
    if text is not None:
        run_scenario_text(text, fmu_paths["AuvPlant"].parent)


def check_study(path: Path, fmu_dir: Path) -> tuple[int, str]:
    """What ``auv-cosim sweep`` checks of a study file before its cluster starts (the
    first steps of :func:`cosim.study.runner.run_study`), as the command reports it: 0, or
    1 and the one line of a refusal. Any other exception escapes, as in the command."""
    from cosim.study import runner
    from cosim.study.factors import resolve_factor
    from cosim.study.spec import check_size, load_study, study_label

    try:
        spec = load_study(path)
        check_size(spec, study_label(path))
        ref = runner._scenario_ref(spec.scenario, path.parent)
        base, facts = runner.prepare(ref, spec.stop_time, fmu_dir, spec.check_step, path.parent)
        factors = {name: resolve_factor(name, facts) for name in spec.factors}
        runner._metrics(spec, facts)
        runner._checked_plan(spec, base, factors, facts)
    except CosimError as exc:
        return 1, f"auv-cosim sweep: {exc}\n"
    return 0, ""


STUDY_DATA = tomllib.loads(STUDY_EXAMPLE.read_text())


def _planned_or_refused_in_one_line(fmu_paths: dict[str, Path], data: dict[str, Any]) -> None:
    """The study ``data`` (written as TOML, if it can be) is planned, or refused in one
    line."""
    text = _toml(data)
    if text is None:
        return
    with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = Path(tmp) / "study.toml"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        code, err = check_study(path, fmu_paths["AuvPlant"].parent)
    event(f"exit {code}")
    assert code == 0 or err.count("\n") == 1, err


@pytest.mark.slow
@HUNT
@given(data=mutated(STUDY_DATA))
def test_a_mutated_study_is_planned_or_refused_in_one_line(
    fmu_paths: dict[str, Path], data: dict[str, Any]
) -> None:
    """docs/study-example.toml, mutated: planned, or refused naming what is wrong."""
    _planned_or_refused_in_one_line(fmu_paths, data)


RAW = SCENARIOS[0].read_bytes()


@pytest.mark.slow
@HUNT
@given(
    cut=st.integers(0, len(RAW)),
    junk=st.binary(max_size=8)
    | st.sampled_from(
        [
            b"\x00",
            b"\xff\xfe",
            b"\xef\xbb\xbf",
            b"[",
            b"=",
            b"\n[[events]]\n",
            b"\nx = " + b"[" * 3000 + b"]" * 3000 + b"\n",
        ]
    ),
)
def test_a_scenario_file_cut_or_spliced_with_bytes_is_refused_in_one_line(
    fmu_paths: dict[str, Path], cut: int, junk: bytes
) -> None:
    """A built-in scenario's bytes cut short at any point, with bytes spliced in."""
    run_scenario_text(RAW[:cut] + junk, fmu_paths["AuvPlant"].parent, "--stop-time", "0.05")


ODD_VALUES = ["0", "-0", "-1", "nan", "-nan", "inf", "-inf", "1e308", "1e-308", "", " ",
              "0x10", "1_0", "٣", "10 s", "1e", "--", "0.05"]  # fmt: skip
OPTIONS = ["--stop-time", "--step", "--tolerance", "--real-time", "--algorithm",
           "--extrapolation"]  # fmt: skip


@pytest.mark.slow
@HUNT
@given(
    flags=st.lists(
        st.tuples(
            st.sampled_from(OPTIONS),
            st.sampled_from(ODD_VALUES),
        ),
        min_size=1,
        max_size=3,
    )
)
def test_odd_option_values_are_refused_in_one_line(
    fmu_paths: dict[str, Path], flags: list[tuple[str, str]]
) -> None:
    """``auv-cosim run bs-3`` with odd values for its numeric options."""
    argv = [part for flag in flags for part in flag]
    if "--stop-time" not in argv:
        argv += ["--stop-time", "0.05"]
    run_scenario_text(SCENARIOS[0].read_text(), fmu_paths["AuvPlant"].parent, *argv)


FACTOR_NAMES = ["plant.v_0", "controller.k0", "plant.yaw_0", "plant.variant", "plant.vehicle",
                "controller.heading_mode", "plant.m", "plant.m_v", "controller.design_step",
                "plant.thrust", "events.turn.time", "faults.fault-1.value", "plant.nosuch",
                "a.b.c", "plant.", ".v_0", "plant.v_0 ", "Plant.V_0",
                "controller.thrust"]  # fmt: skip


def mostly(good: st.SearchStrategy[Any], odd: st.SearchStrategy[Any]) -> st.SearchStrategy[Any]:
    """``good`` five times in six, else ``odd``: a study of one odd part gets past the
    others to the check of that part."""
    return st.sampled_from([good] * 5 + [odd]).flatmap(lambda strategy: strategy)


GOOD_NAMES = st.sampled_from(["plant.v_0", "controller.k0", "plant.yaw_0", "plant.m"])
NAMES = mostly(GOOD_NAMES, st.sampled_from(FACTOR_NAMES))
NUMBERS = mostly(st.floats(-0.2, 0.2), SCALARS)


def _law(kind: str, a: Any, b: Any) -> dict[str, list[Any]]:
    """A random factor's law: two plain numbers made a valid uniform (low < high) or
    normal (std >= 0) law; odd values left as drawn."""
    if isinstance(a, float) and isinstance(b, float):
        a, b = (min(a, b), max(a, b)) if kind == "uniform" else (a, abs(b))
    return {kind: [a, b]}


LAWS = st.builds(
    _law, mostly(st.sampled_from(["uniform", "normal"]), st.just("beta")), NUMBERS, NUMBERS
)


@st.composite
def studies(draw: st.DrawFn) -> dict[str, Any]:
    """A study file put together from odd parts: scenario references, stop times, grid
    values, random factors, sample counts and seeds, overlays and metrics."""
    data: dict[str, Any] = {
        "scenario": draw(mostly(st.just("bs-3"), st.sampled_from(["", "nosuch", "/", ".."]))),
        "stop_time": draw(mostly(st.just(0.05), SCALARS)),
    }
    values = st.lists(NUMBERS, min_size=draw(mostly(st.just(1), st.just(0))), max_size=3)
    grid = draw(st.dictionaries(NAMES, values, min_size=1, max_size=2))
    if grid or draw(st.booleans()):
        data["grid"] = grid
    factors = draw(st.dictionaries(NAMES, LAWS, max_size=1))
    if factors:
        data["random"] = {"n": draw(mostly(st.integers(1, 3), SCALARS)), **factors}
        if draw(st.booleans()):
            data["random"]["seed"] = draw(mostly(st.integers(0, 2**64), SCALARS))
        if draw(st.booleans()):
            data["random"]["sampling"] = draw(st.sampled_from(["latin-hypercube", "random", "lhs"]))
    if draw(st.integers(0, 4)) == 0:
        data["overlay"] = draw(
            st.lists(
                st.sampled_from(
                    ["all", "best:final.plant.yaw", "worst:", "0123456789abcdef", "best:nosuch"]
                ),
                max_size=3,
            )
        )
    if draw(st.integers(0, 4)) == 0:
        data["metrics"] = {
            "collect": draw(
                st.lists(
                    st.sampled_from(
                        ["final.plant.yaw", "yaw_settling_time_s", "nosuch", "", "final.plant"]
                    ),
                    max_size=3,
                )
            )
        }
    return data


@pytest.mark.slow
@HUNT
@given(data=studies())
def test_a_study_of_odd_parts_is_planned_or_refused_in_one_line(
    fmu_paths: dict[str, Path], data: dict[str, Any]
) -> None:
    """A study file of odd parts: planned, or refused naming what is wrong."""
    _planned_or_refused_in_one_line(fmu_paths, data)
