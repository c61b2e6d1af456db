"""A table column of Python values as an Arrow array, built from its buffers: the array
``pa.array(values, type=...)`` gives, without importing pandas.

``pa.array`` asks at its first call in a process whether its argument is a pandas object,
which imports pandas (~0.9 s of CPU): a study's client paid that for ``runs.parquet`` alone,
and on a machine of as many cores as workers every CPU second of the client is taken from
the workers' start or their runs. The columns of a study's table hold floats, whole
numbers, booleans, strings and missing values (None); those are built here. Any other
column (a mix pyarrow converts its own way, or refuses) goes to ``pa.array`` itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import pyarrow as pa

_EXACT_INT = 2**53  # beyond this an int is not a double exactly: pa.array refuses it
_INT64 = 2**63


def column(values: Sequence[Any], wanted: pa.DataType | None = None) -> pa.Array:
    """``pa.array(values, type=wanted)``; ``wanted`` None: the type pyarrow infers
    (double for floats, mixed with ints too; int64; bool; string; null if every value is
    None)."""
    kind = _checked(values, wanted) if wanted is not None else _inferred(values)
    if kind is None:
        return pa.array(values, type=wanted)
    n = len(values)
    if kind == pa.null():
        return pa.nulls(n)
    valid = np.fromiter((v is not None for v in values), dtype=bool, count=n)
    nulls = n - int(valid.sum())
    bitmap = None if nulls == 0 else pa.py_buffer(np.packbits(valid, bitorder="little"))
    if kind == pa.string():
        encoded = [b"" if v is None else v.encode("utf-8") for v in values]
        offsets = np.zeros(n + 1, dtype=np.int32)
        np.cumsum([len(e) for e in encoded], out=offsets[1:])
        buffers = [bitmap, pa.py_buffer(offsets), pa.py_buffer(b"".join(encoded))]
        return pa.Array.from_buffers(kind, n, buffers, null_count=nulls)
    filled = [False if v is None else v for v in values]
    if kind == pa.bool_():
        data = np.packbits(np.array(filled, dtype=bool), bitorder="little")
    else:
        data = np.array(filled, dtype=np.float64 if kind == pa.float64() else np.int64)
    return pa.Array.from_buffers(kind, n, [bitmap, pa.py_buffer(data)], null_count=nulls)


def _inferred(values: Sequence[Any]) -> pa.DataType | None:
    """The type pyarrow infers for ``values``, if built here; else None."""
    kinds = {type(v) for v in values if v is not None}
    if not kinds:
        return pa.null()
    if kinds == {bool}:
        return pa.bool_()
    if kinds == {str}:
        return pa.string()
    if kinds == {int}:
        return pa.int64() if all(-_INT64 <= v < _INT64 for v in values if v is not None) else None
    if kinds == {float} or kinds == {int, float}:
        return _checked(values, pa.float64())
    return None


def _checked(values: Sequence[Any], wanted: pa.DataType) -> pa.DataType | None:
    """``wanted`` if it is double and every value a float, or an int a double holds
    exactly, or if it is int64 and every value an int it holds, or if it is string and
    every value a str; else None (pa.array converts or
    refuses the rest). None values are nulls of either type."""
    if wanted == pa.string():
        return wanted if all(v is None or type(v) is str for v in values) else None
    if wanted == pa.int64():
        fits = all(v is None or (type(v) is int and -_INT64 <= v < _INT64) for v in values)
        return wanted if fits else None
    if wanted != pa.float64():
        return None
    for v in values:
        if v is None or type(v) is float:  # not a subclass (bool, numpy)
            continue
        if type(v) is not int or not -_EXACT_INT <= v <= _EXACT_INT:
            return None
    return wanted
