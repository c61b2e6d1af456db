"""The file sinks of a run: results.csv streamed row chunk by row chunk, summary.json
replaced atomically, and the progress bar.

:class:`CsvSink` writes each chunk the master hands over with one ``os.write`` loop
straight to the file (no user-space buffer), so the rows are in the file within the
master's hand-off interval (a second) and survive the process being killed. A failed
write (disk full) cuts the partial chunk off again and raises with the reason, so the file
always ends with a whole row; a file removed while it is written (its folder removed)
fails the next chunk, rather than the rows going on into a file nobody can read. A
``SIGKILL`` in the middle of a write can still tear the last row (the kernel stops a write
at a page boundary for a fatal signal): the run folder's tail guard
(:mod:`cosim.outputs.folder`) cuts it off once the process is gone. It keeps the SHA-256
of what it has written so far if asked (``hashed``: a run that checkpoints;
:meth:`CsvSink.written`, updated as each chunk is written, never read back), which a
checkpoint records in the run's manifest.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from cosim.engine.rows import NotesIgnored
from cosim.errors import CosimError
from cosim.limits import unwritten
from cosim.outputs.results import csv_header, csv_lines
from cosim.progress_bars import progress_bar
from cosim.whole_file import write_whole


class CsvSink(NotesIgnored):
    """results.csv (:mod:`cosim.outputs.results` describes the format), written as rows come.

    Raises :class:`CosimError` naming the file when it cannot be created or written.
    """

    def __init__(self, path: Path, columns: tuple[str, ...], hashed: bool = False) -> None:
        self.path = path
        self.rows = 0  # data rows in the file
        self.last: tuple[float, np.ndarray] | None = None  # the last row in the file
        self._written = 0  # bytes of whole rows in the file
        self._sha256 = hashlib.sha256() if hashed else None  # of those bytes, if asked
        try:
            self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            created = True
        except FileExistsError:  # not ours to remove if the header cannot be written
            created = False
            try:
                self._fd = os.open(path, os.O_WRONLY | os.O_TRUNC)
            except OSError as exc:
                raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
        except OSError as exc:
            raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
        try:
            self._write(csv_header(columns).encode())
        except CosimError:  # a full disk: no empty results.csv left behind
            self.close()
            if created:
                with contextlib.suppress(OSError):
                    os.unlink(path)
            raise

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        if self._fd >= 0 and os.fstat(self._fd).st_nlink == 0:  # one fstat a chunk
            # removed (its folder removed): every later row would be lost with the file
            raise CosimError(f"cannot write {self.path}: it was removed while the run wrote it")
        self._write(csv_lines(times, values))
        self.rows += len(times)
        if len(times):
            self.last = (float(times[-1]), np.array(values[-1], dtype=float))

    def written(self) -> tuple[int, int, str]:
        """What the file holds now: its data rows, its size (bytes) and the SHA-256 of
        its content (hex; "" unless the sink was made ``hashed``)."""
        return self.rows, self._written, "" if self._sha256 is None else self._sha256.hexdigest()

    def warm_up(self) -> None:
        """Do the CSV writer's one-time set-up now, writing nothing: pyarrow's first CSV
        write in a process takes ~0.25 s (seconds on a cold disk: its lazy initialisation),
        which belongs to the run's start-up, not to its first hand-off (late by as much in
        a paced run, and counted as stepping)."""
        csv_lines(np.zeros(1), np.zeros((1, 1)))

    def close(self) -> None:
        """Close the file; safe to call twice."""
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1

    def _write(self, data: bytes) -> None:
        if self._fd < 0:
            raise CosimError(f"cannot write {self.path}: the file was closed")
        view = memoryview(data)
        try:
            while view:
                view = view[os.write(self._fd, view) :]
        except OSError as exc:
            with contextlib.suppress(OSError):  # leave whole rows; the reason is below
                os.ftruncate(self._fd, self._written)
            raise CosimError(f"cannot write {self.path}: {unwritten(exc)}") from None
        self._written += len(data)
        if self._sha256 is not None:
            self._sha256.update(data)


def write_json_atomically(path: Path, data: dict[str, Any]) -> None:
    """Write ``data`` as JSON to ``path`` so that a reader sees the old file or the new
    one, never a part: a temporary file beside it, then a rename. Non-finite numbers are
    refused (they are not JSON). Raises :class:`CosimError` naming the file."""
    text = json.dumps(data, indent=2, allow_nan=False) + "\n"
    try:
        write_whole(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None


class ProgressSink(NotesIgnored):
    """A tqdm progress bar on stderr: what the run is doing before it steps (:meth:`phase`:
    "building FMUs", "loading FMUs", "initialising"...), then the steps as rows arrive.
    ``total_rows`` may be set once the scenario is known, or ``total_time`` (s): then the
    bar counts simulated seconds to it instead of rows (an adaptive run, whose number of
    steps is not known ahead); ``status`` (a paced run's real-time factors) is shown after
    the bar, refreshed with every chunk. ``replayed_rows``: the rows a resumed run hands on
    again first, read back from its results.csv up to its checkpoint: counted in a phase of
    their own, and the bar starts past them, so that its rate and time left are the
    steps' (the replayed rows, read some times faster than stepped, made its first
    estimates of the time left short)."""

    def __init__(
        self, total_rows: int | None, label: str, status: Callable[[], str] | None = None
    ) -> None:
        self.total_rows = total_rows
        self.total_time: float | None = None
        self._label = label
        self.status = status  # a paced run's real-time factors, settable once known
        self._bar: Any = None
        self._phase: Any = None
        self.replayed_rows = 0
        self._replayed = 0  # of replayed_rows, received so far
        self._replay_shown = 0.0  # time.monotonic() of the replay's last redraw

    def phase(self, text: str) -> None:
        """Show ``text`` (and the time it has taken so far) until the next phase or row; a
        phase after the steps (``--check-step``) ends the step bar first: a second bar
        below it was drawn with cursor-up escapes."""
        self._close_bar()
        if self._phase is None:
            self._phase = progress_bar(
                total=None, bar_format="{desc} [{elapsed}]", leave=False, dynamic_ncols=True
            )
        self._phase.set_description_str(f"{self._label}: {text}")

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        replayed = min(len(times), self.replayed_rows - self._replayed)
        if replayed > 0:
            first = not self._replayed
            self._replayed += replayed
            now = time.monotonic()  # redrawn 5 times a second, not for every chunk
            done = self._replayed == self.replayed_rows
            if first or done or now - self._replay_shown >= 0.2:
                self._replay_shown = now
                self.phase(f"replaying the rows to the checkpoint ({self._replayed} of "
                           f"{self.replayed_rows})")  # fmt: skip
            times = times[replayed:]
            if not len(times):
                return
        if self._bar is None:
            self._close_phase()
            by_time = self.total_time is not None
            total = self.total_time if by_time else self.total_rows
            unit = "s" if by_time else "step"
            # the terminal's width at each redraw, not as the bar began: a terminal
            # narrowed mid-run wrapped every redraw onto a line of its own
            self._bar = progress_bar(
                total=total, unit=unit, desc=self._label, leave=False, dynamic_ncols=True,
                initial=0 if by_time else self._replayed,
            )  # fmt: skip
        if self.status is not None:
            self._bar.set_postfix_str(self.status(), refresh=False)
        if self.total_time is None:
            self._bar.update(len(times))
        elif len(times):
            self._bar.update(float(times[-1]) - self._bar.n)

    def close(self) -> None:
        self._close_phase()
        self._close_bar()

    def _close_bar(self) -> None:
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def _close_phase(self) -> None:
        if self._phase is not None:
            self._phase.close()
            self._phase = None
