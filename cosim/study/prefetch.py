"""The study page's matplotlib, loaded on a thread of its own once a core is idle.

Importing ``matplotlib.figure`` costs ~0.6 s of CPU (its artists build their docstrings
as their classes are made) and the first figure drawn ~0.05 s more (the Agg backend, the
fonts). Done at the start, beside the local cluster starting on its thread in the same
process, it took the interpreter from the cluster; done after the last run, the user
waits for it. So :class:`Prefetch` starts it as the results arrive, at the first result
after which one of this machine's cores has no run to run: a local cluster of as many
workers as cores has one once the runs left are fewer than its workers (a worker has
nothing left to take), a smaller local cluster or a remote one at its first result.
"""

from __future__ import annotations

import importlib
import io
import os
import threading
from collections.abc import Sequence
from contextlib import suppress

# what the figures need (cosim.study.plots), imported in this order
REPORT_MODULES = ("matplotlib.figure", "matplotlib.ticker")


class Prefetch:
    """Loads ``modules`` (and draws one small figure, thrown away) on a thread once a core
    of this machine is idle (:meth:`unfinished`); :meth:`wait` before drawing the page
    (matplotlib's state is not for two threads at once). ``local_workers``: the worker
    processes of a local cluster on this machine (0 for a remote one); ``cores``: this
    machine's (default ``os.cpu_count()``)."""

    def __init__(
        self,
        local_workers: int,
        cores: int | None = None,
        modules: Sequence[str] = REPORT_MODULES,
    ) -> None:
        self.local_workers = local_workers
        self.cores = cores if cores is not None else os.cpu_count() or 1
        self.modules = tuple(modules)
        self.thread: threading.Thread | None = None

    def unfinished(self, runs: int) -> None:
        """A result arrived and ``runs`` runs are not finished: start loading if a core
        now has no run (the busy ones: a local worker each, as many as there are runs)."""
        if self.thread is None and min(self.local_workers, runs) < self.cores:
            self.thread = threading.Thread(target=self._load, name="auv-cosim-prefetch")
            self.thread.daemon = True
            self.thread.start()

    def wait(self) -> None:
        """Until the loading has finished (nothing if it never started)."""
        if self.thread is not None:
            self.thread.join()

    def _load(self) -> None:
        for name in self.modules:
            with suppress(ImportError):
                importlib.import_module(name)
        with suppress(Exception):  # an optimisation: the page draws all the same
            _draw_once()


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
