"""Stop a run on SIGINT, SIGTERM or SIGHUP without raising inside an FMU or a write.

While :func:`stop_on_signals` is active, each of these signals only records itself in a
:class:`StopRequest`; the master checks it once per step and ends the run with partial
results, and the outputs are completed whatever arrives afterwards (a second Ctrl-C during
the clean-up does not abort the writing). ``KeyboardInterrupt`` raised inside an FMU's
Python code would be turned into fmi2Fatal by pythonfmu and crash the host, and raised
inside a write would leave a torn file: neither can happen here.

Exit codes follow the shell's convention, 128 + the signal number: 130 for Ctrl-C
(SIGINT), 143 for SIGTERM, 129 for SIGHUP.
"""

from __future__ import annotations

import functools
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

STOP_SIGNALS = tuple(
    s
    for s in (signal.SIGINT, getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None))
    if s is not None
)
REASONS = {"SIGINT": "interrupted (Ctrl-C)", "SIGTERM": "terminated (SIGTERM)",
           "SIGHUP": "hung up (SIGHUP)"}  # fmt: skip


@functools.cache
def started_under_nohup() -> bool:
    """Whether SIGHUP was ignored when this process first asked (the command asks as it
    starts): ``nohup auv-cosim run ...``, whose hangup must not end the run."""
    hangup = getattr(signal, "SIGHUP", None)
    return hangup is not None and signal.getsignal(hangup) == signal.SIG_IGN


def stop_signals() -> tuple[int, ...]:
    """The stop signals a run or a study catches: all of :data:`STOP_SIGNALS` but SIGHUP
    under nohup, which stays ignored (it ended a run or study started with nohup once its
    terminal hung up: exit 129, partial results)."""
    hangup = getattr(signal, "SIGHUP", None)
    return tuple(s for s in STOP_SIGNALS if not (s == hangup and started_under_nohup()))


@dataclass
class StopRequest:
    """The first stop signal received (None: keep going); later ones are ignored. A stop
    asked for by other means than a signal (a live run's control endpoint or keys) is
    recorded as SIGINT, for its exit code (130), with ``by`` naming who asked."""

    signum: int | None = None
    by: str | None = None  # who asked for the stop when no signal came

    @property
    def requested(self) -> bool:
        return self.signum is not None

    @property
    def reason(self) -> str:
        """One line: what stopped the run (``"interrupted (Ctrl-C)"``)."""
        if self.signum is None:
            return "not stopped"
        if self.by is not None:
            return f"stopped by {self.by}"
        name = signal.Signals(self.signum).name
        return REASONS.get(name, f"stopped by {name}")

    @property
    def exit_code(self) -> int:
        """128 + the signal number (0 if no signal came)."""
        return 0 if self.signum is None else 128 + self.signum

    @property
    def signal(self) -> int | None:
        """The signal that stopped the run (None: none, or a stop asked for otherwise)."""
        return None if self.by is not None else self.signum

    def record(self, signum: int, by: str | None = None) -> None:
        if self.signum is None:
            self.signum, self.by = signum, by


@contextmanager
def stop_on_signals(stop: StopRequest) -> Iterator[StopRequest]:
    """While active, SIGINT/SIGTERM/SIGHUP set ``stop`` instead of ending the process.

    Outside the main thread (where Python cannot install handlers) nothing changes.
    """
    if threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum: int, _frame: Any) -> None:
        stop.record(signum)

    previous = {s: signal.signal(s, handler) for s in stop_signals()}
    try:
        yield stop
    finally:
        for s, old in previous.items():
            signal.signal(s, old)
