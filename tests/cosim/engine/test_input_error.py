"""The adaptive step's extrapolation error estimate (error_estimate = "extrapolation") on
the master tests' loop (an integrator under a sampled gain, x' = -k x in the limit)."""

from __future__ import annotations

import functools
import itertools
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from scenario_factory import K, loop_toml

from cosim.engine import adaptive as adaptive_module
from cosim.engine import master
from cosim.engine.extrapolation import InputRates
from cosim.engine.input_error import InputError
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import scenario_from_toml


def adaptive(tolerance: float, estimate: str = "extrapolation") -> str:
    text = loop_toml(algorithm="adaptive", stop_time=2.0)
    return text.replace(
        "[coupling]", f'[coupling]\ntolerance = {tolerance}\nerror_estimate = "{estimate}"'
    )


def run(test_fmu_dir: Path, text: str) -> master.RunResult:
    return master.run(scenario_from_toml(text, base_dir=test_fmu_dir))


def test_the_estimate_is_the_true_extrapolation_error_of_the_step(
    test_fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The gain holds x over each step (the loop's FMUs take no input derivatives): for
    every accepted step from (t, x) the estimated error of that held input is within a
    factor 1.5 of the true one, |x - x exp(-k H)| (the continuous-time loop's x at t + H
    from the same x)."""
    seen: list[float] = []
    scaled, judge = adaptive_module._Control.scaled, adaptive_module._Control.judge

    def keep_estimate(self, values, sources, du):  # type: ignore[no-untyped-def]
        x = self.index["plant.x"]
        self.last_estimate = float(du[list(sources).index(x)])
        return scaled(self, values, sources, du)

    def keep_accepted(self, err, units, wanted):  # type: ignore[no-untyped-def]
        accepted = judge(self, err, units, wanted)
        if accepted:
            seen.append(self.last_estimate)
        return accepted

    monkeypatch.setattr(adaptive_module._Control, "scaled", keep_estimate)
    monkeypatch.setattr(adaptive_module._Control, "judge", keep_accepted)
    result = run(test_fmu_dir, adaptive(1e-3))
    taken = result.coupling
    assert taken["error_estimate"] == "extrapolation"
    assert len(seen) == taken["accepted_steps"] == result.rows - 1
    t, x = result.times, result.column("plant.x")
    true = np.abs(x[:-1] * (1.0 - np.exp(-K * np.diff(t))))
    ratio = np.asarray(seen) / true
    assert len(ratio) >= 10 and np.all((ratio > 1 / 1.5) & (ratio < 1.5)), ratio


def test_a_steps_err_is_its_inputs_error_times_its_length_over_the_step(
    test_fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every attempt is judged on the error it leaves in the states its inputs drive: the
    inputs' scaled error times H / step (1 at the scenario's step), not the inputs' error
    alone, so steps of different lengths are held to the same local error."""
    judged: list[tuple[float, float, int]] = []
    scaled, judge = adaptive_module._Control.scaled, adaptive_module._Control.judge

    def keep_scaled(self, values, sources, du):  # type: ignore[no-untyped-def]
        self.inputs_error = scaled(self, values, sources, du)
        return self.inputs_error

    def keep_judged(self, err, units, wanted):  # type: ignore[no-untyped-def]
        judged.append((self.inputs_error, err, units))
        return judge(self, err, units, wanted)

    monkeypatch.setattr(adaptive_module._Control, "scaled", keep_scaled)
    monkeypatch.setattr(adaptive_module._Control, "judge", keep_judged)
    result = run(test_fmu_dir, adaptive(1e-3))
    inputs_error, err, units = (np.asarray(column) for column in zip(*judged, strict=True))
    per_step = 2**adaptive_module.MIN_LEVEL  # grid points in the scenario's step
    assert len(np.unique(units)) > 3 and np.any(units != per_step), units
    assert np.allclose(err, inputs_error * units / per_step, rtol=1e-12, atol=0.0)
    assert result.coupling["accepted_steps"] == result.rows - 1


def test_err_is_one_order_above_the_extrapolations_error() -> None:
    """Quadratic extrapolation: the inputs' error is O(H^3), err (times H) O(H^4)."""
    assert extrapolation_control().k == 4


def test_one_do_step_per_attempt_and_a_tighter_tolerance_comes_closer_to_the_limit(
    test_fmu_dir: Path,
) -> None:
    """Each attempt costs each instance one doStep (rejected ones too), and the run's
    error against x0 exp(-k t) falls with the tolerance."""
    loose, tight = run(test_fmu_dir, adaptive(1e-2)), run(test_fmu_dir, adaptive(1e-4))
    for result in (loose, tight):
        taken = result.coupling
        attempts = taken["accepted_steps"] + taken["rejected_steps"]
        assert taken["do_steps"] == {"plant": attempts, "controller": attempts}

    def error(result: master.RunResult) -> float:
        return float(np.max(np.abs(result.column("plant.x") - np.exp(-K * result.times))))

    assert tight.coupling["accepted_steps"] > loose.coupling["accepted_steps"]
    assert error(tight) < error(loose) / 4


def test_an_accepted_step_grows_the_next_by_at_most_ratio_max(test_fmu_dir: Path) -> None:
    """The extrapolation's points stay evenly spaced: no step is more than RATIO_MAX
    times the step before it plus a grid point."""
    result = run(test_fmu_dir, adaptive(1e-3))
    steps = np.diff(result.times)[:-1]  # the last one is cut at the stop time
    grid = adaptive_module.grid_step(result.scenario.coupling)
    allowed = adaptive_module.RATIO_MAX * (steps[:-1] + grid)
    assert np.all(steps[1:] <= allowed + 1e-12)


@pytest.mark.parametrize("bad", ['"halving"', "1", '""'])
def test_a_bad_error_estimate_is_refused_in_one_line_naming_it(
    test_fmu_dir: Path, bad: str
) -> None:
    text = adaptive(1e-3).replace('error_estimate = "extrapolation"', f"error_estimate = {bad}")
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, base_dir=test_fmu_dir)
    message = str(refused.value)
    assert "\n" not in message and "coupling.error_estimate" in message, message


def test_an_error_estimate_without_the_adaptive_algorithm_is_refused(test_fmu_dir: Path) -> None:
    text = loop_toml().replace("[coupling]", '[coupling]\nerror_estimate = "doubling"')
    with pytest.raises(ScenarioError, match=r"coupling\.error_estimate.*adaptive"):
        scenario_from_toml(text, base_dir=test_fmu_dir)


def test_the_default_estimate_is_the_extrapolation(test_fmu_dir: Path) -> None:
    text = loop_toml(algorithm="adaptive")
    assert scenario_from_toml(text, base_dir=test_fmu_dir).coupling.error_estimate == (
        "extrapolation"
    )


class FakeFmu:
    """Takes the input derivatives (through ``fmu.dll``, as the master calls the C
    function) and does nothing with them."""

    component = None

    def __init__(self) -> None:
        self.dll = self

    def __getitem__(self, name: str) -> Any:  # a ctypes library's function by name
        return functools.partial(getattr(self, name))

    def fmi2SetRealInputDerivatives(self, *args: object) -> int:
        return 0  # fmi2OK


class FakeSlave:
    """The parts of a Slave the estimator reads: one Real input from z[0]."""

    def __init__(self, name: str, sources: list[int], rates: InputRates | None) -> None:
        self.name, self.input_rates = name, rates
        self.input_sources = np.asarray(sources, dtype=np.intp)
        self.n_inputs = len(sources)
        self.inputs = np.zeros(self.n_inputs)


def quadratic_estimate(times: list[float], end: float, sign: float = 1.0) -> tuple[float, float]:
    """(estimated, true) error at ``end`` of ``sign`` sin(t) extrapolated quadratically
    from its values at ``times`` (the last three: the polynomial through them, exactly)."""
    grid = 1e-4
    receiver = FakeSlave("receiver", [0], InputRates(FakeFmu(), [1], order=2))
    source = FakeSlave("source", [], None)
    order: list[Any] = [receiver, source]  # the source after: its value at the end is known
    estimator = InputError(order, {"source.y": 0}, jacobi=False, timeline=None, grid=grid)
    z = np.zeros(1)
    points = [round(t / grid) for t in [*times, end]]
    for n, following in itertools.pairwise(points):
        z[0] = sign * np.sin(n * grid)
        receiver.inputs[:] = z[0]
        assert receiver.input_rates is not None
        receiver.input_rates.send(receiver.inputs, n * grid, epoch=0)
        estimator.took(receiver, n, following - n)  # type: ignore[arg-type]
    z[0] = sign * np.sin(end)
    sources, du = estimator.errors(order, z, points[-1], k=3)
    assert list(sources) == [0]
    fit = np.polyfit(times[-3:], sign * np.sin(times[-3:]), 2)
    return float(du[0]), abs(float(np.polyval(fit, end)) - sign * np.sin(end))


@pytest.mark.parametrize("times", [[0.0, 0.1, 0.2, 0.3], [0.0, 0.05, 0.2, 0.25, 0.45]])
def test_the_estimate_is_the_quadratic_extrapolations_error_at_the_steps_end(
    times: list[float],
) -> None:
    """A known input, sin(t), extrapolated through the last three points (any spacing):
    the estimate is the polynomial's distance from sin at the step's end, and it falls
    as the cube of the step (the extrapolation's order) when every spacing halves."""
    step = 0.1
    estimated, true = quadratic_estimate(times, times[-1] + step)
    assert estimated == pytest.approx(true, rel=1e-9)
    half = [t / 2 for t in times]
    finer, _ = quadratic_estimate(half, half[-1] + step / 2)
    assert 6.0 < estimated / finer < 10.0


def test_an_extrapolation_below_the_input_counts_as_much_as_one_above() -> None:
    """The estimate is the distance |u_extrapolated - u|: mirroring the input (-sin for
    sin) mirrors the polynomial too, so the estimate is the same, never negative (a
    signed error below the input would pass any tolerance through the step control's
    max)."""
    times = [0.0, 0.1, 0.2, 0.3]
    above, true = quadratic_estimate(times, 0.4)
    below, _ = quadratic_estimate(times, 0.4, sign=-1.0)
    assert below == pytest.approx(above, rel=1e-9) and below == pytest.approx(true, rel=1e-9)


def lagged_estimate(times: list[float], next_step: float) -> tuple[float, float]:
    """(estimated, true) error of sin(t) extrapolated quadratically over the step from
    times[-2] to times[-1], for an input whose source steps before its instance: known
    only when the instance takes its inputs at times[-1], and judged at the end of the
    next step (``next_step`` s long)."""
    grid = 1e-4
    receiver = FakeSlave("receiver", [0], InputRates(FakeFmu(), [1], order=2))
    source = FakeSlave("source", [], None)
    order: list[Any] = [source, receiver]  # the source first: its end value comes later
    estimator = InputError(order, {"source.y": 0}, jacobi=False, timeline=None, grid=grid)
    z = np.zeros(1)
    points = [round(t / grid) for t in times]
    points.append(points[-1] + round(next_step / grid))
    for n, following in itertools.pairwise(points):
        z[0] = np.sin(n * grid)
        receiver.inputs[:] = z[0]
        assert receiver.input_rates is not None
        receiver.input_rates.send(receiver.inputs, n * grid, epoch=0)
        estimator.took(receiver, n, following - n)  # type: ignore[arg-type]
    sources, du = estimator.errors(order, z, points[-1], k=3)
    assert list(sources) == [0], "the lagged input's error is not judged"
    fit = np.polyfit(times[-4:-1], np.sin(times[-4:-1]), 2)
    return float(du[0]), abs(float(np.polyval(fit, times[-1])) - np.sin(times[-1]))


def test_an_input_known_a_step_late_is_judged_in_the_next_step_scaled_to_it() -> None:
    """Under Gauss-Seidel an input whose source steps first is known only after the step:
    its extrapolation error counts in the next step's judgement, as it is for a step of
    the same length and scaled by (H_next / H)^k for a shorter one (k = 3: quadratic)."""
    times = [0.0, 0.1, 0.2, 0.3]
    estimated, true = lagged_estimate(times, 0.1)
    assert true > 0.0 and estimated == pytest.approx(true, rel=1e-9)
    halved, _ = lagged_estimate(times, 0.05)
    assert halved == pytest.approx(true / 8.0, rel=1e-9)


def extrapolation_control() -> adaptive_module._Control:
    """The step control of an adaptive run with quadratic extrapolation (k = 3), on a
    60 s run at a 10 ms first step, without instances to read."""
    coupling = SimpleNamespace(
        tolerance=1e-3, error_estimate="extrapolation", step=0.01, max_step=None,
        extrapolation_order=2,
    )  # fmt: skip
    scenario = SimpleNamespace(coupling=coupling, stop_time=60.0, instances={})
    receiver = SimpleNamespace(n_inputs=1, input_rates=SimpleNamespace(order=2), k=1)
    return adaptive_module._Control(scenario, [receiver], {}, 0, None)  # type: ignore[arg-type]


def take(control: adaptive_module._Control, err: float) -> tuple[bool, int]:
    """(accepted, grid points) of one attempt with error ``err`` from point 0."""
    units, wanted = control.units(0)
    return control.judge(err, units, wanted), units


def test_a_kink_is_stepped_across_without_collapsing_the_step() -> None:
    """An input's slope jumps inside a step (a saturation, a boundary layer): the step's
    error is far above the smooth steps' before it and falls only like H when the step
    shortens. The step is accepted as it is and its successor is as long: no rejection,
    no collapse to the grid (the smooth steps' error, 0.2, is one they grow at)."""
    control = extrapolation_control()
    for _ in range(10):
        accepted, before = take(control, 0.2)
        assert accepted
    accepted, across = take(control, 50.0)
    assert accepted and across >= before
    accepted, after = take(control, 0.2)
    assert accepted and after >= across
    assert control.rejected == 0 and control.kinks == 1


def test_an_error_that_grows_smoothly_past_the_tolerance_is_still_rejected() -> None:
    """The kink rule does not excuse an error that rose within KINK of the last smooth
    step's: that step is retried shorter."""
    control = extrapolation_control()
    take(control, 0.5)
    accepted, units = take(control, 0.5 * adaptive_module.KINK / 2)
    assert not accepted and control.rejected == 1 and control.kinks == 0
    accepted, retried = take(control, 0.5)
    assert accepted and retried < units


def test_steps_grow_by_at_most_ratio_max_from_the_smallest() -> None:
    """From the smallest step, with an error far below the tolerance, each step is at most
    RATIO_MAX times the last plus a grid point (the fraction carried on: the extrapolation's
    points stay evenly spaced), and the steps still grow, a fraction of a point at a time."""
    control = extrapolation_control()
    control.next = 1.0
    steps = np.asarray([take(control, 1e-6)[1] for _ in range(60)])
    allowed = adaptive_module.RATIO_MAX * (steps[:-1] + 1)
    assert np.all(steps[1:] < allowed), steps
    assert np.all(steps[1:] >= steps[:-1]) and steps[-1] > 100
