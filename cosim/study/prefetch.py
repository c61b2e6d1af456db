"""The study page's matplotlib, loaded on threads of their own where the machine has room.

Importing ``matplotlib.figure`` costs ~0.6-0.8 s of CPU (its artists build their
docstrings as their classes are made) and the first figure drawn ~0.05-0.08 s more (the
Agg backend, the fonts). All of it at the start, beside the local cluster starting on its
thread in the same process and the workers' fork server importing on the other core, it
delayed the first run; all of it once a core is idle near the end, it outlasted that
idle time (half a run on average, with as many workers as cores; none when the workers
share the runs evenly and finish together) and the page waited for it. So
:class:`Prefetch` loads it in two parts: the first (:data:`EARLY_MODULES`, about half) at
:meth:`Prefetch.begin`, which the client calls before it waits for its cluster (it has
little else to do then); the rest (:data:`LATE_MODULES` and one small figure drawn) at the
first result after which one of this machine's cores has no run to run, or the local
workers have two runs each left at most: a local cluster of as many workers as cores
once the runs left are no more than twice its workers (the loading then shares the cores
with the last runs, and costs the user half its CPU time instead of all of it after the
last run; begun with the last wave only, it still ran when the last result came, and the
table waited for the interpreter: ``python scripts/sweep_timeline.py --workers 2``, 2
workers, 16 runs of bs-3 over 120 s, the last run's end to the table 0.08-0.09 s, 0.01 s
with two waves), a smaller local cluster or a remote one at its first result. Where the
client has time to spare before its first run -- the sweep's fork server warms up on the
study before it forks the workers (:mod:`cosim.study.server_warm`), ~0.15-0.2 s of CPU
the client's own start does not fill -- a local cluster of as many workers as cores loads
the rest right after the first part instead (:meth:`Prefetch.begin`). Once one run is
left, the page's figures are drafted on a thread too (:meth:`Prefetch.draft`,
:func:`cosim.study.plots.draft_figures`): the core the last run leaves idle makes what the
figures take from the rows before it (their panels and ticks, ~0.04 s of the benchmark's
~0.12 s page), where it was made after the last result, while the user waited.
"""

from __future__ import annotations

import importlib
import io
import os
import threading
from collections.abc import Callable, Sequence
from contextlib import suppress
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cosim.study.plots import Drafts

# what the figures need (cosim.study.plots), in two parts (~0.35 s and ~0.45 s of CPU)
EARLY_MODULES = ("matplotlib", "matplotlib.font_manager", "matplotlib.text")
LATE_MODULES = ("matplotlib.figure", "matplotlib.ticker")


class Prefetch:
    """Loads ``early`` on a thread at :meth:`begin`, and ``late`` (then draws one small
    figure, thrown away) on another once a core of this machine is idle
    (:meth:`unfinished`); :meth:`wait` before drawing the page (matplotlib's state is not
    for two threads at once). ``local_workers``: the worker processes of a local cluster
    on this machine (0 for a remote one); ``cores``: this machine's (default
    ``os.cpu_count()``)."""

    def __init__(
        self,
        local_workers: int,
        cores: int | None = None,
        early: Sequence[str] = EARLY_MODULES,
        late: Sequence[str] = LATE_MODULES,
    ) -> None:
        self.local_workers = local_workers
        self.cores = cores if cores is not None else os.cpu_count() or 1
        self.early = tuple(early)
        self.late = tuple(late)
        self.first: threading.Thread | None = None
        self.thread: threading.Thread | None = None  # the second part's
        self.drafting: threading.Thread | None = None
        self.drafts: Drafts | None = None  # made by draft(), once its thread has ended

    def begin(self, spare: bool = False) -> None:
        """Start loading the first part (once). ``spare``: the client waits for its
        workers' fork server longer than the first part takes (the server warms up on the
        study before it forks them, :mod:`cosim.study.server_warm`): the rest is loaded
        now too, after the first, where it would otherwise share the cores with the runs
        (as many local workers as cores); elsewhere a core is idle while the runs run."""
        if self.first is None:
            self.first = _started(lambda: _import(self.early))
        if spare and self.thread is None and self.local_workers >= self.cores:
            self.thread = _started(self._load)

    def unfinished(self, runs: int) -> None:
        """A result arrived and ``runs`` runs are not finished: start loading the rest
        if a core now has no run (the busy ones: a local worker each, as many as there
        are runs) or the local workers have two runs each left at most."""
        idle_core = min(self.local_workers, runs) < self.cores
        last_waves = runs <= 2 * self.local_workers
        if self.thread is None and (idle_core or last_waves):
            self.thread = _started(self._load)

    def draft(self, make: Callable[[], Drafts]) -> None:
        """Draft the page's figures with ``make`` on a thread (once), after the loading
        begun; :attr:`drafts` holds them once :meth:`wait` has returned (None if drafting
        failed: the page draws all the same)."""
        if self.drafting is None:
            self.drafting = _started(lambda: self._draft(make))

    def wait(self) -> None:
        """Until the loading and drafting started have finished (nothing if none started)."""
        for thread in (self.first, self.thread, self.drafting):
            if thread is not None:
                thread.join()

    def _draft(self, make: Callable[[], Drafts]) -> None:
        for thread in (self.first, self.thread):  # matplotlib for one thread at a time
            if thread is not None:
                thread.join()
        with suppress(Exception):  # an optimisation, like _draw_once
            self.drafts = make()

    def _load(self) -> None:
        if self.first is not None:  # one thread imports at a time: its modules first
            self.first.join()
        _import(self.late)
        with suppress(Exception):  # an optimisation: the page draws all the same
            _draw_once()


def _started(target: Callable[[], None]) -> threading.Thread:
    # Not a daemon: the interpreter joins it before it finalises. A daemon thread still
    # drawing when a stopped study's process exits was cut off inside matplotlib's C++
    # font code (its file reads call back into Python), which aborted the process
    # ("terminate called without an active exception", exit -6 instead of 143).
    thread = threading.Thread(target=target, name="auv-cosim-prefetch")
    thread.start()
    return thread


def _import(modules: Sequence[str]) -> None:
    for name in modules:
        with suppress(ImportError):
            importlib.import_module(name)


def _draw_once() -> None:
    """Draw a small figure into memory with what the page's figures use (a line with
    markers, a title, labels, a PNG through Agg): the backend and the fonts are loaded."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(2.0, 1.5))
    ax = fig.add_subplot()
    ax.plot([0.0, 1.0], [0.0, 1.0], marker="o", linestyle="--")
    ax.set_title("t")
    ax.set_xlabel("x (m)")
    fig.savefig(io.BytesIO(), format="png", dpi=100)
