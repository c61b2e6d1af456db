"""Event and fault factors (the scenario's [[events]] / [[faults]]): a grid over an event's
time and a fault's gain gives the rows of separate runs of the edited scenarios; a factor
naming an event, a fault or a key the scenario does not have is refused before any run."""

from __future__ import annotations

import itertools
import json
import subprocess
import tomllib
from pathlib import Path

import pytest
import tomli_w
from repo_paths import ROOT
from sweep_helpers import sweep, table

from cosim.cli import main

pytestmark = pytest.mark.usefixtures("no_early_cluster")  # refusals wait for no cluster

EVENTS = """
[[events]]
name = "turn"                     # a yaw setpoint step
time = 10.0
set = { "controller.yaw_setpoint" = 0.3 }

[[faults]]                        # unnamed: "fault-1"
kind = "gain"
target = "plant.mass_position_cmd"
start = 5.0
value = 1.0
"""
METRICS = ["final.plant.yaw", "final.plant.north", "final.plant.east", "final.plant.r"]
STUDY = f"""
scenario = "turning.toml"
stop_time = 20.0
[grid]
"events.turn.time" = [10.0, 15]
"faults.fault-1.value" = [1.0, 0.5]
[metrics]
collect = {json.dumps([*METRICS, "time_reached"])}
"""


@pytest.fixture
def scenario(tmp_path: Path) -> Path:
    """bs-3 with a yaw setpoint step at 10 s and a gain fault on the mass command."""
    path = tmp_path / "turning.toml"
    bs3 = (ROOT / "cosim/scenarios/bs-3.toml").read_text(encoding="utf-8")
    path.write_text(bs3 + EVENTS, encoding="utf-8")
    return path


def separate_run(scenario: Path, fmu_dir: Path, time: float, gain: float) -> dict:
    """The scenario with the event at ``time`` and the fault's gain ``gain``, through
    ``auv-cosim run``: its summary.json."""
    data = tomllib.loads(scenario.read_text(encoding="utf-8"))
    data["events"][0]["time"] = time
    data["faults"][0]["value"] = gain
    edited = scenario.with_name(f"turning_{time}_{gain}.toml")
    edited.write_text(tomli_w.dumps(data), encoding="utf-8")
    out = scenario.parent / edited.stem
    argv = ["run", str(edited), "--stop-time", "20", "--no-rrd", "--quiet", "--out", str(out)]
    assert main([*argv, "--fmu-dir", str(fmu_dir)]) == 0
    return json.loads((out / "summary.json").read_text(encoding="utf-8"))


@pytest.mark.cluster
@pytest.mark.slow
def test_event_time_and_fault_gain_factors_equal_separate_runs(
    scenario: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "2")
    rows = table(tmp_path / "out")
    assert len(rows) == 4 and {r["status"] for r in rows} == {"complete"}
    assert {(r["events.turn.time"], r["faults.fault-1.value"]) for r in rows} == {
        (t, g) for t in ("10.0", "15.0") for g in ("1.0", "0.5")
    }  # the integer 15 became the float time 15.0
    finals = set()
    for row in rows:
        time, gain = float(row["events.turn.time"]), float(row["faults.fault-1.value"])
        summary = separate_run(scenario, fmu_dir, time, gain)
        for metric in METRICS:
            value = summary["final_values"][metric.removeprefix("final.")]
            assert row[metric] == repr(value), (row["run"], metric)
        assert row["time_reached"] == repr(summary["time_reached"])
        finals.add(row["final.plant.yaw"])
    assert len(finals) == 4  # each factor changes the run


@pytest.mark.parametrize(
    ("factor", "expected"),
    [
        ("events.trun.time", "factor 'events.trun.time': the scenario has no event 'trun' "
         "(events: turn)"),
        ("faults.jam.value", "the scenario has no fault 'jam' (faults: fault-1)"),
        ("events.turn.speed", "expected events.turn.time, events.turn.ramp or one of the "
         "values it sets (events.turn.set.controller.yaw_setpoint)"),
        ("events.turn.set.plant.u_0", "(events.turn.set.controller.yaw_setpoint); to vary"),
        ("faults.fault-1.gain", "key one of start, stop, value, std, seed, steps, "
         "probability; got 'gain' (fault 'fault-1' is 'gain')"),
    ],
)  # fmt: skip
def test_a_bad_event_or_fault_factor_is_refused_naming_it(
    factor: str,
    expected: str,
    scenario: Path,
    fmu_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
) -> None:
    study = tmp_path / "bad.toml"
    study.write_text(f'scenario = "turning.toml"\n[grid]\n"{factor}" = [1.0]\n', "utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1
    assert expected in capsys.readouterr().err
    assert not out.exists()


def test_a_key_the_fault_s_kind_does_not_take_is_refused_by_the_scenario(
    scenario: Path, fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    study = tmp_path / "std.toml"
    study.write_text('scenario = "turning.toml"\n[grid]\n"faults.fault-1.std" = [0.1]\n', "utf-8")
    out = tmp_path / "out"
    assert main(["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]) == 1
    error = capsys.readouterr().err
    assert "the run with faults.fault-1.std = 0.1:" in error and "std" in error
    assert not out.exists()


def _heredoc(text: str, name: str, end: str) -> str:
    start = text.index(f"cat > {name} <<'{end}'\n") + len(f"cat > {name} <<'{end}'\n")
    return text[start : text.index(f"\n{end}\n", start) + 1]


@pytest.mark.cluster
@pytest.mark.slow
def test_the_documented_turn_study_answers_with_a_metric_of_the_turn(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """docs/studies.md's turn study asked how the peak thruster force depends on the
    turn, and answered with the initial sway transient's peak: the same 9.18 N for the
    turns to 0.25 and 0.5 rad. Run as documented (the README's turn.toml, the doc's
    commands), the peak grows with the turn at each turn time."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    studies = (ROOT / "docs" / "studies.md").read_text(encoding="utf-8")
    (tmp_path / "turn.toml").write_text(_heredoc(readme, "turn.toml", "EOF"), encoding="utf-8")
    block = studies[studies.index("\nsed 's/^v_0") : studies.index("auv-cosim sweep turn-study")]
    subprocess.run(["bash", "-euo", "pipefail", "-c", block], cwd=tmp_path, check=True)
    sweep(tmp_path / "turn-study.toml", tmp_path / "out", fmu_dir, "--workers", "2")
    peaks: dict[float, dict[float, float]] = {}
    for row in table(tmp_path / "out"):
        assert row["status"] == "complete", row
        setpoint = float(row["events.turn.set.controller.yaw_setpoint"])
        peaks.setdefault(float(row["events.turn.time"]), {})[setpoint] = float(
            row["peak_abs_tunnel_force_N"]
        )
    for at_time in peaks.values():
        ordered = [at_time[s] for s in sorted(at_time)]
        assert all(a < b for a, b in itertools.pairwise(ordered)), peaks


def test_a_grid_value_putting_an_event_after_the_stop_time_is_warned_of(
    scenario: Path, fmu_dir: Path
) -> None:
    """A study of 20 s over the turn's time [10, 30]: the runs with the turn at 30 s end
    before it, and the study planned them without a word; the value is named once, before
    any run, and the fault at 5 s, within every run, is not."""
    study = {"scenario": str(scenario), "grid": {"events.turn.time": [10.0, 30.0]},
             "stop_time": 20.0}  # fmt: skip
    said = _planned_warnings(study, fmu_dir, runs=2)
    assert [line for line in said if "stop time" in line] == [
        "events.turn.time = 30 s is after the stop time (20 s): the run ends before the "
        "event, which is never applied"
    ]


def test_a_grid_value_putting_an_event_between_the_points_of_h_warns_check_step(
    scenario: Path, fmu_dir: Path
) -> None:
    """check_step = true over the turn's time [10, 10.005]: the run at 10.005 s (a point
    of h/2, not of h = 0.01 s) gets a coupling error that `auv-cosim run --check-step`
    calls NOT TO BE TRUSTED, and the study put it in its table without a word. The value
    is named once, before any run; the turn at 10 s, on a point of all three runs, is
    not."""
    grid = {"events.turn.time": [10.0, 10.005]}
    study = {"scenario": str(scenario), "grid": grid, "stop_time": 20.0, "check_step": True}
    said = _planned_warnings(study, fmu_dir, runs=2)
    assert [line for line in said if "TRUSTED" in line] == [
        "check_step: the coupling errors of the run with events.turn.time = 10.005 are NOT "
        "TO BE TRUSTED: events.turn.time = 10.005 s applies at 10.01, 10.005 and 10.005 s "
        "in the runs at h, h/2 and h/4: its time moves with the step, an error Richardson "
        "extrapolation does not model (put it on a point of h)"
    ]


def test_a_check_step_doubt_every_grid_point_has_is_warned_of_once_without_values(
    scenario: Path, fmu_dir: Path
) -> None:
    """docs/coupling.md: a doubt every run of a check_step study has (the base scenario's
    turn at 10.005 s, between the points of h = 0.01 s, whatever the fault's gain) is
    warned of once, without a grid point's values."""
    text = scenario.read_text(encoding="utf-8").replace("time = 10.0\n", "time = 10.005\n")
    scenario.write_text(text, encoding="utf-8")
    grid = {"faults.fault-1.value": [1.0, 0.5]}
    study = {"scenario": str(scenario), "grid": grid, "stop_time": 20.0, "check_step": True}
    said = _planned_warnings(study, fmu_dir, runs=2)
    assert [line for line in said if "TRUSTED" in line] == [
        "check_step: the coupling errors are NOT TO BE TRUSTED: events.turn.time = 10.005 s "
        "applies at 10.01, 10.005 and 10.005 s in the runs at h, h/2 and h/4: its time moves "
        "with the step, an error Richardson extrapolation does not model (put it on a point "
        "of h)"
    ]


def test_a_grid_point_whose_current_a_leg_cannot_beat_is_warned_of(fmu_dir: Path) -> None:
    """A survey study over the current's north and east parts, each up to 1.2 m/s: either
    alone the vehicle (1.525 m/s through the water) beats on every leg, both together
    (1.7 m/s towards north-east) it cannot fly the legs south. The study checked each
    factor's values alone, on the other's start value, and planned it without a word; the
    line now names the grid point."""
    grid = {"plant.current_north": [0.0, 1.2], "plant.current_east": [0.0, 1.2]}
    said = _planned_warnings({"scenario": "survey", "grid": grid, "stop_time": 300.0}, fmu_dir, 4)
    lines = [line for line in said if "cannot be flown" in line]
    assert len(lines) == 1, lines
    assert "leg 3 (waypoint 3 -> 4, course 180 deg) cannot be flown" in lines[0]
    assert "plant.current_north = 1.2, plant.current_east = 1.2" in lines[0]


def test_a_check_step_study_resolves_each_grid_point_once(
    scenario: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """check_step = true: each grid point's scenario was resolved twice before any run
    (~50 ms each: its checks, then why its coupling error is not to be trusted), and so
    was the first sample's; now once each, with the base scenario's once: the same
    warnings."""
    import cosim.study.task as task

    resolved = []

    def counted(data: dict, where: str | None = None) -> object:
        resolved.append(where)
        return from_data(data, where=where)

    from_data = task.scenario_from_data
    monkeypatch.setattr(task, "scenario_from_data", counted)
    grid = {"events.turn.time": [10.0, 10.005]}
    study = {"scenario": str(scenario), "grid": grid, "stop_time": 20.0, "check_step": True,
             "random": {"n": 2, "faults.fault-1.value": {"uniform": [0.5, 1.0]}}}  # fmt: skip
    said = _planned_warnings(study, fmu_dir, runs=4)
    assert len([line for line in said if "TRUSTED" in line]) == 1, said
    assert len(resolved) == 1 + 2 + 1, resolved  # the base, two grid points, a sample


def _planned_warnings(study: dict[str, object], fmu_dir: Path, runs: int) -> list[str]:
    """The warnings a study's plan gives before any run (it planning ``runs`` runs), as
    the command warns of them once in its process."""
    import warnings

    from cosim.study.factors import resolve_factor
    from cosim.study.runner import _checked_plan
    from cosim.study.spec import study_from_dict
    from cosim.study.task import prepare

    spec = study_from_dict(study, "study")
    base, facts = prepare(str(study["scenario"]), spec.stop_time, fmu_dir,
                          check_step=spec.check_step)  # fmt: skip
    factors = {name: resolve_factor(name, facts) for name in spec.factors}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert len(_checked_plan(spec, base, factors, facts)) == runs
    return [str(w.message) for w in caught]
