"""Benchmark studies. Prints four figures for N runs of bs-3 (20 s each):

1. Serial throughput (runs/s): ``cosim.study.task.run_one`` in a loop in this process --
   the baseline, with no Dask at all.
2. Throughput with 2 workers (runs/s): the same runs as a study's tasks on a local Dask
   cluster of 2 single-threaded worker processes (``cosim.study.execution``).
3. Their ratio (goal on a 2-core machine: >= 1.7), beside the ratio of 2 plain worker
   processes without Dask (``multiprocessing``): what the machine itself gives two
   processes at once, the ceiling of the first.
4. The per-run overhead beyond the run's own stepping loop, as a fraction of that loop
   (goal <= 10% of a 20 s bs-3 run): serially, the elapsed time per run minus its loop; in
   the study, each task's time on its worker minus its loop (Dask's own scheduling shows
   in the ratio of item 3).

With ``--end-to-end`` it measures instead what a user waits for: ``auv-cosim sweep`` of a
16-run study of bs-3 over 120 s (``--runs``, ``--stop-time``), from the command to the
prompt in a fresh process, with 1 worker and with 2, alternating ``--repeat`` times, the
best of each; their ratio (goal >= 1.6) includes everything a study does beside its runs
(imports, the cluster's start-up, each worker's first run, hand-offs, the table, the page,
the cluster's close), with our modules imported compiled from a copy of them, as from an
installed copy (:func:`installed`). The load average is printed beside every figure. The
ratio of each 1-worker sweep to the 2-worker one right after it, and their median, are
printed too: this machine's speed drifts by up to 1.4x within minutes, so the two bests
can come from different speeds, while a back-to-back pair shares one.

All throughputs (without ``--end-to-end``) are steady state: the serial loop starts
timing after one warm-up run (imports, FMU loading), the cluster runs one untimed study
first and each timed one is timed from its workers' first completions on, so cluster
start-up and the first FMU load in each process are left out (start-up is printed).
Every process runs with one BLAS / OpenMP thread, as Dask's nanny starts its workers
(``distributed.nanny.pre-spawn-environ``), so the serial baseline is not slowed by idle
BLAS threads spinning beside a busy cluster. The measurements alternate ``--repeat``
times and the best of each is reported, to damp other load on the machine; a busy
machine still lowers the ratios.
With ``--baseline REV`` the end-to-end sweeps also run with the repository's files at git
revision REV (extracted into a temporary folder, its FMUs built there by an untimed sweep),
alternated with this tree's in every round, and both sets of figures are printed.
Usage: ``python scripts/bench_sweep.py [--runs 8] [--stop-time 20] [--repeat 3]``, or
``python scripts/bench_sweep.py --end-to-end [--runs 16] [--stop-time 120] [--repeat 3]
[--baseline REV]``.
"""

from __future__ import annotations

import argparse
import compileall
import io
import multiprocessing
import os
import shutil
import statistics
import subprocess
import sys
import tarfile
import tempfile
import time
import tomllib
from collections.abc import Mapping
from pathlib import Path

# One BLAS / OpenMP thread, as Dask's nanny starts its workers (checked in main); set
# before numpy is imported, here and (inherited) in the plain worker processes.
ONE_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
for _name, _value in ONE_THREAD.items():
    os.environ.setdefault(_name, _value)

import dask  # noqa: E402

from cosim.fmus.build import ensure_fmus  # noqa: E402
from cosim.study.design import PlannedRun, run_id  # noqa: E402
from cosim.study.execution import execute, make_job, open_client  # noqa: E402
from cosim.study.factors import resolve_factor  # noqa: E402
from cosim.study.task import RunRecord, prepare, run_one  # noqa: E402

WORKERS = 2
ROOT = Path(__file__).resolve().parents[1]


def planned(n: int) -> list[PlannedRun]:
    """n runs of bs-3 with distinct sway disturbances v_0 (m/s)."""
    runs = []
    for i in range(n):
        values = {"plant.v_0": -0.10 + 0.2 * i / max(1, n - 1)}
        runs.append(PlannedRun(run_id(values), values))
    return runs


def serial(base, factors, runs: list[PlannedRun]) -> tuple[float, list[RunRecord]]:
    """Seconds for ``runs`` run one after another in this process, and their records."""
    started = time.perf_counter()
    records = [run_one(base, base.fmu_paths, factors, run.values) for run in runs]
    return time.perf_counter() - started, records


def parallel(client, base, factors, runs: list[PlannedRun]) -> tuple[float, list[RunRecord]]:
    """Seconds from the WORKERS-th completion to the last (the runs after each worker's
    first, which loads the FMUs), and the records of those runs."""
    done: list[tuple[float, RunRecord]] = []
    job, plugin = make_job(base, factors, "none")

    def on_record(_run: PlannedRun, record: RunRecord) -> None:
        done.append((time.perf_counter(), record))

    execute(client, job, plugin, runs, on_record)
    assert all(record.status == "complete" for _, record in done), done
    steady = done[WORKERS - 1 :]
    return steady[-1][0] - steady[0][0], [record for _, record in steady[1:]]


_plain_job: tuple = ()  # (base, factors) in a plain worker process


def _plain_start(base, factors) -> None:
    """A plain worker's initialiser: keep the job, and one warm-up run (FMU loading)."""
    global _plain_job
    _plain_job = (base, factors)
    run_one(base, base.fmu_paths, factors, planned(1)[0].values)


def _plain_run(values) -> RunRecord:
    base, factors = _plain_job
    return run_one(base, base.fmu_paths, factors, values)


def plain(pool, runs: list[PlannedRun]) -> float:
    """Seconds from the WORKERS-th completion to the last, as :func:`parallel` times them,
    for the runs on a pool of WORKERS plain processes."""
    done = []
    for _record in pool.imap_unordered(_plain_run, [run.values for run in runs]):
        done.append(time.perf_counter())
    return done[-1] - done[WORKERS - 1]


def study_file(folder: Path, runs: int, stop_time: float) -> Path:
    """A study of ``runs`` runs of bs-3 over ``stop_time`` s (distinct sway disturbances)."""
    values = ", ".join(
        f"{v:.4f}" for v in (-0.10 + 0.2 * i / max(1, runs - 1) for i in range(runs))
    )
    path = folder / "study.toml"
    path.write_text(
        f'scenario = "bs-3"\nstop_time = {stop_time}\n[grid]\n"plant.v_0" = [{values}]\n',
        encoding="utf-8",
    )
    return path


def installed(tree: Path, folder: Path) -> Path:
    """Our packages of the source ``tree`` as ``pip install .`` leaves them in
    site-packages: copied into ``folder`` (never into the tree) and compiled there, as pip
    compiles a package's modules as it installs it; returns ``folder``. A source tree run
    under ``PYTHONDONTWRITEBYTECODE`` (set on some machines, this one included) compiles
    every module of ours afresh in every process, ~0.2 s of CPU each in the client and in
    the workers' fork server, both on the way to the first run."""
    found = tomllib.loads((tree / "pyproject.toml").read_text(encoding="utf-8"))
    for pattern in found["tool"]["setuptools"]["packages"]["find"]["include"]:
        package = pattern.rstrip("*")
        no_bytecode = shutil.ignore_patterns("__pycache__")
        shutil.copytree(tree / package, folder / package, ignore=no_bytecode, dirs_exist_ok=True)
        compileall.compile_dir(folder / package, quiet=1)
    return folder


def installed_env(env: Mapping[str, str], site: Path) -> dict[str, str]:
    """``env`` for a process that imports our packages from ``site`` (:func:`installed`),
    first on its path. Without ``PYTHONPYCACHEPREFIX``: under it Python reads no
    ``__pycache__`` beside a module, so each worker compiled the FMU's Python again
    (~0.05 s of CPU) instead of reading the bytecode the FMU ships
    (:mod:`cosim.fmus.bytecode`), which a user's installed copy reads."""
    env = {k: v for k, v in env.items() if k != "PYTHONPYCACHEPREFIX"}
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(site), env.get("PYTHONPATH")]))
    return env


def sweep_seconds(study: Path, workers: int, fmu_dir: Path, site: Path) -> float:
    """``auv-cosim sweep STUDY --workers N`` in a fresh process, with our packages from the
    installed copy ``site`` (:func:`installed`, its working folder too): seconds from the
    command to its exit (its own process group, ended if the benchmark is interrupted)."""
    out = study.parent / f"out-{workers}"
    shutil.rmtree(out, ignore_errors=True)
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--workers", str(workers)]
    command += ["--out", str(out), "--fmu-dir", str(fmu_dir.resolve()), "--quiet"]
    started = time.perf_counter()
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                               text=True, start_new_session=True, cwd=site,
                               env=installed_env(os.environ, site))  # fmt: skip
    try:
        _, err = process.communicate(timeout=3600)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, 9)
            process.wait()
    if process.returncode != 0:
        raise SystemExit(f"sweep with {workers} worker(s) failed: {err.strip()}")
    if err.strip():  # a study prints nothing on stderr: a traceback at shutdown is a defect
        print(f"  stderr of the sweep with {workers} worker(s):\n{err.rstrip()}", flush=True)
    return time.perf_counter() - started


def tree_at(revision: str, folder: Path) -> Path:
    """The repository's files at git ``revision``, extracted into ``folder``."""
    archive = subprocess.run(["git", "archive", revision], cwd=ROOT, capture_output=True,
                             check=True).stdout  # fmt: skip
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    return folder


def end_to_end(args: argparse.Namespace) -> None:
    """The ``--end-to-end`` figures (see the module docstring)."""
    ensure_fmus(args.fmu_dir)
    with tempfile.TemporaryDirectory(prefix="auv-cosim-bench-") as name:
        folder = Path(name)
        study = study_file(folder, args.runs, args.stop_time)
        trees = {"": (installed(ROOT, folder / "site"), args.fmu_dir)}
        if args.baseline:  # its own FMUs, built by its warm-up sweep
            base = tree_at(args.baseline, folder / "baseline")
            base_site = installed(base, folder / "baseline-site")
            trees = {
                f"{args.baseline} ": (base_site, folder / "baseline-fmus"),
                "this tree ": trees[""],
            }
        for site, fmu_dir in trees.values():
            sweep_seconds(study, 1, fmu_dir, site)  # warm-up: numba's cache, the disk cache
        times: dict[tuple[str, int], list[tuple[float, str]]] = {}
        for _ in range(args.repeat):  # alternating, so all see the same other load
            for label, (site, fmu_dir) in trees.items():
                for workers in (1, 2):
                    seconds = sweep_seconds(study, workers, fmu_dir, site)
                    load = "/".join(f"{x:.1f}" for x in os.getloadavg())
                    times.setdefault((label, workers), []).append((seconds, load))
                    print(
                        f"  {label}{workers} worker(s): {seconds:6.2f} s  load {load}", flush=True
                    )
    for label in trees:
        one, two = min(times[(label, 1)]), min(times[(label, 2)])
        print(
            f"{label}bs-3, {args.runs} runs of {args.stop_time:g} s, command to prompt, "
            f"best of {args.repeat}"
        )
        print(f"1 worker:  {one[0]:6.2f} s (load {one[1]})")
        print(f"2 workers: {two[0]:6.2f} s (load {two[1]})")
        print(f"ratio:     {one[0] / two[0]:.2f} (goal >= 1.6)")
        pairs = [a / b for (a, _), (b, _) in zip(times[(label, 1)], times[(label, 2)], strict=True)]
        print(
            f"ratio of each back-to-back pair: {' '.join(f'{r:.2f}' for r in pairs)}, "
            f"median {statistics.median(pairs):.2f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, help="timed runs [8; 16 --end-to-end]")
    parser.add_argument("--stop-time", type=float, help="s [20; 120 --end-to-end]")
    parser.add_argument("--repeat", type=int, default=3, help="best of [%(default)s]")
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus"))
    parser.add_argument("--end-to-end", action="store_true", help="whole sweeps, 1 vs 2 workers")
    parser.add_argument(
        "--baseline", help="with --end-to-end: also the tree at this git revision, alternated"
    )
    args = parser.parse_args()
    if args.end_to_end:
        args.runs = args.runs or 16
        args.stop_time = args.stop_time or 120.0
        end_to_end(args)
        return
    args.runs = args.runs or 8
    args.stop_time = args.stop_time or 20.0
    workers_environ = dask.config.get("distributed.nanny.pre-spawn-environ")
    if any(str(workers_environ.get(k)) != v for k, v in ONE_THREAD.items()):
        print(f"note: Dask's workers start with {workers_environ}, this process {ONE_THREAD}")
    ensure_fmus(args.fmu_dir)
    base, facts = prepare("bs-3", args.stop_time, args.fmu_dir)
    factors = {"plant.v_0": resolve_factor("plant.v_0", facts)}
    n = args.runs
    run_one(base, base.fmu_paths, factors, planned(1)[0].values)  # warm-up: FMU loading
    started = time.perf_counter()
    spawn = multiprocessing.get_context("spawn")
    with (
        open_client(WORKERS) as client,
        spawn.Pool(WORKERS, _plain_start, (base, factors)) as pool,
    ):
        up_s = time.perf_counter() - started
        parallel(client, base, factors, planned(2 * WORKERS))  # warm-up: FMU loading
        serials, parallels, plains = [], [], []
        for _ in range(args.repeat):  # interleaved, so all see the same other load
            serials.append(serial(base, factors, planned(n)))
            parallels.append(parallel(client, base, factors, planned(n + WORKERS)))
            plains.append(plain(pool, planned(n + WORKERS)))
    serial_s, serial_records = min(serials, key=lambda x: x[0])
    parallel_s, parallel_records = min(parallels, key=lambda x: x[0])
    report(
        args.stop_time, n, up_s, serial_s, serial_records, parallel_s, parallel_records,
        min(plains),
    )  # fmt: skip


def report(
    stop_time, n, up_s, serial_s, serial_records, parallel_s, parallel_records, plain_s
) -> None:
    serial_rate, parallel_rate, plain_rate = n / serial_s, n / parallel_s, n / plain_s
    loop = statistics.mean(r.loop_s for r in serial_records)
    serial_overhead = serial_s / n - loop
    parallel_loop = statistics.mean(r.loop_s for r in parallel_records)
    parallel_overhead = statistics.mean(r.wall_clock_s - r.loop_s for r in parallel_records)
    print(f"bs-3, {stop_time:g} s per run, {n} timed runs, best of the repeats")
    print(f"serial throughput (1 process):     {serial_rate:.3f} runs/s")
    print(
        f"throughput with {WORKERS} workers:         {parallel_rate:.3f} runs/s "
        f"(cluster start-up {up_s:.1f} s, not counted)"
    )
    print(
        f"ratio:                             {parallel_rate / serial_rate:.2f} (goal >= 1.7; "
        f"{WORKERS} plain processes without Dask: {plain_rate / serial_rate:.2f})"
    )
    print(
        f"per-run overhead beyond the loop:  serial {serial_overhead * 1e3:.0f} ms = "
        f"{serial_overhead / loop:.1%} of the {loop:.2f} s loop; in a study task "
        f"{parallel_overhead * 1e3:.0f} ms = {parallel_overhead / parallel_loop:.1%} of the "
        f"{parallel_loop:.2f} s loop (goal <= 10%)"
    )


if __name__ == "__main__":
    main()
