"""The results table: ``runs.csv``, appended one row per finished run, and ``runs.parquet``.

Columns: ``run`` (the stable id), one per factor by its full name, one per metric,
``status`` (``complete``/``failed``), ``error`` (empty if complete), ``wall_clock_s``
(the whole run task: set-up, stepping loop, outputs), and where the run is in the design:
``point`` (its grid point's number) and ``sample`` (its random sample's, empty without
``[random]``), both 0-based (:class:`cosim.study.design.PlannedRun`), so a row ties to the
design however the rows arrived. A table an older version wrote without them is given
them when it is resumed. Every row is one line, written and
flushed as its run finishes, so a killed study keeps every finished row; a line cut short
by the kill is dropped when the table is opened again (:meth:`RunsTable.reopen`). At the
end (:meth:`RunsTable.finish`) the rows are put in the study's order (the grid's points as
the file lists its factors, the first varying slowest, each with its samples in turn) and
both files are written whole: the same study gives the same table whatever the number of
workers or the order of completion (only ``wall_clock_s`` differs between identical runs).

Cells: floats as their shortest round-trip text (``repr``), so the table reads back to the
same doubles; booleans as ``true``/``false``; a missing metric (a failed run, a figure
that does not exist, such as a settling time never reached) as an empty cell. The
Parquet file holds the same rows with types (``pyarrow``; its columns built without
pandas: :mod:`cosim.study.arrow_columns`): every metric and ``wall_clock_s`` double,
``run``, ``status`` and ``error`` strings whatever the rows hold (an ``error`` column of
nulls alone, in a study without a failed run, would be typed ``null`` and not concatenate
with another study's table); each factor's and metric's unit as its field's ``unit``
metadata, and all of them as ``units`` in the ``attrs`` of the frame pandas reads (the
CSV's header names none: its names are what ``--resume`` and ``collect`` match).
"""

from __future__ import annotations

import csv
import errno
import io
import json
import os
import stat
from collections.abc import KeysView, Mapping, Sequence
from pathlib import Path
from typing import Any

import pyarrow as pa
import pyarrow.parquet as pq

from cosim.study.arrow_columns import column
from cosim.study.design import PlannedRun
from cosim.study.factors import Value
from cosim.study.signals import stop_signals_deferred
from cosim.study.spec import StudyEndedError, StudyError
from cosim.study.task import RunRecord
from cosim.whole_file import write_whole

CSV_NAME = "runs.csv"
PARQUET_NAME = "runs.parquet"
TAIL = ("status", "error", "wall_clock_s")
PLACE = ("point", "sample")  # where a run is in the study's design, after TAIL (added later)
Row = dict[str, Any]


class RunsTable:
    """The table of one study folder; rows are kept in memory for :meth:`finish`."""

    def __init__(self, path: Path, factors: Sequence[str], metrics: Sequence[str]) -> None:
        self.path = path
        self.factors = list(factors)
        self.metrics = list(metrics)
        self.columns = ["run", *self.factors, *self.metrics, *TAIL, *PLACE]
        self.rows: dict[str, Row] = {}

    @classmethod
    def create(cls, path: Path, factors: Sequence[str], metrics: Sequence[str]) -> RunsTable:
        """A new table holding only the header."""
        table = cls(path, factors, metrics)
        with path.open("w", encoding="utf-8", newline="") as f:
            f.write(_line(table.columns))
        return table

    @classmethod
    def reopen(
        cls, path: Path, factors: Sequence[str], metrics: Sequence[str], runs: Sequence[PlannedRun]
    ) -> RunsTable:
        """The table as a killed or finished study left it: a last line cut short is
        removed from the file, every complete line is kept. ``runs`` are the study's
        runs: a row of any other run, or another header, is an error. A table without
        the columns :data:`PLACE` (an older version's) is rewritten with them."""
        table = cls(path, factors, metrics)
        older = table.columns[: -len(PLACE)]
        with os.fdopen(_open_own(path), "r+b") as f:
            content = f.read()
            whole = content[: content.rfind(b"\n") + 1]
            lines = list(csv.reader(io.StringIO(whole.decode("utf-8", "replace"))))
            if lines and lines[0] not in (table.columns, older):
                raise StudyError(
                    f"{path}: its columns {lines[0]} are not this study's {table.columns}"
                )
            f.truncate(len(whole))  # a last line cut short goes
            if not lines:
                f.write(_line(table.columns).encode("utf-8"))
                return table
        by_id = {run.id: run for run in runs}
        for number, cells in enumerate(lines[1:], start=2):
            row = dict(zip(lines[0], cells, strict=False))
            run = by_id.get(row["run"])
            if run is None or len(cells) != len(lines[0]):
                raise StudyError(f"{path}, line {number}: not a row of this study's runs")
            table.rows[run.id] = table._parse(run, row)
        if lines[0] == older:
            text = _line(table.columns) + "".join(
                _line(table._cells(r)) for r in table.rows.values()
            )
            write_whole(path, lambda tmp: tmp.write_bytes(text.encode("utf-8")))
        return table

    @property
    def done(self) -> KeysView[str]:
        """Ids of the runs in the table (complete or failed): a view of the rows, so that
        asking it about each of a study's runs copies nothing (``--resume`` of a table of
        n rows asks n times)."""
        return self.rows.keys()

    def append(self, run: PlannedRun, record: RunRecord) -> None:
        """Add a finished run's row and flush it to the file, the two as one: a stop
        signal between them left a row in the file that the study did not count, and
        a study stopped after its first row then discarded the folder holding it."""
        row: Row = {"run": run.id, **run.values}
        row.update({name: _float(record.metrics.get(name)) for name in self.metrics})
        row.update(status=record.status, error=record.error, wall_clock_s=record.wall_clock_s)
        row.update(point=run.point, sample=run.sample)
        with stop_signals_deferred():
            try:
                with self.path.open("a", encoding="utf-8", newline="") as f:
                    f.write(_line(self._cells(row)))
            except OSError as exc:  # a full disk: the line cut short goes at reopen
                raise StudyEndedError(f"cannot write {self.path}: {exc.strerror or exc}") from None
            self.rows[run.id] = row

    def finish(
        self, plan: Sequence[PlannedRun], units: Mapping[str, str] | None = None
    ) -> list[Row]:
        """Rewrite runs.csv with its rows in the order of ``plan`` (the study's runs), write
        runs.parquet (``units``: factor or metric -> unit, :func:`cosim.study.units.units`,
        its fields' metadata); returns the rows in that order."""
        rows = [self.rows[run] for run in dict.fromkeys(run.id for run in plan) if run in self.rows]
        text = _line(self.columns) + "".join(_line(self._cells(row)) for row in rows)
        write_whole(self.path, lambda tmp: tmp.write_bytes(text.encode("utf-8")))
        columns = {name: [row[name] for row in rows] for name in self.columns}
        types = {name: pa.float64() for name in [*self.metrics, "wall_clock_s"]}
        types.update(dict.fromkeys(["run", "status", "error"], pa.string()))
        types.update(dict.fromkeys(PLACE, pa.int64()))
        arrays = {name: column(values, types.get(name)) for name, values in columns.items()}
        places = dict.fromkeys(PLACE, "1")
        table = _with_units(pa.table(arrays), {**(units or {}), "wall_clock_s": "s", **places})
        write_whole(self.path.with_name(PARQUET_NAME), lambda tmp: _write_parquet(table, tmp))
        return rows

    def _cells(self, row: Row) -> list[str]:
        return [_cell(row[name]) for name in self.columns]

    def _parse(self, run: PlannedRun, cells: Mapping[str, str]) -> Row:
        row: Row = {"run": run.id, **run.values}
        for name in [*self.metrics, "wall_clock_s"]:
            row[name] = float(cells[name]) if cells[name] else None
        row["status"] = cells["status"]
        row["error"] = cells["error"] or None
        row.update(point=run.point, sample=run.sample)  # the design's, whatever the file held
        return row


def _float(value: float | None) -> float | None:
    """A metric as the table holds it: a float (a whole number from JSON, a survey's
    ``legs_completed`` of 7, is 7.0, as its row reads back from runs.csv), or None."""
    return None if value is None else float(value)


def _cell(value: Value | None) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


_NO_FOLLOW = getattr(os, "O_NOFOLLOW", 0)  # not on Windows


def _open_own(path: Path) -> int:
    """``path`` (runs.csv) opened to read and write: a regular file of one name, never
    through a link. A study folder from elsewhere may hold runs.csv as a symbolic or hard
    link to one of the user's files, which resuming would cut or write over: refused.
    Raises StudyError naming it, OSError."""
    try:
        fd = os.open(path, os.O_RDWR | _NO_FOLLOW)
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            raise
        kind = "a symbolic link"
    else:
        status = os.fstat(fd)
        if stat.S_ISREG(status.st_mode) and status.st_nlink == 1:
            return fd
        os.close(fd)
        kind = "a hard link" if stat.S_ISREG(status.st_mode) else "not a regular file"
    raise StudyError(
        f"{path}: {kind}, not a runs table a study wrote (from wherever the folder came); "
        "move it away, or choose another folder"
    )


def _line(cells: Sequence[str]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow(cells)
    return buffer.getvalue()


def _with_units(table: pa.Table, units: Mapping[str, str]) -> pa.Table:
    """``table`` with each column's unit in ``units`` as its field's ``unit`` metadata, and
    all of them as the ``units`` attribute of the frame ``pandas.read_parquet`` makes
    (pandas keeps a frame's ``attrs`` in the schema's ``PANDAS_ATTRS`` metadata)."""
    units = {name: units[name] for name in table.column_names if name in units}
    fields = [
        field.with_metadata({"unit": units[field.name]}) if field.name in units else field
        for field in table.schema
    ]
    attrs = json.dumps({"units": units})
    # the same columns under a schema that differs only in its metadata; not table.cast,
    # which imports pyarrow.compute (~0.03 s of CPU) after a study's last run
    schema = pa.schema(fields, metadata={"PANDAS_ATTRS": attrs})
    return pa.Table.from_arrays(table.columns, schema=schema)


def _write_parquet(table: pa.Table, path: Path) -> None:
    """``table`` as Parquet into ``path``, through a file Python opened: pyarrow encodes a
    path it is given as strict UTF-8, and a folder named in bytes that are no UTF-8 (read
    as surrogates) failed the study at its end ("UnicodeEncodeError")."""
    with open(path, "wb") as file:
        pq.write_table(table, file)
