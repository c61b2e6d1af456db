"""Benchmark studies (issue 17). Prints four figures for N runs of bs-3 (20 s each):

1. Serial throughput (runs/s): ``cosim.study.task.run_one`` in a loop in this process --
   the baseline, with no Dask at all.
2. Throughput with 2 workers (runs/s): the same runs as a study's tasks on a local Dask
   cluster of 2 single-threaded worker processes (``cosim.study.execution``).
3. Their ratio (goal on a 2-core machine: >= 1.7).
4. The per-run overhead beyond the run's own stepping loop, as a fraction of that loop
   (goal <= 10% of a 20 s bs-3 run): serially, the run's wall time minus its loop; in the
   study, a worker's share of the elapsed time per run minus the loop.

Both throughputs are steady state: the serial loop starts timing after one warm-up run
(imports, FMU loading), the study after each worker's first run, so cluster start-up and
the first FMU load in each process are left out (they are printed separately). Other load
on the machine lowers the ratio: run it on an otherwise idle machine.
Usage: ``python scripts/bench_sweep.py [--runs 8] [--stop-time 20] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

from cosim.fmus.build import ensure_fmus
from cosim.study.design import PlannedRun, run_id
from cosim.study.execution import execute, make_job, open_client
from cosim.study.factors import resolve_factor
from cosim.study.task import RunRecord, prepare, run_one

WORKERS = 2


def planned(n: int) -> list[PlannedRun]:
    """n runs of bs-3 with distinct sway disturbances v_0 (m/s)."""
    runs = []
    for i in range(n):
        values = {"plant.v_0": -0.10 + 0.2 * i / max(1, n - 1)}
        runs.append(PlannedRun(run_id(values), values))
    return runs


def serial(base, factors, runs: list[PlannedRun]) -> tuple[float, list[RunRecord]]:
    """Seconds for ``runs[1:]`` run one after another here (runs[0] warms up)."""
    run_one(base, base.fmu_paths, factors, runs[0].values)
    started = time.perf_counter()
    records = [run_one(base, base.fmu_paths, factors, run.values) for run in runs[1:]]
    return time.perf_counter() - started, records


def parallel(base, factors, runs: list[PlannedRun]) -> tuple[float, float, list[RunRecord]]:
    """Cluster start-up seconds, and seconds from the WORKERS-th completion to the last
    (the runs after each worker's first), with their records."""
    started = time.perf_counter()
    done: list[tuple[float, RunRecord]] = []
    with open_client(WORKERS) as client:
        up = time.perf_counter() - started
        job, upload = make_job(base, factors, "none")
        execute(
            client,
            job,
            upload,
            runs,
            lambda _run, record: done.append((time.perf_counter(), record)),
        )
    assert all(record.status == "complete" for _, record in done), done
    steady = done[WORKERS - 1 :]
    return up, steady[-1][0] - steady[0][0], [record for _, record in steady[1:]]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8, help="timed runs [%(default)s]")
    parser.add_argument("--stop-time", type=float, default=20.0, help="s [%(default)s]")
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus"))
    args = parser.parse_args()
    ensure_fmus(args.fmu_dir)
    base, facts = prepare("bs-3", args.stop_time, args.fmu_dir)
    factors = {"plant.v_0": resolve_factor("plant.v_0", facts)}
    n = args.runs

    serial_s, serial_records = serial(base, factors, planned(n + 1))
    up_s, parallel_s, parallel_records = parallel(base, factors, planned(n + WORKERS))
    serial_rate, parallel_rate = n / serial_s, n / parallel_s
    loop = statistics.mean(r.loop_s for r in serial_records)
    serial_overhead = serial_s / n - loop
    parallel_loop = statistics.mean(r.loop_s for r in parallel_records)
    parallel_overhead = WORKERS * parallel_s / n - parallel_loop

    print(f"bs-3, {args.stop_time:g} s per run, {n} timed runs")
    print(f"serial throughput (1 process):     {serial_rate:.3f} runs/s")
    print(
        f"throughput with {WORKERS} workers:         {parallel_rate:.3f} runs/s "
        f"(cluster start-up {up_s:.1f} s, not counted)"
    )
    print(f"ratio:                             {parallel_rate / serial_rate:.2f} (goal >= 1.7)")
    print(
        f"per-run overhead beyond the loop:  serial {serial_overhead * 1e3:.0f} ms = "
        f"{serial_overhead / loop:.1%} of the {loop:.2f} s loop; in the study "
        f"{parallel_overhead * 1e3:.0f} ms = {parallel_overhead / parallel_loop:.1%} of the "
        f"{parallel_loop:.2f} s loop (goal <= 10%)"
    )


if __name__ == "__main__":
    main()
