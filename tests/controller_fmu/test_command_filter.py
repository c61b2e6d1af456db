"""The command filters' exact transitions are computed once per interval an adaptive run
comes back to, and each interval's is its own, to the last bit."""

from __future__ import annotations

import gc
import itertools
import weakref

import numpy as np
import pytest

from controller_fmu import command_filter
from controller_fmu.command_filter import CommandFilterBank

GRID = 0.01 / 2**10  # s: an adaptive run's smallest step at a 10 ms coupling step


def _adaptive_intervals() -> list[float]:
    """Intervals as an adaptive run's sample times give them: steps of whole grid units
    growing and shrinking (times k * GRID differenced: the same number of units comes
    back as floats that differ in the last bits), each visited again after dozens of
    others."""
    units = [1024 + 37 * k for k in range(-20, 21)]  # 41 step lengths around 10 ms
    times = np.cumsum([0, *units, *units[::-1], *units]) * GRID
    return [float(b - a) for a, b in itertools.pairwise(times)]


def test_an_interval_come_back_to_is_not_recomputed(monkeypatch: pytest.MonkeyPatch) -> None:
    """Under the adaptive step the backstepping autopilot's filters meet thousands of
    intervals, and the cache of 16 was emptied each time it filled: an interval seen
    again was recomputed (two matrix exponentials each time, 7 % of an adaptive vert-1
    run's profile). Each distinct interval costs its exponentials once."""
    calls: list[int] = []
    exact = command_filter.expm
    monkeypatch.setattr(command_filter, "expm", lambda m: calls.append(1) or exact(m))
    bank = CommandFilterBank(3, frequency=10.0)
    intervals = _adaptive_intervals()
    for interval in intervals:
        bank.transition(interval)
        bank.ramp(interval)
    assert len(calls) == 2 * len(set(intervals)), (len(calls), len(set(intervals)))


def test_each_interval_gets_its_own_transition_to_the_last_bit() -> None:
    """Two floats of one interval in grid units (3 * 0.001 and 0.003) have transitions
    that differ in the last bits: a cached neighbour's would move a fixed-step run's
    results. Each interval's transition and ramp are those a fresh bank computes."""
    bank = CommandFilterBank(3, frequency=10.0)
    intervals = _adaptive_intervals()
    for interval in intervals:
        bank.transition(interval)
        bank.ramp(interval)
    for interval in (*intervals, 3 * 0.001, 0.003):
        fresh = CommandFilterBank(3, frequency=10.0)
        (phi, gamma), (phi_0, gamma_0) = bank.transition(interval), fresh.transition(interval)
        assert phi.tobytes() == phi_0.tobytes() and gamma.tobytes() == gamma_0.tobytes()
        assert bank.ramp(interval).tobytes() == fresh.ramp(interval).tobytes()


def test_a_bank_let_go_frees_its_transitions_at_once() -> None:
    """An autopilot rebuilt (a tunable set, an FMU state restored with other settings, an
    instance freed) lets its bank go: the bank and its up to 2 x 2048 cached transitions
    are freed then, not held in a reference cycle until the garbage collector runs (which
    a study's worker runs seldom: its imports are frozen out of reach)."""
    bank = CommandFilterBank(3, frequency=10.0)
    for interval in _adaptive_intervals():
        bank.transition(interval)
        bank.ramp(interval)
    gone = weakref.ref(bank)
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        del bank
        assert gone() is None, "the bank outlived its last reference (a reference cycle)"
    finally:
        if was_enabled:
            gc.enable()
