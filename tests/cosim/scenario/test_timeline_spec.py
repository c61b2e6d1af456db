"""[[events]] and [[faults]] in a scenario file: each bad row refused before any FMU is
loaded, with one line naming the key, the bad value and what was expected; a resolved
scenario with events and faults written back by to_toml loads to an equal one."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from aliased_fmu import with_alias
from scenario_factory import loop_toml

from cosim.engine import slave
from cosim.scenario.spec import ScenarioError, scenario_from_toml
from cosim.scenario.timeline_spec import first_point

# the loop (tests/fmus): controller.x <- plant.x, plant.u <- controller.u; controller.k and
# plant.x0 are tunable parameters
SET_K = 'set = { "controller.k" = 3.0 }'


@pytest.fixture(autouse=True)
def no_fmu_loading(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if anything tries to load an FMU's binary."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("an FMU was loaded while validating a scenario")

    monkeypatch.setattr(slave, "FMU2Slave", refuse)


def resolve(fmu_dir: Path, extra: str, remove_u: bool = False):
    text = loop_toml() + ('[connections]\nremove = ["plant.u"]\n' if remove_u else "") + extra
    return scenario_from_toml(text, "loop.toml", base_dir=fmu_dir, fmu_dir=fmu_dir)


def write_series(folder: Path, name: str, text: str) -> str:
    (folder / name).write_text(text, encoding="utf-8")
    return name


BAD_ROWS = [
    # (the [[events]]/[[faults]] text, what the one-line message must contain)
    (f"[[events]]\ntime = 0.5\n{SET_K.replace('controller.k', 'nobody.k')}",
     ["events[0].set.nobody.k", "'nobody.k' is not <instance>.<variable>"]),
    (f"[[events]]\ntime = 0.5\n{SET_K.replace('controller.k', 'controller.kk')}",
     ["events[0].set.controller.kk", "has no variable 'kk'"]),
    ('[[events]]\ntime = 0.5\nset = { "controller.x" = 1.0 }',
     ["events[0].set.controller.x", "connected from plant.x"]),
    ('[[events]]\ntime = 0.5\nset = { "controller.u" = 1.0 }',
     ["events[0].set.controller.u", "discrete output", "expected an unconnected input"]),
    ('[[events]]\ntime = 0.5\nset = { "controller.k" = "3" }',
     ["events[0].set.controller.k", "'3' is not a number (k is Real)"]),
    (f'[[events]]\ntime = 0.5\nwhen = "plant.x > 1"\n{SET_K}',
     ["events[0]", "['time', 'when']", "expected exactly one"]),
    (f"[[events]]\n{SET_K}", ["events[0]", "none of time / when / series"]),
    (f'[[events]]\nwhen = "plant.x >> 1"\n{SET_K}',
     ["events[0].when", "'plant.x >> 1'", "one comparison"]),
    (f'[[events]]\nwhen = "plant.x > 1 + 2"\n{SET_K}', ["events[0].when", "one comparison"]),
    # a mistyped variable in a well-formed comparison: named, with the nearest one (it
    # was called "not one comparison")
    (f'[[events]]\nwhen = "plant.fail_ta > 1"\n{SET_K}',
     ["events[0].when", "plant (CosimTestIntegrator.fmu) has no variable 'fail_ta' (did you "
      "mean 'fail_at'?)"]),
    # 1e999999 reads as inf: a crossing that could never come, refused like `< inf`
    (f'[[events]]\nwhen = "plant.x > 1e999999"\n{SET_K}',
     ["events[0].when", "1e999999 is not a finite number"]),
    # a device is never read (it hung, RSS growing ~300 MB/s)
    ('[[events]]\nseries = "/dev/zero"', ["events[0].series", "/dev/zero is not a regular file"]),
    (f'[[events]]\nwhen = "plant.x0 > 1"\n{SET_K}',
     ["events[0].when", "'plant.x0'", "neither a recorded Real variable"]),
    (f"[[events]]\ntime = 0.5\nrepeat = true\n{SET_K}",
     ["events[0].repeat", "only for a `when` event"]),
    (f"[[events]]\ntime = -1.0\n{SET_K}", ["events[0].time", "-1.0", "greater than or equal"]),
    (f"[[events]]\ntime = 0.5\n{SET_K}\nramp = 0.0", ["events[0].ramp", "0.0", "greater"]),
    ("[[events]]\ntime = 0.5", ["events[0].set", "missing"]),
    ('[[events]]\nseries = "missing.csv"', ["events[0].series", "'missing.csv'", "cannot read"]),
    ('[[events]]\nseries = "SERIES"\n' + SET_K, ["events[0].set", "not with series"]),
    (f'[[events]]\nname = "a"\ntime = 0.1\n{SET_K}\n[[events]]\nname = "a"\ntime = 0.2\n{SET_K}',
     ["events[1].name", "'a' is used twice"]),
    # a default name by position clashing with a written one: the written one is named
    (f'[[events]]\nname = "event-2"\ntime = 0.1\n{SET_K}\n[[events]]\ntime = 0.2\n{SET_K}',
     ["key 'events[0].name': 'event-2' is used twice: names are unique (by position: "
      "events[1] has no name)"]),
    (f'[[events]]\nname = "a b"\ntime = 0.1\n{SET_K}', ["events[0].name", "'a b'", "- and _"]),
    (f"[[events]]\ntime = 0.1\n{SET_K}\nspeed = 1", ["unknown key 'events[0].speed'"]),
    ('[[faults]]\nkind = "gain"\ntarget = "plant.x"\nvalue = 2.0',
     ["faults[0].target", "'plant.x' is not the target of a connection",
      "['controller.x', 'plant.u']"]),
    ('[[faults]]\nkind = "stuck"\ntarget = "controller.xx"',
     ["faults[0].target", "'controller.xx' is not the target of a connection (did you mean "
      "'controller.x'?)"]),
    # NaN is no probability (it was refused as "less than or equal to 1")
    ('[[faults]]\nkind = "dropout"\ntarget = "controller.x"\nprobability = nan',
     ["faults[0].probability", "nan", "finite number"]),
    ('[[faults]]\nkind = "gain"\ntarget = "controller.x"',
     ["faults[0].value", "missing: kind 'gain' needs it"]),
    ('[[faults]]\nkind = "stuck"', ["faults[0].target", "missing"]),
    ('[[faults]]\nkind = "bias"\ntarget = "controller.x"\nvalue = 1.0\nstart = 0.5\nstop = 0.5',
     ["faults[0].stop", "0.5 s is not after start = 0.5 s"]),
    ('[[faults]]\nkind = "noise"\ntarget = "controller.x"\nstd = -0.1',
     ["faults[0].std", "-0.1", "greater than or equal to 0"]),
    ('[[faults]]\nkind = "dropout"\ntarget = "controller.x"\nprobability = 1.5',
     ["faults[0].probability", "1.5", "less than or equal to 1"]),
    ('[[faults]]\nkind = "delay"\ntarget = "controller.x"\nsteps = 0',
     ["faults[0].steps", "0", "greater than or equal to 1"]),
    # 2^63-1 steps ended in an OverflowError traceback
    ('[[faults]]\nkind = "delay"\ntarget = "controller.x"\nsteps = 9223372036854775807',
     ["faults[0].steps", "9223372036854775807", "less than or equal to 100000000"]),
    ('[[faults]]\nkind = "gain"\ntarget = "controller.x"\nvalue = 2.0\nstd = 0.1',
     ["faults[0].std", "kind 'gain' takes ['value']"]),
    ('[[faults]]\nkind = "wobble"\ntarget = "controller.x"', ["faults[0].kind", "'wobble'"]),
    ('[[faults]]\nkind = "thruster-off"',
     ["faults[0].kind", "tunnel_force", "0 instances", "expected exactly one"]),
    # a target where no plant has the input: "expected none" read as "give no target"
    ('[[faults]]\nkind = "thruster-off"\ntarget = "plant.tunnel_force"',
     ["faults[0].kind", "tunnel_force", "0 instances", "expected exactly one"]),
    ('[[faults]]\nname = "f"\nkind = "stuck"\ntarget = "controller.x"\n'
     '[[faults]]\nname = "f"\nkind = "stuck"\ntarget = "plant.u"',
     ["faults[1].name", "'f' is used twice"]),
]  # fmt: skip


@pytest.mark.parametrize(("extra", "expected"), BAD_ROWS)
def test_a_bad_event_or_fault_is_refused_in_one_line_naming_the_key(
    test_fmu_dir: Path, extra: str, expected: list[str]
) -> None:
    """Every refusal names the key in one notation, a list index in brackets
    (``faults[0].std``), whether pydantic or the resolution found the problem."""
    with pytest.raises(ScenarioError) as info:
        resolve(test_fmu_dir, extra)
    message = str(info.value)
    assert "\n" not in message and message.startswith("scenario file loop.toml")
    for part in expected:
        assert part in message, message


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("x,plant.u\n0,1\n", "header ['x', 'plant.u'] is not 'time,<instance.variable>,...'"),
        ("time\n0\n", "header ['time'] is not"),
        ("time,controller.x\n0,1\n", "connected from plant.x"),
        ("time,plant.u\n0,1\n0.2,2\n0.2,3\n", "row 3: time 0.2 s is not after 0.2 s"),
        ("time,plant.u\n0,1\n0.2,oops\n", "row 2: ['0.2', 'oops'] is not 2 finite numbers"),
        ("time,plant.u\n", "no rows below the header"),
        ("time,plant.u,plant.u\n0,1,2\n", "column 'plant.u' appears twice in the header"),
    ],
)
def test_a_bad_series_file_is_refused_naming_it(
    test_fmu_dir: Path, tmp_path: Path, text: str, expected: str
) -> None:
    for fmu in test_fmu_dir.glob("*.fmu"):
        (tmp_path / fmu.name).symlink_to(fmu)
    write_series(tmp_path, "profile.csv", text)
    with pytest.raises(ScenarioError, match=r"events\[0\]\.series") as info:
        resolve(tmp_path, '[[events]]\nseries = "profile.csv"', remove_u=True)
    assert expected in str(info.value) and "'profile.csv'" in str(info.value)


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        # a spreadsheet's export in a German or Brazilian locale: ; and decimal commas
        (b"time;plant.u\n0;1\n0,5;2\n",
         "header ['time;plant.u'] is not 'time,<instance.variable>,...': its columns are "
         "separated by ';', expected ',' (and a decimal point: 0.5, not 0,5)"),
        (b"time\tplant.u\n0\t1\n", "its columns are separated by a tab, expected ','"),
        (b"time,plant.u # Gr\xf6\xdfe\n0,1\n",
         "is not UTF-8 text: byte 0xf6 at line 1, column 18; save it as UTF-8"),
        ("time,plant.u\n0,1\n".encode("utf-16"),
         "is not UTF-8 text but UTF-16 (it starts with a UTF-16 byte-order mark)"),
    ],
)  # fmt: skip
def test_a_series_file_from_a_spreadsheet_is_refused_saying_what_to_change(
    test_fmu_dir: Path, tmp_path: Path, data: bytes, expected: str
) -> None:
    """A series file separated by ; (a spreadsheet's CSV where the decimal mark is a
    comma) or by tabs was refused as "header ['time;plant.u'] is not
    'time,<instance.variable>,...'", and one in Latin-1 or UTF-16 as "'utf-8' codec can't
    decode byte 0xf6 in position 17": neither said what to change."""
    for fmu in test_fmu_dir.glob("*.fmu"):
        (tmp_path / fmu.name).symlink_to(fmu)
    (tmp_path / "profile.csv").write_bytes(data)
    with pytest.raises(ScenarioError, match=r"events\[0\]\.series") as info:
        resolve(tmp_path, '[[events]]\nseries = "profile.csv"', remove_u=True)
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_a_series_file_with_blank_lines_or_a_byte_order_mark_reads_as_its_rows(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """Lines of spaces at the end (an editor's), CRLF line ends and a byte-order mark
    (a Windows editor's) are no rows: a line of spaces was refused as "row 3: ['  '] is
    not 2 finite numbers", while an empty line passed."""
    for fmu in test_fmu_dir.glob("*.fmu"):
        (tmp_path / fmu.name).symlink_to(fmu)
    data = b"\xef\xbb\xbftime,plant.u\r\n0,1\r\n0.5,2\r\n\r\n  \r\n\t\n"
    (tmp_path / "profile.csv").write_bytes(data)
    scenario = resolve(tmp_path, '[[events]]\nseries = "profile.csv"', remove_u=True)
    series = scenario.events[0].series
    assert series is not None and series.times == (0.0, 0.5)
    assert series.columns == {"plant.u": (1.0, 2.0)}


def test_events_and_faults_resolve_with_default_names_and_write_back(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    for fmu in test_fmu_dir.glob("*.fmu"):
        (tmp_path / fmu.name).symlink_to(fmu)
    write_series(tmp_path, "profile.csv", "time,plant.u\n0,1\n0.5,2\n")
    extra = f"""
[[events]]
time = 0.25
{SET_K}
ramp = 0.2
[[events]]
name = "crossing"
when = "plant.x >= 1.3"
repeat = true
set = {{ "plant.x0" = 2 }}
[[events]]
series = "profile.csv"
interpolation = "linear"
[[faults]]
kind = "noise"
target = "controller.x"
std = 0.01
start = 0.2
[[faults]]
name = "late"
kind = "delay"
target = "controller.x"
steps = 2
stop = 0.8
"""
    scenario = resolve(tmp_path, extra, remove_u=True)
    assert [e.name for e in scenario.events] == ["event-1", "crossing", "event-3"]
    assert [f.name for f in scenario.faults] == ["fault-1", "late"]
    assert scenario.events[1].when is not None and scenario.events[1].when.op == ">="
    assert scenario.events[1].set == {"plant.x0": 2.0}  # an integer for a Real: a float
    assert scenario.events[2].series is not None
    assert scenario.events[2].series.columns == {"plant.u": (1.0, 2.0)}
    assert scenario.faults[0].seed == 0  # the default seed, written out
    assert scenario.columns[-2:] == ("fault.fault-1", "fault.late")
    again = scenario_from_toml(scenario.to_toml(), "again", base_dir=Path("/"), fmu_dir=tmp_path)
    assert again == scenario
    assert "fault.fault-1" not in scenario.to_toml()  # the columns are not record entries


def test_an_event_into_one_variable_under_two_names_is_refused(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """Aliases (names of one value reference) are one variable: an event setting two of
    them set it twice, the last silently winning, and an event setting an alias of a
    connected input was overwritten by the connection at the next exchange. Both are
    refused naming the aliases."""
    shutil.copy(test_fmu_dir / "CosimTestSource.fmu", tmp_path)
    with_alias(test_fmu_dir / "CosimTestFeedthrough.fmu", tmp_path / "Ft.fmu", "u", "u alias")
    with_alias(test_fmu_dir / "CosimTestForeign.fmu", tmp_path / "F.fmu", "k", "k alias")
    head = (
        'stop_time = 1.0\n[coupling]\nstep = 0.1\n[instances.src]\nfmu = "CosimTestSource.fmu"\n'
        '[instances.ft]\nfmu = "Ft.fmu"\n[instances.f]\nfmu = "F.fmu"\n[connections]\n'
        'same_names = false\nadd = [{ from = "src.x", to = "ft.u" }]\n[[events]]\ntime = 0.5\n'
    )
    connected = head + 'set = { "ft.u alias" = 1.0 }\n'
    with pytest.raises(
        ScenarioError,
        match=r"key 'events\[0\]\.set\.ft\.u alias': ft\.u alias is connected from src\.x "
        r"\(as ft\.u, one variable\): an event sets unconnected inputs only",
    ):
        scenario_from_toml(connected, base_dir=tmp_path)
    twice = head + 'set = { "f.k" = 2.0, "f.k alias" = 3.0 }\n'
    with pytest.raises(
        ScenarioError,
        match=r"key 'events\[0\]\.set\.f\.k alias': f\.k alias and f\.k are one variable "
        r"\(the same value reference\): set one of them",
    ):
        scenario_from_toml(twice, base_dir=tmp_path)


def test_a_series_starting_after_the_stop_time_is_named_as_never_applied() -> None:
    """A series whose first row is after the stop time never writes a value, as an event
    timed after it never fires: one warning line says so, naming its first time and the
    stop time; a series that starts before the stop time, with later rows, says nothing."""
    from cosim.scenario.timeline_spec import Event, Series, unreached

    def series(*times: float) -> Event:
        columns = {"controller.k": tuple(1.0 for _ in times)}
        return Event("profile", series=Series(Path("/p/profile.csv"), "hold", times, columns))

    lines = unreached([series(30.0, 40.0)], [], stop_time=20.0, step=0.01)
    assert lines == [
        "events.profile: series profile.csv starts at 30 s, after the stop time (20 s): the run "
        "ends before the series, which is never applied"
    ]
    assert unreached([series(10.0, 40.0)], [], stop_time=20.0, step=0.01) == []


@pytest.mark.parametrize("h", [0.01, 0.02, 0.005])
def test_a_time_on_a_late_point_is_that_point_however_many_steps_in(h: float) -> None:
    # an event typed at a communication point of a long run, past 2**24 steps (47 h at
    # 10 ms), where time / h carries a rounding of more than 1e-9 of a step: the point
    # itself, never the one after it
    points = range(2**24, 2**25, 4099)
    late = [n for n in points if first_point(float(f"{n * h:.3f}"), h) != n]
    assert late == []


def test_an_actuator_fault_target_of_the_one_plant_is_counted_in_the_singular(
    fmu_dir: Path,
) -> None:
    """A target that is not the one plant's input is refused naming the one plant as one
    instance, not as "1 instances ... have"."""
    from repo_paths import ROOT

    text = (ROOT / "cosim" / "scenarios" / "bs-3.toml").read_text(encoding="utf-8")
    fault = '[[faults]]\nname = "jam"\nkind = "mass-jam"\ntarget = "mass_position_cmd"\n'
    one = (
        r"key 'faults\[0\]\.target': 'mass_position_cmd': 'mass-jam' acts on the plant "
        r"input 'mass_position_cmd', which 1 instance \(\['plant'\]\) has: expected "
        r"one of \['plant\.mass_position_cmd'\]$"
    )
    with pytest.raises(ScenarioError, match=one):
        scenario_from_toml(text + fault, fmu_dir=fmu_dir)


def test_an_actuator_fault_of_two_vehicles_names_the_plant_it_acts_on(fmu_dir: Path) -> None:
    """Two vehicles: a mass-jam was refused for the two plants with the input it acts
    on, and a target naming one of them was refused too (an actuator fault took none), so
    no fault could jam one vehicle's mass. The target names the plant's input now, and the
    resolved scenario keeps it."""
    from two_vehicles import two_vehicles_toml

    text = two_vehicles_toml() + '[[faults]]\nname = "jam"\nkind = "mass-jam"\nstart = 3.0\n'
    several = (
        r"key 'faults\[0\]\.target': missing: 'mass-jam' acts on the plant input "
        r"'mass_position_cmd', which 2 instances \(\['plant_a', 'plant_b'\]\) have: name one, "
        r"target = \"plant_a\.mass_position_cmd\"$"
    )
    with pytest.raises(ScenarioError, match=several):
        scenario_from_toml(text, fmu_dir=fmu_dir)
    named = text + 'target = "plant_b.mass_position_cmd"\n'
    (fault,) = scenario_from_toml(named, fmu_dir=fmu_dir).faults
    assert (fault.target, fault.hold_source) == (
        "plant_b.mass_position_cmd",
        "plant_b.mass_position",
    )
    s = scenario_from_toml(named, fmu_dir=fmu_dir)
    assert scenario_from_toml(s.to_toml(), fmu_dir=fmu_dir) == s
    wrong = text + 'target = "ctrl_b.mass_position_cmd"\n'
    with pytest.raises(ScenarioError, match=r"'ctrl_b\.mass_position_cmd': 'mass-jam' acts on"):
        scenario_from_toml(wrong, fmu_dir=fmu_dir)
