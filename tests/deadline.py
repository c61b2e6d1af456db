"""A block that must end within a time: it fails, rather than hangs, when it does not."""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator


@contextlib.contextmanager
def deadline(seconds: int, what: str = "no answer") -> Iterator[None]:
    """Raise AssertionError "<what> after <seconds> s" if the block takes longer (SIGALRM:
    the main thread only; pytest-timeout would end the whole test, not name the block)."""

    def expired(signum: int, frame: object) -> None:
        raise AssertionError(f"{what} after {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
