"""Events and faults through the master, on the test FMUs (tests/fmus) with known signals.

The open loop: the integrator's input u is unconnected (held at 1, or driven by events),
so plant.x ramps; the sampled gain takes controller.x <- plant.x through the connection
and outputs u = -k x from the value delivered to it. With k = 2 (a power of two) the
delivered value is exactly -controller.u / k, one row later under Gauss-Seidel (the
controller steps first at t_n, from the plant.x of row n; its output is in row n + 1).
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from types import FrameType

import numpy as np
import pytest
from scenario_factory import K, loop_toml

from cosim.engine import master, timeline
from cosim.scenario.spec import Scenario, scenario_from_toml


def open_loop(fmu_dir: Path, extra: str, **kwargs) -> Scenario:
    text = loop_toml(plant_start="u = 1.0", **kwargs)
    text += '[connections]\nremove = ["plant.u"]\n' + extra
    return scenario_from_toml(text, "open.toml", base_dir=fmu_dir, fmu_dir=fmu_dir)


def delivered(fmu_dir: Path, fault: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(gathered plant.x at t_0..t_9, the value the fault delivered then, its flag column)."""
    result = master.run(
        open_loop(fmu_dir, f'[[faults]]\nname = "f"\ntarget = "controller.x"\n{fault}')
    )
    assert result.complete, result.error
    x, u = result.column("plant.x"), result.column("controller.u")
    return x[:-1], -u[1:] / K, result.column("fault.f")


def test_gain_and_bias_are_exact_while_active(test_fmu_dir: Path) -> None:
    x, got, flag = delivered(test_fmu_dir, 'kind = "gain"\nvalue = 3.0\nstart = 0.3\nstop = 0.7')
    active = np.zeros(10, dtype=bool)
    active[3:7] = True  # t = 0.3 .. 0.6
    assert np.array_equal(got, np.where(active, x * 3.0, x))
    assert np.array_equal(flag[:-1], active.astype(float))
    x, got, _ = delivered(test_fmu_dir, 'kind = "bias"\nvalue = -0.25\nstart = 0.3')
    assert np.array_equal(got, np.where(np.arange(10) >= 3, x + -0.25, x))


def test_stuck_holds_the_value_delivered_before_it_started(test_fmu_dir: Path) -> None:
    x, got, _ = delivered(test_fmu_dir, 'kind = "stuck"\nstart = 0.3\nstop = 0.7')
    assert np.array_equal(got[3:7], [x[2]] * 4)
    assert np.array_equal(got[:3], x[:3]) and np.array_equal(got[7:], x[7:])


def test_delay_delivers_the_value_of_k_steps_before(test_fmu_dir: Path) -> None:
    x, got, _ = delivered(test_fmu_dir, 'kind = "delay"\nsteps = 2\nstart = 0.1')
    assert got[0] == x[0]
    assert np.array_equal(got[2:], x[:-2])
    assert got[1] == x[0]  # fewer than k values gathered yet: the first one


@pytest.mark.parametrize(
    "kind", ['kind = "noise"\nstd = 0.1', 'kind = "dropout"\nprobability = 0.5']
)
def test_noise_and_dropout_are_reproducible_with_their_seed(test_fmu_dir: Path, kind: str) -> None:
    x, first, _ = delivered(test_fmu_dir, f"{kind}\nseed = 7\nstart = 0.2")
    _, again, _ = delivered(test_fmu_dir, f"{kind}\nseed = 7\nstart = 0.2")
    _, other, _ = delivered(test_fmu_dir, f"{kind}\nseed = 8\nstart = 0.2")
    assert np.array_equal(first, again) and not np.array_equal(first, other)
    assert np.array_equal(first[:2], x[:2])
    rng = np.random.default_rng(7)  # the specified draws, one per delivery while active
    expected, last = list(x[:2]), x[1]
    for value in x[2:]:
        if "noise" in kind:
            expected.append(value + rng.normal(0.0, 0.1))
        else:
            expected.append(last if rng.random() < 0.5 else value)
        last = expected[-1]
    assert np.array_equal(first, expected)


def k_event(time: float) -> str:
    return f'[[events]]\nname = "k"\ntime = {time}\nset = {{ "controller.k" = 4.0 }}\n'


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_a_time_event_acts_at_the_first_point_at_or_after_its_time(
    test_fmu_dir: Path, algorithm: str
) -> None:
    result = master.run(open_loop(test_fmu_dir, k_event(0.25), algorithm=algorithm))
    assert result.events == [
        {"name": "k", "time": pytest.approx(0.3), "set": {"controller.k": 4.0}}
    ]
    x, u = result.column("plant.x"), result.column("controller.u")
    # both algorithms: the controller steps from t_3 = 0.3 with the new gain, from the
    # plant.x of row n (the plant does not depend on it here); its output is in row n + 1
    assert np.array_equal(-u[1:] / x[:-1], [K] * 3 + [4.0] * 7)


def test_with_step_multiples_an_instance_not_due_sees_the_event_when_it_next_steps(
    test_fmu_dir: Path,
) -> None:
    # controller every 3 steps (due at n = 0, 3, 6, 9); the event fires at t_4 = 0.4
    result = master.run(open_loop(test_fmu_dir, k_event(0.35), controller_multiple=3))
    assert [e["time"] for e in result.events] == [pytest.approx(0.4)]
    x, u = result.column("plant.x"), result.column("controller.u")
    assert u[4] == u[5] == u[6] == -K * x[3]  # held, computed before the event
    assert u[7] == -4.0 * x[6]  # its next step, at t_6, uses the new gain


def series_loop(fmu_dir: Path, tmp_path: Path, profile: str, extra: str) -> Scenario:
    """The open loop with plant.u from the series ``profile`` (u.csv), and ``extra``."""
    for fmu in fmu_dir.glob("*.fmu"):
        (tmp_path / fmu.name).symlink_to(fmu)
    (tmp_path / "u.csv").write_text(profile, encoding="utf-8")
    return open_loop(tmp_path, f'[[events]]\nname = "u"\nseries = "u.csv"\n{extra}\n')


@pytest.mark.parametrize(("repeat", "fired"), [("false", [0.4]), ("true", [0.4, 0.8])])
def test_when_fires_on_crossings_only_once_or_repeatedly(
    test_fmu_dir: Path, tmp_path: Path, repeat: str, fired: list[float]
) -> None:
    # plant.u (a recorded unconnected input) from a series: true at t = 0 (no firing),
    # crossing upwards at 0.4 and 0.8
    profile = "time,plant.u\n0,1\n0.2,0\n0.4,1\n0.6,0\n0.8,1\n"
    event = f'[[events]]\nname = "w"\nwhen = "plant.u > 0.5"\nrepeat = {repeat}\n'
    event += 'set = { "controller.k" = 4.0 }'
    result = master.run(series_loop(test_fmu_dir, tmp_path, profile, event))
    assert result.complete, result.error
    assert result.column("plant.u").tolist() == [1, 1, 0, 0, 1, 1, 0, 0, 1, 1, 1]
    crossings = [e["time"] for e in result.events if e["name"] == "w"]
    assert crossings == pytest.approx(fired)
    assert [e["time"] for e in result.events if e["name"] == "u"] == [0.0]


def test_a_ramp_writes_every_point_and_linear_series_interpolate(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    profile = "time,plant.u\n0.2,0\n0.6,2\n"  # before 0.2: u keeps its start value
    scenario = series_loop(test_fmu_dir, tmp_path, profile, "")
    text = scenario.to_toml().replace('interpolation = "hold"', 'interpolation = "linear"')
    u = master.run(scenario_from_toml(text, "t", fmu_dir=tmp_path)).column("plant.u")
    np.testing.assert_allclose(u, [1, 1, 0, 0.5, 1, 1.5, 2, 2, 2, 2, 2], rtol=0, atol=1e-15)
    ramp = '[[events]]\ntime = 0.2\nset = { "plant.u" = 3.0 }\nramp = 0.4\n'
    u = master.run(open_loop(test_fmu_dir, ramp)).column("plant.u")
    np.testing.assert_allclose(u, [1, 1, 1, 1.5, 2, 2.5, 3, 3, 3, 3, 3], rtol=0, atol=1e-15)


def test_an_event_on_a_ramping_variable_ends_the_ramp(test_fmu_dir: Path) -> None:
    """A later event setting a variable a ramp is moving takes over: its value holds from
    its point on (the ramp used to write over it at once and go on to its own target), and
    a later ramp starts from the value written last (the first ramp's at the point before)."""
    ramp = '[[events]]\ntime = 0.2\nset = { "plant.u" = 3.0 }\nramp = 0.4\n'
    stop = '[[events]]\nname = "abort"\ntime = 0.4\nset = { "plant.u" = 0.0 }\n'
    u = master.run(open_loop(test_fmu_dir, ramp + stop)).column("plant.u")
    np.testing.assert_allclose(u, [1, 1, 1, 1.5, 0, 0, 0, 0, 0, 0, 0], rtol=0, atol=1e-15)
    back = '[[events]]\nname = "back"\ntime = 0.4\nset = { "plant.u" = 0.0 }\nramp = 0.2\n'
    u = master.run(open_loop(test_fmu_dir, ramp + back)).column("plant.u")
    np.testing.assert_allclose(u, [1, 1, 1, 1.5, 1.5, 0.75, 0, 0, 0, 0, 0], rtol=0, atol=1e-15)


def _timeline_lines(fmu_dir: Path, events: int, stop_time: float, algorithm: str) -> int:
    """Lines of cosim/engine/timeline.py executed by a run of the open loop with ``events``
    time events (all at t = 0.4 s, so each fires once whatever the stop time)."""
    extra = "".join(
        f'[[events]]\nname = "e{i}"\ntime = 0.4\nset = {{ "controller.k" = 4.0 }}\n'
        for i in range(events)
    )
    scenario = open_loop(fmu_dir, extra, stop_time=stop_time, algorithm=algorithm)
    counted = [0]

    def local(frame: FrameType, event: str, arg: object) -> Callable[..., object]:
        counted[0] += event == "line"
        return local

    def tracer(frame: FrameType, event: str, arg: object) -> Callable[..., object] | None:
        return local if frame.f_code.co_filename == timeline.__file__ else None

    sys.settrace(tracer)
    try:
        result = master.run(scenario)
    finally:
        sys.settrace(None)
    assert result.complete, result.error
    assert len(result.events) == events
    return counted[0]


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "adaptive"])
def test_many_time_events_cost_nothing_per_step_beyond_their_own_firing(
    test_fmu_dir: Path, algorithm: str
) -> None:
    """A scenario of hundreds of time events: what each step spends on them must not grow
    with their number (every step used to look at every event). Counted in lines the
    timeline executes: the cost of 60 more events is the same over 5 s as over 10 s."""
    extra = {
        stop: _timeline_lines(test_fmu_dir, 61, stop, algorithm)
        - _timeline_lines(test_fmu_dir, 1, stop, algorithm)
        for stop in (5.0, 10.0)
    }
    assert extra[10.0] - extra[5.0] <= 60, f"60 more events cost {extra} lines (stop 5, 10 s)"
