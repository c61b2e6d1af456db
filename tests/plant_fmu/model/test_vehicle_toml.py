"""Vehicle files on a Python without tomllib: the subset reader reads what tomllib reads,
and refuses the rest naming the line."""

from __future__ import annotations

import json
import math
import tomllib
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plant_fmu.model import parameters, vehicle_toml
from plant_fmu.model.parameters import VehicleParameterError, builtin_vehicles, load_vehicle
from plant_fmu.model.vehicle_toml import VehicleTomlError, loads_subset

KEYS = st.from_regex(r"[A-Za-z0-9_-]{1,12}", fullmatch=True)
TEXT = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=20)
VALUES = st.one_of(
    st.floats(allow_nan=False),
    st.integers(-(2**63), 2**63 - 1),
    st.booleans(),
    TEXT,
)


def _render(value: object, literal: bool) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return {math.inf: "inf", -math.inf: "-inf"}.get(value, repr(value))
    if isinstance(value, int):
        return str(value)
    text = str(value)
    if literal and "'" not in text and not any(c < " " or c == "\x7f" for c in text):
        return f"'{text}'"
    return json.dumps(text, ensure_ascii=False).replace("\x7f", "\\u007f")  # TOML's escapes


@settings(max_examples=50)  # the fast tier's minute
@given(
    top=st.dictionaries(KEYS, VALUES, max_size=3),
    tables=st.dictionaries(KEYS, st.dictionaries(KEYS, VALUES, max_size=4), max_size=3),
    literal=st.booleans(),
    comment=st.sampled_from(["", "  # a comment", " #", "\t# kg m^2 [x] = 'y'"]),
)
def test_the_subset_reader_reads_what_tomllib_reads(top, tables, literal, comment):
    tables = {name: keys for name, keys in tables.items() if name not in top}
    lines = ["# a vehicle", ""]
    lines += [f"{key} = {_render(value, literal)}{comment}" for key, value in top.items()]
    for name, keys in tables.items():
        lines += ["", f"[{name}]{comment}"]
        lines += [f"{key}={_render(value, literal)}{comment}" for key, value in keys.items()]
    text = "\n".join(lines) + "\n"
    assert loads_subset(text) == tomllib.loads(text)


@pytest.mark.parametrize("name", builtin_vehicles())
def test_the_built_in_sets_load_without_tomllib(name, monkeypatch):
    """What a host on Python 3.9 or 3.10 gets: the same parameter set."""
    text = (parameters.vehicle_folder() / f"{name}.toml").read_text()
    assert loads_subset(text) == tomllib.loads(text)
    with_tomllib = load_vehicle(name)
    monkeypatch.setattr(vehicle_toml, "loads", loads_subset)
    parameters._loaded.clear()  # not the set parsed by tomllib
    try:
        assert load_vehicle(name) == with_tomllib
    finally:
        parameters._loaded.clear()


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("added = [1.0, 2.0]", r"line 3 \('added = \[1\.0, 2\.0\]'\) is not one this Python"),
        ("added = [1.0,2.0]", r"line 3 .*the value '\[1\.0,2\.0\]' is not one this Python reads"),
        ("rigid.m = 30.5", r"line 3 \('rigid\.m = 30\.5'\) is not one this Python reads"),
        ("m = 0x1e", r"line 3 .*the value '0x1e' is not one"),
        ("m = 01", r"line 3 .*the value '01' is not one"),
        ('name = """a"""', r"line 3 .*is not one this Python reads"),
        ("[[sets]]", r"line 3 \('\[\[sets\]\]'\) is not one this Python reads"),
        ('name = "a\\qb"', r"line 3 .*the value '\"a\\\\qb\"' is not one"),
        ("g = 9.8", r"line 3: key 'g' is defined twice"),
        ("[rigid_body]", r"line 3: table \[rigid_body\] is defined twice"),
    ],
)
def test_a_line_outside_the_subset_is_refused_naming_it(line, message):
    text = f"[rigid_body]\ng = 9.8\n{line}\n"
    with pytest.raises(VehicleTomlError, match=message):
        loads_subset(text)


def test_a_user_file_outside_the_subset_gets_one_line_naming_file_and_line(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    path = tmp_path / "arrays.toml"
    path.write_text('base = "remus100"\n[viscous]\nX_uu = [-3.87]\n')
    monkeypatch.setattr(vehicle_toml, "loads", loads_subset)
    with pytest.raises(
        VehicleParameterError,
        match=rf"^vehicle file '{path}': line 3 \('X_uu = \[-3\.87\]'\): the value "
        r"'\[-3\.87\]' is not one this Python reads: expected \[table\] headers .*"
        r"\(Python >= 3\.11 reads any TOML\)$",
    ):
        load_vehicle(path)


def test_a_vehicle_file_nested_too_deeply_to_read_is_refused_naming_it(tmp_path: Path) -> None:
    """Arrays thousands deep in a vehicle file: tomllib ran out of Python's recursion and
    a run said only "RecursionError: maximum recursion depth exceeded"."""
    path = tmp_path / "deep.toml"
    path.write_text("x = " + "[" * 5000 + "]" * 5000 + "\n", encoding="utf-8")
    with pytest.raises(VehicleParameterError, match=r"deep\.toml.*not valid TOML: arrays or "):
        load_vehicle(str(path))
