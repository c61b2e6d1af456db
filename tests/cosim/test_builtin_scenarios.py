"""The built-in scenarios through the master (both FMUs built, fmpy), against the outcomes
the dissertation reports (docs/model.md#scenarios), and the master's coupling
and failure behaviour on the real FMUs.

Each built-in scenario runs once per session, to its own stop time (module fixture).
"""

from __future__ import annotations

import json
import math
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest
from reference_values import dissertation
from repo_paths import ROOT, script_module

from controller_fmu.autopilot import AutopilotConfig
from controller_fmu.los_guidance import parse_waypoints
from cosim.analysis.equilibria import find_equilibrium
from cosim.engine import master
from cosim.engine.master import RunResult
from cosim.metrics.key_figures import KeyFigures, settling_time
from cosim.metrics.manoeuvres import manoeuvre_metrics, metric_names, summary_metrics
from cosim.outputs.manoeuvre import fault_start
from cosim.outputs.results import read_csv
from cosim.runner import RunOutcome, run_scenario
from cosim.scenario.spec import builtin_scenarios, load_scenario, scenario_from_toml, scenario_path
from cosim.viz.report import load_results, null_reasons
from plant_fmu.model.dynamics import INPUT_NAMES, STATE_INDEX, STATE_NAMES, PlantModel, Variant
from plant_fmu.model.linearization import input_vector
from plant_fmu.model.parameters import load_vehicle

DEG = math.radians(1.0)


@pytest.fixture(scope="module")
def runs(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, RunOutcome]:
    """Every built-in scenario, run once through `run_scenario` (outputs written, no rrd)."""
    out = tmp_path_factory.mktemp("runs")
    return {
        scenario_id: run_scenario(
            scenario_id, out / scenario_id, no_rrd=True, fmu_dir=fmu_dir, keep_rows=True
        )
        for scenario_id in builtin_scenarios()
    }


@pytest.fixture(scope="module")
def results(runs: dict[str, RunOutcome]) -> dict[str, RunResult]:
    return {scenario_id: outcome.result for scenario_id, outcome in runs.items()}


def after(result: RunResult, name: str, t0: float) -> np.ndarray:
    return result.column(name)[result.times >= t0 - 1e-9]


def window(result: RunResult, name: str, t0: float, t1: float) -> np.ndarray:
    return result.column(name)[(result.times >= t0 - 1e-9) & (result.times < t1 - 1e-9)]


@pytest.mark.parametrize(
    ("scenario_id", "printed"),
    [
        ("bs-1", "backstepping_gains"),
        ("bs-2", "backstepping_gains"),
        ("bs-3", "backstepping_gains"),
        ("cur-1", "backstepping_gains"),
        ("cur-2", "backstepping_gains_current"),
        ("slow-1", "backstepping_gains_current"),
        ("slow-2", "backstepping_gains_current"),
    ],
)
def test_backstepping_scenarios_run_the_gains_the_dissertation_ran(
    scenario_id: str, printed: str
) -> None:
    """Sec. 6.3.3 prints two gain sets, k0..k4 = 0.5, 1, 1, 1, 1 and, for heading into the
    current (and again at low speed), 0.3, 0.8, 1, 1, 1: each backstepping case of Ch. 6
    runs the set the text ran it with (a gain the file does not set is the autopilot's
    default). Sec. 6.3.4 gives no gains for vert-1 and vert-2."""
    spec = tomllib.loads(scenario_path(scenario_id).read_text(encoding="utf-8"))
    start = spec["instances"]["controller"]["start"]
    assert start["heading_mode"] == "backstepping"
    defaults = AutopilotConfig.build()
    gains = [float(start.get(k, getattr(defaults, k))) for k in ("k0", "k1", "k2", "k3", "k4")]
    assert gains == list(dissertation(f"section_6_3_3.{printed}"))


@pytest.mark.slow
def test_every_builtin_scenario_runs_to_its_stop_time(results: dict[str, RunResult]) -> None:
    for scenario_id, result in results.items():
        scenario = result.scenario
        assert result.complete, f"{scenario_id}: {result.error}"
        assert result.times[-1] == pytest.approx(scenario.stop_time)
        assert len(result.times) == scenario.n_steps + 1
        assert np.isfinite(result.values).all()
        # the moving mass never leaves its stroke, the thruster never exceeds its limit
        assert np.abs(result.column("plant.mass_position")).max() <= 0.06 + 1e-12
        if "controller" in scenario.instances:  # turning-circle runs the plant alone
            assert np.abs(result.column("controller.tunnel_force")).max() <= 10.0 + 1e-9


@pytest.mark.slow
def test_lqr_1_converges(results: dict[str, RunResult]) -> None:
    assert np.abs(after(results["lqr-1"], "plant.yaw", 25.0)).max() < 1 * DEG
    assert np.all(results["lqr-1"].column("controller.tunnel_force") == 0.0)  # mass alone steers


@pytest.mark.slow
def test_lqr_2_saturates_the_mass_and_comes_back(results: dict[str, RunResult]) -> None:
    """The dissertation's text has the heading back to zero within 20 s (Sec. 6.3.1); with
    the unsaturated command the dissertation used we match an independent reproduction of
    this case instead (continuous LQR gains, RK4 at 0.2 ms: |yaw| < 1 deg for good after
    28-34 s, so we ask it by 34 s) and the fast mass of Fig. 6.14 (rail speeds of tens of
    cm/s); docs/reproduction.md lists the difference."""
    result = results["lqr-2"]
    stop = dissertation("scenarios.lqr_2_mass_stop") / 100  # cm -> m
    assert result.column("plant.mass_position").min() == pytest.approx(stop, abs=1e-6)
    assert np.abs(after(result, "plant.yaw", 34.0)).max() < 1 * DEG
    assert np.abs(result.column("plant.yaw")).max() > 1 * DEG  # it was disturbed
    assert np.abs(result.column("plant.mass_velocity")).max() > 0.15


@pytest.mark.slow
def test_lqr_3_heading_returns(results: dict[str, RunResult]) -> None:
    result = results["lqr-3"]
    assert result.column("plant.yaw").max() > 30 * DEG  # "the yaw angle has to rise" first
    assert np.abs(after(result, "plant.yaw", 60.0)).max() < 1 * DEG


@pytest.mark.slow
@pytest.mark.parametrize("scenario_id", ["bs-1", "bs-3"])
def test_backstepping_converges_within_15_s(
    results: dict[str, RunResult], scenario_id: str
) -> None:
    assert np.abs(after(results[scenario_id], "plant.yaw", 15.0)).max() < 1 * DEG
    assert np.abs(results[scenario_id].column("controller.tunnel_force")).max() > 1.0  # it helps


@pytest.mark.slow
def test_bs_2_heading_back_within_a_short_time(results: dict[str, RunResult]) -> None:
    result = results["bs-2"]
    assert settling_time(result.times, result.column("plant.yaw"), 1 * DEG) < 15.0


@pytest.mark.slow
def test_cur_1_drifts_east_with_the_nose_north(results: dict[str, RunResult]) -> None:
    result = results["cur-1"]
    assert np.abs(after(result, "plant.yaw", 30.0)).max() < 1 * DEG
    east = result.column("plant.east")
    assert east[-1] - east[result.times.searchsorted(30.0)] > 5.0  # still drifting, m


@pytest.mark.slow
def test_cur_2_heads_into_the_current_and_tracks_north(results: dict[str, RunResult]) -> None:
    result = results["cur-2"]
    yaw = after(result, "plant.yaw", 30.0)
    assert np.abs(yaw - dissertation("current.heading_9_newton") * DEG).max() < 0.2 * DEG
    east = after(result, "plant.east", 30.0)
    assert np.ptp(east) < 0.1  # m over the last 30 s: no eastward drift
    assert result.column("plant.north")[-1] > 80.0  # while making way north


@pytest.mark.slow
def test_slow_1_stabilised_within_20_s(results: dict[str, RunResult]) -> None:
    result = results["slow-1"]
    assert np.abs(after(result, "plant.yaw", 20.0)).max() < 1 * DEG
    assert np.all(result.column("controller.thrust") == 4.0)


@pytest.mark.slow
def test_slow_2_converges_to_minus_11_3_deg_in_about_20_s(results: dict[str, RunResult]) -> None:
    result = results["slow-2"]
    error = result.column("plant.yaw") - dissertation("current.heading_4_newton") * DEG
    about = dissertation("scenarios.slow_2_settling_time")  # "about 20 seconds"
    assert settling_time(result.times, error, 1 * DEG) < about + 5.0


@pytest.mark.slow
def test_vert_2_settles_like_the_dissertation(results: dict[str, RunResult]) -> None:
    # Sec. 6.3.4 prints w ~ -0.07 m/s, theta ~ -0.045 rad, mean delta_s ~ -5 deg for
    # vert-1's run (Fig. 6.43), near which vert-2 settles with its mass locked; no integral
    # term, so the depth stays short of z_d = 1 m against the positive buoyancy
    w, theta, fin_deg = dissertation("scenarios.depth_steady_state")
    result = results["vert-2"]
    assert after(result, "plant.down", 40.0).mean() == pytest.approx(1.0, abs=0.1)
    assert np.ptp(after(result, "plant.down", 40.0)) < 0.02
    assert after(result, "plant.pitch", 40.0).mean() == pytest.approx(theta, abs=0.01)
    assert after(result, "plant.w", 40.0).mean() == pytest.approx(w, abs=0.01)
    assert after(result, "controller.fin_angle", 40.0).mean() == pytest.approx(
        fin_deg * DEG, abs=1 * DEG
    )
    # locked from t = 15 s: row n holds the command computed at t_{n-1}, hence 15.01
    assert np.all(after(result, "controller.mass_position_cmd", 15.01) == 0.0)
    assert np.abs(after(result, "plant.yaw", 40.0)).max() < 1 * DEG


@pytest.mark.slow
def test_vert_1_keeps_rolling(results: dict[str, RunResult]) -> None:
    # without the lock the roll oscillation persists (Figs. 6.42, 6.45), with it it decays
    for t0 in (40.0, 45.0, 50.0, 55.0):
        assert np.ptp(window(results["vert-1"], "plant.roll", t0, t0 + 5.0)) > 10 * DEG
        assert np.ptp(window(results["vert-2"], "plant.roll", t0, t0 + 5.0)) < 3 * DEG
    assert after(results["vert-1"], "plant.down", 40.0).mean() == pytest.approx(1.0, abs=0.1)


ACTIVITY = ("mass_position_cmd_variation_m_per_s", "fin_angle_variation_rad_per_s")


def tail_figures(outcome: RunOutcome, seconds: float = 10.0) -> dict[str, float | None]:
    """The key figures of the last ``seconds`` of a run's rows."""
    result = outcome.result
    assert result.times is not None and result.values is not None
    late = result.times >= result.times[-1] - seconds - 1e-9
    figures = KeyFigures(result.columns)
    figures.add_rows(result.times[late], result.values[late])
    return figures.figures()


@pytest.mark.slow
def test_the_command_activity_shows_vert_1s_chatter(runs: dict[str, RunOutcome]) -> None:
    """vert-1's actuators chatter (docs/model.md's table), vert-2's with the roll lock
    settle: the key figures say so without the plots, and a settled run's tail is quiet."""
    chatter, locked, settled = (tail_figures(runs[s]) for s in ("vert-1", "vert-2", "bs-3"))
    for name in ACTIVITY:
        assert chatter[name] > 100 * locked[name], (name, chatter[name], locked[name])
        assert runs["vert-1"].figures[name] > 10 * runs["bs-3"].figures[name], name
    mass = "mass_position_cmd_variation_m_per_s"
    assert settled[mass] < 1e-3 * chatter[mass], (settled[mass], chatter[mass])


MISSION_METRICS = ("legs_total", "first_waypoint_not_reached")


def manoeuvre(kind: str, outcome: RunOutcome) -> dict:
    """The manoeuvre metrics of a run from its summary.json (top level), checked against
    the same metrics computed from its results.csv."""
    summary = json.loads(outcome.paths["summary"].read_text())
    assert summary["manoeuvre"] == kind
    columns, table = read_csv(outcome.paths["results"])
    start = fault_start(outcome.result.scenario)  # 0 without faults
    from_csv = manoeuvre_metrics(kind, dict(zip(columns, table.T, strict=True)), start)
    # a survey's mission (its legs, the first waypoint not reached) is the scenario's, not
    # results.csv's: results.csv gives None for it
    from_csv = {k: summary[k] if k in MISSION_METRICS else v for k, v in from_csv.items()}
    assert {name: summary[name] for name in from_csv} == from_csv  # the same doubles
    assert set(summary_metrics(summary)) == set(from_csv)
    return summary_metrics(summary)


@pytest.mark.slow
def test_turning_circle_is_the_plants_own_steady_turn(runs: dict[str, RunOutcome]) -> None:
    outcome = runs["turning-circle"]
    metrics = manoeuvre("turning-circle", outcome)
    assert None not in metrics.values()  # advance, transfer, tactical and steady diameter, ...
    # The plant's own steady turn: the equilibrium of the model's reduced dynamics with the
    # scenario's inputs (the mass at its stop), from the run's last state.
    plant = outcome.result.scenario.instances["plant"]
    inputs = input_vector(
        {name: float(plant.start.get(name, plant.variable(name).start)) for name in INPUT_NAMES}
    )
    model = PlantModel(load_vehicle("remus100"), variant=Variant(plant.start["variant"]))
    last = {name: outcome.result.column(f"plant.{name}")[-1] for name in STATE_NAMES}
    steady = find_equilibrium(model, last, inputs)
    rates = model.derivative(steady.state, inputs)
    speed = math.hypot(rates[STATE_INDEX["north"]], rates[STATE_INDEX["east"]])
    assert metrics["steady_turning_diameter_m"] == pytest.approx(
        2.0 * speed / rates[STATE_INDEX["yaw"]], rel=0.01
    )
    assert metrics["steady_roll_deg"] == pytest.approx(math.degrees(steady.value("roll")), abs=0.5)
    approach = plant.start["u_0"]
    assert metrics["speed_loss_pct"] == pytest.approx(100 * (1 - speed / approach), abs=0.5)
    assert metrics["advance_m"] > metrics["transfer_m"] > 0.0  # it runs on before it turns
    assert metrics["tactical_diameter_m"] > metrics["steady_turning_diameter_m"]


@pytest.mark.slow
def test_survey_completes_every_leg_in_the_cross_current(runs: dict[str, RunOutcome]) -> None:
    outcome = runs["survey"]
    metrics = manoeuvre("survey", outcome)
    assert isinstance(metrics["legs_completed"], int)
    legs = len(parse_waypoints(outcome.result.scenario.instances["guidance"].start["waypoints"]))
    assert metrics["legs_completed"] == legs - 1 == 7
    assert metrics["legs_total"] == 7 and metrics["first_waypoint_not_reached"] is None
    assert metrics["cross_track_rms_m"] < 2.0  # 1.60 m, most of it in the turns
    assert metrics["cross_track_max_m"] <= 5.0 + 0.01  # at a switch: the acceptance radius
    # on the last quarter of each survey leg the vehicle holds the line against the current
    result = outcome.result
    legs_done = result.column("guidance.legs_completed")
    cross_track = result.column("guidance.cross_track_error")
    for leg in (0, 2, 4, 6):
        on_leg = np.flatnonzero(legs_done == leg)
        assert np.abs(cross_track[on_leg[3 * len(on_leg) // 4 :]]).max() < 0.1  # m
    # and the depth loop holds 2 m (short of it by the PD's steady error, as in vert-2)
    assert np.abs(result.column("plant.down")[result.times > 5.0] - 2.0).max() < 0.2


@pytest.mark.slow
def test_every_figure_the_pages_quote_is_what_the_run_gives(runs: dict[str, RunOutcome]) -> None:
    """README.md and docs/ quote the built-in scenarios' key figures and manoeuvre metrics
    after markers (scripts/doc_figures.py writes them): each is its run's, to the decimals
    the page gives it, so a change that moves a run cannot leave its pages behind."""
    doc_figures = script_module("doc_figures")
    marked = [f for page in doc_figures.pages(ROOT) for f in doc_figures.figures_in(page)]
    values = {
        (f.scenario, f.metric): doc_figures.metric_value(
            f.scenario, f.metric, runs[f.scenario].figures, runs[f.scenario].manoeuvre or {}
        )
        for f in marked
    }
    stale = [
        f"{f.page.name} {f.scenario} {f.metric}: {f.text} -> {new}"
        for f, new in doc_figures.differences(marked, values)
    ]
    assert len(marked) > 50  # the settling times of README's table and the manoeuvres'
    assert not stale, "python scripts/doc_figures.py --write: " + "; ".join(stale)


@pytest.mark.slow
def test_run_outputs_hold_the_result_exactly(runs: dict[str, RunOutcome]) -> None:
    outcome = runs["bs-3"]
    columns, table = read_csv(outcome.paths["results"])
    assert columns == ["time", *outcome.result.columns]
    np.testing.assert_array_equal(table[:, 0], outcome.result.times)
    np.testing.assert_array_equal(table[:, 1:], outcome.result.values)
    summary = json.loads(outcome.paths["summary"].read_text())
    assert summary["complete"] is True and summary["scenario"] == "bs-3"
    within = dissertation("scenarios.bs_3_settling_time")  # "within 10 seconds"
    assert summary["key_figures"]["yaw_settling_time_s"] < within
    assert summary["key_figures"]["peak_abs_mass_position_m"] <= 0.06
    resolved = load_scenario(outcome.paths["scenario"], fmu_dir=outcome.result.scenario.fmu_dir)
    assert resolved.connections == outcome.result.scenario.connections


# --- the coupling algorithms on the real FMUs -----------------------------------------


def bs3(fmu_dir: Path, step: float, algorithm: str, stop_time: float = 6.0) -> RunResult:
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir).with_overrides(
        stop_time=stop_time, step=step, algorithm=algorithm
    )
    result = master.run(scenario)
    assert result.complete, result.error
    return result


@pytest.mark.slow
def test_jacobi_and_gauss_seidel_agree_at_1_ms_and_drift_apart_with_the_step(fmu_dir: Path) -> None:
    # Jacobi feeds the plant the command computed one step earlier: a delay of h in the
    # loop, so the two differ by O(h). Documented tolerance: at h = 1 ms the yaw histories
    # of bs-3 agree within 0.05 deg (measured 0.020 deg; 0.20 deg at 10 ms, 0.41 at 20 ms),
    # and the difference grows about in proportion to h.
    differences = {}
    for step in (0.001, 0.01, 0.02):
        gs, jacobi = bs3(fmu_dir, step, "gauss-seidel"), bs3(fmu_dir, step, "jacobi")
        differences[step] = np.abs(gs.column("plant.yaw") - jacobi.column("plant.yaw")).max()
    assert differences[0.001] < 0.05 * DEG
    assert differences[0.001] < differences[0.01] < differences[0.02]
    assert 5.0 < differences[0.01] / differences[0.001] < 20.0  # first order in h


def test_plant_alone_through_the_master_equals_fmpy_simulate_fmu(fmu_dir: Path) -> None:
    from fmpy import simulate_fmu

    start = {"variant": 1, "u_0": 1.5, "v_0": -0.05, "mass_position_cmd": 0.03, "tunnel_force": 2.0}
    scenario = scenario_from_toml(
        f"""
        stop_time = 5.0
        [coupling]
        step = 0.01
        [instances.plant]
        fmu = "AuvPlant"
        [instances.plant.start]
        {chr(10).join(f"{k} = {v}" for k, v in start.items())}
        """,
        "plant alone",
        fmu_dir=fmu_dir,
    )
    ours = master.run(scenario)
    names = [c.split(".", 1)[1] for c in ours.columns]
    theirs = simulate_fmu(
        str(fmu_dir / "AuvPlant.fmu"),
        stop_time=5.0,
        output_interval=0.01,
        start_values=start,
        output=names,
    )
    np.testing.assert_array_equal(ours.times, theirs["time"])
    for column, name in zip(ours.columns, names, strict=True):
        np.testing.assert_array_equal(ours.column(column), theirs[name], err_msg=column)
    assert np.ptp(ours.column("plant.yaw")) > 0.1  # it did turn


# --- failures of the real FMUs ----------------------------------------------------------


def cli_run(fmu_dir: Path, tmp_path: Path, scenario_text: str) -> subprocess.CompletedProcess:
    path = tmp_path / "scenario.toml"
    path.write_text(scenario_text)
    options = ["--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "run"), "--no-rrd"]
    return subprocess.run(
        [sys.executable, "-m", "cosim.cli", "run", str(path), *options],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )


@pytest.mark.slow
def test_plant_refusing_a_start_value_stops_the_run(fmu_dir: Path, tmp_path: Path) -> None:
    # an absurd propeller thrust (held, unconnected) overflows the first step: the plant
    # returns a non-OK status with its reason (the state that left the model's range, not
    # numpy's overflow); the master stops, keeps t = 0, exits 1
    text = (Path(load_scenario("bs-3", fmu_dir=fmu_dir).source)).read_text()
    text = text.replace("v_0 = -0.10", "v_0 = -0.10\nthrust = 1e300", 1)
    text = text.replace(
        'remove = ["plant.fin_angle"]', 'remove = ["plant.fin_angle", "plant.thrust"]'
    )
    proc = cli_run(fmu_dir, tmp_path, text)
    assert proc.returncode == 1
    assert proc.stderr.startswith("auv-cosim run: plant: fmi2DoStep returned Discard at t = 0 s: ")
    assert "the vehicle left the model's range" in proc.stderr, proc.stderr
    assert "an input or an initial velocity far beyond" in proc.stderr
    assert proc.stderr.count("\n") == 1
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["complete"] is False and summary["time_reached"] == 0.0
    assert (tmp_path / "run" / "results.csv").read_text().count("\n") == 2  # header + t = 0
    # the commands' activity, a rate, needs two rows: the one row of t = 0 gives none, which
    # the printed figures and the report's index say so (they said "not finite")
    activity = "mass_position_cmd_variation_m_per_s"
    assert summary["key_figures"][activity] is None
    said = f"{activity} = none: the rows span no time (a rate needs two)"
    assert said in proc.stdout, proc.stdout
    run = tmp_path / "run"
    reasons = null_reasons(run, load_results(run), summary)
    assert reasons[activity] == "none: the rows span no time (a rate needs two)", reasons


@pytest.mark.slow
def test_plant_failing_initialisation_is_reported_with_its_reason(
    fmu_dir: Path, tmp_path: Path
) -> None:
    text = (Path(load_scenario("bs-3", fmu_dir=fmu_dir).source)).read_text()
    proc = cli_run(  # beyond the 6 cm stroke of the vehicle, which only the plant knows
        fmu_dir, tmp_path, text.replace("v_0 = -0.10", "v_0 = -0.10\nmass_position_0 = 0.1", 1)
    )
    assert proc.returncode == 1
    # the FMU answers the failed initialisation with fmi2Error: when it leaves
    # initialisation mode, or when the master first reads its outputs in it (an FMU that
    # computes them there) to exchange them
    assert re.match(
        r"auv-cosim run: plant: fmi2(ExitInitializationMode|GetReal) returned Error at t = 0 s: ",
        proc.stderr,
    )
    assert "mass_position_0 = 0.1 m: expected |mass_position_0| <= mass_stroke" in proc.stderr


@pytest.mark.slow
def test_zigzag_switches_at_the_test_angle_and_overshoots(runs: dict[str, RunOutcome]) -> None:
    outcome = runs["zigzag-20"]
    metrics = manoeuvre("zigzag", outcome)
    for name in ("overshoot_1_deg", "overshoot_2_deg", "period_s"):
        assert metrics[name] is not None and 0.0 < metrics[name] < math.inf, name
    result = outcome.result
    yaw, setpoint = result.column("plant.yaw"), result.column("controller.yaw_setpoint")
    switches = np.flatnonzero(np.diff(setpoint)) + 1
    assert len(switches) >= 4  # e2 .. e5: two overshoots and a period from e2 on
    # each counter-command comes at the first communication point with yaw past +-20 deg
    for k in switches:
        new = setpoint[k]
        assert abs(new) == pytest.approx(20 * DEG)
        assert -np.sign(new) * yaw[k] > 20 * DEG >= -np.sign(new) * yaw[k - 1]
    cycles = result.times[switches[2:]] - result.times[switches[:-2]]  # e2 -> e4, e3 -> e5, ..
    assert metrics["period_s"] == pytest.approx(np.mean(cycles))


@pytest.mark.slow
def test_depth_steps_rise_overshoot_and_settle(runs: dict[str, RunOutcome]) -> None:
    outcome = runs["depth-steps"]
    metrics = manoeuvre("depth-steps", outcome)
    assert set(metrics) == set(metric_names("depth-steps", steps=2))
    for step in (1, 2):
        rise, settle = metrics[f"step_{step}_rise_time_s"], metrics[f"step_{step}_settling_time_s"]
        assert 0.0 < rise < settle < 50.0  # both settle before the next step / the end
        assert metrics[f"step_{step}_overshoot_pct"] > 0.0
        assert abs(metrics[f"step_{step}_steady_error_m"]) < 0.1  # the PD's offset, 5 cm
    down = outcome.result.column("plant.down")
    assert down[-1] == pytest.approx(2.0, abs=0.1) and down.max() > 3.0  # 1 -> 3 -> 2 m


@pytest.mark.slow
@pytest.mark.parametrize("scenario_id", ["mass-jam", "thruster-failure"])
def test_fault_recovery_metrics_are_finite(runs: dict[str, RunOutcome], scenario_id: str) -> None:
    metrics = manoeuvre("fault-recovery", runs[scenario_id])
    for name in ("heading_error_at_fault_deg", "heading_error_max_deg", "heading_error_final_deg"):
        assert metrics[name] is not None and math.isfinite(metrics[name]), name
    assert metrics["heading_error_max_deg"] >= metrics["heading_error_final_deg"]
    fault = runs[scenario_id].result.column(
        f"fault.{'jam' if scenario_id == 'mass-jam' else 'thruster'}"
    )
    assert fault[runs[scenario_id].result.times >= 3.0].min() == 1.0  # on from 3 s to the end


@pytest.mark.slow
def test_the_jammed_mass_stays_where_it_was(runs: dict[str, RunOutcome]) -> None:
    result = runs["mass-jam"].result
    mass, times = result.column("plant.mass_position"), result.times
    at_jam = mass[np.searchsorted(times, 3.0)]
    # the servo brings the mass to rest at the held command (it was moving at 3 s) ...
    assert np.abs(mass[times >= 3.0] - at_jam).max() < 1e-3
    assert np.abs(mass[times >= 8.0] - at_jam).max() < 1e-6
    # ... whatever the autopilot asks for
    assert np.ptp(result.column("controller.mass_position_cmd")[times >= 3.0]) > 0.01
    # the tunnel thruster alone holds the heading to a steady offset
    assert runs["mass-jam"].result.column("plant.yaw")[-1] == pytest.approx(0.0, abs=3 * DEG)
