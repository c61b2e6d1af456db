"""tests/deadline.py shares the process's one real-time timer (SIGALRM) with whatever
armed it before: pytest-timeout's per-test limit. A block under ``deadline`` disarmed
that limit for the rest of its test (a hang after the block then hung the whole run)."""

from __future__ import annotations

import signal
import time
from collections.abc import Iterator

import pytest
from deadline import deadline


class OuterTimerError(Exception):
    """Raised by the outer timer's handler."""


def _outer_fired(signum: int, frame: object) -> None:
    raise OuterTimerError


@pytest.fixture
def outer_timer() -> Iterator[None]:
    """SIGALRM handled by :func:`_outer_fired`; the timer and handler found (pytest-timeout's)
    put back afterwards."""
    handler = signal.signal(signal.SIGALRM, _outer_fired)
    remaining, _ = signal.setitimer(signal.ITIMER_REAL, 0)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, handler)
        if remaining:
            signal.setitimer(signal.ITIMER_REAL, remaining)


@pytest.mark.usefixtures("outer_timer")
def test_a_timer_armed_before_the_block_is_armed_after_it() -> None:
    signal.setitimer(signal.ITIMER_REAL, 600.0)
    with deadline(60):
        pass
    remaining, _ = signal.getitimer(signal.ITIMER_REAL)
    assert 500.0 < remaining <= 600.0
    assert signal.getsignal(signal.SIGALRM) is _outer_fired


@pytest.mark.usefixtures("outer_timer")
def test_a_timer_due_within_the_block_still_fires() -> None:
    signal.setitimer(signal.ITIMER_REAL, 0.2)
    with pytest.raises(OuterTimerError), deadline(60):
        time.sleep(120)  # ended by the outer timer, long before the block's deadline
    assert signal.getitimer(signal.ITIMER_REAL) == (0.0, 0.0)  # fired once, not re-armed


def test_a_block_over_its_deadline_fails_naming_it() -> None:
    with pytest.raises(AssertionError, match="still busy after 1 s"), deadline(1, "still busy"):
        time.sleep(120)
