"""The page's matplotlib is loaded on a thread once a core of the machine is idle, not at
the start (where it took the interpreter from the local cluster starting beside it) nor
after the last run (where the user waits for it)."""

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
    loading = Prefetch(workers, cores, modules=())
    for k, runs in enumerate(left):
        loading.unfinished(runs)
        if loading.thread is not None:
            loading.wait()
            return k
    return None


def test_as_many_workers_as_cores_start_it_once_a_worker_has_nothing_left(drawn) -> None:
    """2 workers on 2 cores: both busy while 2 or more runs are left."""
    assert started_after(2, 2, [15, 14, 3, 2, 1, 0]) == 4
    assert started_after(4, 4, [9, 4, 3]) == 2


def test_fewer_workers_than_cores_or_a_remote_cluster_start_it_at_the_first_result(
    drawn,
) -> None:
    assert started_after(1, 2, [15, 14]) == 0
    assert started_after(0, 2, [99]) == 0  # a remote cluster's runs use no core here
    assert drawn == ["auv-cosim-prefetch"] * 2


def test_it_starts_once_and_wait_joins_it(drawn) -> None:
    loading = Prefetch(1, 2, modules=("json",))
    loading.wait()  # never started: returns at once
    loading.unfinished(3)
    first = loading.thread
    loading.unfinished(2)
    assert loading.thread is first
    loading.wait()
    assert first is not None and not first.is_alive()
    assert "json" in sys.modules and drawn == ["auv-cosim-prefetch"]


def test_the_throw_away_figure_draws_with_matplotlib() -> None:
    """What the thread draws is a real figure (its failure is swallowed by the thread)."""
    prefetch._draw_once()
