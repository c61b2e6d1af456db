"""The row stream of a run: what a sink is, and the sink that keeps every row in memory.

The master hands the rows of a run to its sinks in order, a chunk at a time:
``add_rows(times, values)`` with ``times`` (k,) in s and ``values`` (k, columns) in SI
units, the columns being the scenario's ``record``. The arrays are views into the
master's buffer, valid during the call only: a sink copies what it keeps. A sink that
cannot take the rows raises ``OSError`` (or :class:`cosim.errors.CosimError`) with the
reason; the master then ends the run (``complete`` false, that reason) and hands the
remaining rows to the other sinks. Between chunks of a run with events or faults the
master hands each sink the timeline's notes so far, ``add_notes(notes)`` with ``notes``
[(t in s, text)]; a sink with no use for them inherits :class:`NotesIgnored`. Who creates
a sink closes it; a run's outputs hand their sinks one last note before closing them, how
the run ended (:func:`cosim.engine.master.ending_note`: :data:`RUN_COMPLETE` or
:data:`RUN_INCOMPLETE` and the reason), at the time of its last row.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

Note = tuple[float, str]  # (t in s, what happened): an event fired, a fault started or ended
RUN_COMPLETE = "run complete"  # how the last note of a run that completed starts
RUN_INCOMPLETE = "run incomplete: "  # ... and of one that failed or was stopped, the reason


class RowSink(Protocol):
    """Anything the master can feed rows to (results.csv, the recording, a progress bar):
    the one interface through which the engine knows its observers."""

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None: ...

    def add_notes(self, notes: Sequence[Note]) -> None: ...


class NotesIgnored:
    """Base of a sink that takes rows only: the timeline's notes are dropped."""

    def add_notes(self, notes: Sequence[Note]) -> None:
        """Drop ``notes`` (this sink shows no events)."""


class RowTable(NotesIgnored):
    """Keeps every row in memory (tests, analyses): memory grows with the stop time."""

    def __init__(self, n_columns: int) -> None:
        self._n_columns = n_columns
        self._times: list[np.ndarray] = []
        self._values: list[np.ndarray] = []

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self._times.append(np.array(times, dtype=float))
        self._values.append(np.array(values, dtype=float))

    def table(self) -> tuple[np.ndarray, np.ndarray]:
        """(times (rows,), values (rows, columns)) of every row received."""
        if not self._times:
            return np.empty(0), np.empty((0, self._n_columns))
        return np.concatenate(self._times), np.concatenate(self._values)
