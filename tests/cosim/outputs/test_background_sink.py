"""The background sink of paced runs: the wrapped sink gets every row and note in order,
closes after the queue is delivered, and its failure reaches the master."""

from __future__ import annotations

import threading

import numpy as np
import pytest

from cosim.outputs.background import BackgroundSink


class Recorder:
    """Records what it is given, and on which thread; fails on a chosen row."""

    def __init__(self, fail_at: float | None = None) -> None:
        self.calls: list[tuple[str, object]] = []
        self.threads: set[str] = set()
        self.fail_at = fail_at
        self.closed = False

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self.threads.add(threading.current_thread().name)
        if self.fail_at is not None and self.fail_at in times:
            raise OSError(28, "No space left on device")
        self.calls.append(("rows", times.tolist()))

    def add_notes(self, notes: list[tuple[float, str]]) -> None:
        self.calls.append(("notes", notes))

    def close(self) -> None:
        self.closed = True


def test_rows_and_notes_arrive_in_order_off_the_calling_thread() -> None:
    inner = Recorder()
    sink = BackgroundSink(inner)
    buffer = np.zeros((2, 3))
    for chunk in range(3):
        buffer[:] = chunk  # the master reuses its buffer: the sink must have copied
        sink.add_rows(np.array([2.0 * chunk, 2.0 * chunk + 1]), buffer)
        sink.add_notes([(2.0 * chunk, f"note {chunk}")])
    sink.close()
    assert inner.closed
    assert inner.calls == [
        item for c in range(3)
        for item in (("rows", [2.0 * c, 2.0 * c + 1]), ("notes", [(2.0 * c, f"note {c}")]))
    ]  # fmt: skip
    assert threading.current_thread().name not in inner.threads


def test_a_failure_of_the_wrapped_sink_is_raised_to_the_caller() -> None:
    inner = Recorder(fail_at=1.0)
    sink = BackgroundSink(inner)
    sink.add_rows(np.array([0.0]), np.zeros((1, 1)))
    sink.add_rows(np.array([1.0]), np.zeros((1, 1)))  # fails in the worker
    with pytest.raises(OSError, match="No space left"):
        sink.close()  # at the latest on close
    assert inner.closed and inner.calls == [("rows", [0.0])]
