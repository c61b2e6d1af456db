"""A study table's Parquet columns, built from their buffers, are the arrays pyarrow's own
conversion gives, type and values, and are built without importing pandas (~0.9 s of the
client's CPU, taken from the workers on a machine of as many cores as workers)."""

from __future__ import annotations

import math

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cosim.study.arrow_columns import column

COLUMNS = [
    [0.1, -2.5e-7, None, math.nan, math.inf, -0.0, 1e308],
    [1, None, 2.5],  # ints beside floats: doubles
    [2**53, -(2**53), 0.5],
    [None, None],
    [],
    [True, False, None, True, True, False, False, False, True],  # more than a byte of bits
    [-1, 0, 2**62, None],
    ["a", "", None, 'é, "quoted"\n', "ünïcödé"],
    [None, "lost: 4 worker processes died"],
    ["x", 1],  # refused by pyarrow, refused here the same way
    [True, 1],
    [2**64],
]


def same(found: pa.Array, expected: pa.Array) -> bool:
    """Same type, the same values and missing values; a NaN equals a NaN, and -0.0 is
    not 0.0 (Arrow's own ``equals`` says no for NaN)."""

    def key(value: object) -> object:
        if isinstance(value, float):
            return ("nan",) if math.isnan(value) else (value, math.copysign(1.0, value))
        return value

    return found.type == expected.type and [key(v) for v in found.to_pylist()] == [
        key(v) for v in expected.to_pylist()
    ]


@pytest.mark.parametrize("values", COLUMNS)
def test_a_column_is_the_array_pyarrow_infers(values) -> None:
    try:
        expected = pa.array(values)
    except (pa.ArrowException, TypeError, ValueError, OverflowError) as exc:
        with pytest.raises(type(exc)):
            column(values)
        return
    found = column(values)
    assert same(found, expected), (found, expected)
    found.validate(full=True)


WANTED = [
    *[(pa.float64(), v) for v in ([1.5, None, 3], [None, None], [], [2**60, 1.0], [True, 2.0])],
    (pa.float64(), ["1.0"]),
    *[(pa.string(), v) for v in (["a", None, "é"], [None, None], [], ["x", 1], [b"x"])],
]


@pytest.mark.parametrize(("wanted", "values"), WANTED)
def test_a_column_of_the_wanted_type_is_the_array_pyarrow_converts(wanted, values) -> None:
    """Doubles and strings asked for: what ``pa.array(values, type=wanted)`` gives, or
    its refusal."""
    try:
        expected = pa.array(values, type=wanted)
    except (pa.ArrowException, TypeError, ValueError) as exc:
        with pytest.raises(type(exc)):
            column(values, wanted)
        return
    found = column(values, wanted)
    assert same(found, expected), (found, expected)
    found.validate(full=True)


FINISH = """
import sys
from pathlib import Path
from cosim.study.design import PlannedRun
from cosim.study.table import RunsTable
from cosim.study.task import RunRecord

table = RunsTable.create(Path(sys.argv[1]) / "runs.csv", ["plant.v_0"], ["final.plant.yaw"])
runs = [PlannedRun("a", {"plant.v_0": 0.5}), PlannedRun("b", {"plant.v_0": 0.1})]
table.append(runs[0], RunRecord("complete", None, {}, 1.0, 0.9))
table.append(runs[1], RunRecord("failed", "bad", {}, 1.0, 0.0))
table.finish(runs)
print("pandas" in sys.modules)
"""


def test_the_table_is_finished_without_importing_pandas(run_python, tmp_path) -> None:
    """runs.parquet is written without pandas: a study's client never imports it."""
    done = run_python(FINISH, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "False"
    table = pq.read_table(tmp_path / "runs.parquet")
    assert table.column("error").to_pylist() == [None, "bad"]
    assert str(table.schema.field("final.plant.yaw").type) == "double"


BUILD = """
import sys
from cosim.study.arrow_columns import column
import pyarrow as pa
arrays = [column([0.5, None]), column(["a", None]), column([True]), column([None]),
          column([1, 2]), column([1.0, None], pa.float64()), column([None], pa.string())]
print("pandas" in sys.modules, [str(a.type) for a in arrays])
"""


def test_columns_are_built_without_importing_pandas(run_python) -> None:
    done = run_python(BUILD)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == (
        "False ['double', 'string', 'bool', 'null', 'int64', 'double', 'string']"
    )


FINISH_WITH_UNITS = FINISH.replace(
    "table.finish(runs)", 'table.finish(runs, {"plant.v_0": "m/s", "final.plant.yaw": "rad"})'
).replace('print("pandas" in sys.modules)', 'print("pyarrow.compute" in sys.modules)')


def test_the_table_gets_its_units_without_importing_pyarrows_compute(run_python, tmp_path) -> None:
    """runs.parquet's units are set without pyarrow.compute (Table.cast imports it, ~0.03 s
    of the client's CPU after a study's last run), and they are still there."""
    done = run_python(FINISH_WITH_UNITS, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "False"
    schema = pq.read_schema(tmp_path / "runs.parquet")
    assert schema.field("plant.v_0").metadata == {b"unit": b"m/s"}
    assert schema.field("final.plant.yaw").metadata == {b"unit": b"rad"}
