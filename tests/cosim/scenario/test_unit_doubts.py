"""An angle typed in degrees where the FMU takes radians is valid, so it runs: a run and a
study say so in one warning line per value, naming the key and the value in radians."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

import cosim
from cosim.scenario.unit_doubts import (
    UnitWarning,
    angle_doubts,
    depth_doubts,
    radius_doubts,
    stroke_doubts,
    when_doubts,
)

TURN = """
[[events]]
name = "turn"
time = 1.0
set = {{ "controller.yaw_setpoint" = {setpoint} }}

[[events]]
name = "past"
when = "plant.yaw > {threshold}"
set = {{ "controller.yaw_setpoint" = 0.0 }}
"""


def _scenario(tmp_path: Path, setpoint: float, threshold: float) -> Path:
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-2.toml").read_text()
    path = tmp_path / "turn.toml"
    path.write_text(text + TURN.format(setpoint=setpoint, threshold=threshold))
    return path


def test_degrees_in_radian_variables_are_named_with_their_value_in_radians(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """yaw_0 = 30, a set-point of 45 and a `when` at 20 ran without a word: the vehicle
    started 30 rad (4.8 turns) round and the event never fired."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = cosim.load_scenario(_scenario(tmp_path, 45, 20), fmu_dir=fmu_dir)
    doubts = angle_doubts(scenario.with_start({"plant.yaw_0": 30}))
    assert doubts == [
        "instances.plant.start.yaw_0 = 30 rad is more than a full turn (1719 deg): angles are "
        "in radians; if 30 deg was meant, give 0.523599",
        "events.turn.set.controller.yaw_setpoint = 45 rad is more than a full turn (2578 deg): "
        "angles are in radians; if 45 deg was meant, give 0.785398",
        "events.past.when = 20 rad is more than a full turn (1146 deg): angles are in "
        "radians; if 20 deg was meant, give 0.349066",
    ]


@pytest.mark.parametrize("value", [0.5, -math.pi, 2 * math.pi])
def test_angles_within_a_turn_and_other_units_are_not_doubted(
    fmu_paths: dict[str, Path], tmp_path: Path, value: float
) -> None:
    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = cosim.load_scenario(_scenario(tmp_path, value, value), fmu_dir=fmu_dir)
    assert angle_doubts(scenario.with_start({"plant.u_0": 30.0, "plant.yaw_0": value})) == []


def test_a_run_warns_once_per_value_and_still_runs(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from cosim.cli import main

    path = _scenario(tmp_path, 30, 0.6)  # past 0.6 rad (34 deg): not from the 30 deg start
    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    argv = ["run", str(path), "--stop-time", "0.5", "--no-rrd", "--quiet", "--fmu-dir", fmu_dir,
            "--out", str(tmp_path / "run")]  # fmt: skip
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(argv) == 0
    lines = [str(w.message) for w in caught if issubclass(w.category, UnitWarning)]
    assert lines == [
        "events.turn.set.controller.yaw_setpoint = 30 rad is more than a full turn (1719 deg): "
        "angles are in radians; if 30 deg was meant, give 0.523599"
    ]


def test_a_study_warns_of_grid_values_and_samples_once_before_any_run(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A sweep over yaw_0 = [10, 20] (degrees meant) or a normal distribution of std 10
    on the set-point ran every run without a word."""
    from cosim.study.factors import resolve_factor
    from cosim.study.runner import _checked_plan
    from cosim.study.spec import study_from_dict
    from cosim.study.task import prepare

    spec = study_from_dict(
        {"scenario": "bs-2", "grid": {"plant.yaw_0": [10, 20, 0.3]},
         "random": {"n": 4, "seed": 1, "controller.yaw_setpoint": {"normal": [0.0, 10.0]}}},
        "study",
    )  # fmt: skip
    base, facts = prepare("bs-2", 1.0, fmu_paths["AuvPlant"].parent)
    factors = {name: resolve_factor(name, facts) for name in spec.factors}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        runs = _checked_plan(spec, base, factors, facts)
    lines = [str(w.message) for w in caught if issubclass(w.category, UnitWarning)]
    assert len(runs) == 12
    assert [line.split(" rad ")[0] for line in lines[:2]] == [
        "instances.plant.start.yaw_0 = 10",
        "instances.plant.start.yaw_0 = 20",
    ]
    assert len(lines) == 3 and lines[2].startswith("factor 'controller.yaw_setpoint': "), lines


def test_a_series_column_in_degrees_is_named_by_its_largest_value(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    (tmp_path / "profile.csv").write_text("time,controller.yaw_setpoint\n0,0\n5,-20\n10,10\n")
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-2.toml").read_text()
    path = tmp_path / "profile.toml"
    path.write_text(text + '\n[[events]]\nname = "steps"\nseries = "profile.csv"\n')
    scenario = cosim.load_scenario(path, fmu_dir=fmu_paths["AuvPlant"].parent)
    assert angle_doubts(scenario) == [
        "events.steps.series column controller.yaw_setpoint = -20 rad is more than a full "
        "turn (-1146 deg): angles are in radians; if -20 deg was meant, give -0.349066"
    ]


def test_the_api_warning_points_at_the_callers_line(fmu_paths: dict[str, Path]) -> None:
    """From a script the warning named cosim/runner.py and one of its lines; it names the
    script's own cosim.run(...) line, as a warning of a library should."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cosim.run("bs-2", stop_time=0.1, start={"plant.yaw_0": 30}, fmu_dir=fmu_dir)
    (warning,) = [w for w in caught if issubclass(w.category, UnitWarning)]
    assert warning.filename == __file__, warning.filename


def test_an_acceptance_radius_as_long_as_a_leg_is_named_and_the_run_warns(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """acceptance_radius = 60 m (a slip for 6) on the survey's 50 m and 20 m legs ran
    without a word: four legs counted at t = 0, none flown, and "legs_completed = 7" of 7
    within 20 s (a leg whose start lies within its end's acceptance circle is done at once).
    """
    fmu_dir = fmu_paths["AuvPlant"].parent
    survey = cosim.load_scenario("survey", fmu_dir=fmu_dir)
    assert radius_doubts(survey) == []
    wide = survey.with_start({"guidance.acceptance_radius": 20.0})
    assert radius_doubts(wide) == [
        "instances.guidance.start.acceptance_radius = 20 m is not shorter than leg 2 (20 m, "
        "waypoint 2 -> 3) and 2 more: a leg whose start lies in its end's acceptance circle "
        "is completed as soon as it begins; the shortest leg is 20 m"
    ]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = cosim.run("survey", stop_time=0.1, start={"guidance.acceptance_radius": 60.0},
                        fmu_dir=fmu_dir)  # fmt: skip
    assert run.summary["legs_completed"] == 4  # at t = 0.1 s: what the warning is about
    lines = [str(w.message) for w in caught if issubclass(w.category, UnitWarning)]
    assert len(lines) == 1 and "leg 1 (50 m, waypoint 1 -> 2) and 6 more" in lines[0]


def test_a_command_beyond_a_written_over_stroke_is_named(fmu_paths: dict[str, Path]) -> None:
    """The turning circle's 6 cm command on a plant whose mass_stroke is written over to
    3 cm ran without a word: the stroke was read from the vehicle set, not from the set
    the plant runs, so the command held at the 3 cm stop went unremarked."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    turn = cosim.load_scenario("turning-circle", fmu_dir=fmu_dir)
    (line,) = stroke_doubts(turn.with_start({"plant.mass_stroke": 0.03}))
    assert line.startswith(
        "instances.plant.start.mass_position_cmd = 0.06 m is beyond the moving mass's stroke "
        "of 0.03 m"
    ), line


def test_a_moving_mass_command_in_centimetres_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """mass_position_cmd = 6 (cm meant) ran without a word as the 0.06 m stop, reached
    faster: the turning circle's advance came out 8.92 m instead of 10.27 m."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    turn = cosim.load_scenario("turning-circle", fmu_dir=fmu_dir)
    assert stroke_doubts(turn) == []
    assert stroke_doubts(turn.with_start({"plant.mass_position_cmd": 6.0})) == [
        "instances.plant.start.mass_position_cmd = 6 m is beyond the moving mass's stroke of "
        "0.06 m: the rail stops hold the mass there (lengths are in metres; if 6 cm was meant, "
        "give 0.06)"
    ]
    path = tmp_path / "port.toml"
    path.write_text(
        (Path(__file__).parents[3] / "cosim" / "scenarios" / "turning-circle.toml").read_text()
        + '\n[[events]]\nname = "helm"\ntime = 1.0\nset = { "plant.mass_position_cmd" = -60.0 }\n'
    )
    (line,) = stroke_doubts(cosim.load_scenario(path, fmu_dir=fmu_dir))
    assert line.startswith("events.helm.set.plant.mass_position_cmd = -60 m is beyond")
    assert line.endswith("(lengths are in metres)")  # -60 cm is no value within the stroke


def test_a_rate_typed_in_degrees_per_second_is_named_with_its_value_in_radians(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """r_0 = 10 (10 deg/s by habit) ran without a word as 10 rad/s, 573 deg/s: the vehicle
    started spinning nearly two turns a second. A rate beyond a full turn a second is
    named as an angle beyond a full turn is; one within it, or in another unit, is not."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = cosim.load_scenario(_scenario(tmp_path, 0.0, 0.2), fmu_dir=fmu_dir)
    doubts = angle_doubts(scenario.with_start({"plant.r_0": 10.0, "plant.p_0": -0.5}))
    assert doubts == [
        "instances.plant.start.r_0 = 10 rad/s is more than a full turn a second (573 deg/s): "
        "rates are in radians per second; if 10 deg/s was meant, give 0.174533"
    ]


def test_a_frequency_in_rad_per_second_is_not_doubted_as_a_turn_rate(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """command_filter_frequency = 20 rad/s (its default is 10), a servo of 8 rad/s and a
    sliding mode reaching at 7 rad/s were each warned of as "more than a full turn a
    second ... if 20 deg/s was meant, give 0.349": no turn rates, and meant in rad/s.
    The FMUs declare their quantity (FMI 2.0 ``quantity``), and only a variable declaring
    an angle's or a turn rate's (or none, r_0) is doubted."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = cosim.load_scenario(_scenario(tmp_path, 0.0, 0.2), fmu_dir=fmu_dir)
    given = {"controller.command_filter_frequency": 20.0, "controller.smc_eta": 7.0,
             "plant.mass_natural_frequency": 8.0, "plant.r_0": 10.0}  # fmt: skip
    doubts = angle_doubts(scenario.with_start(given))
    assert [line.split(" = ")[0] for line in doubts] == ["instances.plant.start.r_0"]


@pytest.mark.parametrize(
    ("key", "value", "unit"),
    [("current_east", '"0.5 kn"', "m/s"), ("yaw_0", '"270 deg"', "rad"),
     ("current_north", '"0.3 m/s"', "m/s")],
)  # fmt: skip
def test_a_value_written_with_its_unit_is_refused_naming_the_unit_expected(
    fmu_paths: dict[str, Path], tmp_path: Path, key: str, value: str, unit: str
) -> None:
    """An operator's current of "0.5 kn" or heading of "270 deg" was refused as "not a
    number (current_east is Real)", which did not say what number to give: the unit the
    variable takes is named."""
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    path = tmp_path / "units.toml"
    path.write_text(text.replace("v_0 = -0.10", f"{key} = {value}\nv_0 = -0.10"))
    with pytest.raises(cosim.ScenarioError) as refused:
        cosim.load_scenario(path, fmu_dir=fmu_paths["AuvPlant"].parent)
    assert str(refused.value).endswith(
        f"{value.strip(chr(34))!r} is not a number ({key} is Real): expected a number of {unit}"
    )


def test_a_start_above_the_surface_is_named(fmu_paths: dict[str, Path]) -> None:
    """down_0 = -3 (a depth of 3 m written with the sign of an altitude) ran without a word,
    the vehicle starting 3 m above the water the plant does not model: depth is positive
    down, as a waypoint's, whose negative depth is refused."""
    scenario = cosim.load_scenario("depth-steps", fmu_dir=fmu_paths["AuvPlant"].parent)
    assert depth_doubts(scenario) == []
    assert depth_doubts(scenario.with_start({"plant.down_0": -3.0})) == [
        "instances.plant.start.down_0 = -3 m is above the surface: depths are positive down "
        "(NED); if a depth of 3 m was meant, give 3 (the plant has no free surface)"
    ]


def test_a_when_event_true_from_the_start_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A vehicle started at 350 deg (yaw_0 = 6.109 rad) with an event `when = "plant.yaw >
    0.6"`, meant for the heading passing 034 deg: the yaw counts whole turns, so the
    comparison held from the start, never turned true, and the event never fired, without
    a word."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = cosim.load_scenario(_scenario(tmp_path, 0.2, 0.6), fmu_dir=fmu_dir)
    assert when_doubts(scenario) == []  # bs-2 starts at yaw_0 = 30 deg: 0.52 rad
    north = scenario.with_start({"plant.yaw_0": math.radians(350.0)})
    assert when_doubts(north) == [
        "events.past.when = 'plant.yaw > 0.6' holds from the start (plant.yaw_0 = 6.109 rad): "
        "a when event fires when its comparison turns true, so this one waits for the value "
        "to go back across 0.6 first; angles count whole turns (6.109 rad is -0.1745 on the "
        "turn before)"
    ]
