"""Every output of a run as a sink of the master's row stream, each given the Scenario.

In a claimed run folder (:mod:`cosim.run.folder`), :meth:`RunOutputs.open` writes
``scenario.toml`` and ``summary.json`` (``"status": "running"``) and opens the sinks:
results.csv (:class:`cosim.run.sinks.CsvSink`, with the folder's tail guard), the key
figures (:class:`cosim.run.figures.KeyFigures`), the manoeuvre metrics of a scenario that
names one (:class:`cosim.run.manoeuvre.ManoeuvreSink`), the Rerun recording and the live viewer
(:class:`cosim.viz.recording.RerunSink`, one each) and the progress bar. Creating them
probes that every path is writable before the first step. :meth:`RunOutputs.close`
closes them and :meth:`RunOutputs.finish` replaces summary.json with how the run ended.
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
from typing import Any

from cosim.errors import CosimError
from cosim.run.figures import KeyFigures
from cosim.run.folder import RESULTS_FILE, SCENARIO_FILE, SUMMARY_FILE, RunFolder
from cosim.run.manoeuvre import ManoeuvreSink, fault_start
from cosim.run.master import RunResult
from cosim.run.results import final_summary, running_summary
from cosim.run.rows import RowSink
from cosim.run.scenario import Scenario
from cosim.run.sinks import CsvSink, ProgressSink, write_json_atomically


class RunOutputs:
    """The open outputs of one run (use :meth:`open`)."""

    def __init__(self, scenario: Scenario, folder: RunFolder, paths: dict[str, Path]) -> None:
        self.scenario = scenario
        self.folder = folder
        self.paths = paths  # results, scenario, summary and (if written) recording
        self.figures = KeyFigures(scenario.record)
        self.manoeuvre = (
            None if scenario.manoeuvre is None
            else ManoeuvreSink(scenario.manoeuvre, scenario.record, fault_start(scenario))
        )  # fmt: skip
        self.csv: CsvSink | None = None
        self.sinks: list[RowSink] = [self.figures]
        if self.manoeuvre is not None:
            self.sinks.append(self.manoeuvre)
        self.manoeuvre_summary: dict[str, Any] | None = None  # set by finish
        self._created: list[Path] = []
        self._running: dict[str, Any] = {}

    @classmethod
    def open(
        cls,
        scenario: Scenario,
        folder: RunFolder,
        rrd: Path | None,
        connect: str | None,
        progress: bool,
    ) -> RunOutputs:
        """Write scenario.toml and the running summary, open every sink.

        Raises :class:`CosimError` naming the path that cannot be written; what was
        created by then is removed again.
        """
        paths = {name: folder.path / file for name, file in
                 (("results", RESULTS_FILE), ("scenario", SCENARIO_FILE),
                  ("summary", SUMMARY_FILE))}  # fmt: skip
        if rrd is not None:
            paths["recording"] = rrd
        outputs = cls(scenario, folder, paths)
        try:
            outputs._open_sinks(rrd, connect, progress)
        except BaseException:
            outputs.discard()
            raise
        return outputs

    def _open_sinks(self, rrd: Path | None, connect: str | None, progress: bool) -> None:
        self.csv = CsvSink(self.paths["results"], self.scenario.columns)
        self._created.append(self.paths["results"])
        self.sinks.insert(0, self.csv)
        self.folder.start_guard(self.paths["results"], rrd)
        if rrd is not None:
            sink = _rerun_sink(self.scenario, rrd, None, self.folder.recording_flushed)
            if sink is not None:
                self._created.append(rrd)
                self.sinks.append(sink)
            else:
                del self.paths["recording"]
        if connect is not None:
            sink = _rerun_sink(self.scenario, None, connect, None)
            if sink is not None:
                self.sinks.append(sink)
        if progress:
            self.sinks.append(ProgressSink(self.scenario.n_steps + 1, self.scenario.id))
        try:
            self.paths["scenario"].write_text(self.scenario.to_toml(), encoding="utf-8")
        except OSError as exc:
            raise CosimError(f"cannot write {self.paths['scenario']}: {exc.strerror}") from None
        self._created.append(self.paths["scenario"])
        self._running = running_summary(self.scenario, self.paths, self.folder.path)
        self._created.append(self.paths["summary"])
        write_json_atomically(self.paths["summary"], self._running)

    def close(self) -> str | None:
        """Close every sink (the recording's last rows are flushed); the first failure."""
        error = None
        for sink in self.sinks:
            close = getattr(sink, "close", None)
            if close is None:
                continue
            try:
                close()
            except (OSError, CosimError) as exc:
                error = error or str(exc)
        return error

    def finish(self, result: RunResult, error: str | None, signum: int | None) -> str | None:
        """Replace summary.json with the final summary; the failure to write it, if any."""
        name = signal.Signals(signum).name if signum is not None else None
        rows = self.csv.rows if self.csv is not None else 0
        if self.manoeuvre is not None:
            self.manoeuvre_summary = self.manoeuvre.summary()
        figures, manoeuvre = self.figures.figures(), self.manoeuvre_summary
        data = final_summary(self._running, result, figures, error, name, rows, manoeuvre)
        try:
            write_json_atomically(self.paths["summary"], data)
        except CosimError as exc:
            return str(exc)
        return None

    def discard(self) -> None:
        """Close the sinks and remove every file this run created (it never stepped)."""
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            self.close()
        for path in self._created:
            with contextlib.suppress(OSError):
                os.unlink(path)


def _rerun_sink(
    scenario: Scenario,
    rrd: Path | None,
    url: str | None,
    on_flushed: Callable[[int], None] | None,
) -> Any:
    """A Rerun sink for the file or the viewer; None (with a warning) without rerun."""
    try:
        from cosim.viz.recording import RerunSink
    except ImportError as exc:
        warnings.warn(
            f"no Rerun recording: cannot import cosim.viz.recording ({exc})", stacklevel=3
        )
        return None
    try:
        return RerunSink(scenario, rrd, url, on_flushed)
    except (OSError, ValueError) as exc:
        raise CosimError(f"cannot start the Rerun recording: {exc}") from None
