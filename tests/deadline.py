"""A block that must end within a time: it fails, rather than hangs, when it does not."""

from __future__ import annotations

import contextlib
import signal
import time
from collections.abc import Iterator


@contextlib.contextmanager
def deadline(seconds: int, what: str = "no answer") -> Iterator[None]:
    """Raise AssertionError "<what> after <seconds> s" if the block takes longer (SIGALRM:
    the main thread only; pytest-timeout would end the whole test, not name the block).

    The process has one real-time timer, which pytest-timeout arms for each test: one due
    within the block fires there (its own handler runs, once), and one due later is armed again
    after the block for the time it had left (disarmed, a hang after the block hung the
    whole run)."""
    started = time.monotonic()
    outer, _ = signal.getitimer(signal.ITIMER_REAL)
    previous = signal.getsignal(signal.SIGALRM)
    outer_first = bool(outer) and outer <= seconds and callable(previous)
    fired = []

    def expired(signum: int, frame: object) -> None:
        fired.append(signum)
        if outer_first and callable(previous):  # the earlier timer's time came first
            previous(signum, frame)
        raise AssertionError(f"{what} after {seconds} s")

    signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, outer if outer_first else seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
        if outer and not (fired and outer_first):  # the earlier timer has yet to fire
            signal.setitimer(signal.ITIMER_REAL, max(outer - (time.monotonic() - started), 1e-3))
