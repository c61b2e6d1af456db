"""Where a whole study's wall time goes: ``auv-cosim sweep`` of the end-to-end benchmark's
study (16 runs of bs-3 over 120 s, ``scripts/bench_sweep.py --end-to-end``) in a fresh
process, with 1 worker and with 2, as a timeline of seconds from the command:

* client ready: the local cluster's client is connected (its workers started);
* study checked: the scenario loaded and the factors checked (``prepare`` returned);
* worker warm-up: each worker's first task loads its FMUs (``StudyPlugin.warm``);
* runs: the first run starts (after its worker's warm-up) and the last one ends;
* table, page: ``runs.parquet`` and ``index.html`` written;
* exit: the command's process ended; pipes closed: its stderr reached end of file (the
  fork server and Dask's helpers hold it until they end: what the benchmark waits for).

The marks come from a tracer put on the sweep's ``PYTHONPATH`` as ``sitecustomize``
(written into a temporary folder, never into the tree), which wraps a few functions of
``cosim.study`` as their modules are imported, in the client and in every worker (forked
from the fork server, which imports them first). The trace costs ~1 ms a mark. CPU time
of the client is printed too (``os.wait4``). The load average is printed beside it.
Usage: ``python scripts/sweep_timeline.py [--runs 16] [--stop-time 120] [--workers 1 2]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_sweep import study_file

from cosim.fmus.build import ensure_fmus

TRACER = """
import contextlib, functools, importlib.abc, os, sys, time

LOG = os.environ["AUV_COSIM_SWEEP_TRACE"]


def mark(what):
    with open(LOG, "a", encoding="utf-8") as f:
        f.write(f"{time.time():.4f} {os.getpid()} {what}\\n")


def wrap(owner, name, label):
    original = getattr(owner, name, None)
    if original is None:
        return

    @functools.wraps(original)
    def traced(*args, **kwargs):
        mark(label + " begin")
        try:
            return original(*args, **kwargs)
        finally:
            mark(label + " end")

    setattr(owner, name, traced)


def wrap_client(module):
    original = module.open_client

    @contextlib.contextmanager
    @functools.wraps(original)
    def traced(*args, **kwargs):
        with original(*args, **kwargs) as client:
            mark("client ready")
            yield client

    module.open_client = traced


PATCHES = {
    "cosim.study.execution": lambda m: (
        wrap_client(m), wrap(m.StudyPlugin, "warm", "warm-up"), wrap(m, "run_on_worker", "task")
    ),
    "cosim.study.task": lambda m: wrap(m, "prepare", "prepare"),
    "cosim.study.table": lambda m: wrap(m.RunsTable, "finish", "table"),
    "cosim.study.runner": lambda m: wrap(m, "_write_report", "page"),
}


class Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path, target=None):
        if fullname not in PATCHES:
            return None
        for finder in sys.meta_path:
            found = None if finder is self else finder.find_spec(fullname, path, target)
            if found is not None:
                run = found.loader.exec_module

                def exec_module(module, run=run):
                    run(module)
                    PATCHES[fullname](module)

                found.loader.exec_module = exec_module
                return found
        return None


sys.meta_path.insert(0, Finder())
"""


def traced_sweep(study: Path, workers: int, fmu_dir: Path, folder: Path) -> dict[str, object]:
    """One sweep with the tracer: its marks (seconds from the command, by pid), the
    process's exit, its pipes' end of file and the client's CPU seconds."""
    log = folder / f"trace-{workers}.log"
    log.unlink(missing_ok=True)
    shutil.rmtree(folder / f"out-{workers}", ignore_errors=True)
    env = dict(os.environ, AUV_COSIM_SWEEP_TRACE=str(log))
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(folder), env.get("PYTHONPATH")]))
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--workers", str(workers)]
    command += ["--out", str(folder / f"out-{workers}"), "--fmu-dir", str(fmu_dir.resolve())]
    command += ["--quiet"]
    started = time.time()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE, start_new_session=True)  # fmt: skip
    ended: dict[str, float] = {}

    def reap() -> None:
        _, status, usage = os.wait4(process.pid, 0)
        ended["exit"], ended["status"] = time.time(), status
        ended["cpu"] = usage.ru_utime + usage.ru_stime

    reaper = threading.Thread(target=reap)
    reaper.start()
    err = process.stderr.read() if process.stderr is not None else b""
    pipes = time.time()
    reaper.join()
    if ended["status"] != 0 or err.strip():
        raise SystemExit(f"sweep with {workers} worker(s): {err.decode()[-2000:]}")
    marks = []
    for line in log.read_text(encoding="utf-8").splitlines():
        stamp, pid, what = line.split(" ", 2)
        marks.append((float(stamp) - started, int(pid), what))
    return {"marks": sorted(marks), "exit": ended["exit"] - started,
            "pipes": pipes - started, "cpu": ended["cpu"]}  # fmt: skip


def phases(trace: dict[str, object]) -> list[tuple[str, float]]:
    """The timeline's rows: (what, seconds from the command)."""
    marks = trace["marks"]
    assert isinstance(marks, list)

    def first(what: str) -> float:
        return min(t for t, _, w in marks if w == what)

    def last(what: str) -> float:
        return max(t for t, _, w in marks if w == what)

    rows = [("client ready", first("client ready")), ("study checked", first("prepare end"))]
    for k, pid in enumerate(sorted({p for _, p, w in marks if w == "warm-up begin"}), 1):
        begin = min(t for t, p, w in marks if p == pid and w == "warm-up begin")
        end = min(t for t, p, w in marks if p == pid and w == "warm-up end")
        rows += [(f"worker {k} warm-up begins", begin), (f"worker {k} warm-up ends", end)]
    rows += [("first run starts", first("warm-up end")), ("last run ends", last("task end"))]
    rows += [("table written", first("table end")), ("page written", first("page end"))]
    exit_s, pipes_s = trace["exit"], trace["pipes"]
    assert isinstance(exit_s, float) and isinstance(pipes_s, float)
    return [*rows, ("process exit", exit_s), ("pipes closed", pipes_s)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--stop-time", type=float, default=120.0, help="s [%(default)s]")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus"))
    args = parser.parse_args()
    ensure_fmus(args.fmu_dir)
    with tempfile.TemporaryDirectory(prefix="auv-cosim-timeline-") as name:
        folder = Path(name)
        (folder / "sitecustomize.py").write_text(TRACER, encoding="utf-8")
        study = study_file(folder, args.runs, args.stop_time)
        traced_sweep(study, 1, args.fmu_dir, folder)  # warm-up: compiled-code cache, disk
        traces = {}
        for workers in args.workers:
            traces[workers] = traced_sweep(study, workers, args.fmu_dir, folder)
            load = "/".join(f"{x:.1f}" for x in os.getloadavg())
            print(f"{workers} worker(s): done, load {load}", flush=True)
    print(f"bs-3, {args.runs} runs of {args.stop_time:g} s: seconds from the command")
    print(f"{'':<26}" + "".join(f"{f'{w} worker(s)':>14}" for w in traces))
    rows = {w: dict(phases(t)) for w, t in traces.items()}
    widest = sorted(rows.values(), key=len, reverse=True)  # the most workers' rows first
    names = list(dict.fromkeys(name for r in widest for name in r))
    for name in names:
        cells = [f"{rows[w][name]:14.2f}" if name in rows[w] else f"{'':>14}" for w in traces]
        print(f"{name:<26}" + "".join(cells))
    print(f"{'client CPU (s)':<26}" + "".join(f"{t['cpu']:14.2f}" for t in traces.values()))


if __name__ == "__main__":
    main()
