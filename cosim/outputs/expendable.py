"""A sink whose failure the run outlives: the Rerun recording.

A recording that cannot be written (a full disk, a quota, the file-size limit) is no
reason to stop computing the results a run writes elsewhere: :class:`Expendable` closes
and drops the sink it wraps at its first failure, keeps the reason in :attr:`lost`, and
the run goes on. results.csv and summary.json remain the run's record (summary.json
names the failure as ``recording_error``; ``auv-cosim run`` says it on stderr and exits
3); the recording keeps what it held at its last whole flush.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from typing import Protocol

import numpy as np

from cosim.engine.rows import Note, RowSink
from cosim.errors import CosimError


class ClosableSink(RowSink, Protocol):
    """A sink that holds a file or a connection, closed once the run has ended."""

    def close(self) -> None: ...


class Expendable:
    """``sink`` fed until it first fails (``OSError`` or :class:`CosimError`); then closed,
    dropped and its reason kept in :attr:`lost`. Never raises what the sink raised."""

    def __init__(self, sink: ClosableSink) -> None:
        self._sink: ClosableSink | None = sink
        self.lost: str | None = None  # why the sink failed, once it has

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        if self._sink is not None:
            try:
                self._sink.add_rows(times, values)
            except (OSError, CosimError) as exc:
                self._drop(exc)

    def add_notes(self, notes: Sequence[Note]) -> None:
        if self._sink is not None:
            try:
                self._sink.add_notes(notes)
            except (OSError, CosimError) as exc:
                self._drop(exc)

    def close(self) -> None:
        """Close the sink (if it has not failed before); a failure now is kept too."""
        sink, self._sink = self._sink, None
        if sink is not None:
            try:
                sink.close()
            except (OSError, CosimError) as exc:
                self.lost = self.lost or str(exc)

    def _drop(self, exc: BaseException) -> None:
        self.lost = str(exc)
        sink, self._sink = self._sink, None
        if sink is not None:
            with contextlib.suppress(OSError, CosimError):  # the first failure is the reason
                sink.close()
