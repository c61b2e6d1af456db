"""A study ends on SIGINT, SIGTERM or SIGHUP as a run does: one line, exit 128 + the signal
number (130 Ctrl-C, 143 SIGTERM, 129 SIGHUP), the finished rows kept in ``runs.csv``.

While :func:`stop_study_on_signals` is active, the first of these signals raises
:class:`StudyStopped` in the client's main thread (waiting for the next result); later
ones are ignored, so closing the cluster is not interrupted. The local cluster's worker
processes are started with SIGINT ignored (:func:`workers_ignore_sigint`; a child
inherits an ignored signal through fork and exec, and Python then installs no
KeyboardInterrupt handler): a Ctrl-C in the terminal reaches the whole process group, and
the workers would each print a traceback; the client stops them instead.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from cosim.engine.signals import REASONS, stop_signals


class StudyStopped(BaseException):  # like KeyboardInterrupt: not an error
    """A stop signal ended the study; ``where`` says what was kept (set by the runner)."""

    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum
        self.where = ""

    @property
    def exit_code(self) -> int:
        return 128 + self.signum

    def __str__(self) -> str:
        reason = REASONS.get(signal.Signals(self.signum).name, "stopped")
        return reason + (f"; {self.where}" if self.where else "")


@contextmanager
def stop_study_on_signals(ignore_after: bool = False) -> Iterator[None]:
    """While active, the first stop signal raises :class:`StudyStopped`; later ones are
    ignored. Outside the main thread nothing changes. ``ignore_after``: for a process
    that ends with the study (the command), the stop signals stay ignored after it, as
    ``auv-cosim run`` ignores them once its run is over; a Ctrl-C while the report was
    printed or the interpreter shut down turned a finished study into "interrupted", 130,
    or killed the process (Python's finalization puts back the default action of a
    signal a Python function handles)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    stopped = False

    def handler(signum: int, _frame: Any) -> None:
        nonlocal stopped
        if stopped:
            return
        if _deferral.depth:  # inside stop_signals_deferred: delivered as it ends
            _deferral.pending = signum
            return
        stopped = True
        raise StudyStopped(signum)

    previous = {s: signal.signal(s, handler) for s in stop_signals()}
    try:
        yield
    finally:
        for s, old in previous.items():
            signal.signal(s, signal.SIG_IGN if ignore_after else old)


class _Deferral:
    """How deep in :func:`stop_signals_deferred` the process is, and the stop signal that
    arrived there (delivered as the outermost block ends)."""

    depth = 0
    pending: int | None = None


_deferral = _Deferral()


@contextmanager
def stop_signals_deferred() -> Iterator[None]:
    """A stop signal arriving while the block runs is delivered after it (a
    :class:`StudyStopped` then raises after the block, never inside it): for what must
    happen whole, like a row written to runs.csv and counted as kept. Held back by the
    handler of :func:`stop_study_on_signals`, not by a signal mask: the kernel hands a
    process's signal to any thread not masking it (Dask's event loop, say), and Python
    then runs the handler in the main thread at once."""
    _deferral.depth += 1
    try:
        yield
    finally:
        _deferral.depth -= 1
    if _deferral.depth == 0 and _deferral.pending is not None:
        signum, _deferral.pending = _deferral.pending, None
        signal.raise_signal(signum)  # to the handler, which raises now


@contextmanager
def workers_ignore_sigint() -> Iterator[None]:
    """Processes started inside this block inherit SIGINT ignored (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
