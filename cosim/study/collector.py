"""The study command's garbage collector, off while the command imports what a study needs
and starts its cluster, as the workers' fork server's is (:mod:`cosim.study.server_environ`).

Those imports (Dask, pydantic, pyarrow, the first half of matplotlib on a thread) make about
a million objects and hardly any garbage, yet the collector ran as they did, two of its
collections walking everything imported so far: ~0.06-0.12 s of the client's CPU before
its first run (``python scripts/sweep_timeline.py``), on a 2-core machine whose other core
the fork server's imports fill. :func:`resume` turns it on again, with what exists then
frozen out of its reach (``gc.freeze``: a later full collection would walk it all again),
once the study's client is connected and before its runs are sent: what the client does
while they run, and a long remote study, collects as before.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

_paused = False  # whether pause() turned the collector off and resume() has not yet


def pause() -> None:
    """Turn the garbage collector off (nothing if it is off already)."""
    global _paused
    if gc.isenabled():
        gc.disable()
        _paused = True


def resume() -> None:
    """Freeze what exists and turn the collector on again, if :func:`pause` turned it off;
    idempotent."""
    global _paused
    if _paused:
        _paused = False
        gc.freeze()
        gc.enable()


@contextmanager
def paused() -> Iterator[None]:
    """The collector off from now until :func:`resume`, or the end of the block."""
    pause()
    try:
        yield
    finally:
        resume()


@contextmanager
def gc_diagnosis_registered() -> Iterator[None]:
    """distributed's GC diagnosis (``distributed.gc``: a ``gc.callbacks`` entry timing full
    collections) registered from this thread for the block, and taken back at its end.

    A local cluster's scheduler registers it as it starts, from its IO-loop thread; a full
    collection running meanwhile on another thread (this one, importing or checking the
    study) then ended with a "stop" the callback never saw start, which distributed
    printed as "Exception ignored in: <bound method GCDiagnosis._gc_callback ...>"
    (``assert start is not None``). Registered here first, before the cluster's threads
    start, its start and close only count the diagnosis's users. By hand: distributed has
    no setting that turns the diagnosis off or registers it safely."""
    from distributed.gc import disable_gc_diagnosis, enable_gc_diagnosis

    enable_gc_diagnosis()
    try:
        yield
    finally:
        disable_gc_diagnosis()
