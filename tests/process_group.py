"""A command in a process group of its own, run to its end (:func:`run_in_group`) or while
a test talks to it (:func:`started_in_group`), the group killed as it returns, times out
or the test ends: whatever the command started (a Dask cluster, a viewer, a forked
worker) ends with it, whatever happens in the test."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import time
from collections.abc import Iterator, Sequence
from typing import Any


def run_in_group(
    command: Sequence[Any], *, timeout: float, **popen: Any
) -> subprocess.CompletedProcess:
    """``command`` run with ``popen`` (subprocess.Popen's keywords; stdout and stderr
    captured as text unless given), its result; ``subprocess.TimeoutExpired`` after
    ``timeout`` s, the group killed either way."""
    options = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True, **popen}
    proc = subprocess.Popen(command, start_new_session=True, **options)
    try:
        out, err = proc.communicate(timeout=timeout)
    finally:
        with contextlib.suppress(ProcessLookupError):  # the group may have ended on its own
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        close_pipes(proc)  # left open when communicate timed out
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


@contextlib.contextmanager
def started_in_group(command: Sequence[Any], **popen: Any) -> Iterator[subprocess.Popen]:
    """``command`` started with ``popen`` (subprocess.Popen's keywords; stdout and stderr
    piped as text unless given) for the ``with`` block; its group killed at the block's
    end, and its output read to the end."""
    options = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True, **popen}
    proc = subprocess.Popen(command, start_new_session=True, **options)
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        try:
            proc.communicate()
        finally:
            close_pipes(proc)  # those the test closed or read from leave communicate early


def close_pipes(proc: subprocess.Popen) -> None:
    """Close the pipes to and from ``proc`` that this process holds (its stdin, stdout,
    stderr), once it has ended: a pipe left to the garbage collector is a ResourceWarning
    in whichever test happens to collect it."""
    for pipe in (proc.stdin, proc.stdout, proc.stderr):
        if pipe is not None:
            with contextlib.suppress(OSError):  # stdin's last flush to an ended process
                pipe.close()


def as_in_a_terminal() -> None:
    """In a child before it runs its command: SIGHUP, SIGINT and SIGTERM at their default
    and unblocked, as a command started from a terminal has them, whatever the test
    process inherited or was left with (an ignored or blocked signal is inherited by every
    process it starts, and a command started under an ignored SIGHUP is ``nohup``'s)."""
    import signal

    stops = {signal.SIGHUP, signal.SIGINT, signal.SIGTERM}
    for signum in stops:
        signal.signal(signum, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, stops)


def group_ended(group: int, within: float = 60.0) -> bool:
    """Whether every process of the process group ``group`` has ended, looked for until it
    has or ``within`` s passed (a guard against a hang, not a measure: a fixed wait guesses
    how long the group takes to end, too short under load)."""
    deadline = time.monotonic() + within
    while time.monotonic() < deadline:
        try:
            os.killpg(group, 0)
        except ProcessLookupError:
            return True
        time.sleep(0.02)
    return False
