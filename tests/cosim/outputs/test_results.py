"""results.csv's row format (cosim/outputs/results.py): every double reads back exactly."""

from __future__ import annotations

import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from cosim.outputs import results
from cosim.outputs.results import csv_header, csv_lines, header_columns, read_csv

doubles = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)


@pytest.mark.slow
@settings(max_examples=200, deadline=None)
@given(values=hnp.arrays(np.float64, hnp.array_shapes(min_dims=2, max_dims=2), elements=doubles))
def test_every_double_reads_back_bit_for_bit(values: np.ndarray, tmp_path_factory) -> None:
    """Any value a run can record -- subnormals, -0.0, +-inf, nan -- comes back from the
    file as the same double (nan as nan), one line per row."""
    times = np.arange(values.shape[0]) * 0.01
    text = csv_lines(times, values)
    assert text.count(b"\n") == values.shape[0] and text.endswith(b"\n")
    path: Path = tmp_path_factory.mktemp("csv") / "results.csv"
    columns = [f"c{i}" for i in range(values.shape[1])]
    path.write_bytes(csv_header(columns).encode() + text)
    names, table = read_csv(path)
    assert names == ["time", *columns]
    same = (table[:, 1:] == values) | (np.isnan(table[:, 1:]) & np.isnan(values))
    assert same.all()
    numbers = ~np.isnan(values)  # a nan's sign is not data
    assert np.array_equal(np.signbit(table[:, 1:])[numbers], np.signbit(values)[numbers])
    assert np.array_equal(table[:, 0], times)


WRITE_ROWS = """
import sys
import numpy as np
from cosim.outputs.results import csv_lines
print(csv_lines(np.array([0.0, 0.5]), np.array([[0.1, -2.5e-7], [np.nan, np.inf]])))
print("pandas" in sys.modules)
"""


def test_rows_are_written_without_importing_pandas(run_python) -> None:
    """A process writes its rows without importing pandas (pyarrow's conversion of a
    numpy array imports it, ~0.9 s, at its first call): a run, and each study worker,
    starts without it; the text is the shortest round-trip one."""
    done = run_python(WRITE_ROWS)
    assert done.returncode == 0, done.stderr[-2000:]
    text, pandas = done.stdout.splitlines()
    assert text == repr(b"0,0.1,-2.5e-7\n0.5,nan,inf\n")
    assert pandas == "False"


@settings(max_examples=300, deadline=None)
@given(names=st.lists(st.text(st.characters(exclude_characters="\r\n"), min_size=1), min_size=1))
def test_every_column_name_reads_back_as_itself(names: list[str]) -> None:
    """Any name an FMU may give a variable, commas and quotes included, is one column (FMI
    names are XML normalizedStrings: never a line break)."""
    line = csv_header(names)
    assert line.endswith("\n") and line.count("\n") == 1
    assert header_columns(line) == ["time", *names]


def _read_peak(path: Path) -> tuple[int, np.ndarray]:
    """tracemalloc's peak (bytes) while :func:`read_csv` reads ``path``, and the table."""
    tracemalloc.start()
    try:
        _, table = read_csv(path)
        return tracemalloc.get_traced_memory()[1], table
    finally:
        tracemalloc.stop()


def test_reading_a_long_run_holds_little_beyond_its_table(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A report of a long run (36000 s at 10 ms: a 2 GB results.csv) read the whole text,
    then a list of its lines, then the numbers: about five times the table at its peak.
    What it holds beyond the table must not grow with the file; and a torn last row is
    still skipped."""
    monkeypatch.setattr(results, "READ_CHUNK_ROWS", 5000)  # both files span several chunks
    rng = np.random.default_rng(1)
    overhead = {}
    for rows in (20_000, 80_000):
        values = rng.normal(size=(rows, 12))
        path = tmp_path / f"results{rows}.csv"
        header = csv_header([f"c{i}" for i in range(12)]).encode()
        path.write_bytes(header + csv_lines(np.arange(rows) * 0.01, values) + b"1.5,2")
        peak, table = _read_peak(path)
        assert np.array_equal(table[:, 1:], values) and table.shape == (rows, 13)
        overhead[rows] = peak - table.nbytes
    assert overhead[80_000] < 1.5 * overhead[20_000], f"bytes held beyond the table: {overhead}"
