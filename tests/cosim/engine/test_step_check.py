"""--check-step: the estimated coupling error against the loop's known limit."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from scenario_factory import X0, K, loop_toml

from cosim.engine import master
from cosim.engine.step_check import check_step, doubts, summary_line
from cosim.errors import CosimError
from cosim.runner import run_scenario
from cosim.scenario.spec import scenario_from_toml


def test_the_estimated_error_is_within_a_factor_two_of_the_true_one(test_fmu_dir: Path) -> None:
    """The loop x' = -k x (sampled gain) at h = 0.1 s: the error the check estimates for
    x(2 s) is within a factor 2 of its distance from x0 exp(-2 k)."""
    scenario = scenario_from_toml(loop_toml(stop_time=2.0), base_dir=test_fmu_dir)
    result = master.run(scenario)
    check = check_step(scenario, {}, result.final)
    x = check["final_values"]["plant.x"]
    true_error = x["value"] - X0 * math.exp(-K * 2.0)
    assert 0.5 < x["error"] / true_error < 2.0
    assert check["steps_s"] == [0.1, 0.05, 0.025]
    assert 0.8 < x["order"] < 1.2  # held inputs: first order
    assert "plant.x" in summary_line(check) or "largest final-value error" in summary_line(check)


DELAY = '[[faults]]\nkind = "delay"\ntarget = "plant.u"\nsteps = 4\n'


def test_a_delay_fault_is_checked_as_the_same_delay_in_seconds(test_fmu_dir: Path) -> None:
    """A delay of 4 steps (0.4 s at h = 0.1 s) was 0.2 s and 0.1 s in the runs at h/2
    and h/4: the estimate was the change of the delay, +70 % of a figure. Now it is
    within a factor 2 of the distance from a run at h/32 with the same 0.4 s."""
    scenario = scenario_from_toml(loop_toml(stop_time=2.0) + DELAY, base_dir=test_fmu_dir)
    check = check_step(scenario, {}, master.run(scenario).final)
    x = check["final_values"]["plant.x"]
    fine_text = loop_toml(stop_time=2.0, step=0.1 / 32) + DELAY.replace("4", str(4 * 32))
    fine = master.run(scenario_from_toml(fine_text, base_dir=test_fmu_dir))
    true_error = x["value"] - fine.column("plant.x")[-1]
    assert 0.5 < x["error"] / true_error < 2.0, (x, true_error)


@pytest.mark.parametrize("kind", ['noise"\nstd = 0.1', 'dropout"\nprobability = 0.5'])
def test_a_fault_drawing_at_every_exchange_is_not_checked(test_fmu_dir: Path, kind) -> None:
    fault = f'[[faults]]\nname = "drawn"\nkind = "{kind}\ntarget = "plant.u"\n'
    scenario = scenario_from_toml(loop_toml() + fault, base_dir=test_fmu_dir)
    with pytest.raises(CosimError, match=r"fault 'drawn' \((noise|dropout)\) draws anew"):
        check_step(scenario, {}, master.run(scenario).final)


def test_an_adaptive_run_is_not_checked(test_fmu_dir: Path) -> None:
    scenario = scenario_from_toml(loop_toml(algorithm="adaptive"), base_dir=test_fmu_dir)
    with pytest.raises(CosimError, match="controls its error itself"):
        check_step(scenario, {}, master.run(scenario).final)


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        (loop_toml(algorithm="adaptive"), "controls its error itself"),
        (loop_toml() + '[[faults]]\nname = "drawn"\nkind = "noise"\nstd = 0.1\n'
         'target = "plant.u"\n', r"fault 'drawn' \(noise\) draws anew"),
    ],
)  # fmt: skip
def test_a_run_that_cannot_be_checked_is_refused_before_its_first_step(
    test_fmu_dir: Path, tmp_path: Path, text: str, reason: str
) -> None:
    """docs/coupling.md says an adaptive run or a noise fault is refused by --check-step,
    but the run went through to its stop time and only then said "coupling error not
    estimated", exit code 0: now it is refused at once, naming the option, and leaves no
    run folder."""
    from cosim.api import run

    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    with pytest.raises(CosimError, match=rf"^--check-step: .*{reason}"):
        run_scenario(scenario, tmp_path / "run", no_rrd=True, check_step=True)
    assert not (tmp_path / "run").exists()
    with pytest.raises(CosimError, match=rf"^check_step=True: .*{reason}"):
        run(scenario, check_step=True)


def test_the_run_reports_the_estimate_in_its_summary_and_last_line(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    scenario = scenario_from_toml(loop_toml(), base_dir=test_fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True, check_step=True)
    check = outcome.result.coupling["check_step"]
    assert set(check) >= {"steps_s", "order", "key_figures", "final_values"}
    summary = (tmp_path / "run" / "summary.json").read_text()
    assert '"check_step"' in summary


def test_the_largest_final_value_error_is_printed_with_its_unit() -> None:
    """The report's last line read "largest final-value error controller.tunnel_force
    +0.0058", the one figure of the line without a unit (the key figures carry theirs in
    their names)."""
    entry = {"value": 1.0, "half_step": 1.0, "quarter_step": 1.0, "order": 2.0,
             "order_observed": True, "limit": 0.99, "error": 0.0058,
             "relative_error": 0.006}  # fmt: skip
    worst = {"column": "controller.tunnel_force", "unit": "N", **entry}
    check = {"steps_s": [0.01, 0.005, 0.0025], "order": 2.0, "key_figures": {},
             "largest_final_error": worst}  # fmt: skip
    assert summary_line(check).endswith(
        "largest final-value error controller.tunnel_force +0.0058 N"
    )


def test_the_largest_final_value_error_names_its_unit_in_the_summary(
    test_fmu_dir: Path,
) -> None:
    scenario = scenario_from_toml(loop_toml(stop_time=2.0), base_dir=test_fmu_dir)
    check = check_step(scenario, {}, master.run(scenario).final)
    worst = check["largest_final_error"]
    variable = worst["column"].partition(".")[2]
    instance = scenario.instances[worst["column"].partition(".")[0]]
    assert worst["unit"] == (instance.interface.variables[variable].unit or "")


def _gain_event(time: float) -> str:
    return f'[[events]]\nname = "gain"\ntime = {time}\nset = {{ "controller.k" = 0.5 }}\n'


def test_an_event_between_the_checked_runs_points_makes_the_estimate_untrusted(
    test_fmu_dir: Path,
) -> None:
    """An event at 0.33 s applies at 0.4 s at h = 0.1 s but at 0.35 s at h/2 and h/4:
    the runs differ by where the event lands, an error of O(h) with no order of its own.
    The check printed its estimate as any other, with an order of 2.4 observed on a
    coupling of order 1 (held inputs) and 22 % short of the distance from a run at h/32
    (event at 0.33125 s). Now it says the estimate is not to be trusted, naming the
    event and the times it applies at."""
    text = loop_toml(stop_time=2.0) + _gain_event(0.33)
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    check = check_step(scenario, {}, master.run(scenario).final)
    assert check["doubts"] == [
        "events.gain.time = 0.33 s applies at 0.4, 0.35 and 0.35 s in the runs at h, h/2 "
        "and h/4: its time moves with the step, an error Richardson extrapolation does "
        "not model (put it on a point of h)"
    ]
    assert summary_line(check).startswith(
        "  coupling error NOT TO BE TRUSTED (events.gain.time = 0.33 s applies at 0.4, "
    )


def test_only_what_lies_on_a_point_of_h_leaves_the_estimate_trusted(test_fmu_dir: Path) -> None:
    """An event at 0.3 s and a fault from 0.5 s to 1.2 s lie on points of all three runs:
    no doubt. A fault from 0.325 s, a point of h/4 but not of h, starts at 0.4, 0.35 and
    0.325 s: a doubt naming it; and an event on a condition always."""
    fault = '[[faults]]\nname = "off"\nkind = "bias"\nvalue = 0.1\ntarget = "plant.u"\n'
    on_points = loop_toml(stop_time=2.0) + _gain_event(0.3) + fault + "start = 0.5\nstop = 1.2\n"
    scenario = scenario_from_toml(on_points, base_dir=test_fmu_dir)
    assert check_step(scenario, {}, master.run(scenario).final)["doubts"] == []
    between = loop_toml(stop_time=2.0) + fault + "start = 0.325\n"
    between += '[[events]]\nname = "low"\nwhen = "plant.x < 0.5"\nset = { "controller.k" = 1.0 }\n'
    scenario = scenario_from_toml(between, base_dir=test_fmu_dir)
    found = check_step(scenario, {}, master.run(scenario).final)["doubts"]
    assert [line.split(" ", 1)[0] for line in found] == ["events.low", "faults.off.start"]
    assert "applies at 0.4, 0.35 and 0.325 s" in found[1]


def test_an_event_on_a_slow_instance_counts_that_instances_points(test_fmu_dir: Path) -> None:
    """The gain steps every 3 h: an event at 0.5 s setting its k (a point of h = 0.1 s)
    reaches it at its own next points, 0.6, 0.6 and 0.525 s in the runs at h, h/2 and h/4:
    the runs differ by where the jump lands, and the check said nothing of it. A fault
    from 0.5 s on the plant (every h) and an event at 0.6 s (a point of 3 h) stay
    trusted."""
    fault = '[[faults]]\nname = "off"\nkind = "bias"\nvalue = 0.1\ntarget = "plant.u"\n'
    text = loop_toml(stop_time=2.0, controller_multiple=3) + fault + "start = 0.5\n"
    on_points = scenario_from_toml(text + _gain_event(0.6), base_dir=test_fmu_dir)
    assert doubts(on_points) == []
    between = scenario_from_toml(text + _gain_event(0.5), base_dir=test_fmu_dir)
    assert doubts(between) == [
        "events.gain.time = 0.5 s applies at 0.6, 0.6 and 0.525 s in the runs at h, h/2 "
        "and h/4 (controller steps every 3 h): its time moves with the step, an error "
        "Richardson extrapolation does not model (put it on a point of 3 h)"
    ]


def test_an_event_off_h_on_a_slow_instance_is_advised_onto_that_instances_points(
    test_fmu_dir: Path,
) -> None:
    """The gain steps every 3 h: an event at 0.33 s setting its k, off the points of h
    too, was reported at the points of h (0.4, 0.35 and 0.35 s) and advised onto "a point
    of h", where it would still move (0.5 s reaches the gain at 0.6, 0.6 and 0.525 s). The
    line names the slow instance's points, where it lands, and advises onto them."""
    text = loop_toml(stop_time=2.0, controller_multiple=3) + _gain_event(0.33)
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    assert doubts(scenario) == [
        "events.gain.time = 0.33 s applies at 0.6, 0.45 and 0.375 s in the runs at h, h/2 "
        "and h/4 (controller steps every 3 h): its time moves with the step, an error "
        "Richardson extrapolation does not model (put it on a point of 3 h)"
    ]


def test_the_line_says_when_the_order_was_assumed_or_the_runs_agree_to_rounding(
    test_fmu_dir: Path,
) -> None:
    """The line printed "order 1" as if observed where it was the coupling's nominal
    order, no value converging monotonically (an event at 0.37 s applying at 0.4, 0.4
    and 0.375 s), and where the three runs gave the same values (a gain of 0: x holds
    x0), leaving no error and no order to see. Now it says which."""
    text = loop_toml(stop_time=2.0) + _gain_event(0.37)
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    check = check_step(scenario, {}, master.run(scenario).final)
    assert not check["order_observed"] and not check["within_rounding"]
    assert "(Richardson from h = 0.1, 0.05, 0.025 s, order 1 assumed, none observed)" in (
        summary_line(check)
    )
    text = loop_toml(stop_time=2.0).replace("k = 2.0", "k = 0.0")
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    check = check_step(scenario, {}, master.run(scenario).final)
    assert check["within_rounding"]
    assert "the three runs agree to rounding: no error to see" in summary_line(check)
    observed = scenario_from_toml(loop_toml(stop_time=2.0), base_dir=test_fmu_dir)
    line = summary_line(check_step(observed, {}, master.run(observed).final))
    assert "s, order 1" in line and "assumed" not in line and "rounding" not in line
