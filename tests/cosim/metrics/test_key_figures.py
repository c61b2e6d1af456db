"""Key figures computed as the rows stream by equal those of the whole series at once."""

from __future__ import annotations

import itertools
import json
import math
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import cosim
from cosim.metrics.key_figures import (
    ACTIVITY_FIGURES,
    KeyFigures,
    SettlingTime,
    Vehicle,
    key_figures,
    settling_time,
    vehicles,
    why_none,
    why_none_of,
)
from cosim.scenario.mission_doubts import MissionWarning

TOLERANCE = 0.1


def whole_series_settling_time(times: np.ndarray, error: np.ndarray) -> float | None:
    """The definition, evaluated on the whole series by brute force: the first sample
    after which every one is inside, the entry interpolated from the sample before it."""
    for i in range(len(times)):
        if np.all(np.abs(error[i:]) < TOLERANCE):
            if i == 0 or not math.isfinite(error[i - 1]):
                return float(times[i])
            outside, inside = abs(float(error[i - 1])), abs(float(error[i]))
            t0, t1 = float(times[i - 1]), float(times[i])
            return t0 + (t1 - t0) * (outside - TOLERANCE) / (outside - inside)
    return None


def test_the_settling_time_is_where_the_error_crosses_into_the_band():
    """A linear decay crossing the band between two samples settles at the crossing, not
    at the next sample: the figure moves continuously with the step."""
    times = np.array([0.0, 1.0, 2.0, 3.0])
    error = np.array([0.4, 0.25, 0.05, 0.01])  # 0.25 -> 0.05 crosses 0.1 at t = 1.75
    assert settling_time(times, error, TOLERANCE) == pytest.approx(1.75)
    assert settling_time(times, -error, TOLERANCE) == pytest.approx(1.75)


@pytest.mark.parametrize("cut", range(1, 9))
def test_settling_time_streamed_in_two_pieces_is_the_whole_series_one(cut: int) -> None:
    """The fast twin of the streamed property below: the error leaves the band, enters
    it for good between 2.5 s and 3 s; split anywhere (in particular just before the
    entry, so the piece after is all inside and the entry is interpolated from the last
    sample of the piece before), the tracker gives the definition's crossing time."""
    error = np.array([0.4, 0.25, 0.05, 0.01, 0.3, 0.2, 0.05, 0.02, 0.0])
    times = np.arange(len(error)) * 0.5
    tracker = SettlingTime(TOLERANCE)
    tracker.add(times[:cut], error[:cut])
    tracker.add(times[cut:], error[cut:])
    expected = whole_series_settling_time(times, error)
    assert expected == pytest.approx(2.5 + 0.5 * (0.2 - TOLERANCE) / (0.2 - 0.05))
    assert tracker.value == pytest.approx(expected)


errors = st.lists(st.sampled_from([0.0, 0.05, -0.05, 0.2, -0.3, math.nan]), min_size=1, max_size=40)
cuts = st.lists(st.integers(min_value=0, max_value=40), max_size=6)


@pytest.mark.slow
@settings(max_examples=300, deadline=None)
@given(errors, cuts)
def test_streamed_settling_time_is_the_whole_series_one(values: list[float], cut: list[int]):
    error = np.array(values)
    times = np.arange(len(error)) * 0.5
    tracker = SettlingTime(TOLERANCE)
    bounds = sorted({0, len(error), *(c for c in cut if c <= len(error))})
    for lo, hi in itertools.pairwise(bounds):
        tracker.add(times[lo:hi], error[lo:hi])
    expected = whole_series_settling_time(times, error)
    assert tracker.value == expected
    assert settling_time(times, error, TOLERANCE) == expected


def test_key_figures_of_chunks_equal_those_of_the_whole_run():
    rng = np.random.default_rng(3)
    columns = ("plant.yaw", "controller.yaw_setpoint", "plant.mass_position", "plant.tunnel_force")
    times = np.arange(500) * 0.01
    values = rng.normal(0.0, 0.002, (500, 4))
    values[:200, 0] += np.linspace(0.5, 0.0, 200)  # yaw settles at t = 2 s
    values[:, 1] = 0.0
    values[123, 2] = -0.06  # the peak of |mass_position|
    values[321, 3] = 9.5  # and of |tunnel_force|
    figures = _whole_as_in_chunks(columns, times, values, 37)
    assert figures["peak_abs_mass_position_m"] == 0.06
    assert figures["peak_abs_tunnel_force_N"] == 9.5
    assert figures["yaw_settling_time_s"] == settling_time(
        times, values[:, 0], math.radians(1.0), angle=True
    )
    assert 1.0 < figures["yaw_settling_time_s"] < 2.0


def test_figures_of_columns_not_recorded_are_none():
    figures = KeyFigures(("plant.north",))
    figures.add_rows(np.arange(3.0), np.zeros((3, 1)))
    assert figures.figures() == {
        "yaw_settling_time_s": None,
        "peak_abs_mass_position_m": None,
        "peak_abs_tunnel_force_N": None,
        "mass_position_cmd_variation_m_per_s": None,
        "tunnel_force_variation_N_per_s": None,
        "fin_angle_variation_rad_per_s": None,
    }


def test_command_activity_is_the_total_variation_per_simulated_second() -> None:
    """Each actuator command's activity: sum |c_k - c_(k-1)| over the rows divided by the
    time they span, the same in chunks as at once: a chattering command's is large,
    a settled one's zero."""
    columns = ("controller.mass_position_cmd", "controller.tunnel_force", "plant.fin_angle")
    times = np.arange(5) * 0.5  # 2 s
    values = np.array([[0.0, 3.0, 0.1], [1.0, 3.0, -0.1], [-1.0, 3.0, 0.1],
                       [-1.0, 3.0, -0.1], [2.0, 3.0, 0.1]])  # fmt: skip
    figures = _whole_as_in_chunks(columns, times, values, 2)
    assert figures["mass_position_cmd_variation_m_per_s"] == (1 + 2 + 0 + 3) / 2.0
    assert figures["tunnel_force_variation_N_per_s"] == 0.0
    assert figures["fin_angle_variation_rad_per_s"] == pytest.approx(4 * 0.2 / 2.0)
    one_row = KeyFigures(columns)
    one_row.add_rows(times[:1], values[:1])  # no time spanned: no rate
    assert one_row.figures()["mass_position_cmd_variation_m_per_s"] is None


def test_names_are_the_figures_the_columns_can_give():
    assert KeyFigures(("d.x", "time")).names() == ()
    assert KeyFigures(("plant.mass_position", "plant.yaw")).names() == (
        "yaw_settling_time_s",
        "peak_abs_mass_position_m",
    )


def test_a_figure_that_is_none_says_why() -> None:
    """What a run's report prints in place of a figure it has none of: for the settling
    time, plainly that the yaw ends outside its band (it read "within 1 deg at the
    end", the opposite)."""
    columns = ["plant.yaw", "plant.mass_position", "controller.yaw_setpoint"]
    figures = KeyFigures(columns)
    rows = np.array([[0.0, 0.01, 0.0], [0.5, 0.02, 0.0]])
    figures.add_rows(np.array([0.0, 1.0]), rows)
    absent = {k: why_none(k, columns) for k, v in figures.figures().items() if v is None}
    assert absent == {
        "yaw_settling_time_s": "not settled: the yaw is not within 1 deg of its set-point at "
        "the end",
        "peak_abs_tunnel_force_N": "not recorded",
        "mass_position_cmd_variation_m_per_s": "not recorded",
        "tunnel_force_variation_N_per_s": "not recorded",
        "fin_angle_variation_rad_per_s": "not recorded",
    }
    assert why_none("yaw_settling_time_s", ["plant.roll"]) == "not recorded"
    # the turning circle has no autopilot: "its set-point" named one it does not have; a
    # set-point driven by a connection but not recorded is not "no set-point" either
    assert why_none("yaw_settling_time_s", ["plant.yaw"]) == (
        "not settled: the yaw is not within 1 deg of 0 at the end (0: controller.yaw_setpoint "
        "is not recorded)"
    )


def test_a_run_that_did_not_complete_has_no_settling_time() -> None:
    """A run interrupted at 0.54 s, its yaw inside the band since the start, reported a
    settling time of 0 s: where the yaw stays after its last row is not known."""
    columns = ["plant.yaw", "plant.mass_position"]
    figures = KeyFigures(columns)
    figures.add_rows(np.array([0.0, 0.54]), np.array([[0.001, 0.01], [0.002, 0.02]]))
    assert figures.figures()["yaw_settling_time_s"] == 0.0
    cut = figures.figures(complete=False)
    assert cut["yaw_settling_time_s"] is None and cut["peak_abs_mass_position_m"] == 0.02
    reason = why_none("yaw_settling_time_s", columns, complete=False)
    assert reason == "none: the run did not complete"


def test_a_command_activity_over_no_time_says_so_not_that_it_is_not_finite() -> None:
    """A run that stopped at its first row (t = 0) has no command activity, a rate: its
    reason was "not finite", which a run that overflowed would give; a run whose rows span
    time keeps that reason for a figure that is None."""
    columns = ["controller.mass_position_cmd"]
    figures = KeyFigures(columns)
    figures.add_rows(np.array([0.0]), np.array([[0.01]]))
    name = "mass_position_cmd_variation_m_per_s"
    assert figures.figures(complete=False)[name] is None
    reason = why_none(name, columns, complete=False, spanned=False)
    assert reason == "none: the rows span no time (a rate needs two)"
    assert why_none(name, columns) == "not finite"
    assert why_none("peak_abs_mass_position_m", columns, spanned=False) == "not recorded"


@pytest.mark.slow
def test_the_figures_do_not_depend_on_what_the_scenario_calls_its_instances(
    fmu_paths, tmp_path
) -> None:
    """bs-3 with its instances named "auv" and "ap" printed "not settled" for a yaw that
    settled (the setpoint read as 0 without a controller.yaw_setpoint column), and a
    renamed plant gave no figure at all."""
    from cosim.runner import run_scenario
    from cosim.scenario.spec import load_scenario

    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    text = text.replace("yaw_setpoint = 0.0", "yaw_setpoint = 0.05")
    renamed = re.sub(r"\bplant\b", "auv", re.sub(r"\bcontroller\b", "ap", text))
    fmu_dir = fmu_paths["AuvPlant"].parent
    figures = {}
    for name, scenario_text in (("shipped", text), ("renamed", renamed)):
        path = tmp_path / f"{name}.toml"
        path.write_text(scenario_text, encoding="utf-8")
        scenario = load_scenario(path, fmu_dir=fmu_dir).with_overrides(stop_time=8.0)
        if name == "renamed":
            assert scenario.key_instances == {"plant": "auv", "controller": "ap"}
        outcome = run_scenario(scenario, tmp_path / name, no_rrd=True)
        figures[name] = outcome.figures
    assert figures["renamed"] == figures["shipped"]
    assert all(value is not None for value in figures["shipped"].values()), figures


def test_a_yaw_set_point_a_guidance_moves_is_not_taken_as_zero(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A waypoint mission (the guidance drives the autopilot's yaw_setpoint, which is not
    recorded: its source is) got a yaw settling time measured against 0 deg: north in
    still water a "settling time" of a heading the guidance never asked to hold, and on
    any other course "not within 1 deg of 0", printed on every mission run. A moving
    set-point has no settling time; the run now says why it has none."""
    from cosim.runner import report, run_scenario

    fmu_dir = fmu_paths["AuvPlant"].parent
    still = {f"{name}.current_east": 0.0 for name in ("plant", "controller", "guidance")}
    north = cosim.load_scenario("survey", fmu_dir=fmu_dir).with_start(
        {**still, "guidance.waypoints": "0, 0, 2; 100, 0, 2"}
    )
    with pytest.warns(MissionWarning, match="waypoint 2 onwards will not be reached"):
        outcome = run_scenario(
            north, tmp_path / "run", stop_time=10.0, no_rrd=True, fmu_dir=fmu_dir
        )  # 10 s of a 100 m leg
    assert outcome.figures["yaw_settling_time_s"] is None
    assert (
        "yaw_settling_time_s = not measured: controller.yaw_setpoint follows "
        "guidance.yaw_setpoint, a set-point that moves (a mission's tracking: its survey "
        "metrics)"
    ) in report(outcome)
    figures = KeyFigures(["plant.yaw"], setpoint_driver="guidance.yaw_setpoint")
    assert figures.names() == ()  # no settling time to give, whatever the rows


@pytest.mark.slow
def test_two_vehicles_each_get_their_own_key_figures(fmu_paths, tmp_path) -> None:
    """Two plants, each closed by its own autopilot (LQR on a, backstepping with the
    tunnel thruster on b): the key figures were those of the first plant and autopilot
    alone, under the single-vehicle names (a peak tunnel force of 0 N for a run whose
    vehicle b fires its thruster); now each vehicle's figures carry its plant's name."""
    from two_vehicles import two_vehicles_toml

    from cosim.runner import report, run_scenario
    from cosim.scenario.spec import scenario_from_toml
    from cosim.viz.report import null_reasons

    fmu_dir = fmu_paths["AuvPlant"].parent
    scenario = scenario_from_toml(two_vehicles_toml(stop_time=10.0), fmu_dir=fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True)
    figures = outcome.figures
    names = ("yaw_settling_time_s", "peak_abs_mass_position_m", "peak_abs_tunnel_force_N",
             *ACTIVITY_FIGURES)  # fmt: skip
    assert list(figures) == [f"{p}.{n}" for p in ("plant_a", "plant_b") for n in names]
    assert figures["plant_a.peak_abs_tunnel_force_N"] == 0.0  # LQR: the mass alone
    assert figures["plant_b.peak_abs_tunnel_force_N"] > 1.0  # backstepping fires it
    assert figures["plant_b.yaw_settling_time_s"] is not None  # settles within 10 s
    summary = json.loads((tmp_path / "run" / "summary.json").read_text(encoding="utf-8"))
    assert summary["key_figures"] == figures
    assert "plant_a.yaw_settling_time_s = not settled" in report(outcome)
    table = {c: np.asarray(v) for c, v in pd.read_csv(tmp_path / "run" / "results.csv").items()}
    reasons = null_reasons(tmp_path / "run", table, summary)  # the report's index page
    assert reasons["plant_a.yaw_settling_time_s"].startswith("not settled"), reasons


def test_each_plant_is_paired_with_the_autopilot_connected_to_it() -> None:
    """The vehicles of the key figures: one plant keeps the plain names (the first
    autopilot, connected or not); several are each paired with the autopilot a connection
    joins to them, whatever order the instances come in, and a plant no autopilot steers
    gets none (its settling time is then read against a set-point of 0)."""
    models = {"ap_b": "AuvAutopilot", "auv_a": "AuvPlant", "ap_a": "AuvAutopilot",
              "auv_b": "AuvPlant", "auv_c": "AuvPlant", "nav": "AuvGuidance"}  # fmt: skip
    links = [("auv_a.yaw", "ap_a.yaw"), ("ap_b.thrust", "auv_b.thrust"),
             ("nav.yaw_setpoint", "ap_b.yaw_setpoint"), ("auv_b.north", "nav.north")]  # fmt: skip
    fleet = vehicles(models, links)
    assert [(v.prefix, v.roles["controller"], v.setpoint_driver) for v in fleet] == [
        ("auv_a.", "ap_a", None),
        ("auv_b.", "ap_b", "nav.yaw_setpoint"),
        ("auv_c.", "", None),
    ]
    (one,) = vehicles({"p": "AuvPlant", "c": "AuvAutopilot"}, [])
    assert one == Vehicle("", {"plant": "p", "controller": "c"}, None)
    columns = ["auv_a.yaw", "auv_c.yaw"]
    sink = key_figures(columns, fleet)
    sink.add_rows(np.array([0.0, 1.0]), np.array([[0.5, 0.0], [0.0, 0.0]]))
    figures = sink.figures()
    assert figures["auv_a.yaw_settling_time_s"] == pytest.approx(1.0 - 0.0175 / 0.5, abs=1e-3)
    assert figures["auv_c.yaw_settling_time_s"] == 0.0
    assert why_none_of("auv_b.yaw_settling_time_s", columns, fleet) == "not recorded"


def _whole_as_in_chunks(
    columns: tuple[str, ...], times: np.ndarray, values: np.ndarray, size: int
) -> dict[str, float | None]:
    """The key figures of the rows given at once, asserted equal to those of the same rows
    given ``size`` at a time (a run's rows come in chunks)."""
    whole, chunked = KeyFigures(columns), KeyFigures(columns)
    whole.add_rows(times, values)
    for lo in range(0, len(times), size):
        chunked.add_rows(times[lo : lo + size], values[lo : lo + size])
    assert chunked.figures() == whole.figures()
    return whole.figures()
