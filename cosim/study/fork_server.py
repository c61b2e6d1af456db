"""Where a local study's worker processes come from: a fork server that imported the run's
modules once (multiprocessing's "forkserver", where the platform has it).

Dask's default spawns each worker as a new interpreter that imports Dask, pandas, fmpy and
the run's modules again (~1.5 s of CPU each, beside the client's own imports on a 2-core
machine) and tears the interpreter down again at the end. A worker forked from the server
starts with those modules imported and ends without the teardown: on 2 cores two workers
were ready in 1.2-1.5 s instead of 2.7-2.8 s and closed in 0.05 s instead of 0.9 s
(``cosim.study.execution.open_client``). :func:`start` starts the server as early as the
command knows it will run a local study, so its imports run beside the client's.

The server is one clean process (no thread). The first module it imports
(:mod:`cosim.study.server_environ`) sets Dask's pre-spawn environment (one BLAS
thread...) in it, as Dask sets it before it spawns a worker, before numpy is imported;
not the command before it starts the server: reading Dask's configuration imports dask
(~0.2 s), which the server's imports would wait for. It then imports what every run
needs (:mod:`cosim.study.preload`: the engine, numba with its cache folder set
first and its compiler's target initialised, ~2 s of each worker's warm-up before) and
freezes it out of the garbage collector's reach; then, for the command's study only
(:func:`start` with ``warm``), it waits for the client to hand the study over
(:func:`hand_over`) and warms up on it once (:mod:`cosim.study.server_warm`), so that the
workers it forks start with the FMUs loaded; last :mod:`cosim.study.server_exit`, so
that it ends without its interpreter's teardown. This module:
standard library, dask's configuration and numba's cache folder only (not distributed,
~1 s to import, nor numba), so that the server starts before the client has imported what
the server imports.
"""

from __future__ import annotations

import functools
import importlib.util
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager, suppress
from typing import Any

import cosim.environ_writes as environ_writes
from plant_fmu.model import jit  # standard library only until numba is loaded

# what a study ends on (as cosim.engine.signals.STOP_SIGNALS, not imported here: it imports
# dataclasses and more, ~0.1 s before the server could start); no SIGHUP on Windows, where
# there is no fork server either
STOP_SIGNALS = {
    getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name)
}
# imported once, in the server, in this order
PRELOAD = [
    "cosim.study.server_environ",  # distributed too, once the environment is set
    "cosim.study.preload",
    "cosim.study.server_warm",
    "cosim.study.server_exit",
]
_pre_spawn: dict[str, str] | None = None  # Dask's pre-spawn environment, once read (start)
# names, in the server's environment, the client (its process id) and the file its
# warm-up's study is handed over in: ``<pid>:<path>``
WARM_VARIABLE = "AUV_COSIM_SERVER_WARM"
HAND_OVER_FILE = "auv-cosim-warm-up.pickle"
_hand_over: str | None = None  # that file, while the server waits for it (hand_over)
_handing = threading.Lock()  # the command's thread and its cluster's may hand over
# the study (its plugin's name) this process warmed up on, in the server
# (cosim.study.server_warm): every worker it forks afterwards inherits the mark
_warmed_on: str | None = None
# s stop() waits for the server to end before it kills it: an idle server ends in ms
STOP_WAIT_S = 1.0
STOP_POLL_S = 0.005  # s between two looks whether it has ended


def available() -> bool:
    """Whether this platform has the fork server (not Windows: there Dask spawns)."""
    return "forkserver" in multiprocessing.get_all_start_methods()


def start(warm: bool = False) -> bool:
    """Start the fork server now, if the platform has one and it is not running; whether it
    runs. Never raises: where it cannot start (its socket's path too long for AF_UNIX
    under a long TMPDIR, say), Dask starts the workers its own way. This process takes
    Dask's pre-spawn environment at each call (read at the first only: reading it parses
    Dask's defaults file, ~0.04 s, and the command calls this twice: early, and as its
    cluster starts), through :mod:`cosim.environ_writes`, so that a study of the Python
    API puts it back as it ends (Dask's nanny sets the same values before each worker).
    ``warm``: the server, if this call starts it, forks no worker before this
    process has handed it the study (:func:`hand_over`) and it has warmed up on it, or
    it gave up waiting (:mod:`cosim.study.server_warm`): only for a caller that hands it
    over as soon as it can, or ends."""
    global _pre_spawn
    if not available():
        return False
    from multiprocessing import forkserver, resource_tracker

    _say_cache_problem()
    try:
        multiprocessing.get_context("forkserver").set_forkserver_preload(PRELOAD)
        with _stop_signals_blocked():
            resource_tracker.ensure_running()
        with _stop_signals_blocked(), _warm_up_named(warm):  # (the tracker unblocked them)
            forkserver.ensure_running()
        running = True
    except (OSError, ValueError):
        running = False
    if _pre_spawn is None:
        _pre_spawn = {}
        with suppress(ImportError, KeyError):  # this process's own BLAS threads, as before
            _pre_spawn = pre_spawn_environ()
    for name, value in _pre_spawn.items():
        environ_writes.set_variable(name, value)
    return running


def stop() -> None:
    """End the fork server this process started, if it runs, and wait until it has ended,
    STOP_WAIT_S at most: a server still warming up then (importing the run's modules,
    waiting for its study or warming up on it, seconds) is killed (SIGKILL): nothing is
    lost but its warm-up, for workers no longer to be forked, and its scratch folder, which
    the next process removes (:mod:`cosim.scratch`). A later :func:`start` starts another.
    For a command whose local cluster has closed (its workers are gone) and that ends soon:
    left running, the server would end only once the command had ended (its pipe from the
    command closed), and a pipe reading the command's stderr, which the server inherited,
    waited for that (0.03-0.08 s under load, ``python scripts/sweep_pipe_holders.py``).
    By hand, as multiprocessing's own ``ForkServer._stop`` (for its tests) does, but with
    the wait bounded (``_stop`` waits for as long as the server runs). Never raises."""
    if not available():
        return
    from multiprocessing import forkserver, util

    server: Any = forkserver._forkserver  # (its private attributes, untyped)
    # (a Python without these private attributes: the server ends with the command)
    with suppress(AttributeError), server._lock:
        pid = server._forkserver_pid
        if pid is None:
            return
        os.close(server._forkserver_alive_fd)  # its end of file tells the server to end
        server._forkserver_alive_fd = server._forkserver_pid = None
        if not _reaped(pid, STOP_WAIT_S):
            with suppress(OSError):
                os.kill(pid, signal.SIGKILL)
            with suppress(ChildProcessError):
                os.waitpid(pid, 0)
        address, server._forkserver_address = server._forkserver_address, None
        if not util.is_abstract_socket_namespace(address):
            with suppress(OSError):
                os.unlink(address)


def _reaped(pid: int, wait_s: float) -> bool:
    """Whether the child ``pid`` ended (and was reaped here, or elsewhere) within
    ``wait_s`` s. By hand: the standard library waits for a child without a time limit
    only (``os.waitpid``); looked at every STOP_POLL_S."""
    deadline = time.monotonic() + wait_s
    while True:
        try:
            if os.waitpid(pid, os.WNOHANG)[0]:
                return True
        except ChildProcessError:
            return True
        if time.monotonic() >= deadline:
            return False
        time.sleep(STOP_POLL_S)


@contextmanager
def _stop_signals_blocked() -> Iterator[None]:
    """The stop signals (:data:`STOP_SIGNALS`) blocked in this thread while the block
    starts the fork server and multiprocessing's resource tracker (the server starts it
    first), so that they start with them blocked: a signal sent to the whole process group
    meanwhile (a Ctrl-C, a CI job cancelled, a hangup) waits in each, and is delivered
    here once unblocked.

    The server unblocks them once its first preload (:mod:`cosim.study.server_environ`)
    ignores them: a Ctrl-C 0.4-0.7 s into ``auv-cosim sweep`` reached the server while its
    interpreter started and imported, before that, and printed a KeyboardInterrupt
    traceback of 9-24 lines under the command's one line. The tracker unblocks only the
    two it ignores (SIGINT, SIGTERM), and keeps SIGHUP blocked: a hangup to the whole
    group killed it, and the tracker started in its place printed a KeyError traceback for
    each of the workers' semaphores it had never seen (12 in a two-worker study), after
    "process died unexpectedly ... might leak"."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _say_cache_problem() -> None:
    """Warn here, before the server starts, when numba's cache folder cannot be written (a
    ``NUMBA_CACHE_DIR`` or ``XDG_CACHE_HOME`` that cannot): the warning is then marked as
    said in the environment the server and every worker forked from it inherit
    (:data:`plant_fmu.model.jit.WARNED_VARIABLE`), so it is said once, not once by each
    worker as it compiles its FMUs' kernels. Nothing when numba is off or not installed;
    numba itself is not imported (the server's imports would wait for it)."""
    if os.environ.get(jit.NO_JIT_VARIABLE, "").strip() not in ("", "0"):
        return
    if importlib.util.find_spec("numba") is None:
        return
    environ_writes.set_default("NUMBA_CACHE_DIR", str(jit.default_cache_dir()))  # as numba's
    with environ_writes.noted(jit.WARNED_VARIABLE):  # (the model imports nothing of cosim)
        jit.cache_problem()


@contextmanager
def _warm_up_named(warm: bool) -> Iterator[None]:
    """While on, this process's environment names it and the file :func:`hand_over` will
    write (in multiprocessing's own temporary folder of this process, which holds the server's
    socket and is removed with it), for a server started meanwhile; not for one running."""
    global _hand_over
    from multiprocessing import forkserver, util

    named = warm and forkserver._forkserver._forkserver_pid is None  # type: ignore[attr-defined]
    if named:
        _hand_over = os.path.join(util.get_temp_dir(), HAND_OVER_FILE)
        os.environ[WARM_VARIABLE] = f"{os.getpid()}:{_hand_over}"
    try:
        yield
    except BaseException:
        _hand_over = None
        raise
    finally:
        if named:
            del os.environ[WARM_VARIABLE]


def hand_over(
    job: object | None, interfaces: Callable[[], Mapping[str, object]] | None = None
) -> bool:
    """Hand the study's :class:`cosim.study.execution.Job` to the fork server waiting for it
    (:func:`start` with ``warm``), once, written whole (pickled with what ``interfaces``
    returns, called only then: the job's FMU files' interfaces this process has read, by
    file, :func:`cosim.study.execution.read_interfaces`); whether it was (not if
    none waits: a server that gave up waiting left the file, empty, where the study
    would go, :func:`cosim.study.server_warm.handed_over`). None: the server is to wait
    no longer and warm nothing (a study ending before it could hand its job over, whose
    cluster's start waits for the server; a job pickle cannot write is handed over as
    None). Never raises: a server that finds nothing, or nothing it can read, warms
    nothing."""
    global _hand_over
    with _handing:
        path, _hand_over = _hand_over, None
    if path is None:
        return False
    import pickle

    content = b""
    if job is not None:
        given: Mapping[str, object] = {}
        with suppress(Exception):  # none known: the server reads the FMUs, as before
            given = dict(interfaces()) if interfaces is not None else {}
        with suppress(pickle.PicklingError, TypeError, AttributeError):  # (unpicklable)
            content = pickle.dumps((job, given), protocol=pickle.HIGHEST_PROTOCOL)
    part = path + ".part"
    try:
        with open(part, "wb") as out:
            out.write(content)
        _publish(part, path)
    except OSError:  # FileExistsError: the server's own, empty: it waits no longer
        return False
    finally:
        with suppress(OSError):
            os.unlink(part)
    return bool(content)


def _publish(part: str, path: str) -> None:
    """``part`` (written whole) made ``path`` at once, unless ``path`` exists:
    FileExistsError then (a hard link, which never replaces; a rename would overwrite
    the server's mark that it gave up). Where the file system has no hard links, a copy
    renamed into place, as before the server could give up."""
    try:
        os.link(part, path)
    except FileExistsError:
        raise
    except OSError:
        if os.path.exists(path):
            raise FileExistsError(path) from None
        os.replace(part, path)


def mark_warmed(plugin: str) -> None:
    """Note that this process, the fork server, has warmed up on the study whose plugin is
    named ``plugin`` (:mod:`cosim.study.server_warm`), for the workers it forks."""
    global _warmed_on
    _warmed_on = plugin


def warmed(plugin: str) -> bool:
    """Whether this process was forked, after its warm-up, from a fork server that warmed
    up on the study whose plugin is named ``plugin`` (a name unique to one study): its
    FMUs' package is imported, their kernels and libraries loaded."""
    return plugin == _warmed_on


def pre_spawn_environ() -> dict[str, str]:
    """Dask's ``distributed.nanny.pre-spawn-environ`` (its default and the user's Dask
    config), read without importing distributed (~1 s): its defaults file is registered
    with dask's config as ``distributed/config.py`` does when distributed is imported."""
    import importlib.util

    with libyaml_parsing():  # dask's own defaults and the user's files, read as imported
        import dask.config

    spec = importlib.util.find_spec("distributed")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("distributed is not installed")
    defaults = os.path.join(spec.submodule_search_locations[0], "distributed.yaml")
    with libyaml_parsing():
        configs = list(dask.config.collect_yaml([defaults]))  # (a generator: read now)
    for config in configs:
        dask.config.update_defaults(config)
    environ = dask.config.get("distributed.nanny.pre-spawn-environ")
    return {name: str(value) for name, value in environ.items()}


@contextmanager
def libyaml_parsing() -> Iterator[None]:
    """While on, PyYAML's ``safe_load`` parses with libyaml (``yaml.CSafeLoader``): the same
    safe constructor and resolver, so the same data, from a parser in C. Dask reads its
    configuration files with ``safe_load``, which parses in pure Python: distributed's
    defaults (``distributed.yaml``, ~1000 lines) took ~14 ms of CPU, ~1.6 ms with
    libyaml, and the command and the fork server each read it twice (as the pre-spawn
    environment is read, :func:`pre_spawn_environ`, and as distributed is imported), on
    the way to the first run. By hand: neither dask nor PyYAML has a setting for it.
    Nothing changes where PyYAML was built without libyaml; meant for one thread's
    imports (another thread's ``safe_load`` meanwhile parses in C too, to the same data)."""
    import yaml

    loader = getattr(yaml, "CSafeLoader", None)
    plain = yaml.safe_load
    if loader is not None:
        yaml.safe_load = functools.partial(yaml.load, Loader=loader)
    try:
        yield
    finally:
        yaml.safe_load = plain
