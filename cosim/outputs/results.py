"""The formats of a run's files: ``results.csv`` and ``summary.json``.

``results.csv``: a ``time`` column (s), then one column per recorded variable named
``<instance>.<variable>`` (in double quotes where the name holds a comma or a quote, as
RFC 4180 says), SI units (angles in rad), then a column ``fault.<name>`` per
fault of the scenario (1.0 while it acts, else 0.0), one row per communication step
including t = 0; values printed as the shortest text that reads back to the same double
(Arrow's CSV writer: ``0.1``, ``1``, ``2.5e-7``, ``inf``/``nan`` for a non-finite
value). Rows are appended as the run advances; every row ends with a newline, so a line
without one is a row still being written and readers skip it.

``summary.json`` (plain JSON: a non-finite number is written as null) exists from the
start of a run with ``"status": "running"`` and is replaced (atomically) at its end by
the full summary: ``status`` ``"complete"`` or ``"incomplete"``, ``complete``, ``error``
(the one-line reason, null if complete), ``signal`` (the signal that stopped or
interrupted the run, null if none), scenario id, ``scenario_file`` (the absolute path of the
scenario file it was read from, null for one made in memory), stop_time, step, algorithm, pid,
``outputs`` (the files the run writes), ``units`` (:func:`column_units`: ``time`` and
every results.csv column, in its order, to its unit), ``versions`` (:func:`versions`),
``fmus`` (each instance's FMU: ``model`` identifier and ``guid``), wall_clock_s (the
stepping loop alone), real_time_factor (of the loop: the simulated time it stepped, a
resumed run's from its checkpoint, over wall_clock_s), ``startup_s`` (s before the loop,
by phase: ``prepare`` the scenario and any FMU build, ``outputs`` opening the files and recording,
``load_fmus`` loading and instantiating the FMUs, ``initialise`` their initialisation,
where the plant compiles or loads its numba code, and a resumed run's ``replay`` of the rows
up to its checkpoint) and ``startup_total_s``,
time_reached (the last row computed), rows (the rows in results.csv: fewer than computed
only when results.csv could not be written, and then time_reached and the final values
are those of its last row), the final value of every column, the key figures
(:mod:`cosim.metrics.key_figures`), the FMUs' logged warnings and errors, ``events`` (each firing
of an event: ``name``, ``time`` in s, the values it ``set``; docs/events.md) and
``faults`` (``name``, ``kind``, ``target``, ``start`` and ``stop`` in s, null: never),
``overrides`` (each value set while the run went on, docs/live-runs.md: ``name``, ``time``
in s, the values it ``set``, ``source``: where it came from) and ``real_time`` (a paced
run's ``target_factor``, ``achieved_factor``, ``late_steps``, ``max_lateness_s``,
``max_lateness_at_s`` (the simulated time of that step), ``fell_behind``; null for a run
not paced), ``ended`` (the FMU that ended the simulation and when, null if none) and
``coupling`` (how the run stepped: docs/coupling.md; with ``--check-step`` its
``check_step`` holds the estimated error of every key figure and final value).
A scenario with a ``manoeuvre`` adds at the top level, from the start,
``"manoeuvre": <kind>`` and, at the end, its metrics (:mod:`cosim.outputs.manoeuvre`:
``tactical_diameter_m``, ...; null where the run cannot give one). A summary still
saying ``running`` once its process is gone belongs to a run that was killed: its
results.csv holds every row up to the last flush.
"""

from __future__ import annotations

import csv
import functools
import importlib.metadata
import io
import itertools
import math
import os
import platform
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any, BinaryIO

import numpy as np

from cosim.paths import path_text
from cosim.version import version

if TYPE_CHECKING:  # types only: the readers of results.csv need not import the master
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    from cosim.engine.master import RunResult
    from cosim.scenario.spec import Scenario


READ_CHUNK_ROWS = 50_000  # rows parsed at a time by read_csv
DIMENSIONLESS = "1"  # the unit of a fault's column, and of a variable its FMU gives none


def _doubles(column: np.ndarray) -> pa.Array:
    """One column as an Arrow array of doubles, the values as they are (a NaN stays a
    NaN). Built from the array's buffer, not with ``pa.array``, which imports pandas
    (~0.9 s) at its first call in a process to ask whether the column is pandas'."""
    import pyarrow as pa

    data = np.ascontiguousarray(column, dtype=np.float64)
    return pa.Array.from_buffers(pa.float64(), len(data), [None, pa.py_buffer(data)])


def csv_header(columns: tuple[str, ...] | list[str]) -> str:
    """The first line of results.csv, newline included: a name holding a comma or a quote
    (FMI 2.0 allows ``der(y, 2)`` and Modelica writes ``A[1,2]``) quoted as RFC 4180 says,
    so that every CSV reader finds one column per name."""
    line = io.StringIO()
    csv.writer(line, lineterminator="\n").writerow(["time", *columns])
    return line.getvalue()


def header_columns(line: str) -> list[str]:
    """The column names of results.csv's first line (:func:`csv_header`'s inverse)."""
    return next(csv.reader([line.rstrip("\r\n")]))


def csv_lines(times: np.ndarray, values: np.ndarray) -> bytes:
    """Rows as results.csv lines (UTF-8), each ending with a newline.

    pyarrow's CSV writer, not ``repr`` per value: it prints the same shortest round-trip
    text in C++ at about a quarter of the cost (the CSV was the largest per-row cost of a
    run beyond the FMUs' own steps; scripts/bench_cosim.py). ``times`` (s) and ``values``
    are doubles (the engine's row chunks).

    pyarrow is imported here, at the first rows written, not with this module: a study's
    runs write no results.csv by default (``keep = "none"``), and the workers' fork server
    imports this module for them (:mod:`cosim.study.preload`) on the way to the first run,
    where pyarrow took ~0.02-0.03 s of CPU.
    """
    import pyarrow as pa
    import pyarrow.csv as pa_csv

    columns = [_doubles(times), *(_doubles(values[:, i]) for i in range(values.shape[1]))]
    table = pa.Table.from_arrays(columns, names=[str(i) for i in range(len(columns))])
    sink = pa.BufferOutputStream()
    pa_csv.write_csv(table, sink, _csv_options())
    return sink.getvalue().to_pybytes()


@functools.cache
def _csv_options() -> pa_csv.WriteOptions:
    """Arrow's CSV writer options for results.csv's rows (no header, no quotes), made once."""
    import pyarrow.csv as pa_csv

    return pa_csv.WriteOptions(include_header=False, quoting_style="none")


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """Column names and the (rows, columns) table of a results.csv (``time`` first).

    A last line without its newline (a row being written, or torn by a crash) is skipped.
    The rows are counted first and parsed :data:`READ_CHUNK_ROWS` at a time into the
    table, so reading holds the table and one chunk of lines, not the file's whole text
    (a 36000 s run at 10 ms writes 2 GB).
    """
    with path.open("rb") as file:
        columns = _header(file, path)
        start = file.tell()
        rows = _complete_lines(file)
        file.seek(start)
        table = np.empty((rows, len(columns)))
        filled = 0
        for chunk in _parsed(file, rows, len(columns)):
            table[filled : filled + len(chunk)] = chunk
            filled += len(chunk)
    return columns, table[:filled]


class CsvRows:
    """The first ``count`` rows of a results.csv, parsed :data:`READ_CHUNK_ROWS` at a time
    as :meth:`chunks` goes, so memory holds one chunk, not the rows (a resumed run replays
    them all: 2.16 million rows of 36 columns, 620 MB as a table, for 6 h of bs-3).

    The file is opened here and read through that handle to the end of :meth:`chunks` (or
    :meth:`close`): the run that replays the rows renames the file aside and writes a new
    one by its name. ``columns``: the header's names (``time`` first); ``available``: its
    complete rows, up to ``count``; ``last``: the ``count``-th row (None if the file holds
    fewer). Raises OSError or ValueError for a file that does not read.
    """

    def __init__(self, path: Path, count: int) -> None:
        self.path, self.count = path, count
        self._file = path.open("rb")
        try:
            self.columns = _header(self._file, path)
            self._start = self._file.tell()
            self.available, last_at = _count_lines(self._file, count)
            self.last: np.ndarray | None = None
            if count and self.available == count:
                self._file.seek(last_at)
                self.last = next(_parsed(self._file, 1, len(self.columns)))[0]
        except BaseException:
            self._file.close()
            raise

    def chunks(self) -> Iterator[np.ndarray]:
        """The rows, (rows, columns) a chunk at a time, ``time`` first; the file closed at
        the end. Raises ValueError if the file holds fewer rows than counted."""
        with self._file:
            self._file.seek(self._start)
            filled = 0
            for chunk in _parsed(self._file, self.available, len(self.columns)):
                filled += len(chunk)
                yield chunk
            if filled < self.available:
                raise ValueError(f"{self.path}: {filled} rows, {self.available} counted before")

    def close(self) -> None:
        self._file.close()


def _header(file: BinaryIO, path: Path) -> list[str]:
    """The column names of the header line ``file`` starts with."""
    header = file.readline()
    if not header.endswith(b"\n"):
        raise ValueError(f"{path} holds no complete header line")
    return header_columns(header.decode("utf-8"))


def _parsed(file: BinaryIO, rows: int, columns: int) -> Iterator[np.ndarray]:
    """The next ``rows`` lines of ``file`` (or fewer, to its end) parsed as (k, ``columns``)
    arrays of at most :data:`READ_CHUNK_ROWS` rows."""
    lines = (line.decode("utf-8") for line in file)
    filled = 0
    while filled < rows:
        chunk = np.loadtxt(
            itertools.islice(lines, min(READ_CHUNK_ROWS, rows - filled)),
            delimiter=",",
            ndmin=2,
        )
        if not chunk.size:
            return
        if chunk.shape[1] != columns:
            raise ValueError(f"{chunk.shape[1]} values per row for {columns} columns")
        filled += len(chunk)
        yield chunk


def _count_lines(file: BinaryIO, most: int) -> tuple[int, int]:
    """(the newlines from ``file``'s position, up to ``most``; the offset where the line
    ending in the last one counted starts), read a block at a time."""
    count = 0
    offset = line_start = next_start = file.tell()
    while count < most and (block := file.read(1 << 20)):
        in_block = block.count(b"\n")
        if count + in_block < most:
            count += in_block
            if in_block:
                next_start = offset + block.rindex(b"\n") + 1
        else:  # the line ending in the most-th newline is in this block
            end = 0
            for _ in range(most - count):
                line_start = next_start
                end = block.index(b"\n", end) + 1
                next_start = offset + end
            count = most
        offset += len(block)
    return count, line_start if count == most else next_start


def _complete_lines(file: BinaryIO) -> int:
    """The newlines from ``file``'s position to its end (read a block at a time)."""
    count = 0
    while block := file.read(1 << 20):
        count += block.count(b"\n")
    return count


def running_summary(scenario: Scenario, outputs: Mapping[str, Path], out_dir: Path) -> dict:
    """summary.json while the run is going."""
    manoeuvre = {} if scenario.manoeuvre is None else {"manoeuvre": scenario.manoeuvre}
    return {
        "scenario": scenario.id,
        "scenario_file": None if scenario.source is None else str(Path(scenario.source).resolve()),
        **manoeuvre,
        "status": "running",
        "complete": False,
        "error": None,
        # null until the run ends; listed here, beside error, as docs/runs.md orders the keys
        "recording_error": None,
        "signal": None,
        "stop_time": scenario.stop_time,
        "step": scenario.coupling.step,
        "algorithm": scenario.coupling.algorithm,
        "pid": os.getpid(),
        "outputs": {name: _relative(path, out_dir) for name, path in outputs.items()},
        "units": column_units(scenario),
        "versions": versions(),
        "fmus": {
            name: {
                "model": inst.interface.model_identifier,
                "guid": inst.interface.guid,
                "path": path_text(inst.interface.path),
            }
            for name, inst in scenario.instances.items()
        },
    }


def column_units(scenario: Scenario) -> dict[str, str]:
    """``time`` and each results.csv column of ``scenario`` -> its unit: ``s`` for time,
    the unit the variable's FMU declares (``"1"`` where it declares none), ``"1"`` for a
    fault's column (a flag). The header of results.csv names no unit; this says them."""
    units = {"time": "s"}
    for column in scenario.record:
        instance, _, variable = column.partition(".")
        owner = scenario.instances.get(instance)  # a loaded scenario records only its own
        declared = owner.interface.variables.get(variable) if owner is not None else None
        units[column] = (declared.unit if declared is not None else None) or DIMENSIONLESS
    units.update(dict.fromkeys(scenario.columns[len(scenario.record) :], DIMENSIONLESS))
    return units


@functools.cache
def versions() -> dict[str, str | None]:
    """The versions of what ran a run: this tool (:mod:`cosim.version`; None where it
    states none), fmpy (which loads and steps the FMUs) and Python."""
    return {
        "auv-cosim": version(),
        "fmpy": importlib.metadata.version("fmpy"),
        "python": platform.python_version(),
    }


def final_summary(
    running: dict[str, Any],
    result: RunResult,
    figures: dict[str, float | None],
    error: str | None,
    signal: str | None,
    rows: int,
    manoeuvre: Mapping[str, Any] | None = None,
    last_row: tuple[float, np.ndarray] | None = None,
    recording_error: str | None = None,
) -> dict[str, Any]:
    """summary.json at the end of a run: ``running`` completed with how it ended;
    ``rows``: those in results.csv; ``manoeuvre``: the manoeuvre and its metrics
    (:meth:`cosim.outputs.manoeuvre.ManoeuvreSink.summary`), put at the top level;
    ``last_row``: (time, values) of results.csv's last row when the file stopped short
    of the rows computed (a full disk): time_reached and the final values are then that
    row's, so the summary agrees with the file; ``recording_error``: why the recording
    was cut short (the run went on without it)."""
    wall = result.wall_clock_s
    time_reached, values = result.time_reached, result.final
    if last_row is not None:
        time_reached, values = last_row
    # s, simulated by this process's loop (past the file's last row if that stopped short)
    stepped = result.time_reached - result.time_started
    final = dict(zip(result.columns, values.tolist(), strict=True))
    return {
        **running,
        "status": "complete" if error is None else "incomplete",
        "complete": error is None,
        "error": error,
        "recording_error": recording_error,
        "signal": signal,
        "wall_clock_s": wall,
        "real_time_factor": _finite(stepped / wall) if wall > 0 else None,
        "startup_s": result.startup_s,
        "startup_total_s": sum(result.startup_s.values()),
        "time_reached": time_reached,
        "rows": rows,
        "final_values": {name: _finite(value) for name, value in final.items()},
        "key_figures": figures,
        "fmu_messages": {name: lines for name, lines in result.messages.items() if lines},
        # how many each logged, the lines left out of fmu_messages (its last ones) too
        "fmu_messages_logged": result.messages_logged,
        "events": result.events,
        "faults": [
            {"name": f.name, "kind": f.kind, "target": f.target, "start": f.start, "stop": f.stop}
            for f in result.scenario.faults
        ],
        "overrides": result.overrides,
        "real_time": result.real_time,
        "ended": result.ended,
        "coupling": result.coupling,
        **(manoeuvre or {}),
    }


def _relative(path: Path, folder: Path) -> str:
    """``path`` relative to the run folder when inside it, else absolute."""
    path, folder = path.resolve(), folder.resolve()
    return str(path.relative_to(folder)) if path.is_relative_to(folder) else str(path)


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None
