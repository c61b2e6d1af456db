"""The Python API as a guest in someone else's process (a web service, a GUI, a notebook
kernel, a test suite): every public call leaves the process-wide state it found (logging,
warnings, signal handlers and the wakeup fd, hooks, environment, working folder,
``sys.path``, numpy's error state and print options, matplotlib's backend and rcParams,
umask, resource limits, the garbage collector, the locale, multiprocessing's start method,
threads, standard streams) as it was, also when it is refused or interrupted; and many
calls in one process hold no more files, libraries or objects than one.

The libraries the calls import are imported first, in the caller's process: what their
imports change (scipy's warnings filters, their ``atexit`` handlers) is theirs, not
auv-cosim's."""

from __future__ import annotations

import json
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

SNAPSHOT = """
import gc, json, locale, logging, multiprocessing, os, resource, signal, socket, sys
import threading, warnings
import matplotlib
matplotlib.use("svg")  # the user's own backend (a GUI's QtAgg, a notebook's inline)
import fmpy, matplotlib.pyplot, numba, numpy as np, pandas, PIL.Image, rerun
import scipy.sparse, scipy.special

LIMITS = ("RLIMIT_NOFILE", "RLIMIT_AS", "RLIMIT_FSIZE", "RLIMIT_STACK", "RLIMIT_CORE")
SIGNALS = ("SIGINT", "SIGTERM", "SIGHUP", "SIGPIPE", "SIGCHLD", "SIGUSR1")


def wakeup_fd():
    fd = signal.set_wakeup_fd(-1)
    signal.set_wakeup_fd(fd)
    return fd


def state():
    root, umask = logging.getLogger(), os.umask(0)
    os.umask(umask)
    loggers = logging.root.manager.loggerDict.items()
    return {
        "root logger": repr((root.handlers, root.level)),
        "loggers": {name: repr((logger.level, logger.handlers, logger.propagate,
                                logger.disabled))
                    for name, logger in loggers if isinstance(logger, logging.Logger)},
        "logging.disable": logging.root.manager.disable,
        "warnings.filters": [repr(f) for f in warnings.filters],
        "warnings.showwarning": repr(warnings.showwarning),
        "signal handlers": {s: repr(signal.getsignal(getattr(signal, s))) for s in SIGNALS},
        "signal mask": repr(signal.pthread_sigmask(signal.SIG_BLOCK, [])),
        "hooks": repr((sys.excepthook, threading.excepthook, sys.unraisablehook,
                       sys.displayhook, sys.gettrace(), sys.getprofile())),
        "os.environ": dict(os.environ),
        "cwd": os.getcwd(),
        "sys.path": list(sys.path),
        "numpy errstate": np.geterr(),
        "matplotlib backend": matplotlib.get_backend(),
        "umask": umask,
        "limits": {name: resource.getrlimit(getattr(resource, name)) for name in LIMITS},
        "threads": sorted(t.name for t in threading.enumerate()),
        "streams": repr((sys.stdin, sys.stdout, sys.stderr)),
        "interpreter": [sys.getrecursionlimit(), sys.getswitchinterval()],
        "gc": [gc.isenabled(), gc.get_threshold(), gc.get_freeze_count(), gc.get_debug()],
        "signal.set_wakeup_fd": wakeup_fd(),
        "numpy printoptions": repr(np.get_printoptions()),
        "locale": locale.setlocale(locale.LC_ALL),
        "matplotlib rcParams": {k: repr(v) for k, v in matplotlib.rcParams.items()},
        "multiprocessing start method": multiprocessing.get_start_method(allow_none=True),
    }


def changes(before, after):
    # loggers made by the call are new names, not a change of the caller's
    after["loggers"] = {n: v for n, v in after["loggers"].items() if n in before["loggers"]}
    return {k: [before[k], after[k]] for k in before if before[k] != after[k]}


def call(label, function):
    before = state()
    try:
        function()
    except (Exception, KeyboardInterrupt) as error:  # a refusal or stop: no more behind
        print(f"{label}: refused: {error}", file=sys.stderr)
    report[label] = changes(before, state())


if __name__ == "__main__":
    fmu_dir, out = sys.argv[1], sys.argv[2]
    os.environ.pop("NUMBA_CACHE_DIR", None)  # the user's own environment, as it comes
    logging.basicConfig(level=logging.INFO, format="user: %(message)s")
    warnings.simplefilter("default")
    _, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    resource.setrlimit(resource.RLIMIT_NOFILE, (min(32, hard), hard))
    wakeup, peer = socket.socketpair()  # an event loop's (asyncio sets one in its thread)
    wakeup.setblocking(False)
    signal.set_wakeup_fd(wakeup.fileno())
    report = {}
    call("import cosim", lambda: __import__("cosim").run)
    import cosim
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    call("cosim.load_scenario", lambda: cosim.load_scenario("bs-3", fmu_dir=fmu_dir))
    call("cosim.run", lambda: cosim.run(scenario, stop_time=0.5))
    call("cosim.run(out=)", lambda: cosim.run(scenario, stop_time=0.5, out=out))
    call("a refused cosim.run", lambda: cosim.run(scenario, stop_time=-1.0))
    call("cosim.run(progress=True)", lambda: cosim.run(scenario, stop_time=0.5, progress=True))
    def interrupted():
        threading.Timer(2.0, os.kill, (os.getpid(), signal.SIGINT)).start()
        cosim.run(scenario, stop_time=1e5)
    call("an interrupted cosim.run", interrupted)
    call("cosim.build_fmus", lambda: cosim.build_fmus(fmu_dir))
    study = {"scenario": "no-such-scenario", "grid": {"plant.v_0": [0.1]}}
    call("a refused cosim.sweep", lambda: cosim.sweep(study, workers=1))
    print(json.dumps(report, default=repr))
"""
# What a run leaves by design, each scoped to auv-cosim's own code (docs/api.md):
# numba's cache folder, which the plant FMU names before numba is imported and numba reads
# again at every compilation, and the filter of the stepping loop's own numpy warning.
LEFT_BY_DESIGN_ENVIRON = {"NUMBA_CACHE_DIR"}
OWN_FILTER = "re.compile('cosim\\\\.engine\\\\.master$')"


def _beyond_design(changes: dict[str, list[object]]) -> dict[str, object]:
    """``changes`` without what :data:`LEFT_BY_DESIGN_ENVIRON` and :data:`OWN_FILTER` allow."""
    left = dict(changes)
    if "os.environ" in left:
        before, after = left.pop("os.environ")
        assert isinstance(before, dict) and isinstance(after, dict)
        names = {n for n in {*before, *after} if before.get(n) != after.get(n)}
        if names - LEFT_BY_DESIGN_ENVIRON:
            left["os.environ"] = {n: [before.get(n), after.get(n)] for n in names}
    if "warnings.filters" in left:
        before, after = left.pop("warnings.filters")
        assert isinstance(before, list) and isinstance(after, list)
        if [f for f in after if not f.endswith(f"{OWN_FILTER}, 0)")] != before:
            left["warnings.filters"] = [before, after]
    return left


@pytest.mark.slow
def test_every_public_call_leaves_the_callers_process_as_it_found_it(
    run_python: Callable[..., subprocess.CompletedProcess],
    fmu_paths: dict[str, Path],
    tmp_path: Path,
) -> None:
    """A web service, a GUI or a notebook kernel calls cosim.run, load_scenario,
    build_fmus and sweep in its own process: none may leave a logging handler or level, a
    warnings filter, a signal handler, a hook, an environment variable, a working folder,
    a ``sys.path`` entry, numpy's error state, matplotlib's backend, the umask, a resource
    limit (a refused sweep left the open-files limit raised to its workers' 48), the
    collector's settings, multiprocessing's start method (a run with its progress bar chose
    it), a thread (tqdm's monitor) or a replaced standard stream behind, also when a stop
    signal ends the call."""
    fmu_dir = tmp_path / "fmus"
    fmu_dir.mkdir()
    for path in fmu_paths["AuvPlant"].parent.glob("*.fmu*"):
        shutil.copyfile(path, fmu_dir / path.name)
    done = run_python(SNAPSHOT, str(fmu_dir), str(tmp_path / "run"), timeout=600)
    assert done.returncode == 0, done.stderr
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert len(report) == 9, report
    left = {call: _beyond_design(changes) for call, changes in report.items()}
    assert all(not changes for changes in left.values()), json.dumps(left, indent=1)
    assert "no-such-scenario" in done.stderr  # the refusals were refusals, not crashes
    assert "an interrupted cosim.run: refused: interrupted (Ctrl-C)" in done.stderr


@pytest.mark.slow
def test_two_runs_on_threads_of_an_event_loop_match_a_run_in_the_main_thread(
    fmu_paths: dict[str, Path],
) -> None:
    """An asyncio service runs cosim.run on worker threads (``asyncio.to_thread``), two at
    once: no signal handler can be installed there (``signal.signal`` raises ValueError
    outside the main thread), and the runs share no folder or module state: each
    completes with the numbers of the same run in the main thread, whose SIGINT handler
    stays the caller's."""
    import asyncio
    import signal

    import cosim

    fmu_dir = fmu_paths["AuvPlant"].parent
    handler = signal.getsignal(signal.SIGINT)
    reference = cosim.run("bs-3", stop_time=1.0, fmu_dir=fmu_dir)

    async def two_at_once() -> list[cosim.Run]:
        runs = [
            asyncio.to_thread(cosim.run, "bs-3", stop_time=1.0, fmu_dir=fmu_dir) for _ in range(2)
        ]
        return list(await asyncio.gather(*runs))

    for run in asyncio.run(two_at_once()):
        assert run.complete and run.out_dir is None
        assert run.results.equals(reference.results)
    assert signal.getsignal(signal.SIGINT) is handler


@pytest.mark.slow
def test_a_run_with_progress_leaves_no_thread_and_no_start_method(
    run_python: Callable[..., subprocess.CompletedProcess], fmu_paths: dict[str, Path]
) -> None:
    """``cosim.run(..., progress=True)`` drew its bars with tqdm, which started its monitor
    thread (left running in the caller's process for good: tqdm no longer ends it with
    its last bar) and fixed multiprocessing's default start method as it made its lock,
    so that the caller's own ``multiprocessing.set_start_method("spawn")`` afterwards
    raised "context has already been set"."""
    done = run_python(
        """
        import multiprocessing, sys, threading
        import cosim

        before = {t.name for t in threading.enumerate()}
        run = cosim.run("bs-3", stop_time=0.5, fmu_dir=sys.argv[1], progress=True)
        print(run.complete)
        print(sorted(t.name for t in threading.enumerate() if t.name not in before))
        print(multiprocessing.get_start_method(allow_none=True))
        multiprocessing.set_start_method("spawn")  # the caller's own choice, still open
        """,
        fmu_paths["AuvPlant"].parent,
    )
    assert done.returncode == 0, done.stderr
    complete, threads, start_method = done.stdout.strip().splitlines()[-3:]
    assert complete == "True", done.stdout
    assert threads == "[]", threads
    assert start_method == "None", start_method
    assert "bs-3" in done.stderr  # the bar was drawn


@pytest.mark.cluster
@pytest.mark.slow
def test_a_sweep_with_or_without_progress_leaves_no_thread_and_no_start_method(
    run_python: Callable[..., subprocess.CompletedProcess], fmu_paths: dict[str, Path]
) -> None:
    """``cosim.sweep(..., progress=False)`` made its progress bar anyway, disabled: tqdm
    then still started its monitor thread, left running in the caller's process, and
    fixed multiprocessing's default start method, so that the caller's own
    ``multiprocessing.set_start_method("spawn")`` afterwards raised "context has already
    been set". With ``progress=True`` the bar it draws left tqdm's monitor thread too."""
    done = run_python(
        """
        import multiprocessing, sys, threading
        import cosim

        if __name__ == "__main__":
            before = {t.name for t in threading.enumerate()}
            study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [0.1]}}
            table = cosim.sweep(study, workers=1, fmu_dir=sys.argv[1]).table
            again = cosim.sweep(study, workers=1, fmu_dir=sys.argv[1], progress=True).table
            print(list(table["status"]) + list(again["status"]))
            print(sorted(t.name for t in threading.enumerate() if t.name not in before))
            print(multiprocessing.get_start_method(allow_none=True))
            multiprocessing.set_start_method("spawn")  # the caller's own choice, still open
        """,
        fmu_paths["AuvPlant"].parent,
    )
    assert done.returncode == 0, done.stderr
    status, threads, start_method = done.stdout.strip().splitlines()[-3:]
    assert status == "['complete', 'complete']", done.stdout
    assert "tqdm" not in threads, threads
    assert "runs:" in done.stderr  # the second study's bar was drawn
    assert start_method == "None", start_method


@pytest.mark.slow
def test_many_runs_in_one_process_hold_no_more_than_one(
    run_python: Callable[..., subprocess.CompletedProcess], fmu_paths: dict[str, Path]
) -> None:
    """An optimisation loop calls cosim.run many times in one process: each run loads
    three FMUs (their shared libraries, pythonfmu's modules, the native runtime) and
    opens files; after the first, further runs leave no more open files, mapped
    libraries, atexit handlers, threads or live Python objects (an FMU instance kept per
    run is thousands) behind."""
    done = run_python(
        """
        import atexit, gc, json, os, sys, threading
        import cosim

        def held():
            gc.collect()
            with open("/proc/self/maps") as maps:
                mapped = sorted({line.split()[-1] for line in maps if ".so" in line})
            return {
                "files": sorted(os.readlink(f"/proc/self/fd/{fd}")
                                for fd in os.listdir("/proc/self/fd") if fd.isdigit()
                                and os.path.exists(f"/proc/self/fd/{fd}")),
                "libraries": mapped, "atexit": atexit._ncallbacks(),
                "threads": sorted(t.name for t in threading.enumerate()),
                "objects": len(gc.get_objects()),
            }

        scenario = cosim.load_scenario("bs-3", fmu_dir=sys.argv[1])
        counts = []
        for batch in range(3):
            for _ in range(5):
                assert cosim.run(scenario, stop_time=0.5).complete
            counts.append(held())
        print(json.dumps(counts))
        """,
        fmu_paths["AuvPlant"].parent,
    )
    assert done.returncode == 0, done.stderr
    first, second, third = json.loads(done.stdout.strip().splitlines()[-1])
    for name in ("files", "libraries", "atexit", "threads"):
        assert first[name] == second[name] == third[name], name
    # a leak of a run's FMUs or table is thousands of objects a run; caches fill up once
    assert third["objects"] - second["objects"] < 5 * 20, (first, second, third)


@pytest.mark.cluster
@pytest.mark.slow
def test_a_ctrl_c_as_the_local_cluster_starts_stops_the_sweep(
    run_python: Callable[..., subprocess.CompletedProcess], fmu_paths: dict[str, Path]
) -> None:
    """A Ctrl-C (a notebook's stop button) while ``cosim.sweep`` started its local cluster
    was lost: SIGINT was ignored in the caller's process for the seconds the worker
    processes took to start, so that they would inherit it ignored, and the study then
    ran to its end. It stops the study as soon as the cluster has started, whose
    workers end with it."""
    done = run_python(
        """
        import os, signal, sys
        import psutil
        import cosim
        from cosim.study import execution

        class Interrupted(execution.LocalCluster):
            def __init__(self, *args, **kwargs):
                os.kill(os.getpid(), signal.SIGINT)  # the user's Ctrl-C, as it starts
                super().__init__(*args, **kwargs)

        if __name__ == "__main__":
            execution.LocalCluster = Interrupted
            study = {"scenario": "bs-3", "stop_time": 2.0, "grid": {"plant.v_0": [0.1, 0.2]}}
            try:
                table = cosim.sweep(study, workers=1, fmu_dir=sys.argv[1]).table
                print("finished", len(table))
            except cosim.SweepInterrupted as stop:
                print("stopped", len(stop.study.table))
            # the workers: the fork server's children (it stays, for the next study), or
            # processes Dask spawned itself
            children = psutil.Process().children()
            workers = [worker for child in children for worker in child.children()]
            workers += [child for child in children if "spawn_main" in child.cmdline()[-1]]
            print(len(workers))
        """,
        fmu_paths["AuvPlant"].parent,
    )
    assert done.returncode == 0, done.stderr
    outcome, workers = done.stdout.strip().splitlines()[-2:]
    assert outcome == "stopped 0", done.stdout
    assert workers == "0", done.stdout
