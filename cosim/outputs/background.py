"""A sink fed from a thread of its own, for paced runs.

The Rerun recording sends its buffered rows every few seconds, and each send takes 10-25
ms whatever its length (some 25 ``send_columns`` calls: :mod:`cosim.viz.recording`). A run
paced at 10x real time has 1 ms per step, so a send on the stepping thread makes the next
steps late by as much. :class:`BackgroundSink` queues the rows and notes (copies: the
master's arrays are views valid during the call only) and hands them to the wrapped sink,
in order, from a worker thread; the stepping thread only copies and queues. When nothing
has come for :data:`IDLE_S` (the run is paused, or paced slowly), the worker calls the
wrapped sink's ``send_due`` if it has one, so what it holds back reaches a viewer at its
usual pace instead of waiting for the next rows.

A failure of the wrapped sink (disk full) is raised at the next ``add_rows`` or
``add_notes`` (the master then ends the run, as it would have one hand-off earlier) or at
:meth:`BackgroundSink.close`, which first lets the worker finish the queue and then closes
the wrapped sink.
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np

from cosim.engine.rows import Note, RowSink
from cosim.errors import CosimError

IDLE_S = 0.2  # s without rows or notes after which the worker asks the sink to send what is due


class _Closable(RowSink, Protocol):
    def close(self) -> None: ...


class BackgroundSink:
    """``sink``'s ``add_rows``/``add_notes`` run in a worker thread; see the module."""

    def __init__(self, sink: _Closable) -> None:
        self._sink = sink
        self._queue: queue.SimpleQueue[tuple[str, tuple[Any, ...]] | None] = queue.SimpleQueue()
        self._error: OSError | CosimError | None = None
        self._thread = threading.Thread(target=self._work, name="sink", daemon=True)
        self._thread.start()

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self._raise()
        self._queue.put(("add_rows", (np.array(times), np.array(values))))

    def add_notes(self, notes: Sequence[Note]) -> None:
        self._raise()
        self._queue.put(("add_notes", (list(notes),)))

    def close(self) -> None:
        """Deliver what is queued, then close the wrapped sink; safe to call twice."""
        if self._thread.is_alive():
            self._queue.put(None)
            self._thread.join()
        self._sink.close()
        self._raise()

    def _work(self) -> None:
        while True:
            try:
                item = self._queue.get(timeout=IDLE_S)
            except queue.Empty:
                item = ("send_due", ())
            if item is None:
                return
            if self._error is not None:
                continue  # the sink failed: what follows is dropped
            method, args = item
            call = getattr(self._sink, method, None)
            if call is None:  # a sink without send_due
                continue
            try:
                call(*args)
            except (OSError, CosimError) as exc:
                self._error = exc
            except Exception as exc:  # a worker must not die silently
                self._error = CosimError(f"{type(self._sink).__name__}: {exc}")

    def _raise(self) -> None:
        if self._error is not None:
            raise self._error
