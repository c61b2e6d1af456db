"""The input derivatives the master sends an FMU that interpolates its inputs."""

from __future__ import annotations

import ctypes
import functools
from typing import Any

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from cosim.engine.extrapolation import InputRates


class FakeFmu:
    """Records every fmi2SetRealInputDerivatives call as {(vr, order): value} (the master
    calls the library's C function, ``fmu.dll``, and checks its status)."""

    component = None

    def __init__(self) -> None:
        self.calls: list[dict[tuple[int, int], float]] = []
        self.dll = self

    def __getitem__(self, name: str) -> Any:  # a ctypes library's function by name
        return functools.partial(getattr(self, name))

    def fmi2SetRealInputDerivatives(self, c, vrs, n, orders, values) -> int:
        doubles = ctypes.cast(values, ctypes.POINTER(ctypes.c_double))
        self.calls.append({(vrs[i], orders[i]): doubles[i] for i in range(n.value)})
        return 0


def signal(t: float) -> np.ndarray:
    """Two inputs: a quadratic and a line."""
    return np.array([1.0 + 2.0 * t - 3.0 * t * t, 4.0 - t])


@pytest.mark.parametrize(
    "times", [[0.0, 0.1, 0.2], [0.0, 0.1, 0.2, 0.3], [0.0, 0.05, 0.2, 0.25, 0.45]]
)
def test_quadratic_extrapolation_sends_the_exact_derivatives_of_a_quadratic(times) -> None:
    """Divided differences over the last three points (any spacing: the adaptive
    algorithm's) give a quadratic's first and second derivatives exactly, from the third
    point on (the first with two points behind it)."""
    fmu = FakeFmu()
    rates = InputRates(fmu, [7, 9], order=2)
    for t in times:
        rates.send(signal(t), t, epoch=0)
    assert len(fmu.calls) == len(times) - 1  # nothing at the first point: no history
    t = times[-1]
    last = fmu.calls[-1]
    assert last[(7, 1)] == pytest.approx(2.0 - 6.0 * t) and last[(7, 2)] == pytest.approx(-6.0)
    assert last[(9, 1)] == pytest.approx(-1.0) and last[(9, 2)] == pytest.approx(0.0, abs=1e-9)
    second = fmu.calls[0]  # two points: a line through them, no curvature
    assert second[(7, 2)] == 0.0


def test_linear_extrapolation_sends_the_slope_of_the_last_two_points() -> None:
    fmu = FakeFmu()
    rates = InputRates(fmu, [1, 2], order=1)
    for t in (0.0, 0.1, 0.2):
        rates.send(signal(t), t, epoch=0)
    slope = (signal(0.2) - signal(0.1)) / 0.1
    assert fmu.calls[-1] == {(1, 1): pytest.approx(slope[0]), (2, 1): pytest.approx(slope[1])}


def test_the_history_starts_again_after_a_jump() -> None:
    """A new epoch (an event fired, a fault started) starts the history: no derivative
    across the jump, then a slope from the points after it only."""
    fmu = FakeFmu()
    rates = InputRates(fmu, [1, 2], order=2)
    for t in (0.0, 0.1, 0.2):
        rates.send(signal(t), t, epoch=0)
    sent = len(fmu.calls)
    rates.send(signal(0.3) + 100.0, 0.3, epoch=1)  # the values jumped at this point
    assert len(fmu.calls) == sent
    rates.send(signal(0.4) + 100.0, 0.4, epoch=1)
    slope = (signal(0.4) - signal(0.3)) / 0.1
    assert fmu.calls[-1][(1, 1)] == pytest.approx(slope[0])
    assert fmu.calls[-1][(1, 2)] == 0.0


def test_a_restored_history_repeats_the_same_derivatives() -> None:
    """snapshot/restore (a rolled-back adaptive step) gives the same derivatives again."""
    fmu = FakeFmu()
    rates = InputRates(fmu, [1, 2], order=2)
    for t in (0.0, 0.1):
        rates.send(signal(t), t, epoch=0)
    saved = rates.snapshot()
    rates.send(signal(0.2), 0.2, epoch=0)
    first = fmu.calls[-1]
    rates.restore(saved)
    rates.send(signal(0.2), 0.2, epoch=0)
    assert fmu.calls[-1] == first


@pytest.mark.parametrize(("status", "raises"), [(0, False), (1, False), (2, True), (3, True)])
def test_a_refused_derivative_call_raises_what_fmpy_raises(status, raises) -> None:
    """The master calls the FMU's C function directly: a status worse than fmi2Warning
    raises fmpy's FMICallException naming the function, as fmpy's wrapper would."""
    fmu = FakeFmu()
    fmu.fmi2SetRealInputDerivatives = lambda *args: status  # type: ignore[method-assign]
    rates = InputRates(fmu, [7, 9], order=1)
    rates.send(signal(0.0), 0.0, epoch=0)  # no history yet: nothing sent
    if not raises:
        rates.send(signal(0.1), 0.1, epoch=0)
        return
    with pytest.raises(FMICallException) as caught:
        rates.send(signal(0.1), 0.1, epoch=0)
    assert caught.value.status == status
    assert caught.value.function == "fmi2SetRealInputDerivatives"


def test_a_second_send_at_the_same_point_changes_nothing() -> None:
    """A feedthrough is given its inputs at a point twice (once refreshed after the step,
    once before the next): the second send at the same time sends nothing and leaves the
    history, so the next derivatives are those of one send per point."""
    once, twice = FakeFmu(), FakeFmu()
    single, repeated = InputRates(once, [1, 2], order=2), InputRates(twice, [1, 2], order=2)
    for t in (0.0, 0.1, 0.2, 0.3):
        single.send(signal(t), t, epoch=0)
        repeated.send(signal(t), t, epoch=0)
        repeated.send(signal(t) + 5.0, t, epoch=0)  # a point's values again: ignored
    assert once.calls == twice.calls
    assert single.count == repeated.count == 4


def test_the_master_s_input_array_is_bound_once_and_followed() -> None:
    """The master passes the same input array at every step, refilled in place: the
    derivatives follow its values."""
    fmu = FakeFmu()
    rates = InputRates(fmu, [1, 2], order=1)
    inputs = np.zeros(2)
    for t in (0.0, 0.1, 0.2):
        inputs[:] = signal(t)
        rates.send(inputs, t, epoch=0)
    slope = (signal(0.2) - signal(0.1)) / 0.1
    assert fmu.calls[-1] == {(1, 1): pytest.approx(slope[0]), (2, 1): pytest.approx(slope[1])}


def test_a_held_input_gets_no_slope_and_no_curvature() -> None:
    """An input whose source steps less often is held over the step (``held``): with
    quadratic extrapolation both its first and its second derivative are sent as 0 (a
    parabola through its stairs would zigzag), while the other input still gets the
    exact derivatives of its quadratic."""
    fmu = FakeFmu()
    rates = InputRates(fmu, [7, 9], order=2, held=[1])
    for t in (0.0, 0.1, 0.2, 0.3):
        stairs = signal(t)
        stairs[1] = float(np.floor(t / 0.2))  # a source stepping every 0.2 s
        rates.send(stairs, t, epoch=0)
    last = fmu.calls[-1]
    assert last[(9, 1)] == 0.0 and last[(9, 2)] == 0.0
    assert last[(7, 1)] == pytest.approx(2.0 - 6.0 * 0.3) and last[(7, 2)] == pytest.approx(-6.0)
