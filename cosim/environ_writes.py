"""Environment variables a piece of work sets, recorded so that only they are put back.

A study of the Python API (``cosim.sweep``) sets variables in its caller's process (Dask's
pre-spawn environment for the workers it starts, numba's cache folder, matplotlib's
folder): every process the caller starts later would inherit them, so the study puts
them back as it ends. Putting back the whole environment as it was also undid what
another thread of the caller set meanwhile; so each write of the study goes through
:func:`set_variable`, which notes, while a :func:`recorded` block is on, the value the
variable had before and the one written, and the block's end puts back only a variable
that still holds what the study wrote (one written since by another thread is that
thread's, and stays). A library that writes the environment itself (Dask's nanny writes
its pre-spawn environment before each worker) is given the same values first through
:func:`set_variable`; a write that cannot be routed here (the model's own, which imports
nothing of cosim) is noted by :func:`noted`, around that write only.

By hand: the standard library has no record of who wrote ``os.environ``, and
``unittest.mock.patch.dict`` puts back the whole mapping, as before.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager

# name -> (the value before the block's first write, None for unset; the value written)
Writes = dict[str, tuple[str | None, str]]

_lock = threading.Lock()
_recordings: list[Writes] = []  # the blocks on, innermost last


def set_variable(name: str, value: str) -> None:
    """``os.environ[name] = value``, noted by every :func:`recorded` block on."""
    with _lock:
        _note(name, os.environ.get(name), value)
        os.environ[name] = value


def set_default(name: str, value: str) -> None:
    """:func:`set_variable` of ``name`` if it is not set (``os.environ.setdefault``)."""
    with _lock:
        if name not in os.environ:
            _note(name, None, value)
            os.environ[name] = value


@contextmanager
def noted(*names: str) -> Iterator[None]:
    """While on, a write of one of ``names`` by code that cannot call :func:`set_variable`
    (a library's, the model's) is noted as if it had: keep it around that call only, since
    a write of the same name by another thread meanwhile would be taken for it."""
    before = {name: os.environ.get(name) for name in names}
    try:
        yield
    finally:
        with _lock:
            for name, value in before.items():
                after = os.environ.get(name)
                if after is not None and after != value:
                    _note(name, value, after)


@contextmanager
def recorded() -> Iterator[Writes]:
    """While on, the writes of :func:`set_variable` are noted (yielded: name -> (before,
    written)); at its end each variable that still holds what was written gets its value
    from before (unset if it had none), and one another thread wrote since keeps it."""
    writes: Writes = {}
    with _lock:
        _recordings.append(writes)
    try:
        yield writes
    finally:
        with _lock:
            _recordings.remove(writes)
            for name, (before, written) in writes.items():
                if os.environ.get(name) != written:
                    continue  # written since by someone else: theirs
                if before is None:
                    del os.environ[name]
                else:
                    os.environ[name] = before


def _note(name: str, before: str | None, value: str) -> None:
    """Note a write in each block on (the first write of a name keeps its ``before``);
    under :data:`_lock`."""
    for writes in _recordings:
        first = writes.get(name, (before, value))[0]
        writes[name] = (first, value)
