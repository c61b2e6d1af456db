"""The timing helpers the benchmarks share: the median of single calls (bench_plant.py,
bench_cosim.py, bench_no_numba.py) and the load average printed beside a figure."""

from __future__ import annotations

import os
import statistics
import time
from collections.abc import Callable


def median_us(call: Callable[[], object], repetitions: int) -> float:
    """Median wall time of ``call()`` in microseconds (each call timed on its own), after
    up to 100 untimed calls. Written by hand: ``timeit`` reports totals over loops, not the
    median of single calls, which shrugs off the machine's other load."""
    for _ in range(min(100, repetitions)):
        call()
    times = []
    for _ in range(repetitions):
        start = time.perf_counter_ns()
        call()
        times.append(time.perf_counter_ns() - start)
    return statistics.median(times) / 1000.0


def load() -> str:
    """The load average, 1/5/15 minutes."""
    return "/".join(f"{x:.1f}" for x in os.getloadavg())
