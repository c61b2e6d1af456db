"""The adaptive communication step (algorithm = "adaptive"): step doubling with rollback
on the master tests' loop (an integrator under a sampled gain, x' = -k x in the limit)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from aliased_fmu import with_alias
from scenario_factory import X0, K, loop_toml

from cosim.engine import adaptive as adaptive_module
from cosim.engine import master
from cosim.engine.adaptive import MIN_LEVEL, grid_step
from cosim.engine.pacing import Pacer
from cosim.errors import FLAGS, CosimError
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import load_scenario, scenario_from_toml


def adaptive(
    tolerance: float, extra: str = "", multiple: int = 1, estimate: str = "doubling"
) -> str:
    text = loop_toml(algorithm="adaptive", stop_time=2.0, controller_multiple=multiple)
    return text.replace(
        "[coupling]",
        f'{extra}\n[coupling]\ntolerance = {tolerance}\nerror_estimate = "{estimate}"',
    )


def run(test_fmu_dir: Path, text: str) -> master.RunResult:
    return master.run(scenario_from_toml(text, base_dir=test_fmu_dir))


def limit_error(result: master.RunResult) -> float:
    """The largest distance of x from the continuous-time loop's x0 exp(-k t)."""
    return float(np.max(np.abs(result.column("plant.x") - X0 * np.exp(-K * result.times))))


def test_every_point_is_on_the_grid_and_the_run_ends_at_its_stop_time(
    test_fmu_dir: Path,
) -> None:
    result = run(test_fmu_dir, adaptive(1e-3))
    assert result.complete, result.error
    grid = grid_step(result.scenario.coupling)
    units = result.times / grid
    np.testing.assert_allclose(units, np.round(units), rtol=0, atol=1e-6)
    assert result.times[-1] == 2.0 and np.all(np.diff(result.times) > 0)
    taken = result.coupling
    assert taken["accepted_steps"] * 2 == result.rows - 1  # a row at each half and end
    # each attempt: one step of H and two of H / 2
    assert taken["do_steps"]["plant"] == 3 * (taken["accepted_steps"] + taken["rejected_steps"])


def test_a_tighter_tolerance_takes_smaller_steps_and_comes_closer_to_the_limit(
    test_fmu_dir: Path,
) -> None:
    loose, tight = run(test_fmu_dir, adaptive(1e-2)), run(test_fmu_dir, adaptive(1e-4))
    assert tight.coupling["accepted_steps"] > loose.coupling["accepted_steps"]
    assert limit_error(tight) < limit_error(loose) / 4
    # and closer than a fixed step taking as many steps as the tight run accepted
    steps = tight.coupling["accepted_steps"]
    fixed = loop_toml(stop_time=2.0, step=2.0 / steps)
    assert limit_error(tight) < limit_error(run(test_fmu_dir, fixed))


def test_steps_end_on_time_events_fault_boundaries_and_a_slow_instances_points(
    test_fmu_dir: Path,
) -> None:
    """A time event at 0.37 s, a fault from 0.55 to 0.8 s and the gain sampled every
    0.2 s (step multiple 2) all fall on points of the adaptive run."""
    extra = """
[[events]]
time = 0.37
set = { "controller.k" = 3.0 }

[[faults]]
kind = "bias"
target = "plant.u"
value = 0.1
start = 0.55
stop = 0.8
"""
    result = run(test_fmu_dir, adaptive(1e-3, extra, multiple=2))
    assert result.complete, result.error
    grid = grid_step(result.scenario.coupling)
    fired = result.events[0]["time"]
    assert fired == math.ceil(0.37 / grid) * grid and fired in result.times
    for t in (0.55, 0.8, *np.arange(0.0, 2.0, 0.2)):
        assert np.min(np.abs(result.times - t)) < grid
    u = result.column("controller.u")
    stepped = result.times[:-1][np.diff(u) != 0.0]  # the gain steps from its points only
    np.testing.assert_allclose(stepped / 0.2, np.round(stepped / 0.2), atol=1e-9)


@pytest.mark.parametrize(
    "extra",
    [
        '[[events]]\ntime = 5.0\nset = { "controller.k" = 3.0 }',
        '[[faults]]\nkind = "bias"\ntarget = "plant.u"\nvalue = 0.1\nstart = 3.0',
    ],
    ids=["event", "fault"],
)
def test_an_event_or_fault_after_the_stop_time_leaves_the_last_step_at_the_stop_time(
    test_fmu_dir: Path, extra: str
) -> None:
    """An event or fault timed after the stop time (valid: a shorter --stop-time keeps the
    file) does not stretch the last adaptive step past the stop time, where the FMUs refuse
    it: the run completes at its stop time."""
    result = run(test_fmu_dir, adaptive(1e-3, extra))
    assert result.complete, result.error
    assert result.times[-1] == 2.0 and np.all(result.times <= 2.0)


def test_a_rejected_step_leaves_no_event_behind(test_fmu_dir: Path) -> None:
    """A when event fires once, at an accepted point, however many attempts crossed it."""
    extra = '[[events]]\nwhen = "plant.x < 0.5"\nset = { "controller.k" = 0.0 }'
    result = run(test_fmu_dir, adaptive(1e-4, extra))
    assert result.coupling["rejected_steps"] >= 1
    assert len(result.events) == 1 and result.events[0]["time"] in result.times
    x = result.column("plant.x")
    assert x[-1] == pytest.approx(x[result.times > result.events[0]["time"]][1], rel=1e-2)


def test_a_paced_run_is_refused(test_fmu_dir: Path) -> None:
    scenario = scenario_from_toml(adaptive(1e-3), base_dir=test_fmu_dir)
    with pytest.raises(CosimError, match="needs a fixed step"):
        master.run(scenario, pacer=Pacer(scenario.coupling.step))


def test_the_grid_is_a_power_of_two_below_the_step() -> None:
    scenario_step = 0.01
    assert grid_step(type("C", (), {"step": scenario_step})()) == scenario_step / 2**MIN_LEVEL  # type: ignore[arg-type]


def test_steps_it_never_rejects_give_the_fixed_step_run_of_their_halves(
    test_fmu_dir: Path,
) -> None:
    """Every step rolled back and redone in halves: with a tolerance it always meets and
    its longest step its first, an adaptive run at 0.2 s is the fixed run at 0.1 s to the
    bit (the states, the extrapolation's history and an event restored exactly)."""
    extra = '[[events]]\ntime = 0.6\nset = { "controller.k" = 3.0 }'
    text = adaptive(0.99, extra).replace("step = 0.1", "step = 0.2\nmax_step = 0.2")
    halves = run(test_fmu_dir, text)
    fixed = run(
        test_fmu_dir, loop_toml(stop_time=2.0).replace("[coupling]", f"{extra}\n[coupling]")
    )
    assert halves.coupling["rejected_steps"] == 0
    np.testing.assert_array_equal(halves.times, fixed.times)
    np.testing.assert_array_equal(halves.values, fixed.values)


def test_the_error_estimate_is_within_a_factor_of_the_true_local_error(
    test_fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """On the loop, whose continuous-time limit is x0 exp(-k t): for every accepted step
    from (t, x) the estimate of the halves' local error is within a factor 1.5 of their
    true one, x(t + H) - x exp(-k H) (the held gain is first order: k^2 H^2 / 4 x)."""
    estimates: list[float] = []
    estimate, judge = adaptive_module._Control.estimate, adaptive_module._Control.judge

    def keep_estimate(self, big, halves):  # type: ignore[no-untyped-def]
        self.last_estimate = estimate(self, big, halves)[self.index["plant.x"]]
        return estimate(self, big, halves)

    def keep_accepted(self, err, units, wanted):  # type: ignore[no-untyped-def]
        accepted = judge(self, err, units, wanted)
        if accepted:
            estimates.append(self.last_estimate)
        return accepted

    monkeypatch.setattr(adaptive_module._Control, "estimate", keep_estimate)
    monkeypatch.setattr(adaptive_module._Control, "judge", keep_accepted)
    result = run(test_fmu_dir, adaptive(1e-3))
    assert result.coupling["order"] == 1 and len(estimates) == result.coupling["accepted_steps"]
    t, x = result.times[::2], result.column("plant.x")[::2]  # the accepted steps' ends
    true = x[1:] - x[:-1] * np.exp(-K * np.diff(t))
    ratio = np.asarray(estimates) / np.abs(true)
    assert len(ratio) >= 10 and np.all((ratio > 1 / 1.5) & (ratio < 1.5)), ratio


def test_the_step_follows_the_error_not_powers_of_two(test_fmu_dir: Path) -> None:
    """The loop's error falls with x: the steps grow smoothly (any length on the grid,
    by at most FAC_MAX at a time) and the accepted steps use most of the tolerance."""
    result = run(test_fmu_dir, adaptive(1e-3))
    steps = np.diff(result.times[::2])[:-1]  # the last one is cut at the stop time
    growth = steps[1:] / steps[:-1]
    assert np.all(growth <= adaptive_module.FAC_MAX + 1e-9)
    levels = np.log2(steps / grid_step(result.scenario.coupling))
    assert np.any(np.abs(levels - np.round(levels)) > 0.01)  # not only 2^j grid points
    assert result.coupling["rejected_steps"] <= result.coupling["accepted_steps"] // 10


@pytest.mark.parametrize("bad", ["0.0", "-1e-3", "1.0", "2.0", "nan", "inf"])
def test_a_bad_tolerance_is_refused_in_one_line_naming_it(test_fmu_dir: Path, bad: str) -> None:
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(adaptive(1e-3).replace("tolerance = 0.001", f"tolerance = {bad}"),
                           base_dir=test_fmu_dir)  # fmt: skip
    message = str(refused.value)
    assert "\n" not in message and "coupling.tolerance" in message, message


@pytest.mark.parametrize("estimate", ["extrapolation", "doubling"])
def test_a_step_an_instance_discards_is_retried_shorter(test_fmu_dir: Path, estimate: str) -> None:
    """FMI 2.0, 4.2.3: after a Discard that does not end the simulation "the master should
    retry with a shorter communication step"; the adaptive run does, and completes."""
    longest = 0.045  # s: the integrator refuses (Error logged, Discard) a longer step
    text = adaptive(1e-2, estimate=estimate).replace(
        f"x0 = {X0}", f"x0 = {X0}\nlongest_step = {longest}"
    )
    result = run(test_fmu_dir, text)
    assert result.complete, result.error
    assert result.coupling["discarded_steps"] >= 1
    assert result.coupling["rejected_steps"] >= result.coupling["discarded_steps"]
    assert np.max(np.diff(result.times)) <= longest
    assert limit_error(result) < 0.05 * X0


def test_a_discard_at_the_shortest_step_still_fails_the_run(test_fmu_dir: Path) -> None:
    text = adaptive(1e-2).replace(f"x0 = {X0}", f"x0 = {X0}\nlongest_step = 1e-9")
    result = run(test_fmu_dir, text)
    assert not result.complete
    assert "longer than longest_step" in (result.error or "")


def test_the_report_says_how_many_steps_missed_the_tolerance(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """At a tolerance of 1e-9 the loop's held input misses it even at the shortest step:
    every step was taken over the tolerance, and the report said "2048 adaptive steps of
    9.766e-05 to 9.766e-05 s (4 rejected, tolerance 1e-09)" as if it had been met. Now
    it counts the steps over the tolerance, and the kinks and shortest steps among them."""
    from cosim.runner import report, run_scenario

    text = adaptive(1e-9, estimate="extrapolation").replace("stop_time = 2.0", "stop_time = 0.2")
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True)
    taken = outcome.result.coupling
    over = taken["steps_over_tolerance"]
    assert over == taken["accepted_steps"] > 0 and taken["kinks"] == 0
    assert f"{over} over the tolerance (all at the shortest step" in report(outcome)


def test_a_digital_autopilot_samples_on_its_period_in_an_adaptive_run(
    fmu_paths: dict[str, Path],
) -> None:
    """lqr-1's autopilot samples every sample_period = 0.01 s (its LQR is designed for
    that), at the first doStep at or after each multiple: an adaptive step ends on each
    multiple, so every sample is taken there (within one grid point), not up to a step late."""
    scenario = load_scenario("lqr-1", fmu_dir=fmu_paths["AuvPlant"].parent).with_overrides(
        stop_time=0.5, algorithm="adaptive"
    )
    result = master.run(scenario, keep_rows=True)
    assert result.complete, result.error
    period, grid = 0.01, grid_step(scenario.coupling)
    command = result.column("controller.mass_position_cmd")
    sampled = result.times[:-1][np.diff(command) != 0.0]  # the points a sample was taken at
    late = sampled - np.floor(sampled / period + 1e-9) * period
    assert late.max() < grid, f"a sample {late.max():.2e} s after its time {sampled[late.argmax()]}"
    assert len(sampled) >= 45  # (a sample that leaves the command as it was is not seen)


def test_another_fmus_sample_period_sets_no_sample_times(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """Only our autopilot's ``sample_period`` is a sampling period: another tool's FMU with
    a variable of that name (0.3 here) had every adaptive step end on a multiple of it, as
    if it sampled there, which that FMU may not mean at all."""
    with_alias(
        test_fmu_dir / "CosimTestForeign.fmu", tmp_path / "Sampled.fmu", "k", "sample_period"
    )
    text = (
        'stop_time = 0.4\n[coupling]\nstep = 0.2\nalgorithm = "adaptive"\n'
        '[instances.f]\nfmu = "Sampled.fmu"\n[instances.f.start]\nsample_period = 0.3\n'
    )
    scenario = scenario_from_toml(text, base_dir=tmp_path)
    assert adaptive_module.sample_periods(scenario) == []


def test_our_autopilots_sample_period_sets_the_sample_times(fmu_dir: Path) -> None:
    scenario = load_scenario("lqr-1", fmu_dir=fmu_dir).with_overrides(algorithm="adaptive")
    assert adaptive_module.sample_periods(scenario) == [0.01]


@pytest.mark.slow
def test_a_sample_time_is_reached_in_even_steps_not_a_sliver(fmu_dir: Path) -> None:
    """Two vehicles, the LQR autopilot of one sampling every 0.01 s, the adaptive step:
    a step that would overshoot a sample time by less than a step was taken whole up to a
    grid point or so short of it, then a sliver (down to 9.8e-6 s, one grid point) to reach
    it, and the steps regrew from the sliver over several more: 3016 steps in 2 s, each
    of all four FMUs (47 s for 10 s on a loaded machine). The distance left is now split
    into two even steps: no step but the last shorter than a tenth of the median."""
    from two_vehicles import two_vehicles_toml

    text = two_vehicles_toml(stop_time=1.0)
    text = text.replace("step = 0.01\n", 'step = 0.01\nalgorithm = "adaptive"\n', 1)
    text = text.replace('heading_mode = "lqr"', 'heading_mode = "lqr"\nsample_period = 0.01')
    result = master.run(scenario_from_toml(text, fmu_dir=fmu_dir), keep_rows=True)
    assert result.complete, result.error
    steps = np.diff(result.times)[:-1]  # the last: shortened to the stop time
    median = float(np.median(steps))
    slivers = steps[steps < median / 10]
    assert len(slivers) == 0, f"{len(slivers)} steps under {median / 10:.2g} s: {slivers[:5]}"


def test_a_slow_instances_last_step_ends_at_a_stop_time_its_multiple_does_not_divide(
    fmu_paths: dict[str, Path],
) -> None:
    """The autopilot stepping every 3 steps of 10 ms under a stop time of 0.1 s: its last
    step, from 0.09 s, is shortened to the stop time as a fixed-step run shortens it, not
    asked to end at 0.12 s, which the FMU (as FMI 2.0 asks) refuses."""
    text = bs3_toml(0.1, 'algorithm = "adaptive"\nstep_multiples = { controller = 3 }')
    scenario = scenario_from_toml(text, "slow-last", fmu_dir=fmu_paths["AuvPlant"].parent)
    result = master.run(scenario, keep_rows=True)
    assert result.complete, result.error
    assert result.times[-1] == 0.1


def test_the_kinks_counted_are_steps_that_missed_the_tolerance(
    fmu_paths: dict[str, Path],
) -> None:
    """A kink is a step accepted over the tolerance: summary.json's ``kinks`` are among its
    ``steps_over_tolerance``, so the report's "N over the tolerance (K kinks, N - K at the
    shortest step)" never counts a negative number of steps at the shortest step. Steps
    shortened to reach the slow autopilot's points (step multiple 3) that met the tolerance
    were counted as kinks too: 51 over the tolerance, 60 kinks, "-9 at the shortest step"."""
    text = bs3_toml(1.0, 'algorithm = "adaptive"\nstep_multiples = { controller = 3 }')
    scenario = scenario_from_toml(text, "kinks", fmu_dir=fmu_paths["AuvPlant"].parent)
    result = master.run(scenario)
    assert result.complete, result.error
    taken = result.coupling
    assert 0 < taken["kinks"] <= taken["steps_over_tolerance"], taken


@pytest.mark.parametrize(
    ("kind", "keys", "what"),
    [("delay", "steps = 5", "delays by 5 of its deliveries"),
     ("noise", "std = 0.1", "draws once per delivery"),
     ("dropout", "probability = 0.3", "draws once per delivery")],
)  # fmt: skip
def test_a_fault_counting_deliveries_is_refused_under_the_adaptive_algorithm(
    test_fmu_dir: Path, kind: str, keys: str, what: str
) -> None:
    """A delay of 5 deliveries to plant.u was 5 steps of whatever length the error control
    chose (a step can be step / 1024): its delay in seconds, and a noise's or dropout's
    draws per second, followed the tolerance; the run went on without a word. Refused in
    one line naming the fault and the algorithm, from the file and from an override."""
    fault = f'[[faults]]\nkind = "{kind}"\ntarget = "plant.u"\n{keys}\n'
    expected = (
        rf"key 'faults\[0\]\.kind': fault 'fault-1' \({kind} on plant\.u\) {what}, one "
        r"per step of plant, and algorithm 'adaptive' chooses the steps"
    )
    with pytest.raises(ScenarioError, match=expected):
        scenario_from_toml(adaptive(1e-3, fault), base_dir=test_fmu_dir)
    fixed = scenario_from_toml(loop_toml(stop_time=2.0) + fault, base_dir=test_fmu_dir)
    with pytest.raises(ScenarioError, match=rf"^--algorithm adaptive: .*{expected}"):
        fixed.with_overrides(algorithm="adaptive", names=FLAGS)


def bs3_toml(stop_time: float, coupling: str) -> str:
    """bs-3's set-up (backstepping and tunnel thruster, v0 = -0.1 m/s) with the
    ``coupling`` lines given and its stop time."""
    return f"""
stop_time = {stop_time}
[coupling]
step = 0.01
order = ["controller", "plant"]
{coupling}
[instances.plant]
fmu = "AuvPlant"
[instances.plant.start]
variant = "lateral"
u_0 = 1.5
v_0 = -0.1
[instances.controller]
fmu = "AuvAutopilot"
[instances.controller.start]
heading_mode = "backstepping"
depth_mode = "off"
[connections]
remove = ["plant.fin_angle"]
"""
