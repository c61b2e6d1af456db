"""A study's runs in flight on one worker, stopped together as the study ends there.

Dask cancels a task only before it starts: a run in flight when its study stopped (a stop
signal, an error) went on, and the worker, asked by its nanny to close, waited for it;
4 s later the nanny killed the worker (SIGKILL, ``distributed.nanny``), which left its
scratch folder (:mod:`cosim.scratch`), the run's folder in it. The ~1 s runs of a study
outlived that under load (two workers' folders left, seen in a loaded suite). Each run of
a study on a worker is started here with a :class:`StopRequest` of its own, which
:meth:`RunsInFlight.stop_all` sets when the study's plugin is torn down on the worker (the
study unregistering it as it ends, or the worker closing): the master ends the run at its
next step (:mod:`cosim.engine.master`), and the task returns, its folder removed.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

from cosim.engine.signals import StopRequest

# what a run stopped so records: SIGTERM for its exit code, which no one reads (the study
# has ended), and who asked
STOPPED_BY = "the study's end"


class RunsInFlight:
    """The stop requests of the runs a worker runs for one study (thread-safe: the runs
    run on the worker's threads, the tear-down on its event loop)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._stops: dict[int, StopRequest] = {}  # id -> the run's, while it runs
        self._ended = False

    @contextmanager
    def run(self) -> Iterator[StopRequest]:
        """A run's stop request for the ``with`` block; set already if the study ended
        before the run started (its task taken as the plugin was torn down)."""
        stop = StopRequest()
        with self._lock:
            if self._ended:
                stop.record(signal.SIGTERM, by=STOPPED_BY)
            self._stops[id(stop)] = stop
        try:
            yield stop
        finally:
            with self._lock:
                del self._stops[id(stop)]

    def stop_all(self) -> int:
        """Stop every run in flight, and each run started later; how many were in
        flight."""
        with self._lock:
            self._ended = True
            for stop in self._stops.values():
                stop.record(signal.SIGTERM, by=STOPPED_BY)
            return len(self._stops)
