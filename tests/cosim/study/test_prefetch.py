"""The page's matplotlib is loaded on threads: a first part while the client waits for its
cluster, the rest once a core of the machine is idle -- not all at the start (where it
took the interpreter from the local cluster starting beside it) nor all after the last
run (where the user waits for it)."""

from __future__ import annotations

import sys
import threading

import pytest

from cosim.study import prefetch
from cosim.study.prefetch import Prefetch


@pytest.fixture
def drawn(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The threads that drew the throw-away figure (none drawn for real)."""
    threads: list[str] = []
    monkeypatch.setattr(
        prefetch, "_draw_once", lambda: threads.append(threading.current_thread().name)
    )
    return threads


def started_after(workers: int, cores: int, left: list[int]) -> int | None:
    """After which of the results (runs left after it) the loading starts, if any."""
    loading = Prefetch(workers, cores, early=(), late=())
    for k, runs in enumerate(left):
        loading.unfinished(runs)
        if loading.thread is not None:
            loading.wait()
            return k
    return None


def test_as_many_workers_as_cores_start_it_with_the_last_two_waves_of_runs(drawn) -> None:
    """2 workers on 2 cores: two runs each left at most once 4 runs are left. The loading
    shares the cores with those runs then, and is done when the last result comes,
    instead of running alone after the last one while the user waits (the runs end
    nearly together when the workers share them evenly)."""
    assert started_after(2, 2, [15, 14, 5, 4, 3, 2, 1, 0]) == 3
    assert started_after(4, 4, [11, 9, 8, 7]) == 2


def test_fewer_workers_than_cores_or_a_remote_cluster_start_it_at_the_first_result(
    drawn,
) -> None:
    assert started_after(1, 2, [15, 14]) == 0
    assert started_after(0, 2, [99]) == 0  # a remote cluster's runs use no core here
    assert drawn == ["auv-cosim-prefetch"] * 2


def test_it_starts_once_and_wait_joins_it(drawn) -> None:
    loading = Prefetch(1, 2, early=("json",), late=("csv",))
    loading.wait()  # never started: returns at once
    loading.begin()
    loading.unfinished(3)
    first, rest = loading.first, loading.thread
    loading.begin()
    loading.unfinished(2)
    assert (loading.first, loading.thread) == (first, rest)
    loading.wait()
    assert first is not None and rest is not None
    assert not first.is_alive() and not rest.is_alive()
    assert {"json", "csv"} <= set(sys.modules) and drawn == ["auv-cosim-prefetch"]


def test_the_parts_are_imported_one_after_the_other(monkeypatch, drawn) -> None:
    """The second part waits for the first (one import at a time, in order)."""
    order: list[str] = []
    gate = threading.Event()

    def record(modules) -> None:
        if modules == ("first",):
            gate.wait(5.0)
        order.extend(modules)

    monkeypatch.setattr(prefetch, "_import", record)
    loading = Prefetch(0, 2, early=("first",), late=("second",))
    loading.begin()
    loading.unfinished(5)
    gate.set()
    loading.wait()
    assert order == ["first", "second"]


def test_the_throw_away_figure_draws_with_matplotlib() -> None:
    """What the thread draws is a real figure (its failure is swallowed by the thread)."""
    prefetch._draw_once()


EXIT_WHILE_DRAWING = """
import atexit, sys
from cosim.study.prefetch import Prefetch
drawing = Prefetch(local_workers=1, cores=2)
drawing.begin()
drawing.unfinished(runs=1)  # a core is idle: the rest loads and a figure is drawn
atexit.register(lambda: print("alive" if drawing.thread.is_alive() else "joined"))
sys.exit(143)  # a stopped study's process, leaving while the drawing goes on
"""


def test_a_process_leaving_while_the_page_loads_waits_for_it(run_python) -> None:
    """The loading threads were daemons: a study stopped by SIGTERM while one drew its
    throw-away figure exited with them inside matplotlib's C++ font code, which aborted
    the process now and then (exit -6, "terminate called without an active exception").
    Now they end before the interpreter finalises: joined by the time atexit runs."""
    done = run_python(EXIT_WHILE_DRAWING)
    assert (done.returncode, done.stdout.strip()) == (143, "joined"), done.stderr


@pytest.mark.parametrize(("workers", "cores", "now"), [(2, 2, True), (1, 2, False), (0, 2, False)])
def test_with_time_to_spare_the_rest_starts_at_once_where_it_would_share_the_cores(
    drawn, workers: int, cores: int, now: bool
) -> None:
    """The client waits for a fork server warming up on the study (spare): as many local
    workers as cores load the rest before their runs, not beside their last ones; fewer
    workers, or a remote cluster, leave a core idle while the runs run and load it then."""
    loading = Prefetch(workers, cores, early=(), late=())
    loading.begin(spare=True)
    assert (loading.thread is not None) is now
    loading.unfinished(15)
    loading.wait()
    assert drawn == ["auv-cosim-prefetch"]


def test_the_figures_are_drafted_on_a_thread_after_the_loading(monkeypatch, drawn) -> None:
    """The draft waits for the loading begun (matplotlib for one thread at a time), runs
    on a thread of its own, once; wait joins it and then holds what it made."""
    order: list[str] = []
    gate = threading.Event()

    def record(modules) -> None:
        gate.wait(5.0)
        order.extend(modules)

    monkeypatch.setattr(prefetch, "_import", record)
    loading = Prefetch(1, 2, early=("first",), late=("second",))
    loading.begin()
    loading.unfinished(1)
    made = object()

    def make() -> object:
        order.append(threading.current_thread().name)
        return made

    loading.draft(make)  # type: ignore[arg-type]
    loading.draft(lambda: order.append("again"))  # type: ignore[arg-type,func-returns-value]
    assert loading.drafts is None
    gate.set()
    loading.wait()
    assert order == ["first", "second", "auv-cosim-prefetch"]
    assert loading.drafts is made


def test_a_draft_that_fails_leaves_none(drawn) -> None:
    """Drafting is an optimisation: one that raises leaves no drafts, and the page is
    drawn without them."""
    loading = Prefetch(1, 2, early=(), late=())

    def fail() -> object:
        raise RuntimeError("no fonts")

    loading.draft(fail)  # type: ignore[arg-type]
    loading.wait()
    assert loading.drafts is None
