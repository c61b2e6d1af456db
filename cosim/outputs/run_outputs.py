"""Every output of a run as a sink of the master's row stream, each given the Scenario.

In a claimed run folder (:mod:`cosim.outputs.folder`), :meth:`RunOutputs.open` writes
``scenario.toml`` and ``summary.json`` (``"status": "running"``) and opens the sinks:
results.csv (:class:`cosim.outputs.sinks.CsvSink`, with the folder's tail guard), the key
figures (:class:`cosim.metrics.key_figures.KeyFigures`), the manoeuvre metrics of a scenario that
names one (:class:`cosim.outputs.manoeuvre.ManoeuvreSink`), the recording and the live viewer
(made by the ``recorder`` the command hands over, one each: this room knows no viewer) and
the progress bar. Creating them
probes that every path is writable before the first step. The first sink,
:class:`FirstStep`, tells the folder when the first step's rows arrive: only then is an
earlier run it replaces removed. :meth:`RunOutputs.close`
closes them and :meth:`RunOutputs.finish` replaces summary.json with how the run ended;
each file is recorded in the folder's manifest (:meth:`cosim.outputs.folder.RunFolder.wrote`)
whenever the run has finished writing it.
A run that fails before its first step calls :meth:`RunOutputs.discard` instead: what it
created is removed again.
"""

from __future__ import annotations

import contextlib
import os
import signal
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from cosim.engine.master import RunResult
from cosim.engine.rows import Note, NotesIgnored, RowSink
from cosim.errors import CosimError
from cosim.limits import unwritten
from cosim.metrics.key_figures import key_figures
from cosim.outputs.expendable import ClosableSink, Expendable
from cosim.outputs.folder import RESULTS_FILE, SCENARIO_FILE, SUMMARY_FILE, RunFolder
from cosim.outputs.manoeuvre import ManoeuvreSink, fault_start, mission_legs, survey_mission
from cosim.outputs.results import final_summary, running_summary
from cosim.outputs.sinks import CsvSink, ProgressSink, write_json_atomically
from cosim.scenario.spec import Scenario
from cosim.whole_file import write_whole


class Recorder(Protocol):
    """Makes the sink that records a run to ``rrd`` or streams it to the viewer at ``url``
    (one of the two given); None if recording is unavailable (it warns why). Raises
    :class:`CosimError` if the recording cannot start."""

    def __call__(
        self,
        scenario: Scenario,
        rrd: Path | None,
        url: str | None,
        on_flushed: Callable[[int], None] | None,
    ) -> ClosableSink | None: ...


class FirstStep(NotesIgnored):
    """Commits the run folder (:meth:`cosim.outputs.folder.RunFolder.commit`) when the
    rows of the run's first step arrive (a row after t = 0, and after the ``replayed``
    rows a resumed run hands on first): the earlier run it replaces is removed then, and
    not before. A resume killed while it replayed removed the earlier results.csv at the
    first replayed row, leaving a part of the rows the checkpoint needs: now the tail
    guard puts the earlier files back, and the next resume starts from the same
    checkpoint."""

    def __init__(self, folder: RunFolder, replayed: int = 0) -> None:
        self.folder = folder
        self.replayed = replayed
        self.received = 0  # rows so far

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self.received += len(times)
        if (
            not self.folder.committed
            and len(times)
            and times[-1] > 0.0
            and self.received > self.replayed
        ):
            self.folder.commit()


class RunOutputs:
    """The open outputs of one run (use :meth:`open`)."""

    def __init__(
        self, scenario: Scenario, folder: RunFolder, paths: dict[str, Path], replayed: int = 0
    ) -> None:
        self.scenario = scenario
        self.folder = folder
        self.paths = paths  # (if written) results, scenario, summary and recording
        self.figures = key_figures(scenario.record, scenario.key_vehicles)
        self.manoeuvre = (
            None if scenario.manoeuvre is None
            else ManoeuvreSink(scenario.manoeuvre, scenario.record, fault_start(scenario),
                               mission_legs(scenario), *(survey_mission(scenario) or ()))
        )  # fmt: skip
        self.csv: CsvSink | None = None
        self.sinks: list[RowSink] = [FirstStep(folder, replayed), self.figures]
        if self.manoeuvre is not None:
            self.sinks.append(self.manoeuvre)
        self.manoeuvre_summary: dict[str, Any] | None = None  # set by finish
        self._created: list[Path] = []
        self._closable: list[ClosableSink] = []  # the sinks this object opened
        self._running: dict[str, Any] = {}
        self.recording: Expendable | None = None  # the recording file's sink, if any

    @classmethod
    def open(
        cls,
        scenario: Scenario,
        folder: RunFolder,
        rrd: Path | None,
        connect: str | None,
        progress: ProgressSink | None,
        recorder: Recorder | None = None,
        results_csv: bool = True,
        checkpointed: bool = False,
        replayed: int = 0,
    ) -> RunOutputs:
        """Write scenario.toml and the running summary, open every sink (``progress``:
        the bar, if one is shown, its total set here; no results.csv without
        ``results_csv``; ``checkpointed``: results.csv's SHA-256 kept as it is written, for
        the checkpoints to record; ``replayed``: the rows a resumed run hands on before
        its first step, :class:`FirstStep`).

        Raises :class:`CosimError` naming the path that cannot be written; what was
        created by then is removed again.
        """
        paths = {name: folder.path / file for name, file in
                 (("results", RESULTS_FILE), ("scenario", SCENARIO_FILE),
                  ("summary", SUMMARY_FILE))}  # fmt: skip
        if not results_csv:
            del paths["results"]
        if rrd is not None:
            paths["recording"] = rrd
        outputs = cls(scenario, folder, paths, replayed)
        try:
            outputs._open_sinks(rrd, connect, progress, recorder, checkpointed)
        except BaseException:
            outputs.discard()
            raise
        return outputs

    def _open_sinks(
        self,
        rrd: Path | None,
        connect: str | None,
        progress: ProgressSink | None,
        recorder: Recorder | None,
        checkpointed: bool,
    ) -> None:
        if "results" in self.paths:
            self.csv = CsvSink(self.paths["results"], self.scenario.columns, checkpointed)
            if checkpointed:
                self.folder.results_written = self.csv.written
            self._created.append(self.paths["results"])
            self.folder.wrote(self.paths["results"])
            self.sinks.insert(1, self.csv)
            self._closable.append(self.csv)
        self.folder.start_guard(self.folder.path / RESULTS_FILE, rrd)  # none there: no cut
        if rrd is not None and recorder is not None:
            self._created.append(rrd)  # the folder's lock made it: removed if the sink fails
            sink = recorder(self.scenario, rrd, None, self.folder.recording_flushed)
            if sink is not None:
                self.folder.wrote(rrd)
                self.recording = Expendable(sink)  # the run outlives it
                self._add(self.recording)
            else:
                del self.paths["recording"]
        elif rrd is not None:
            del self.paths["recording"]
        if connect is not None and recorder is not None:
            sink = recorder(self.scenario, None, connect, None)
            if sink is not None:
                self._add(sink)
        if progress is not None:
            if self.scenario.coupling.algorithm == "adaptive":  # steps not known ahead
                progress.total_time = self.scenario.stop_time
            else:
                progress.total_rows = self.scenario.n_steps + 1
            self._add(progress)
        try:
            self.paths["scenario"].write_text(self.scenario.to_toml(), encoding="utf-8")
        except OSError as exc:
            raise CosimError(f"cannot write {self.paths['scenario']}: {exc.strerror}") from None
        self._created.append(self.paths["scenario"])
        self.folder.wrote(self.paths["scenario"])
        self._running = running_summary(self.scenario, self.paths, self.folder.path)
        self._created.append(self.paths["summary"])
        write_json_atomically(self.paths["summary"], self._running)
        self.folder.wrote(self.paths["summary"])

    def _add(self, sink: ClosableSink) -> None:
        self.sinks.append(sink)
        self._closable.append(sink)

    def close(self, ending: Note | None = None) -> str | None:
        """Close every sink (the recording's last rows are flushed) and record the files
        in the manifest; the first failure. ``ending``, how the run ended
        (:func:`cosim.engine.master.ending_note`), is each sink's last note (the recording's
        last events entry)."""
        error = self._close_sinks(ending)
        error = self._record("results") or error
        unrecorded = self._record("recording")
        if unrecorded is None or self.recording is None:
            return error or unrecorded
        rrd = self.paths["recording"]  # gone: the run went on without it all the same
        gone = f"the recording {rrd} was removed while the run wrote it"
        self.recording.lost = self.recording.lost or (
            gone if not os.path.lexists(rrd) else unrecorded
        )
        return error

    def _close_sinks(self, ending: Note | None) -> str | None:
        error = None
        for sink in self._closable:
            try:
                try:
                    if ending is not None:
                        sink.add_notes([ending])
                finally:
                    sink.close()
            except (OSError, CosimError) as exc:
                error = error or str(exc)
        return error

    def _record(self, name: str) -> str | None:
        """Record the output ``name`` in the folder's manifest; the failure, if any."""
        path = self.paths.get(name)
        if path is None or path not in self._created:
            return None
        try:
            self.folder.wrote(path)
        except CosimError as exc:
            return str(exc)
        return None

    def finish(self, result: RunResult, error: str | None, signum: int | None) -> str | None:
        """Replace summary.json with the final summary; the failure to write it, if any."""
        name = signal.Signals(signum).name if signum is not None else None
        rows = self.csv.rows if self.csv is not None else result.rows
        if self.manoeuvre is not None:
            self.manoeuvre_summary = self.manoeuvre.summary()
        figures, manoeuvre = self.figures.figures(result.complete), self.manoeuvre_summary
        short = self.csv is not None and self.csv.rows < result.rows
        last = self.csv.last if short and self.csv is not None else None
        data = final_summary(
            self._running, result, figures, error, name, rows, manoeuvre, last, self.recording_lost
        )
        try:
            write_json_atomically(self.paths["summary"], data)
        except CosimError as exc:
            return str(exc)
        return self._record("summary")

    @property
    def recording_lost(self) -> str | None:
        """Why the recording file could not be written (the run went on without it)."""
        return self.recording.lost if self.recording is not None else None

    def write_scenario(self, scenario: Scenario) -> str | None:
        """Replace scenario.toml (a live run's, its overrides as events: a replay); the
        failure to write it, if any."""
        path, text = self.paths["scenario"], scenario.to_toml()
        try:
            write_whole(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))
        except OSError as exc:
            return f"cannot write {path}: {unwritten(exc)}"
        return self._record("scenario")

    def discard(self) -> None:
        """Close the sinks and remove every file this run created (it never stepped)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self._close_sinks(None)
        for path in self._created:
            with contextlib.suppress(OSError):
                os.unlink(path)
