"""Hypothesis strategies that write scenario files, study files and ``auv-cosim run``
command lines from their documented schema (docs/scenario-example.toml, docs/events.md,
docs/study-example.toml, docs/studies.md, ``auv-cosim run --help``): every key a file
takes, each value drawn valid most of the time and pushed to an edge otherwise (another
type, NaN, infinities, huge and negative numbers, integers past 64 bits, empty, very long
and unicode strings, lists where tables go, tables nested 60 deep), with unknown keys,
duplicated instances, missing sections, events at odd times and stop times off the
communication grid. ``tests/cosim/test_schema_fuzz.py`` states what each must do."""

from __future__ import annotations

import math
from typing import Any

from hypothesis import strategies as st


def _nested(depth: int) -> dict[str, Any]:
    """A table ``depth`` tables deep: ``{"a": {"a": ... {"a": 1}}}``."""
    table: dict[str, Any] = {"a": 1}
    for _ in range(depth):
        table = {"a": table}
    return table


def _nested_list(depth: int) -> list[Any]:
    """An array ``depth`` arrays deep: ``[[[...[1]...]]]``."""
    array: list[Any] = [1]
    for _ in range(depth):
        array = [array]
    return array


EDGE_NUMBERS = [math.nan, math.inf, -math.inf, -0.0, 0.0, 1e308, -1e308, 5e-324, 1e-300,
                -1.0, -1, 0, 2**63 - 1, -(2**63), 2**64, 2**200, True, False]  # fmt: skip
EDGE_TEXT = ["", " ", "x" * 5000, "名前", "\u202eevil", "\x00", "\x1b[31m", "é" * 300,
             "plant.yaw", "plant.", ".yaw", "nan", "1e999", "0.01", "10 s", "../x", "\ud7ff",
             "\U0001f600"]  # fmt: skip
EDGE_SHAPES = [[], [[]], {}, {"": {}}, [1, "a", True], _nested(60), _nested_list(60),
               {"x": [{"y": [1]}]}]  # fmt: skip
_EDGES = EDGE_NUMBERS + EDGE_TEXT + EDGE_SHAPES
EDGE = st.one_of(
    st.integers(0, len(_EDGES) - 1).map(_EDGES.__getitem__),  # (no repr of 5000 x's)
    st.floats(max_value=1.0),  # (no valid stop time of hours: the runs stay short)
    st.integers(-3, 3),
    st.text(max_size=20),
)


def mostly(good: st.SearchStrategy[Any], odd: st.SearchStrategy[Any] = EDGE) -> Any:
    """``good`` 19 times in 20, else ``odd``: a file of one odd part gets past the
    others to the check of that part, and one in three files is valid."""
    return st.integers(0, 19).flatmap(lambda n: odd if n == 7 else good)  # (not 0: shrunk to)


STEPS = [0.01, 0.02, 0.05]
# names a scenario's values refer to: good ones, near misses and odd ones
VARIABLES = ["plant.yaw", "plant.r", "plant.v", "plant.roll", "plant.mass_position",
             "controller.mass_position_cmd", "controller.yaw_setpoint", "plant.current_east",
             "controller.k0", "plant.u_0"]  # fmt: skip
ODD_VARIABLES = ["plant.nosuch", "plant", "nosuch.yaw", "plant.yaw.x", "Plant.Yaw", "",
                 "controller.yaw", "plant.der(yaw)", "plant.yaw "]  # fmt: skip
NAMES = mostly(st.sampled_from(VARIABLES), st.sampled_from(ODD_VARIABLES))


@st.composite
def times(draw: st.DrawFn, step: Any, stop: float) -> Any:
    """A time of an event or a fault: on the grid, between two points, at 0, at or past
    the stop time, or an odd value."""
    h = step if isinstance(step, float) and 0 < step < 1 else 0.01
    stop = stop if math.isfinite(stop) and h <= stop < 1 else h
    on = h * draw(st.integers(0, 6))
    return draw(
        mostly(
            st.sampled_from([on, on + h / 3, on + 1e-12, on - 1e-12, 0.0, stop, stop + h, 1e-300])
            | st.floats(0, 2 * stop)
        )
    )


@st.composite
def coupling(draw: st.DrawFn, step: Any) -> dict[str, Any]:
    """The ``[coupling]`` table: step, algorithm and, some of the time, every other key."""
    algorithm = draw(mostly(st.sampled_from(["jacobi", "gauss-seidel", "adaptive"])))
    table: dict[str, Any] = {"step": step, "algorithm": algorithm}
    if draw(st.booleans()):
        table["order"] = draw(
            mostly(
                st.sampled_from([["controller", "plant"], ["plant", "controller"]]),
                st.sampled_from([["plant"], ["plant", "plant", "controller"], [], ["x", "y"]])
                | EDGE,
            )
        )
    if draw(st.booleans()):
        table["extrapolation"] = draw(mostly(st.sampled_from(["none", "linear", "quadratic"])))
    if draw(st.integers(0, 3)) == 0:
        table["step_multiples"] = draw(
            mostly(st.fixed_dictionaries({"controller": mostly(st.integers(1, 5))}))
        )
    if algorithm == "adaptive" or draw(st.integers(0, 7)) == 0:
        for key, good in (
            ("tolerance", st.sampled_from([1e-3, 1e-2])),
            ("max_step", st.sampled_from([0.05, 0.64])),
            ("error_estimate", st.sampled_from(["doubling", "extrapolation"])),
        ):
            if draw(st.booleans()):
                table[key] = draw(mostly(good))
    return table


@st.composite
def instances(draw: st.DrawFn) -> dict[str, Any]:
    """The ``[instances]`` tables: a plant and an autopilot with start values, and now and
    then a duplicated instance, a guidance or an odd one."""
    plant_start = {
        "variant": draw(mostly(st.sampled_from(["lateral", "full", "horizontal", 1]))),
        "u_0": draw(mostly(st.floats(0.5, 2.0))),
        "v_0": draw(mostly(st.floats(-0.2, 0.2))),
    }
    if draw(st.integers(0, 3)) == 0:
        plant_start[draw(st.sampled_from(["m", "yaw_0", "max_substep", "vehicle", "nosuch"]))] = (
            draw(EDGE)
        )
    control_start = {
        "heading_mode": draw(mostly(st.sampled_from(["lqr", "backstepping", "sliding_mode"]))),
        "depth_mode": draw(mostly(st.just("off"))),
        "yaw_setpoint": draw(mostly(st.floats(-0.5, 0.5))),
    }
    table: dict[str, Any] = {
        "plant": {"fmu": draw(mostly(st.just("AuvPlant"))), "start": plant_start},
        "controller": {"fmu": draw(mostly(st.just("AuvAutopilot"))), "start": control_start},
    }
    if draw(st.integers(0, 5)) == 0:
        name = draw(st.sampled_from(["plant2", "guidance", "", "a.b", "名前", "x" * 300]))
        table[name] = draw(
            st.sampled_from(
                [
                    {"fmu": "AuvPlant", "start": dict(plant_start)},
                    {"fmu": "AuvGuidance"},
                    {"fmu": "nosuch.fmu"},
                    {},
                ]
            )
            | EDGE
        )
    if draw(st.integers(0, 7)) == 0:
        table["controller"][draw(st.sampled_from(["debug_logging", "log_categories"]))] = draw(
            mostly(st.sampled_from([True, ["logAll"], []]))
        )
    return table


@st.composite
def events(draw: st.DrawFn, step: Any, stop: float) -> list[dict[str, Any]]:
    """Zero to two ``[[events]]``: at a time, when a comparison turns true, or a series."""
    found: list[dict[str, Any]] = []
    for _ in range(draw(st.integers(0, 2))):
        event: dict[str, Any] = {}
        if draw(st.booleans()):
            event["name"] = draw(mostly(st.sampled_from(["turn", "event-1", "a_b"])))
        trigger = draw(st.sampled_from(["time", "when", "series", "both"]))
        if trigger in ("time", "both"):
            event["time"] = draw(times(step, stop))
        if trigger in ("when", "both"):
            op = draw(st.sampled_from(["<", "<=", ">", ">=", "==", ">>", ""]))
            number = draw(mostly(st.sampled_from(["0.01", "-0.01", "1e999", "nan", "x", ""])))
            event["when"] = f"{draw(NAMES)} {op} {number}"
            if draw(st.booleans()):
                event["repeat"] = draw(mostly(st.booleans()))
        if trigger == "series":
            event["series"] = draw(mostly(st.sampled_from(["nosuch.csv", "", "/dev/zero", "."])))
        else:
            event["set"] = draw(
                mostly(st.dictionaries(NAMES, mostly(st.floats(-0.3, 0.3)), min_size=1))
            )
        if draw(st.integers(0, 3)) == 0:
            event["ramp"] = draw(mostly(st.sampled_from([0.02, 0.001, 5.0])))
        found.append(event)
    return found


FAULT_KINDS = ["stuck", "bias", "gain", "noise", "delay", "dropout", "mass-jam",
               "thruster-off", "plane-stuck"]  # fmt: skip
FAULT_KEYS = {"value": st.floats(-2, 2), "std": st.floats(0, 0.1), "seed": st.integers(0, 9),
              "steps": st.integers(1, 5), "probability": st.floats(0, 1)}  # fmt: skip


@st.composite
def faults(draw: st.DrawFn, step: Any, stop: float) -> list[dict[str, Any]]:
    """Zero or one ``[[faults]]``, its keys those of its kind or any other."""
    if draw(st.integers(0, 2)) != 0:
        return []
    fault: dict[str, Any] = {"kind": draw(mostly(st.sampled_from(FAULT_KINDS)))}
    if draw(st.booleans()):
        fault["target"] = draw(
            mostly(st.sampled_from(["plant.mass_position_cmd", "controller.yaw", "plant.thrust"]))
        )
    for key in ("start", "stop"):
        if draw(st.booleans()):
            fault[key] = draw(times(step, stop))
    for key in draw(st.sets(st.sampled_from(sorted(FAULT_KEYS)), max_size=2)):
        fault[key] = draw(mostly(FAULT_KEYS[key]))
    return [fault]


@st.composite
def scenarios(draw: st.DrawFn) -> dict[str, Any]:
    """A scenario file's data, short (a few communication steps) where it is valid."""
    step = draw(mostly(st.sampled_from(STEPS)))
    h = step if isinstance(step, float) and 0 < step < 1 else 0.01
    off_grid = st.sampled_from([h * 2.5, 3 * h + 1e-9, 3 * h - 1e-9, h / 7, 3 * h + 1e-15])
    stop = draw(mostly(st.integers(1, 5).map(lambda n: n * h), off_grid | EDGE))
    data: dict[str, Any] = {
        "stop_time": stop,
        "coupling": draw(coupling(step)),
        "instances": draw(instances()),
        "connections": draw(
            mostly(
                st.just({"remove": ["plant.fin_angle"]}),
                st.sampled_from(
                    [
                        {"remove": ["plant.fin_angle", "plant.fin_angle"]},
                        {"same_names": False, "add": [{"from": "plant.yaw", "to": "plant.yaw"}]},
                        {"add": [{"from": "plant.yaw"}]},
                        {"remove": ["nosuch.x"]},
                    ]
                )
                | EDGE,
            )
        ),
    }
    for key, good in (
        ("id", st.sampled_from(["fuzz", "a.b", "a-b_c"])),
        ("summary", st.text(max_size=30)),
        ("manoeuvre", st.sampled_from(["zigzag", "turning-circle", "none"])),
    ):
        if draw(st.integers(0, 3)) == 0:
            data[key] = draw(mostly(good))
    if draw(st.integers(0, 3)) == 0:
        data["output"] = {
            "record": draw(mostly(st.lists(NAMES, max_size=3))),
            "rrd": draw(mostly(st.just(False))),
        }
    data["events"] = draw(events(step, stop if isinstance(stop, float) else 0.05))
    data["faults"] = draw(faults(step, stop if isinstance(stop, float) else 0.05))
    for key in ("events", "faults"):
        if not data[key]:
            del data[key]
    return _reshaped(draw, data)


def _reshaped(draw: st.DrawFn, data: dict[str, Any]) -> dict[str, Any]:
    """``data`` with, now and then, a section dropped, an unknown key added to a table or a
    table given as a list."""
    shape = draw(st.integers(0, 19))
    sections = sorted(data)
    if shape == 0:
        del data[draw(st.sampled_from(sections))]
    elif shape == 1:
        table = draw(
            st.sampled_from([data, data.get("coupling"), data.get("instances", {}).get("plant")])
        )
        if isinstance(table, dict):
            table[draw(st.sampled_from(["nosuch", "Step", "", "名前", "a.b"]))] = draw(EDGE)
    elif shape == 2:
        section = draw(st.sampled_from(sections))
        data[section] = [data[section]]
    return data


def _grid_values() -> st.SearchStrategy[Any]:
    return mostly(st.lists(mostly(st.floats(-0.1, 0.1)), min_size=1, max_size=3))


@st.composite
def studies(draw: st.DrawFn) -> dict[str, Any]:
    """A study file's data: a scenario, a stop time, a grid and random factors, each key
    drawn valid most of the time."""
    data: dict[str, Any] = {"scenario": draw(mostly(st.just("bs-3")))}
    if draw(st.booleans()):
        data["stop_time"] = draw(mostly(st.sampled_from([0.05, 0.025, 0.033])))
    factor = mostly(st.sampled_from(["plant.v_0", "controller.k0", "plant.yaw_0"]), NAMES)
    if draw(st.booleans()):
        data["grid"] = draw(mostly(st.dictionaries(factor, _grid_values(), min_size=1)))
    if draw(st.booleans()) or "grid" not in data:
        law = mostly(
            st.sampled_from([{"uniform": [-0.1, 0.1]}, {"normal": [0.0, 0.01]}]),
            st.dictionaries(
                st.sampled_from(["uniform", "normal", "beta", "", "Uniform"]),
                st.lists(EDGE, max_size=3) | EDGE,
                max_size=2,
            )
            | EDGE,
        )
        table = draw(st.dictionaries(factor, law, min_size=1, max_size=2))
        table["n"] = draw(mostly(st.integers(1, 3)))
        for key, good in (("seed", st.integers(0, 2**64)), ("sampling", st.just("random"))):
            if draw(st.booleans()):
                table[key] = draw(mostly(good))
        data["random"] = draw(mostly(st.just(table)))
    if draw(st.integers(0, 4)) == 0:
        data[draw(st.sampled_from(["overlay", "metrics", "nosuch", "check_step"]))] = draw(
            mostly(st.sampled_from([["all"], {"collect": ["final.plant.yaw"]}, True]))
        )
    return data
