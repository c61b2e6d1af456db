"""Where a whole study's wall time goes: ``auv-cosim sweep`` of the end-to-end benchmark's
study (16 runs of bs-3 over 120 s, ``scripts/bench_sweep.py --end-to-end``) in a fresh
process, with 1 worker and with 2, as a timeline of seconds from the command:

* study checked: the scenario loaded and the factors checked (``prepare`` returned);
* fork server imported: the workers' fork server has imported what they need
  (:mod:`cosim.study.preload`);
* client ready: the local cluster's client is connected (its workers started);
* worker warm-up: each worker's first task loads its FMUs (``StudyPlugin.warm``);
* runs: the first run starts (after its worker's warm-up), each worker's last run ends
  (from one worker's last to the other's, a core is idle) and the last one ends;
* table, page: ``runs.parquet`` and ``index.html`` written;
* exit: the command's process ended; pipes closed: its stderr reached end of file (the
  fork server and Dask's helpers hold it until they end: what the benchmark waits for).

Every sweep imports our packages compiled, from a copy of them made as ``pip install``
makes one (``bench_sweep.installed``).

The marks come from a tracer put on the sweep's ``PYTHONPATH`` as ``sitecustomize``
(written into a temporary folder, never into the tree), which wraps a few functions of
``cosim.study`` as their modules are imported, in the client and in every worker (forked
from the fork server, which imports them first). The trace costs ~1 ms a mark.

Each mark also carries its process's CPU seconds (``time.process_time``), so a second
table shows what the machine's load does not distort: the client's CPU until its cluster
is ready, while its runs run (the scheduler, the nannies and the client share its
process: on 2 cores the workers' rival; split by thread: the command's main thread, the
page's matplotlib loaded on threads of its own, and Dask's threads, the rest) and in all
(its own process's, read as it ends, :func:`reaped`), the fork server's imports and the
chain before the first warm-up that the client's readiness races (the client's CPU until
it calls the server, the server's imports -- where the server warms up on the study,
the later of them and the client's hand-over, then the server's warm-up -- the first
worker's start: which of the two is
longer says, at any load, which one the first run waits for on an idle machine), each
worker's tasks (count), warm-up and runs, and the runs' CPU over their wall time (below
1: the worker waited for a core). The load average is printed beside it. A third table
estimates, from those CPU seconds, what each sweep would take on this machine idle
(:func:`idle_estimate`): the start's longer chain, the longest warm-up, the runs spread
over the cores with the client's CPU beside them, and the client alone after the last
run; and the ratio of the two estimates, which the end-to-end benchmark's goal is about.
Under load it compares trees measured at the same time, not a tree with the goal: the
client's CPU during the runs grows with their wall time (Dask's periodic work), which
makes the two-worker estimate pessimistic (docs/performance.md).
A fourth table shows where the workers wait in the runs' phase (:func:`runs_phase`): when
each worker's first task began, the gaps between its tasks, how long it was idle before
the last run ended, when the page's figures were drafted beside the last run, and the
client's wall and CPU seconds from the last result to the page written.
``--marks`` also lists every mark until the first run, at the millisecond: among them the
local cluster's start in the client, the server's warm-up, each worker's registration
with the scheduler and each nanny's wait for its worker's word that it has started.
Usage: ``python scripts/sweep_timeline.py [--runs 16] [--stop-time 120] [--workers 1 2]
[--marks]``.
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
from bench_sweep import ROOT, installed, installed_env, study_file

from cosim.fmus.build import ensure_fmus

TRACER = """
import contextlib, functools, importlib.abc, os, sys, time

LOG = os.environ["AUV_COSIM_SWEEP_TRACE"]


def mark(what, cpu=None):
    cpu = time.process_time() if cpu is None else cpu
    with open(LOG, "a", encoding="utf-8") as f:
        f.write(f"{time.time():.4f} {os.getpid()} {cpu:.4f} {what}\\n")


def mark_threads(what, own_last):
    # each live thread's own CPU seconds, keyed "name#ident"; the marking thread's own
    # clock read last (own_last) or first, so that writing the marks falls outside
    import threading

    threads = [t for t in threading.enumerate() if t is not threading.current_thread()]
    own = [threading.current_thread()]
    for thread in [*threads, *own] if own_last else [*own, *threads]:
        with contextlib.suppress(AttributeError, OSError, TypeError):
            cpu = time.clock_gettime(time.pthread_getcpuclockid(thread.ident))
            mark(f"{what} thread {thread.name}#{thread.ident}", cpu)


def wrap_execute(module):
    original = module.execute

    @functools.wraps(original)
    def traced(*args, **kwargs):
        mark_threads("execute begin", own_last=True)  # the threads' marks before the
        mark("execute begin")  # process's, so that their cost is not counted in the runs
        try:
            return original(*args, **kwargs)
        finally:
            mark("execute end")
            mark_threads("execute end", own_last=False)

    module.execute = traced


def wrap_threads(module):
    # a prefetch thread's CPU seconds when it ends (it may end before the runs do)
    import threading

    original = module._started

    def started(target):
        def traced():
            try:
                target()
            finally:
                me = threading.current_thread()
                mark(f"thread end {me.name}#{me.ident}", time.thread_time())

        return original(traced)

    module._started = started


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


def wrap_async(owner, name, label):
    original = getattr(owner, name, None)
    if original is None:
        return

    @functools.wraps(original)
    async def traced(*args, **kwargs):
        mark(label + " begin")
        try:
            return await original(*args, **kwargs)
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
        wrap_client(m), wrap(m.StudyPlugin, "warm", "warm-up"), wrap(m, "run_on_worker", "task"),
        wrap_execute(m), wrap(m, "_local_cluster", "local cluster"),
    ),
    "distributed.worker": lambda m: wrap_async(m.Worker, "_register_with_scheduler", "register"),
    "distributed.nanny": lambda m: wrap_async(
        m.WorkerProcess, "_wait_until_connected", "nanny wait"
    ),
    "cosim.study.fork_server": lambda m: (
        wrap(m, "start", "fork server call"), wrap(m, "hand_over", "hand-over"),
    ),
    "cosim.study.server_warm": lambda m: mark("server warm-up end"),
    "cosim.study.prefetch": wrap_threads,
    "cosim.study.preload": lambda m: (mark("preload end"), wrap(m, "dask_setup", "worker start")),
    "cosim.study.task": lambda m: (wrap(m, "prepare", "prepare"), wrap(m, "warm_up", "warm_up")),
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
mark("process start")
"""


# marks of the runs' phase and after it, added to the tracer: the page's figures drafted
# beside the last run (cosim.study.prefetch's Prefetch._draft); the tasks' begin and end
# in each worker are marked already ("task begin", "task end")
TAIL_MARKS = """
_prefetch_patch = PATCHES["cosim.study.prefetch"]
PATCHES["cosim.study.prefetch"] = lambda m: (
    _prefetch_patch(m), wrap(m.Prefetch, "_draft", "draft"),
)
"""


def traced_sweep(study: Path, workers: int, fmu_dir: Path, folder: Path) -> dict[str, object]:
    """One sweep with the tracer: its marks (seconds from the command, by pid), the
    process's exit, its pipes' end of file and the client's CPU seconds."""
    log = folder / f"trace-{workers}.log"
    log.unlink(missing_ok=True)
    shutil.rmtree(folder / f"out-{workers}", ignore_errors=True)
    site = folder / "site"  # our packages, installed (an untimed sweep found them first)
    env = dict(installed_env(os.environ, site), AUV_COSIM_SWEEP_TRACE=str(log))
    env["PYTHONPATH"] = os.pathsep.join([str(folder), env["PYTHONPATH"]])  # the tracer
    command = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--workers", str(workers)]
    command += ["--out", str(folder / f"out-{workers}"), "--fmu-dir", str(fmu_dir.resolve())]
    command += ["--quiet"]
    started = time.time()
    process = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, cwd=site,
                               stderr=subprocess.PIPE, start_new_session=True)  # fmt: skip
    ended: dict[str, float] = {}

    def reap() -> None:
        ended["status"], ended["cpu"] = reaped(process.pid)
        ended["exit"] = time.time()

    reaper = threading.Thread(target=reap)
    reaper.start()
    err = process.stderr.read() if process.stderr is not None else b""
    pipes = time.time()
    reaper.join()
    if ended["status"] != 0 or err.strip():
        raise SystemExit(f"sweep with {workers} worker(s): {err.decode()[-2000:]}")
    marks = []
    for line in log.read_text(encoding="utf-8").splitlines():
        stamp, pid, cpu, what = line.split(" ", 3)
        marks.append((float(stamp) - started, int(pid), what, float(cpu)))
    return {"marks": sorted(marks), "exit": ended["exit"] - started,
            "pipes": pipes - started, "cpu": ended["cpu"]}  # fmt: skip


def reaped(pid: int) -> tuple[int, float]:
    """Wait for the child ``pid`` to end and reap it: its exit status (as ``os.wait4``'s)
    and the CPU seconds (user + system, to the kernel's tick, 0.01 s) of its own process.

    Read from ``/proc/<pid>/stat`` while the ended child waits to be reaped: the command
    ends by ``os._exit`` (:mod:`cosim.study.command_end`), after its last mark, so only
    its end can say its CPU, and ``wait4``'s figure adds the CPU of every child the
    command waited for, its descendants' with it (the fork server's, whose workers' runs
    made "client after runs" 5.2 s). Where ``/proc`` cannot say it: ``wait4``'s figure."""
    os.waitid(os.P_PID, pid, os.WEXITED | os.WNOWAIT)  # ended, not reaped: /proc has it
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            fields = stat.read().rsplit(")", 1)[1].split()  # after the command's name
        own = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime
    except (OSError, IndexError, ValueError):
        own = None
    _, status, usage = os.wait4(pid, 0)
    return status, usage.ru_utime + usage.ru_stime if own is None else own


def phases(trace: dict[str, object]) -> list[tuple[str, float]]:
    """The timeline's rows: (what, seconds from the command)."""
    marks = trace["marks"]
    assert isinstance(marks, list)

    def first(what: str) -> float:
        return min(t for t, _, w, _ in marks if w == what)

    def last(what: str) -> float:
        return max(t for t, _, w, _ in marks if w == what)

    rows = [("study checked", first("prepare end"))]
    server = [p for _, p, w, _ in marks if w == "preload end"]
    if server:
        start = min(t for t, p, w, _ in marks if p == server[0] and w == "process start")
        rows.append(("fork server starts", start))
        rows.append(("fork server imported", first("preload end")))
        rows.append(("first worker starts", first("worker start begin")))
    rows.append(("client ready", first("client ready")))
    for k, pid in enumerate(_workers(marks), 1):
        begin = min(t for t, p, w, _ in marks if p == pid and w == "warm-up begin")
        end = min(t for t, p, w, _ in marks if p == pid and w == "warm-up end")
        rows += [(f"worker {k} warm-up begins", begin), (f"worker {k} warm-up ends", end)]
    rows.append(("first run starts", first("warm-up end")))
    for k, pid in enumerate(_workers(marks), 1):  # the other's end to the last: a core idle
        rows.append((f"worker {k} last run ends", max(_task_ends(marks, pid))))
    rows.append(("last run ends", last("task end")))
    rows += [("table written", first("table end")), ("page written", first("page end"))]
    exit_s, pipes_s = trace["exit"], trace["pipes"]
    assert isinstance(exit_s, float) and isinstance(pipes_s, float)
    return [*rows, ("process exit", exit_s), ("pipes closed", pipes_s)]


def cpu_phases(trace: dict[str, object]) -> list[tuple[str, float]]:
    """CPU seconds (user + system, each process's own ``time.process_time``) of the
    processes and phases that make a study's fixed costs and its parallel efficiency:
    the client until its cluster is ready and while its runs run (the scheduler, the
    nannies and the client's threads, all in the command's process: the workers' rival
    for the cores), the fork server's imports and the chain to the first warm-up that
    the client's readiness races (the client's CPU until it calls the server, the
    server's imports, the first worker's start: the longer of it and "client until
    ready" is the start's critical path on an idle machine), each worker's warm-up, and the CPU its
    runs took against their wall time (below 1: the worker waited for a core)."""
    marks = trace["marks"]
    assert isinstance(marks, list)

    def at(what: str, pid: int | None = None) -> tuple[float, float]:
        t, cpu = min((t, c) for t, p, w, c in marks if w == what and pid in (None, p))
        return t, cpu

    client = next(p for _, p, w, _ in marks if w == "client ready")
    rows = [("client until ready", at("client ready")[1])]
    begin, end = (
        at("execute begin", client),
        max((t, c) for t, p, w, c in marks if w == "execute end" and p == client),
    )
    rows.append(("client until runs", begin[1]))
    rows.append(("client during runs", end[1] - begin[1]))
    rows += [(f"  {group}", cpu) for group, cpu in _threads_during(marks, client).items()]
    total = trace["cpu"]
    assert isinstance(total, float)
    rows.append(("client after runs", total - end[1]))
    rows.append(("client in all", total))
    servers = [(t, p, c) for t, p, w, c in marks if w == "preload end"]
    if servers:
        rows.append(("fork server imports", servers[0][2]))
        # the chain the client's readiness races: its CPU until it spawns the server, the
        # server's imports, the first worker's start (both ~1 CPU s/s when nothing waits)
        before = at("fork server call begin", client)[1]
        first = min(at("warm-up begin", pid) for pid in _workers(marks))[1]
        rows.append(("client until server call", before))
        rows.append(("server chain to warm-up", _server_chain(marks, client, before) + first))
    for k, pid in enumerate(_workers(marks), 1):
        warm = at("warm-up end", pid)[1] - at("warm-up begin", pid)[1]
        spans = _task_spans(marks, pid)
        cpu = sum(c for _, c in spans)
        wall = sum(t for t, _ in spans)
        rows.append((f"worker {k} until warm-up", at("warm-up begin", pid)[1]))  # from its fork
        rows.append((f"worker {k} tasks (count)", float(len(spans))))
        rows += [(f"worker {k} warm-up", warm), (f"worker {k} runs", cpu - warm)]
        rows.append((f"worker {k} runs CPU/wall", (cpu - warm) / max(wall - warm, 1e-9)))
    return rows


def _server_chain(marks: list[tuple[float, int, str, float]], client: int, before: float) -> float:
    """The client's CPU until it calls the fork server and the server's imports; where the
    server warms the workers up before it forks them (:mod:`cosim.study.server_warm`), the
    later of that and the client's hand-over of the study, then the server's warm-up."""
    server = next((t, p, c) for t, p, w, c in marks if w == "preload end")
    chain = before + server[2]
    warmed = [c for t, p, w, c in marks if p == server[1] and w == "server warm-up end"]
    handed = [c for t, p, w, c in marks if p == client and w == "hand-over end"]
    if warmed and handed:
        chain = max(chain, handed[0]) + warmed[0] - server[2]
    return chain


# the client's threads by what they do while the runs run: the command itself and the
# page's matplotlib loaded on its threads (cosim.study.prefetch); the rest of its CPU is
# Dask's threads' (the event loop of the scheduler, the client and the nannies, Dask's
# offload thread, each nanny's watchers of its worker process)
THREAD_GROUPS = {"MainThread": "main thread", "auv-cosim-prefetch": "page's matplotlib"}
OTHER_THREADS = "Dask's threads (the rest)"


def _threads_during(marks: list[tuple[float, int, str, float]], client: int) -> dict[str, float]:
    """The client's CPU seconds from the first run sent to the last result in (its
    ``execute``) by group of threads (:data:`THREAD_GROUPS`): each thread's own CPU clock
    at both ends, or at its end for a thread that ended between them (the page's second
    part of matplotlib, which may end before the last run); :data:`OTHER_THREADS` the
    process's CPU meanwhile that those groups did not take."""
    own = [(t, w, c) for t, p, w, c in marks if p == client]
    (start, first), (stop, last) = (
        min((t, c) for t, w, c in own if w == "execute begin"),
        max((t, c) for t, w, c in own if w == "execute end"),
    )
    begun: dict[str, float] = {}  # the first mark of each thread, its last below
    ended: dict[str, float] = {}
    for _, w, c in sorted(own):
        if w.startswith("execute begin thread "):
            begun.setdefault(w.removeprefix("execute begin thread "), c)
        elif w.startswith("execute end thread "):
            ended[w.removeprefix("execute end thread ")] = c
    for t, w, c in own:  # a thread that ended while the runs ran: its CPU at its end
        name = w.removeprefix("thread end ")
        if w.startswith("thread end ") and start <= t <= stop:
            ended.setdefault(name, c)
    groups = dict.fromkeys(THREAD_GROUPS.values(), 0.0)
    for thread, cpu in ended.items():
        group = THREAD_GROUPS.get(thread.rsplit("#", 1)[0])
        if group is not None:
            groups[group] += cpu - begun.get(thread, 0.0)
    return {**groups, OTHER_THREADS: last - first - sum(groups.values())}


def runs_phase(trace: dict[str, object]) -> list[tuple[str, float]]:
    """Where the workers wait in the runs' phase, in seconds of wall: each worker's first
    task's begin (from the first task of any worker), the gaps between one task's end and
    its next one's begin (Dask's hand-off: the result sent, the next task received), and
    its last task's end before the last run's (its core idle); the page's figures drafted
    beside the last run (begin and end from the last run's end: negative, before it);
    from the last result in to the page written, the client's wall and CPU seconds."""
    marks = trace["marks"]
    assert isinstance(marks, list)
    workers = _workers(marks)
    begins = {pid: [t for t, p, w, _ in marks if p == pid and w == "task begin"] for pid in workers}
    ends = {pid: _task_ends(marks, pid) for pid in workers}
    first = min(min(b) for b in begins.values())
    last = max(max(e) for e in ends.values())
    rows = []
    for k, pid in enumerate(workers, 1):
        gaps = [b - e for e, b in zip(ends[pid], begins[pid][1:], strict=False)]
        rows.append((f"worker {k} first task at", min(begins[pid]) - first))
        rows.append((f"worker {k} gaps (sum)", sum(gaps)))
        rows.append((f"worker {k} gap (largest)", max(gaps, default=0.0)))
        rows.append((f"worker {k} idle at the end", last - max(ends[pid])))
    drafts = [(t, w) for t, _, w, _ in marks if w in ("draft begin", "draft end")]
    rows += [(f"{w.replace('draft', 'drafting')}s", t - last) for t, w in sorted(drafts)]
    client = next(p for _, p, w, _ in marks if w == "client ready")
    result = max((t, c) for t, p, w, c in marks if p == client and w == "execute end")
    page = min((t, c) for t, p, w, c in marks if p == client and w == "page end")
    rows.append(("last result to page", page[0] - result[0]))
    rows.append(("  the client's CPU", page[1] - result[1]))
    return rows


def idle_estimate(cpu: dict[str, float], cores: int) -> list[tuple[str, float]]:
    """What the sweep whose CPU seconds are ``cpu`` (:func:`cpu_phases`) would take on an
    idle machine of ``cores`` cores, in seconds, each phase from the CPU it took (which the
    machine's load distorts far less than the wall clock): the start (the longer of the
    client's CPU until it sends the runs and the fork server's chain to the first warm-up,
    which run beside each other), the longest warm-up (the workers warm up at once, each
    on a core), the runs (the longest worker's runs, or all the workers' runs and the
    client's CPU beside them shared by the cores, whichever is longer: one worker leaves a
    core to the client, two on two cores share theirs with it) and the client's CPU after
    the last run (the table, the page, the exit: one process, alone)."""
    start = max(cpu["client until runs"], cpu.get("server chain to warm-up", 0.0))
    count = 1
    while f"worker {count} runs" in cpu:
        count += 1
    workers = range(1, count)
    warm = max(cpu[f"worker {k} warm-up"] for k in workers)
    warm = max(warm, sum(cpu[f"worker {k} warm-up"] for k in workers) / cores)
    runs = [cpu[f"worker {k} runs"] for k in workers]
    shared = (sum(runs) + cpu["client during runs"]) / cores
    rows = [("start (the longer chain)", start), ("warm-up", warm)]
    rows += [("runs", max(*runs, shared)), ("after the last run", cpu["client after runs"])]
    return [*rows, ("command to prompt", sum(s for _, s in rows))]


def start_marks(trace: dict[str, object]) -> list[str]:
    """The marks until the first run starts, one a line: ms from the command, the process
    (client, server, worker k) and its CPU ms, what."""
    marks = trace["marks"]
    assert isinstance(marks, list)
    client = next(p for _, p, w, _ in marks if w == "client ready")
    server = next((p for _, p, w, _ in marks if w == "preload end"), None)
    roles = {client: "client", server: "server"}
    roles.update({pid: f"worker {k}" for k, pid in enumerate(_workers(marks), 1)})
    first_run = min(t for t, _, w, _ in marks if w == "warm-up end")
    return [
        f"{t * 1000:7.1f} {roles.get(p, str(p)):>9} {c * 1000:7.1f}  {w}"
        for t, p, w, c in sorted(marks)
        if t <= first_run and "thread" not in w
    ]


def _workers(marks: list[tuple[float, int, str, float]]) -> list[int]:
    return sorted({p for _, p, w, _ in marks if w == "warm-up begin"})


def _task_ends(marks: list[tuple[float, int, str, float]], pid: int) -> list[float]:
    """Seconds from the command at which each task of the worker ``pid`` ended."""
    return [t for t, p, w, _ in marks if p == pid and w == "task end"]


def _task_spans(marks: list[tuple[float, int, str, float]], pid: int) -> list[tuple[float, float]]:
    """(wall s, CPU s) of each task of the worker ``pid``, its warm-up included."""
    own = [(t, w, c) for t, p, w, c in marks if p == pid and w in ("task begin", "task end")]
    spans, begun = [], None
    for t, what, cpu in own:
        if what == "task begin":
            begun = (t, cpu)
        elif begun is not None:
            spans.append((t - begun[0], cpu - begun[1]))
            begun = None
    return spans


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--stop-time", type=float, default=120.0, help="s [%(default)s]")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus"))
    parser.add_argument("--marks", action="store_true", help="print the start's every mark")
    args = parser.parse_args()
    ensure_fmus(args.fmu_dir)
    with tempfile.TemporaryDirectory(prefix="auv-cosim-timeline-") as name:
        folder = Path(name)
        (folder / "sitecustomize.py").write_text(TRACER + TAIL_MARKS, encoding="utf-8")
        study = study_file(folder, args.runs, args.stop_time)
        installed(ROOT, folder / "site")
        traced_sweep(study, 1, args.fmu_dir, folder)  # warm-up: bytecode, numba's cache, disk
        traces = {}
        for workers in args.workers:
            traces[workers] = traced_sweep(study, workers, args.fmu_dir, folder)
            load = "/".join(f"{x:.1f}" for x in os.getloadavg())
            print(f"{workers} worker(s): done, load {load}", flush=True)
    if args.marks:
        for workers, trace in traces.items():
            print(f"{workers} worker(s): the marks until the first run, ms from the command")
            print("\n".join(start_marks(trace)))
    print(f"bs-3, {args.runs} runs of {args.stop_time:g} s: seconds from the command")
    print(f"{'':<26}" + "".join(f"{f'{w} worker(s)':>14}" for w in traces))
    rows = {w: dict(phases(t)) for w, t in traces.items()}
    widest = sorted(rows.values(), key=len, reverse=True)  # the most workers' rows first
    names = list(dict.fromkeys(name for r in widest for name in r))
    for name in names:
        cells = [f"{rows[w][name]:14.2f}" if name in rows[w] else f"{'':>14}" for w in traces]
        print(f"{name:<26}" + "".join(cells))
    print("CPU seconds (ratio for CPU/wall)")
    cpu = {w: dict(cpu_phases(t)) for w, t in traces.items()}
    names = list(
        dict.fromkeys(name for r in sorted(cpu.values(), key=len, reverse=True) for name in r)
    )
    for name in names:
        cells = [f"{cpu[w][name]:14.2f}" if name in cpu[w] else f"{'':>14}" for w in traces]
        print(f"{name:<26}" + "".join(cells))
    print("the runs' phase, seconds of wall (drafting: from the last run's end)")
    tail = {w: dict(runs_phase(t)) for w, t in traces.items()}
    widest = sorted(tail.values(), key=len, reverse=True)
    for name in dict.fromkeys(name for r in widest for name in r):
        cells = [f"{tail[w][name]:14.2f}" if name in tail[w] else f"{'':>14}" for w in traces]
        print(f"{name:<26}" + "".join(cells))
    cores = os.cpu_count() or 1
    print(f"estimate for this machine idle ({cores} cores), from the CPU seconds (s)")
    estimates = {w: dict(idle_estimate(cpu[w], cores)) for w in traces}
    for name in estimates[next(iter(traces))]:
        print(f"{name:<26}" + "".join(f"{estimates[w][name]:14.2f}" for w in traces))
    if 1 in estimates and 2 in estimates:
        one, two = (estimates[w]["command to prompt"] for w in (1, 2))
        print(f"estimated ratio, 1 worker against 2: {one / two:.2f} (goal >= 1.6)")


if __name__ == "__main__":
    main()
