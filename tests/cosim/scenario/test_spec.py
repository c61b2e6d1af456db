"""Scenario files: the built-ins, the resolved model, and bad files failing before any FMU
is loaded with the file and the key named."""

from __future__ import annotations

import dataclasses
import os
import re
import shutil
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from aliased_fmu import with_alias
from repo_paths import ROOT

from cosim.engine import master, slave
from cosim.scenario.spec import (
    SCENARIO_FOLDER,
    ScenarioError,
    builtin_scenarios,
    load_scenario,
    scenario_from_toml,
    scenario_path,
)

MODEL_MD_IDS = ["bs-1", "bs-2", "bs-3", "cur-1", "cur-2", "lqr-1", "lqr-2", "lqr-3",
                "slow-1", "slow-2", "vert-1", "vert-2"]  # fmt: skip
MANOEUVRE_IDS = [
    "depth-steps",
    "mass-jam",
    "survey",
    "thruster-failure",
    "turning-circle",
    "zigzag-20",
]  # standard manoeuvres, faults and a mission
BS3 = (SCENARIO_FOLDER / "bs-3.toml").read_text()


@pytest.fixture
def no_fmu_loading(monkeypatch: pytest.MonkeyPatch) -> None:
    """Fail the test if anything tries to load an FMU's binary."""

    def refuse(*args: object, **kwargs: object) -> None:
        raise AssertionError("an FMU was loaded while validating a scenario")

    monkeypatch.setattr(slave, "FMU2Slave", refuse)
    monkeypatch.setattr("fmpy.fmi2.FMU2Slave.__init__", refuse)


def test_builtin_scenarios_are_model_md_section_5() -> None:
    scenarios = builtin_scenarios()
    assert sorted(scenarios) == sorted(MODEL_MD_IDS + MANOEUVRE_IDS)
    assert all(summary and "\n" not in summary for summary in scenarios.values())


def _first_column(page: str, heading: str) -> set[str]:
    """The first cells (backticks dropped) of the table rows under ``heading`` in ``page``,
    up to the next heading of any level."""
    text = (ROOT / page).read_text(encoding="utf-8")
    section = re.split(r"\n#+ ", text.split(f"\n{heading}\n", 1)[1], maxsplit=1)[0]
    cells = re.findall(r"^\| ([^|]+?) \|", section, re.MULTILINE)
    return {cell.strip("`") for cell in cells if cell not in ("id", "---")}


def test_every_builtin_scenario_has_its_row_in_the_docs() -> None:
    """A scenario file added to cosim/scenarios/ (``auv-cosim scenarios`` lists it at once)
    has its row in the README's tables, and its row in model.md's (a case of the
    dissertation) or its section in manoeuvres.md; no row names a scenario that is not
    built in."""
    readme = set()
    for cell in _first_column("README.md", "### Built-in scenarios"):
        readme |= {part.strip(" `") for part in cell.split(" / ")}  # `bs-1` / `bs-2`
    manoeuvres = set()  # the sections "## `mass-jam` and `thruster-failure`", ...
    for line in (ROOT / "docs" / "manoeuvres.md").read_text(encoding="utf-8").splitlines():
        if line.startswith("## `"):
            manoeuvres |= set(re.findall(r"`([\w-]+)`", line))
    assert readme == set(builtin_scenarios())
    assert _first_column("docs/model.md", "## Scenarios") == set(MODEL_MD_IDS)
    assert manoeuvres == set(MANOEUVRE_IDS)


def test_builtin_files_resolve_as_model_md_says(fmu_dir: Path, no_fmu_loading: None) -> None:
    for scenario_id in MODEL_MD_IDS:
        s = load_scenario(scenario_id, fmu_dir=fmu_dir)
        plant, controller = s.instances["plant"].start, s.instances["controller"].start
        assert s.id == scenario_id and s.coupling.step == 0.01
        assert plant["variant"] == (0 if scenario_id.startswith("vert") else 1)
        assert plant["u_0"] == (1.0 if scenario_id.startswith("slow") else 1.5)
        fin = [c for c in s.connections if c.target == "plant.fin_angle"]
        assert fin == [] or scenario_id.startswith("vert")  # only vert-* uses the planes
        assert controller.get("depth_mode", 0) == (1 if scenario_id.startswith("vert") else 0)
        # the current reaches both the plant and the controller, or neither
        assert plant.get("current_east", 0.0) == controller.get("current_east", 0.0)
    thrust = load_scenario("bs-3", fmu_dir=fmu_dir).connections
    assert ("controller.thrust", "plant.thrust") in [(c.source, c.target) for c in thrust]


def test_a_third_instance_connects_by_name(fmu_dir: Path, no_fmu_loading: None) -> None:
    """survey: the guidance reads the plant's position and feeds the autopilot's set-points;
    its measured current stays an unconnected input, held at its start value."""
    s = load_scenario("survey", fmu_dir=fmu_dir)
    assert list(s.instances) == ["plant", "controller", "guidance"]
    assert s.instances["guidance"].fmu_path == fmu_dir / "AuvGuidance.fmu"
    pairs = {(c.source, c.target) for c in s.connections}
    assert {("plant.north", "guidance.north"), ("plant.east", "guidance.east"),
            ("guidance.yaw_setpoint", "controller.yaw_setpoint"),
            ("guidance.depth_setpoint", "controller.depth_setpoint")} <= pairs  # fmt: skip
    guided = {c.target for c in s.connections if c.target_instance == "guidance"}
    assert guided == {"guidance.north", "guidance.east", "guidance.yaw"}
    assert s.unconnected_inputs("guidance") == ["current_north", "current_east"]
    assert s.coupling.order == ("guidance", "controller", "plant")
    assert {"guidance.cross_track_error", "guidance.legs_completed"} <= set(s.record)
    assert scenario_from_toml(s.to_toml(), "resolved", fmu_dir=fmu_dir) == s


def test_default_connections_and_record(fmu_dir: Path) -> None:
    s = load_scenario("vert-1", fmu_dir=fmu_dir)
    pairs = {(c.source, c.target) for c in s.connections}
    for name in ("mass_position_cmd", "tunnel_force", "fin_angle", "thrust"):
        assert (f"controller.{name}", f"plant.{name}") in pairs
    for name in ("yaw", "r", "p", "roll", "v_rel", "u_rel", "down", "pitch", "q", "w_rel"):
        assert (f"plant.{name}", f"controller.{name}") in pairs
    assert all(c.source_instance != c.target_instance for c in s.connections)
    # every output, plus the inputs nothing drives: set-points and the current
    expected = ["plant.yaw", "plant.kinetic_energy", "controller.tunnel_force",
                "controller.yaw_setpoint", "controller.depth_setpoint",
                "controller.current_east", "plant.current_east", "plant.roll_torque"]  # fmt: skip
    assert set(expected) <= set(s.record)
    assert "controller.yaw" not in s.record  # a connected input repeats plant.yaw


def test_to_toml_loads_back_to_an_equal_scenario(fmu_dir: Path, tmp_path: Path) -> None:
    s = load_scenario("cur-2", fmu_dir=fmu_dir)
    again = scenario_from_toml(s.to_toml(), "resolved", fmu_dir=fmu_dir)
    assert again == s
    resolved = tomllib.loads(s.to_toml())
    assert resolved["connections"]["same_names"] is False
    assert len(resolved["connections"]["add"]) == len(s.connections)
    assert "manoeuvre" not in resolved
    turn = load_scenario("turning-circle", fmu_dir=fmu_dir)
    assert turn.manoeuvre == "turning-circle"
    assert scenario_from_toml(turn.to_toml(), "resolved", fmu_dir=fmu_dir).manoeuvre == (
        "turning-circle"
    )
    assert turn.with_overrides(stop_time=2.0).manoeuvre == "turning-circle"


def test_overrides_are_validated(fmu_dir: Path) -> None:
    s = load_scenario("bs-3", fmu_dir=fmu_dir).with_overrides(
        stop_time=2.0, step=0.02, algorithm="jacobi"
    )
    assert (s.stop_time, s.coupling.step, s.coupling.algorithm, s.n_steps) == (
        2.0,
        0.02,
        "jacobi",
        100,
    )
    with pytest.raises(
        ScenarioError,
        match=r"stop_time.*not a whole number of communication steps.*: the nearest are 1 s "
        r"and 1\.02 s$",
    ):
        s.with_overrides(stop_time=1.005)
    assert [s.with_overrides(stop_time=t).n_steps for t in (1.0, 1.02)] == [50, 51]
    # within a step of 0 the one stop time offered is a step (0 s is no run)
    with pytest.raises(ScenarioError, match=r"2\.0 s is not a whole .*: the nearest is 3 s$"):
        s.with_overrides(step=3.0, stop_time=2.0)
    with pytest.raises(ScenarioError, match=r"coupling\.step.*greater than 0"):
        s.with_overrides(step=-0.01)


def test_step_override_redesigns_a_controller_tied_to_the_step(fmu_dir: Path) -> None:
    """An LQR designed for design_step = coupling step and sampled at every step: --step
    0.05 must not leave it designed for 10 ms. A digital autopilot with a sample period of
    its own (lqr-1 as shipped) keeps both. An explicit, different design_step is left
    alone."""
    shipped = load_scenario("lqr-1", fmu_dir=fmu_dir)
    kept = shipped.with_overrides(step=0.005).instances["controller"].start
    assert (kept["design_step"], kept["sample_period"]) == (0.01, 0.01)
    path = scenario_path("lqr-1")
    text = path.read_text(encoding="utf-8").replace("sample_period = 0.01", "")
    lqr = scenario_from_toml(text, base_dir=path.parent, fmu_dir=fmu_dir)
    assert lqr.instances["controller"].start["design_step"] == lqr.coupling.step
    moved = lqr.with_overrides(step=0.05)
    assert moved.instances["controller"].start["design_step"] == 0.05
    assert (
        "design_step"
        not in load_scenario("bs-3", fmu_dir=fmu_dir)
        .with_overrides(step=0.05)
        .instances["controller"]
        .start
    )


def test_a_sample_period_no_whole_number_of_its_steps_is_refused(fmu_dir: Path) -> None:
    """lqr-1's digital autopilot (sample_period = 0.01 s) at --step 0.004 sampled at the
    first doStep at or after each multiple of 0.01 s: at 0.012 s, 0.032 s, ..., every other
    sample 2 ms late, without a word. A period that is a whole number of the instance's
    steps (k x step) runs; so does the adaptive algorithm, whose steps end on each sample."""
    shipped = load_scenario("lqr-1", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError) as refused:
        shipped.with_overrides(step=0.004)
    assert str(refused.value).endswith(
        "key 'instances.controller.start.sample_period': 0.01 s is not a whole number of "
        "controller's steps of 0.004 s (coupling.step x its step_multiples): it samples at "
        "the first step at or after each multiple of its period, so some samples would be "
        "up to a step late; choose a sample_period that is a multiple of 0.004 s, or a step "
        "that divides 0.01 s"
    ), str(refused.value)
    assert shipped.with_overrides(step=0.005).coupling.step == 0.005  # 2 steps a sample
    assert shipped.with_overrides(step=0.02).coupling.step == 0.02  # a sample every step
    adaptive = shipped.with_overrides(step=0.004, algorithm="adaptive")
    assert adaptive.coupling.algorithm == "adaptive"
    path = scenario_path("lqr-1")
    text = path.read_text(encoding="utf-8")
    text = text.replace("\nstep = 0.01", "\nstep = 0.002\nstep_multiples = { controller = 3 }")
    with pytest.raises(ScenarioError, match=r"controller's steps of 0\.006 s"):
        scenario_from_toml(text, base_dir=path.parent, fmu_dir=fmu_dir)


def test_another_fmus_sample_period_is_its_own(test_fmu_dir: Path, tmp_path: Path) -> None:
    """A start value named ``sample_period`` of an FMU other than our autopilot (here a
    Real of another tool's FMU, 0.3 at steps of 0.2 s) was refused as if it were our
    autopilot's sampling period, which that FMU may not mean at all: it is the FMU's own
    value, set as given."""
    with_alias(
        test_fmu_dir / "CosimTestForeign.fmu", tmp_path / "Sampled.fmu", "k", "sample_period"
    )
    text = (
        'stop_time = 0.4\n[coupling]\nstep = 0.2\n[instances.f]\nfmu = "Sampled.fmu"\n'
        "[instances.f.start]\nsample_period = 0.3\n"
    )
    scenario = scenario_from_toml(text, base_dir=tmp_path)
    assert scenario.instances["f"].start["sample_period"] == 0.3


def test_a_design_step_is_moved_when_it_is_a_multiple_step_up_to_rounding(fmu_dir: Path) -> None:
    """A controller stepping every 3 steps of 0.1 s, designed for 0.3 s: 3 x 0.1 is
    0.30000000000000004, which the exact comparison missed, leaving it designed for 0.3 s
    at --step 0.2."""
    path = scenario_path("lqr-1")
    text = path.read_text(encoding="utf-8").replace("sample_period = 0.01", "")
    text = text.replace("\nstep = 0.01", "\nstep = 0.1\nstep_multiples = { controller = 3 }")
    text = text.replace("design_step = 0.01", "design_step = 0.3")
    lqr = scenario_from_toml(text, base_dir=path.parent, fmu_dir=fmu_dir)
    moved = lqr.with_overrides(step=0.2).instances["controller"].start["design_step"]
    assert moved == pytest.approx(0.6, rel=1e-12)


@pytest.mark.parametrize("scenario", ["bs-3", "vert-1"])
def test_naming_the_algorithm_a_scenario_runs_changes_nothing(fmu_dir: Path, scenario) -> None:
    """A scenario whose algorithm was resolved (gauss-seidel, quadratic inputs) ran held
    inputs after --algorithm gauss-seidel: the override reset the extrapolation."""
    shipped = load_scenario(scenario, fmu_dir=fmu_dir)
    named = shipped.with_overrides(algorithm=shipped.coupling.algorithm)
    assert named.coupling == shipped.coupling


def test_another_algorithm_drops_the_adaptive_keys_it_does_not_take(fmu_dir: Path) -> None:
    """--algorithm gauss-seidel on a scenario with algorithm = "adaptive" and a tolerance
    was refused ("applies to algorithm = 'adaptive' only"): only the file could change it."""
    path = scenario_path("bs-3")
    text = path.read_text(encoding="utf-8").replace(
        'algorithm = "gauss-seidel"', 'algorithm = "adaptive"\ntolerance = 1e-4'
    )
    adaptive = scenario_from_toml(text, base_dir=path.parent, fmu_dir=fmu_dir)
    fixed = adaptive.with_overrides(algorithm="gauss-seidel").coupling
    assert (fixed.algorithm, fixed.tolerance, fixed.extrapolation) == (
        "gauss-seidel", None, adaptive.coupling.extrapolation,
    )  # fmt: skip


def test_a_fault_whose_column_an_instance_named_fault_records_is_refused(fmu_dir: Path) -> None:
    """A fault named "yaw" beside a plant instance named "fault" gave results.csv two
    fault.yaw columns, and the run died in an index error blamed on the autopilot FMU."""
    path = scenario_path("bs-3")
    text = re.sub(r"\bplant\b", "fault", path.read_text(encoding="utf-8"))
    text += '[[faults]]\nname = "yaw"\nkind = "bias"\ntarget = "fault.mass_position_cmd"\n'
    with pytest.raises(ScenarioError, match=r"key 'faults\[0\]\.name': 'yaw': its results\.csv "
                       r"column fault\.yaw is also the column of instance fault's"):  # fmt: skip
        scenario_from_toml(text + "value = 0.001\n", base_dir=path.parent, fmu_dir=fmu_dir)


def test_a_start_value_on_an_input_connections_add_drives_names_add(fmu_dir: Path) -> None:
    """The hint said to add the input to connections.remove, which holds nothing that
    connections.add drives: following it changed nothing."""
    path = scenario_path("bs-3")
    text = path.read_text(encoding="utf-8").replace("v_0 = -0.10", "v_0 = -0.10\nthrust = 4.0")
    text = text.replace(
        'remove = ["plant.fin_angle"]',
        'remove = ["plant.fin_angle", "plant.thrust"]\n'
        'add = [{ from = "controller.thrust", to = "plant.thrust" }]',
    )
    hint = r"; take its connection out of connections\.add to hold it instead$"
    with pytest.raises(ScenarioError, match=r"plant\.thrust is connected from .*" + hint):
        scenario_from_toml(text, base_dir=path.parent, fmu_dir=fmu_dir)


REMOVE = 'remove = ["plant.fin_angle"]'
ADD = 'add = [{{ from = "{}", to = "{}" }}]'
BAD_EDITS = [
    # unknown keys, top level and nested
    ("stop_time = 60.0", "stop_time = 60.0\nstop_tme = 3", r"unknown key 'stop_tme'"),
    ("step = 0.01", "step = 0.01\nstep_size = 1", r"unknown key 'coupling\.step_size'"),
    # wrong types and values
    ("step = 0.01", 'step = "fast"', r"key 'coupling\.step' = 'fast'"),
    ('algorithm = "gauss-seidel"', 'algorithm = "euler"', r"'coupling\.algorithm' = 'euler'"),
    ('heading_mode = "backstepping"', "heading_mode = 3.5", r"start\.heading_mode.*not an integer"),
    ('heading_mode = "backstepping"', 'heading_mode = "pid"',
     r"start\.heading_mode': 'pid' is not a heading_mode: expected one of 'off' \(0\), 'lqr' "
     r"\(1\), 'sliding_mode' \(2\), 'backstepping' \(3\)$"),
    ("v_0 = -0.10", 'v_0 = "-0.10"', r"instances\.plant\.start\.v_0.*not a number"),
    # start values for what takes none
    ("v_0 = -0.10", "v_0 = -0.10\nyaw = 1.0", r"plant\.start\.yaw.*continuous output"),
    ("v_0 = -0.10", "v_0 = -0.10\nv_00 = 1.0", r"start\.v_00.*has no variable 'v_00'"),
    ("v_0 = -0.10", "v_0 = -0.10\nthrust = 4.0", r"plant\.thrust is connected from controller"),
    # the hint names the entry as connections.remove holds it: a TOML string
    ("v_0 = -0.10", "v_0 = -0.10\nthrust = 4.0",
     r'add "plant\.thrust" to connections\.remove to hold it instead$'),
    # connections: a missing variable, output -> output, input -> input, bad names
    (REMOVE, ADD.format("controller.tunnel_forse", "plant.tunnel_force"),
     r"add\[0\]\.from.*controller \(AuvAutopilot\.fmu\) has no variable 'tunnel_forse'"),
    (REMOVE, ADD.format("plant.yaw", "controller.tunnel_force"),
     r"add\[0\]\.to.*'controller\.tunnel_force' is an output, not an input"),
    (REMOVE, ADD.format("controller.yaw", "plant.thrust"),
     r"add\[0\]\.from.*'controller\.yaw' is an input, not an output"),
    (REMOVE, 'remove = ["plant.yaw"]', r"remove\[0\].*'plant\.yaw' is an output"),
    (REMOVE, 'remove = ["autopilot.fin_angle"]', r"not <instance>\.<variable>"),
    (REMOVE, 'remove = ["plant.fin_angle", "plant.fin_angle"]',
     r"remove\[1\]': 'plant\.fin_angle' is listed twice$"),
    # coupling and FMUs
    ('order = ["controller", "plant"]', 'order = ["controller"]', r"coupling\.order.*every"),
    ("step = 0.01", "step = 0.01\nstep_multiples = { ctrl = 5 }",
     r"coupling\.step_multiples\.ctrl.*no instance 'ctrl'"),
    ('fmu = "AuvPlant"', 'fmu = "NoSuch.fmu"', r"instances\.plant\.fmu.*neither a built-in"),
    # no coercion, no wrap-around, no infinity, no last-one-wins, no "..", no
    # step count beyond the ceiling
    ("stop_time = 60.0", 'stop_time = "2.0"', r"key 'stop_time' = '2\.0': expected a num.* 2\.0"),
    ("step = 0.01", 'step = "0.01"', r"key 'coupling\.step' = '0\.01': expected a number.* 0\.01"),
    ("step = 0.01", "step = inf", r"key 'coupling\.step' = inf: .* finite number"),
    ("stop_time = 60.0", "stop_time = nan", r"key 'stop_time' = nan: .* finite number"),
    ("step = 0.01", "step = 0.01\nstep_multiples = { controller = 2.0 }",
     r"'coupling\.step_multiples\.controller' = 2\.0: expected an integer"),
    # more steps than a run takes (beyond TOML's 64-bit integers in the resolved file)
    ("step = 0.01", "step = 0.01\nstep_multiples = { controller = 1000000000000000000000 }",
     r"'coupling\.step_multiples\.controller' = 1000000000000000000000: expected a number less"),
    ("stop_time = 60.0", "stop_time = 1e12",
     r"key 'stop_time': 1000000000000\.0 s is 1e\+14 communication steps .* at most 1e\+08"),
    ("stop_time = 60.0", 'id = ".."\nstop_time = 60.0', r"key 'id' = '\.\.': expected a name of"),
    ("stop_time = 60.0", 'id = "../x"\nstop_time = 60.0', r"key 'id' = '\.\./x'"),
    ('heading_mode = "backstepping"', "heading_mode = 4294967297",
     r"start\.heading_mode': 4294967297 is outside \[0, 3\], the range heading_mode takes"),
    ('variant = "lateral"', "variant = 4294967297",
     r"start\.variant': 4294967297 is outside \[0, 2\], the range variant takes"),
    # a Real outside its declared range: before, the FMU refused it once loaded (and an
    # FMU that does not check would have run with it)
    ('heading_mode = "backstepping"', 'heading_mode = "backstepping"\nk0 = -5.0',
     r"start\.k0': -5\.0 is outside \[0\.0, inf\], the range k0 takes"),
    # an initial speed beyond the model's range, refused at the load, not at the first step
    ("v_0 = -0.10", "v_0 = -0.10\nw_0 = 1e5",
     r"start\.w_0': 100000\.0 is outside \[-100\.0, 100\.0\], the range w_0 takes"),
    ("v_0 = -0.10", "v_0 = -0.10\nmax_substep = -1.0",
     r"start\.max_substep': -1\.0 is outside \[0\.0, inf\], the range max_substep takes"),
    (REMOVE, REMOVE + "\n" + 'add = [{ from = "controller.thrust", to = "plant.thrust" }, '
     '{ from = "controller.tunnel_force", to = "plant.thrust" }]',
     r"add\[1\]\.to.*'plant\.thrust' is driven twice: by connections\.add\[0\] "
     r"\(controller\.thrust\) and here \(controller\.tunnel_force\)"),
    ("v_0 = -0.10", 'v_0 = -0.10\nvehicle = "nosuch.toml"',
     r"start\.vehicle': 'nosuch\.toml' names no file \(looked for .*/nosuch\.toml\)"),
    # a vehicle the plant or the autopilot would refuse only once initialised
    ("v_0 = -0.10", 'v_0 = -0.10\nvehicle = "remus200"',
     r"plant\.start\.vehicle': unknown vehicle 'remus200': expected one of \['remus100', "),
    ('heading_mode = "backstepping"', 'heading_mode = "backstepping"\nvehicle = "remus200"',
     r"controller\.start\.vehicle': unknown vehicle 'remus200'"),
    # the plant's physical parameters written over its set, valid one by one but not
    # together: refused by the plant only once initialised, or by the design check's
    # warning as a bare VehicleParameterError naming no file and no key
    ("v_0 = -0.10", "v_0 = -0.10\nm = 1e-300",
     r"key 'instances\.plant\.start\.m': vehicle 'remus100' with m written over: m_v = "
     r"5\.08\d* kg: expected less than m = 1e-300 kg"),
    ("v_0 = -0.10", "v_0 = -0.10\nm = -0.0",  # in the FMU's declared range (>= 0)
     r"key 'instances\.plant\.start\.m': vehicle 'remus100' with m written over: m = -0\.0: "
     r"expected a number greater than 0"),
    # a manoeuvre is a known kind whose variables the run records
    ("stop_time = 60.0", 'stop_time = 60.0\nmanoeuvre = "zig-zag"',
     r"key 'manoeuvre': 'zig-zag' is not a manoeuvre \(did you mean 'zigzag'\?\): expected "
     r"one of \['turning-circle', "),
    ("stop_time = 60.0", 'stop_time = 60.0\nmanoeuvre = "survey"',
     r"key 'manoeuvre': manoeuvre 'survey' needs the variable 'cross_track_error', but the "
     r"run has no column for it \(columns: .*\); record it in output\.record"),
    ("stop_time = 60.0", 'stop_time = 60.0\nmanoeuvre = 2',
     r"key 'manoeuvre' = 2: expected a text"),
    # a mistyped instance in the order or the step multiples: the nearest one named
    ('order = ["controller", "plant"]', 'order = ["controler", "plant"]',
     r"key 'coupling\.order': \['controler', 'plant'\] must name every instance \['plant', "
     r"'controller'\] once: no instance 'controler' \(did you mean 'controller'\?\)"),
    ("step = 0.01", "step = 0.01\nstep_multiples = { controler = 5 }",
     r"step_multiples\.controler': no instance 'controler' \(did you mean 'controller'\?\) in"),
]  # fmt: skip


SURVEY = (SCENARIO_FOLDER / "survey.toml").read_text()
WAYPOINTS = re.search(r"^waypoints = .*$", SURVEY, re.MULTILINE)[0]  # type: ignore[index]
# A waypoint list or guidance parameter AuvGuidance refuses: named with its key at the load,
# like a bad vehicle set (it failed the run once the FMUs were loaded, and `auv-cosim
# export` wrote a system no host could initialise).
GUIDANCE = r"key 'instances\.guidance\."  # the survey's guidance instance
BAD_MISSIONS = [
    (WAYPOINTS, 'waypoints = "0, 0, 2"',
     r"start\.waypoints': waypoints '0, 0, 2': expected at least two entries"),
    (WAYPOINTS, 'waypoints = "0, 0, 2; 0, 0, 2; 50, 0, 2"',
     r"start\.waypoints': waypoint 2 \('0, 0, 2'\) is at the same north and east as waypoint 1"),
    (WAYPOINTS, 'waypoints = "0, 0, 2; 50, x, 2"',
     r"start\.waypoints': waypoint 2 \('50, x, 2'\): east = 'x' is not a finite number"),
    ("lookahead = 8.0", "lookahead = 0.0",
     r"start\.lookahead': lookahead = 0\.0: expected a number greater than 0"),
]  # fmt: skip
# An autopilot parameter within its FMI range that AuvAutopilot refuses once initialised
# (design_speed = 0 is within [0, inf)): `auv-cosim validate` called the scenario valid and
# the run failed at t = 0 with the FMU's error, naming neither the file nor the key.
CONTROLLER = r"key 'instances\.controller\.start\."  # bs-3's autopilot instance
BAD_AUTOPILOTS = [
    ("yaw_setpoint = 0.0", "yaw_setpoint = 0.0\ndesign_speed = 0.0",
     r"design_speed': design_speed = 0\.0: expected a number greater than 0"),
    ("yaw_setpoint = 0.0", "yaw_setpoint = 0.0\nk0 = 0.0",
     r"k0': k0 = 0\.0: expected a number greater than 0"),
]  # fmt: skip


@pytest.mark.parametrize(
    ("base", "old", "new", "message"),
    [(BS3, *edit) for edit in BAD_EDITS]
    + [(SURVEY, old, new, GUIDANCE + message) for old, new, message in BAD_MISSIONS]
    + [(BS3, old, new, CONTROLLER + message) for old, new, message in BAD_AUTOPILOTS],
)
def test_bad_scenario_fails_before_loading_naming_the_key(
    fmu_dir: Path,
    tmp_path: Path,
    no_fmu_loading: None,
    base: str,
    old: str,
    new: str,
    message: str,
) -> None:
    assert old in base
    path = tmp_path / "bad.toml"
    path.write_text(base.replace(old, new, 1))
    with pytest.raises(ScenarioError, match=message) as info:
        load_scenario(path, fmu_dir=fmu_dir)
    assert str(info.value).startswith(f"scenario file {path}: ")


def test_a_file_that_is_no_fmu_given_as_an_instance_s_fmu_names_the_key(
    fmu_dir: Path, tmp_path: Path, no_fmu_loading: None
) -> None:
    """A vehicle file typed as the autopilot's fmu (meant for its start.vehicle) was refused
    as "my-auv.toml: not a valid FMU: File is not a zip file", naming neither the scenario
    file nor its key, where a missing file names both."""
    vehicle = tmp_path / "my-auv.toml"
    vehicle.write_text('base = "remus100"\n')
    path = tmp_path / "wrong.toml"
    path.write_text(BS3.replace('fmu = "AuvAutopilot"', 'fmu = "my-auv.toml"', 1))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, fmu_dir=fmu_dir)
    assert str(info.value) == (
        f"scenario file {path}: key 'instances.controller.fmu': {vehicle}: not a valid FMU: "
        "File is not a zip file"
    )


@pytest.mark.parametrize(
    ("fmu", "reason"),
    [
        ("\\u0000", "a path holds no NUL character"),
        ("é" * 300, "File name too long"),
    ],
)
def test_an_fmu_path_the_system_cannot_look_up_is_refused_naming_the_key(
    fmu: str, reason: str, fmu_dir: Path, tmp_path: Path, no_fmu_loading: None
) -> None:
    """An instance's fmu holding a NUL character or a name too long for the file system
    escaped load_scenario as ValueError ("embedded null byte", which the command showed as
    "auv-cosim run: ValueError: embedded null byte") and OSError ("File name too long"):
    both are refused as the file's key, as a missing file is."""
    path = tmp_path / "bad.toml"
    path.write_text(BS3.replace('fmu = "AuvAutopilot"', f'fmu = "{fmu}"', 1), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, fmu_dir=fmu_dir)
    said = str(info.value)
    assert said.startswith(f"scenario file {path}: key 'instances.controller.fmu': "), said
    assert reason in said and "\n" not in said, said


@pytest.mark.parametrize("given", ["\x00/0", "a\x1b[31m/b.toml", "two\nlines/x.toml"])
def test_a_missing_scenario_path_is_named_with_its_control_characters_escaped(
    given: str,
) -> None:
    """A scenario path holding a NUL, an escape or a line break that names no file was
    refused as "no such file: <the path>" with the characters themselves, which the
    command escaped but a caller of the API (a study's StudyError, a log) got raw; the
    refusal now shows them as Python writes them, as the command does."""
    with pytest.raises(ScenarioError) as info:
        load_scenario(given)
    said = str(info.value)
    assert said.startswith(f"no such file: {given.encode('unicode_escape').decode()}"), said
    assert said.isprintable(), said


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        (('summary = "', 'summary = 3 # "'), "key 'summary' = 3: expected a text"),
        (("step = 0.01", "step = 0.01\nstep_multiples = { controller = 2.0 }"),
         "key 'coupling.step_multiples.controller' = 2.0: expected an integer"),
        (('fmu = "AuvAutopilot"', 'fmu = ""'),
         "key 'instances.controller.fmu' = '': expected a text of at least 1 character"),
    ],
)  # fmt: skip
def test_a_scenario_refusal_says_what_is_expected_in_the_houses_words(
    change: tuple[str, str], expected: str, fmu_dir: Path, tmp_path: Path
) -> None:
    """A scenario's value of the wrong type or size was refused in pydantic's words
    ("Input should be a valid string", "Input should be a valid integer"); the refusal
    says what is expected as every other refusal does, naming the key and the value."""
    path = tmp_path / "bad.toml"
    assert change[0] in BS3
    path.write_text(BS3.replace(*change, 1), encoding="utf-8")
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, fmu_dir=fmu_dir)
    assert str(info.value) == f"scenario file {path}: {expected}"


def test_invalid_toml_and_unknown_id_are_named(tmp_path: Path) -> None:
    path = tmp_path / "broken.toml"
    path.write_text("stop_time = = 3\n")
    with pytest.raises(ScenarioError, match=f"scenario file {path}: not valid TOML"):
        load_scenario(path)
    with pytest.raises(
        ScenarioError, match=r"unknown scenario 'bs-9': expected a built-in id \(bs-1, "
    ):
        load_scenario("bs-9")


def test_a_scenario_given_through_a_pipe_is_refused_saying_why(tmp_path: Path) -> None:
    """`auv-cosim run <(sed ... bs3.toml)` said "not a file: /dev/fd/63", as if the shell's
    pipe were a folder: a scenario file is read more than once (its id names the run
    folder before it loads), which a pipe cannot give, so the refusal says that."""
    fifo = tmp_path / "scenario.toml"
    os.mkfifo(fifo)  # nothing writes to it: opening it would wait for ever
    with pytest.raises(ScenarioError) as refused:
        scenario_path(fifo)
    assert str(refused.value) == (
        f"scenario file {fifo}: cannot read it: a pipe or a device, not a file (a scenario "
        "file is read more than once: `<(...)` gives it once, and a FIFO with no writer "
        "never); write it to a file first"
    )
    with pytest.raises(ScenarioError, match=r"^not a file: .*; expected a scenario \.toml"):
        scenario_path(tmp_path)  # a folder is still "not a file"


@pytest.mark.slow
def test_cli_rejects_a_bad_file_with_one_line_and_no_run(fmu_dir: Path, tmp_path: Path) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(BS3.replace("stop_time = 60.0", "stop_time = 60.0\ncolour = 'red'"))
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "cosim.cli",
            "run",
            str(path),
            "--fmu-dir",
            str(fmu_dir),
            "--out",
            "out",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 1
    assert proc.stderr.startswith(f"auv-cosim run: scenario file {path}: unknown key 'colour': ")
    assert proc.stderr.count("\n") == 1
    assert not (tmp_path / "out").exists()


def test_documented_example_resolves(fmu_dir: Path, no_fmu_loading: None) -> None:
    example = ROOT / "docs" / "scenario-example.toml"
    s = load_scenario(example, fmu_dir=fmu_dir)
    assert s.coupling.step_multiples == {"plant": 1, "controller": 5}
    assert len(s.connections) == 10 and not s.rrd
    assert s.record[0] == "plant.yaw"
    assert [e.name for e in s.events] == ["turn"] and [f.name for f in s.faults] == ["weak-mass"]


def test_a_utf8_byte_order_mark_is_accepted(fmu_dir: Path, tmp_path: Path) -> None:
    """Regression: a BOM made the file "Invalid statement"."""
    path = tmp_path / "bs-3.toml"
    path.write_bytes("\ufeff".encode() + BS3.encode())
    assert load_scenario(path, fmu_dir=fmu_dir) == load_scenario("bs-3", fmu_dir=fmu_dir)


@pytest.mark.parametrize(
    ("data", "expected"),
    [
        # Latin-1 (an editor's "Western European"): the byte and where it is
        (("id = 'x'\n# Gr\u00f6\u00dfe\n" + BS3).encode("latin-1"),
         "not UTF-8 text: byte 0xf6 at line 2, column 5; save it as UTF-8"),
        # UTF-16 (Windows' "Unicode"): said as such, not as its first byte
        (BS3.encode("utf-16"), "not UTF-8 text but UTF-16 (it starts with a UTF-16 "
         "byte-order mark); save it as UTF-8"),
    ],
)  # fmt: skip
def test_a_scenario_file_not_utf8_is_refused_saying_so(
    fmu_dir: Path, tmp_path: Path, data: bytes, expected: str
) -> None:
    """A scenario file in another encoding was refused as "cannot read it: 'utf-8' codec
    can't decode byte 0xf6 in position 13: invalid start byte": a byte offset and the
    codec's words, not what is wrong with the file or where."""
    path = tmp_path / "kodiert.toml"
    path.write_bytes(data)
    with pytest.raises(ScenarioError) as info:
        load_scenario(path, fmu_dir=fmu_dir)
    assert str(info.value) == f"scenario file {path}: {expected}"


def test_files_named_in_a_scenario_are_relative_to_it(fmu_dir: Path, tmp_path: Path) -> None:
    """Regression: `vehicle = "myveh.toml"` was resolved against the current folder."""
    folder = tmp_path / "mission"
    folder.mkdir()
    (folder / "myveh.toml").write_text('base = "remus100"\nm = 31.0\n')
    (folder / "s.toml").write_text(
        BS3.replace("v_0 = -0.10", 'v_0 = -0.10\nvehicle = "myveh.toml"')
    )
    scenario = load_scenario(folder / "s.toml", fmu_dir=fmu_dir)
    assert scenario.instances["plant"].start["vehicle"] == str(folder / "myveh.toml")
    assert scenario.instances["plant"].files() == {"vehicle": folder / "myveh.toml"}
    assert scenario_from_toml(scenario.to_toml(), "resolved", fmu_dir=fmu_dir) == scenario


def test_an_integer_outside_the_fmi_range_is_refused_without_a_declared_one(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """fmi2Integer is 32 bits: 2**32 + 1 would wrap to 1 in the FMU call, also
    for a variable declaring no min/max."""
    interface = load_scenario("bs-3", fmu_dir=fmu_dir).instances["plant"].interface
    unbounded = dataclasses.replace(interface.variables["variant"], min=None, max=None)
    monkeypatch.setitem(interface.variables, "variant", unbounded)  # the cached interface
    edited = BS3.replace('variant = "lateral"', "variant = 4294967297")
    with pytest.raises(ScenarioError, match=r"4294967297 is outside \[-2147483648, 2147483647\]"):
        scenario_from_toml(edited, "bs-3 edited", fmu_dir=fmu_dir)
    edited = BS3.replace('variant = "lateral"', "variant = 2147483647")
    assert scenario_from_toml(edited, "bs-3", fmu_dir=fmu_dir).instances["plant"].start[
        "variant"
    ] == (2**31 - 1)  # the scenario takes it; the FMU judges it at its write


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        ("max_substep = 1e-9", "instances.plant.start.max_substep"),
        ("max_substep = 0.000001", None),  # 10,000 sub-steps: the limit itself runs
    ],
)
def test_a_substep_that_would_hang_a_step_is_refused_before_loading(
    fmu_dir: Path, no_fmu_loading: None, edit: str, key: str | None
) -> None:
    """Regression: `max_substep = 1e-9` made no progress after 17 min and ignored Ctrl-C."""
    scenario = scenario_from_toml(
        BS3.replace("v_0 = -0.10", f"v_0 = -0.10\n{edit}"), "bs-3 edited", fmu_dir=fmu_dir
    )
    if key is None:
        master.preflight(scenario)
        return
    with pytest.raises(ScenarioError, match=rf"key '{key}': plant\.max_substep = 1e-09 s would "
                       r"take 1e\+07 sub-steps per communication step of 0\.01 s; at most "
                       r"10000 are allowed \(max_substep >= 1e-06 s\)"):  # fmt: skip
        master.preflight(scenario)
    with pytest.raises(ScenarioError, match="sub-steps"):
        master.run(scenario)  # the master itself refuses it too, before any FMU


def test_a_zero_substep_is_refused_before_loading_naming_the_key_and_its_range(
    fmu_dir: Path, no_fmu_loading: None
) -> None:
    """``max_substep = 0`` passed the load (the FMU declares min 0, FMI has no open
    bound) and ``auv-cosim validate``, and failed the run inside the plant at t = 0: it is
    refused before any FMU loads, naming the key and the range the plant takes."""
    scenario = scenario_from_toml(
        BS3.replace("v_0 = -0.10", "v_0 = -0.10\nmax_substep = 0"), "bs-3 edited", fmu_dir=fmu_dir
    )
    with pytest.raises(ScenarioError) as refused:
        master.preflight(scenario)
    assert str(refused.value) == (
        "scenario file bs-3 edited: key 'instances.plant.start.max_substep': 0.0 is outside "
        "(0.0, inf], the range max_substep takes"
    )


def test_an_adaptive_step_that_may_grow_past_the_sub_step_limit_is_refused_before_loading(
    fmu_dir: Path, no_fmu_loading: None
) -> None:
    # Guards the adaptive run: its steps grow to max_step, which the check did not look at.
    scenario = scenario_from_toml(
        BS3.replace('algorithm = "gauss-seidel"', 'algorithm = "adaptive"\nmax_step = 1000.0'),
        "bs-3 adaptive",
        fmu_dir=fmu_dir,
    )
    assert scenario.coupling.max_step == 1000.0
    with pytest.raises(ScenarioError, match=r"key 'coupling.max_step': plant\.max_substep = "
                       r"0\.01 s would take 1e\+05 sub-steps per communication step of 1000\.0 "
                       r"s; at most 10000"):  # fmt: skip
        master.preflight(scenario)


@pytest.mark.parametrize(
    ("plant", "controller", "expected"),
    [
        ('variant = "horizontal"', 'heading_mode = "sliding_mode"', (2, 2)),
        ("variant = 2", "heading_mode = 2", (2, 2)),  # the numbers still work
    ],
)
def test_a_mode_is_given_by_its_name_or_its_number(
    fmu_dir: Path, plant: str, controller: str, expected: tuple[int, int]
) -> None:
    """Named values come from the FMU's own model description (its annotation of the
    Integer), and resolve to the number the FMU is given."""
    text = BS3.replace('variant = "lateral"', plant).replace(
        'heading_mode = "backstepping"', controller
    )
    scenario = scenario_from_toml(text, "named", fmu_dir=fmu_dir)
    starts = scenario.instances["plant"].start, scenario.instances["controller"].start
    assert (starts[0]["variant"], starts[1]["heading_mode"]) == expected
    assert scenario_from_toml(scenario.to_toml(), "named", fmu_dir=fmu_dir) == scenario


def test_an_unknown_vehicle_is_refused_when_the_fmu_is_named_by_its_path(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """The vehicle set was checked only for `fmu = "AuvPlant"`: named by its file (as a
    study's tasks and the scenarios of other folders name it), `vehicle = "remus-100"`
    passed every check, and a study ran it into a failed row with the FMU's error."""
    text = (ROOT / "cosim" / "scenarios" / "bs-3.toml").read_text()
    text = text.replace('fmu = "AuvPlant"', f'fmu = "{fmu_paths["AuvPlant"]}"')
    text = text.replace('variant = "lateral"', 'variant = "lateral"\nvehicle = "remus-100"')
    with pytest.raises(ScenarioError, match=r"start\.vehicle': unknown vehicle 'remus-100'"):
        scenario_from_toml(text, base_dir=tmp_path)


@pytest.mark.parametrize("nested", ["[" * 5000 + "]" * 5000, "{a=" * 5000 + "1" + "}" * 5000])
def test_toml_nested_too_deeply_to_read_is_refused_as_not_valid_toml(
    tmp_path: Path, nested: str
) -> None:
    """Arrays or inline tables thousands deep: tomllib ran out of Python's recursion and
    the command said only "RecursionError: maximum recursion depth exceeded", naming
    neither the file nor what was wrong."""
    path = tmp_path / "deep.toml"
    path.write_text(f"{BS3}\nx = {nested}\n")
    expected = r": not valid TOML: arrays or inline tables nested too deeply to read"
    with pytest.raises(ScenarioError, match=f"^scenario file {re.escape(str(path))}{expected}"):
        load_scenario(path)
    with pytest.raises(ScenarioError, match=f"^scenario <string>{expected}"):
        scenario_from_toml(f"{BS3}\nx = {nested}\n")


def test_two_start_values_for_one_variable_under_two_names_are_refused(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """Aliases are one variable: start values for two of its names would be set one after
    the other, the last silently winning; the second is refused naming both. One of
    them alone sets the value, which both names then read."""
    with_alias(test_fmu_dir / "CosimTestForeign.fmu", tmp_path / "Aliased.fmu", "k", "k alias")
    text = (
        'stop_time = 0.2\n[coupling]\nstep = 0.1\n[instances.f]\nfmu = "Aliased.fmu"\n'
        '[instances.f.start]\nk = 2.0\n"k alias" = 3.0\n'
        '[output]\nrecord = ["f.k", "f.k alias"]\n'
    )
    with pytest.raises(
        ScenarioError,
        match=r"key 'instances\.f\.start\.k alias': f\.k alias and f\.k are one variable "
        r"\(the same value reference\): give one of them a start value",
    ):
        scenario_from_toml(text, base_dir=tmp_path)
    result = master.run(scenario_from_toml(text.replace("k = 2.0\n", ""), base_dir=tmp_path))
    assert list(result.column("f.k")) == list(result.column("f.k alias")) == [3.0] * 3


def test_an_input_driven_under_two_names_is_refused(test_fmu_dir: Path, tmp_path: Path) -> None:
    """Two connections into two names of one input (aliases) drove it twice, the last set
    silently winning; and a start value for one name of a connected input was silently
    overwritten. Both are refused naming the aliases."""
    folder = tmp_path
    for name in ("CosimTestSource.fmu", "CosimTestIntegrator.fmu"):
        shutil.copy(test_fmu_dir / name, folder / name)
    with_alias(test_fmu_dir / "CosimTestFeedthrough.fmu", folder / "Ft.fmu", "u", "u alias")
    head = (
        'stop_time = 0.2\n[coupling]\nstep = 0.1\n[instances.src]\nfmu = "CosimTestSource.fmu"\n'
        '[instances.plant]\nfmu = "CosimTestIntegrator.fmu"\n[instances.ft]\nfmu = "Ft.fmu"\n'
    )
    twice = head + (
        '[connections]\nsame_names = false\nadd = [{ from = "src.x", to = "ft.u" }, '
        '{ from = "plant.x", to = "ft.u alias" }]\n'
    )
    with pytest.raises(
        ScenarioError,
        match=r"key 'connections\.add\[1\]\.to': 'ft\.u alias' and 'ft\.u' are one variable "
        r"\(the same value reference\), driven by src\.x and plant\.x; an input has one source",
    ):
        scenario_from_toml(twice, base_dir=folder)
    held = head.replace(
        'fmu = "Ft.fmu"\n', 'fmu = "Ft.fmu"\n[instances.ft.start]\n"u alias" = 1.0\n'
    )
    held += '[connections]\nsame_names = false\nadd = [{ from = "src.x", to = "ft.u" }]\n'
    with pytest.raises(
        ScenarioError,
        match=r"key 'instances\.ft\.start\.u alias': input ft\.u alias is connected from src\.x "
        r"\(as ft\.u, one variable\), so a start value would be overwritten",
    ):
        scenario_from_toml(held, base_dir=folder)


def test_two_vehicles_connect_by_name_where_add_and_remove_name_the_rest(
    fmu_dir: Path, no_fmu_loading: None
) -> None:
    """Two plants and two autopilots: every autopilot input has two same-named outputs.
    The refusal said to connect such an input in connections.add, yet it refused the same
    way once every one was there (same names were resolved before add was read); an
    input that add drives or remove leaves unconnected is no longer ambiguous."""
    from two_vehicles import two_vehicles_toml

    s = scenario_from_toml(two_vehicles_toml(same_names=True), fmu_dir=fmu_dir)
    pairs = {(c.source, c.target) for c in s.connections}
    for plant, controller in (("plant_a", "ctrl_a"), ("plant_b", "ctrl_b")):
        assert (f"{plant}.yaw", f"{controller}.yaw") in pairs
        assert (f"{controller}.thrust", f"{plant}.thrust") in pairs
    assert {c.source_instance for c in s.connections if c.target_instance == "ctrl_a"} == {
        "plant_a"
    }
    assert scenario_from_toml(s.to_toml(), "resolved", fmu_dir=fmu_dir) == s


def test_an_ambiguous_same_name_input_names_every_way_out(
    fmu_dir: Path, no_fmu_loading: None
) -> None:
    """The refusal of an input with several same-named outputs names the three ways to
    settle it: connections.add, connections.remove, or same_names = false."""
    from two_vehicles import two_vehicles_toml

    text = two_vehicles_toml(same_names=True).replace(
        '{ from = "ctrl_b.thrust", to = "plant_b.thrust" }, ', ""
    )
    expected = (
        r"input plant_b\.thrust has several same-named outputs \['ctrl_a', 'ctrl_b'\]: "
        r"connect it in connections\.add, leave it unconnected in connections\.remove, or "
        r"set same_names = false and list every connection$"
    )
    with pytest.raises(ScenarioError, match=expected):
        scenario_from_toml(text, fmu_dir=fmu_dir)
