"""Running a study's runs on Dask: a local cluster of worker processes, or an existing one.

Local (no scheduler address): ``dask.distributed.LocalCluster`` with N single-threaded
worker PROCESSES (pythonfmu FMUs share one interpreter's modules per process, so never
threads), scheduler, nannies and workers bound to 127.0.0.1; the dashboard is off unless
asked for, and then on 127.0.0.1 too. Remote: ``Client(address)``; a ``tls://`` address
needs certificates (:func:`tls_security`, Dask's ``Security``).

Workers need the package installed, not a shared disk: the client reads each FMU once and
a worker plugin (:class:`StudyPlugin`) carries the study's shared data (:class:`Job`) to
every worker and, for a remote cluster, the FMUs and the other files the runs read
(vehicle sets, series CSVs), written into its local directory (a local cluster's workers
load the client's copies of the FMUs: :mod:`cosim.study.unpacked`) -- also to workers
that join later or are restarted by their nanny; the plugin is removed (and the files
with it) at the end. Each worker's first task first runs the scenario for one step
(:func:`cosim.study.task.warm_up`, once per worker: :meth:`StudyPlugin.warm`), so the
worker loads its FMU libraries and compiled code before its first run, which then costs
what every later one does (a worker forked from ``auv-cosim sweep``'s fork server starts
with that done once, there: :mod:`cosim.study.server_warm`); a worker that is ready starts
its runs without waiting for the others to be. Each run is one task
(:func:`run_on_worker`) that needs nothing but the plugin, so no task depends on data held
by a worker that may be lost. A run that fails is a result, not an exception. A task whose
worker died is rescheduled by the scheduler on another worker, up to
``distributed.scheduler.allowed-failures`` times (3 by default, the scheduler's setting);
only when that is exhausted (``KilledWorker``) is the run recorded as failed, with an
error saying so.

What a user waits for beyond the runs is mostly fixed cost (docs/performance.md): the
command's imports, the local cluster's start-up and each worker's first run. So
:func:`early_client` starts the local cluster on a thread while the client imports and
checks the study, and each local worker imports the run's modules as it starts
(:mod:`cosim.study.preload`).
"""

from __future__ import annotations

import ast
import asyncio
import hashlib
import logging
import multiprocessing.util
import shutil
import socket
import sys
import threading
import time
import uuid
from collections.abc import Callable, Coroutine, Iterable, Iterator, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from contextlib import AbstractContextManager, ExitStack, contextmanager, nullcontext, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, cast

import dask
import dask.system
from distributed import Client, LocalCluster, as_completed, get_worker
from distributed.comm.addressing import parse_address, parse_host_port
from distributed.diagnostics.plugin import WorkerPlugin
from distributed.scheduler import KilledWorker
from distributed.security import Security

import cosim.environ_writes as environ_writes
from cosim.errors import CosimError
from cosim.fmus.interface import FmuInterface, read_interface
from cosim.scratch import claim
from cosim.study import fork_server
from cosim.study.dask_settings import check_dask_settings
from cosim.study.design import PlannedRun
from cosim.study.factors import FactorKind, Value
from cosim.study.in_flight import RunsInFlight
from cosim.study.signals import StudyStopped, stop_signals_deferred, workers_ignore_sigint
from cosim.study.spec import StudyEndedError, StudyError
from cosim.study.task import Base, RunRecord, run_one, warm_up
from cosim.study.unpacked import local_copy, use_unpacked

LOCALHOST = "127.0.0.1"
DASHBOARD_PORT = 8787
CONNECT_TIMEOUT_S = 30
PROBE_TIMEOUT_S = 5.0  # a scheduler that does not accept a connection by then is refused
WORKER_WAIT_S = 30.0  # a scheduler without a worker for this long ends the study
WORKER_CHECK_S = 1.0  # s between two looks at the cluster's workers while no run ends
POLL_S = 0.05  # s between two looks for finished runs
HEARTBEAT_DRAIN_S = 5.0  # at most this long for a worker's last heartbeat to be answered
MAX_WORKERS_PER_CORE = 16  # local worker processes beyond this are refused, oversubscribed
FMU_FOLDER = "auv-cosim-fmus"  # in each worker's local directory
PRELOAD = "cosim.study.preload"  # imported by each local worker as it starts
# what Dask's nannies write in this process's environment as they start besides the
# pre-spawn environment (cosim.study.fork_server sets that first): the workers' hash seed
# and the process id their titles name; put back after a study of the Python API
DASK_WRITES = ("PYTHONHASHSEED", "__DASK_PARENT_PID")
# the record of a task that starts after its study ended (never shown: nobody waits for it)
ENDED_BEFORE_RUN = "the study ended before this run started"
# Dask's event-loop health check, 20 ms by default, in the scheduler, each nanny and each
# worker: ~6% of a core in an idle local cluster's client process (cluster_settings)
TICK_INTERVAL = "1s"
SYSTEM_MONITOR_INTERVAL = "5s"  # 500 ms by default; what it samples feeds the dashboard
# how often each nanny and each worker reads its worker's memory (100 ms by default, about
# half the CPU an idle local cluster takes in the client's process, its nannies', and in
# each worker, which reads it in its event loop beside the run)
MEMORY_MONITOR_INTERVAL = "500ms"
# s between two looks of a local worker's nanny for its worker's word that it has started
# and joined the scheduler (Dask's: 0.05 s); a few looks in all, each a queue's poll
NANNY_LOOK_S = 0.005
OWNERS = "auv-cosim-study-owners"  # scheduler metadata: study plugin -> its client's id


@dataclass(frozen=True)
class Job:
    """What every task of a study shares (carried to each worker by its plugin)."""

    base: Base
    factors: Mapping[str, FactorKind]
    keep: str
    check_step: bool  # each run also at h / 2 and h / 4: its coupling error metrics
    # instance -> its FMU's path in the uploaded folder, or for a local cluster's workers
    # the absolute path of the client's copy (cosim.study.unpacked.local_copy)
    fmu_files: Mapping[str, str]
    plugin: str  # name of the StudyPlugin carrying the job and the FMUs
    session: str  # this study session's token (in task keys and the plugin name)
    # SHA-256 of an FMU file -> the folder the client extracted it into, for a local
    # cluster's workers (cosim.study.unpacked); empty for a remote cluster
    unpacked: Mapping[str, str] = field(default_factory=dict)
    # a file the runs read (a vehicle set, a series CSV) as the client names it -> its
    # path in the uploaded folder; empty for a local cluster, whose workers read the file
    data_files: Mapping[str, str] = field(default_factory=dict)


class StudyPlugin(WorkerPlugin):
    """Carries a study's :class:`Job` to every worker and writes its FMU files into the
    worker's local directory at set-up; removes them at tear-down. ``files``: relative
    path -> content. The scheduler keeps the plugin, so a worker that joins later or is
    restarted after a crash gets it too."""

    def __init__(self, job: Job, files: Mapping[str, bytes]) -> None:
        self.job = job
        self.files = dict(files)
        self.name = job.plugin
        self.folder: Path | None = None
        self._warm: threading.Lock | None = None  # held while warming up; None once warm
        self.in_flight: RunsInFlight | None = None  # this study's runs on the worker

    def setup(self, worker: Any) -> None:
        """Write the FMUs; StudyError naming the worker and the folder if it cannot (a
        full or read-only disk)."""
        folder = Path(worker.local_directory) / FMU_FOLDER / self.name
        try:
            for relative, content in self.files.items():
                path = folder / relative
                path.parent.mkdir(parents=True, exist_ok=True)
                path.write_bytes(content)
        except OSError as exc:
            shutil.rmtree(folder, ignore_errors=True)
            raise StudyError(
                f"worker {worker.address} cannot write the study's FMUs into {folder}: "
                f"{exc.strerror or exc}; free its disk, or start it with a writable "
                "`dask worker --local-directory`"
            ) from None
        self.folder = folder
        use_unpacked(self.job.unpacked)
        self._warm = threading.Lock()
        self.in_flight = RunsInFlight()

    def fmu_paths(self) -> dict[str, Path]:
        """Instance -> its FMU file in this worker's local directory (after set-up)."""
        if self.folder is None:  # setup runs when the plugin is registered, before any task
            raise StudyError(f"study plugin {self.name}: not set up on this worker")
        # a path relative to the folder (carried), or the client's copy (absolute: local)
        return {instance: self.folder / rel for instance, rel in self.job.fmu_files.items()}

    def data_paths(self) -> dict[str, Path]:
        """A file the runs read, as the client names it -> its copy on this worker."""
        folder = self.folder or Path()
        return {client: folder / rel for client, rel in self.job.data_files.items()}

    def warm(self) -> None:
        """Run the scenario for one step in this worker, once (its first task does, the
        worker's other threads waiting): its FMUs and their compiled code are loaded.
        Here and not in :meth:`setup`, which every worker must finish before the client
        may submit a task: a worker that is ready starts its runs at once. Not in a worker
        forked from a fork server that warmed up on this study
        (:func:`cosim.study.fork_server.warmed`): that would be one more run of one step,
        which no later run needs."""
        lock = self._warm
        if lock is None:
            return
        with lock:
            if self._warm is not None:
                if not fork_server.warmed(self.job.plugin):
                    warm_up(self.job.base, self.fmu_paths(), self.data_paths())
                self._warm = None

    def teardown(self, worker: Any) -> None:
        """The study's end on this worker: its runs in flight stopped at their next step
        (:mod:`cosim.study.in_flight`), its FMUs removed."""
        if self.in_flight is not None:
            self.in_flight.stop_all()
        if self.folder is not None:
            shutil.rmtree(self.folder, ignore_errors=True)


def usable_cores() -> int:
    """The cores this process may use, as Dask counts them: the machine's, fewer under a
    CPU affinity (``taskset -c 0``) or a cgroup's CPU quota (a container's ``--cpus 1``),
    which a count of the machine's cores (``os.cpu_count()``) ignores."""
    return int(dask.system.cpu_count())


def local_workers(requested: object, oversubscribe: bool = False) -> int:
    """The local worker processes of a study asked for ``requested`` (None: one per core
    this process may use, :func:`usable_cores`): a whole number >= 1, at most those cores
    unless ``oversubscribe``. Raises StudyError."""
    cores = usable_cores()
    if requested is None:
        return cores
    shown = repr(requested) if len(repr(requested)) <= 40 else f"{repr(requested)[:30]}..."
    if isinstance(requested, bool) or not isinstance(requested, int) or requested < 1:
        raise StudyError(f"workers={shown}: expected a whole number of worker processes >= 1")
    if requested > cores and not oversubscribe:
        raise StudyError(
            f"workers={shown}: more than the {cores} cores this process may use; expected at most "
            f"{cores}, or oversubscribe=True to start them all"
        )
    if requested > MAX_WORKERS_PER_CORE * cores:
        raise StudyError(
            f"workers={shown}: expected at most {MAX_WORKERS_PER_CORE * cores} worker "
            f"processes ({MAX_WORKERS_PER_CORE} per core), even oversubscribed"
        )
    return requested


def check_main_guard(caller: str) -> None:
    """Refuse, in one line, a call made at the top level of the script Python runs (its
    ``__main__``) outside an ``if __name__ == "__main__":`` block: each local worker is a
    new process (Dask starts them with multiprocessing's "spawn") that imports that script
    again, which would call ``caller`` again and flood the terminal with tracebacks.

    Written by hand: multiprocessing finds the problem only in the child, too late. The
    call is placed by the stack (the script's module-level frame and its line) and the
    script's syntax tree (the ``if __name__ == "__main__":`` blocks).
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or not path or getattr(main, "__name__", None) != "__main__":
        return  # an interactive session, python -c, a notebook: nothing is imported again
    frame = sys._getframe(1)
    while frame is not None and not (
        frame.f_code.co_name == "<module>" and frame.f_globals is vars(main)
    ):
        frame = frame.f_back  # type: ignore[assignment]
    if frame is None:
        return
    try:
        tree = ast.parse(Path(path).read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return
    line = frame.f_lineno
    guards = [n for n in ast.walk(tree) if isinstance(n, ast.If) and _is_main_test(n.test)]
    if any(n.lineno <= line <= (n.end_lineno or n.lineno) for n in guards):
        return
    raise StudyError(
        f"{caller} is called at the top level of {path} (line {line}), which each worker "
        'process imports again: put the call under `if __name__ == "__main__":`'
    )


def _is_main_test(test: ast.expr) -> bool:
    """``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1):
        return False
    sides = [test.left, test.comparators[0]]
    names = [s.id for s in sides if isinstance(s, ast.Name)]
    values = [s.value for s in sides if isinstance(s, ast.Constant)]
    return isinstance(test.ops[0], ast.Eq) and names == ["__name__"] and values == ["__main__"]


def make_job(
    base: Base,
    factors: Mapping[str, FactorKind],
    keep: str,
    check_step: bool = False,
    unpacked: Mapping[str, str] | None = None,
    data_files: Sequence[Path] = (),
) -> tuple[Job, StudyPlugin]:
    """The study's shared task data and the plugin carrying it and its FMUs (read once);
    ``unpacked``: the FMUs the client extracted for local workers (:func:`unpack`), who
    then load the client's copies of the FMU files instead of being carried them;
    ``data_files``: the other files the runs read, for remote workers
    (:func:`cosim.study.task.study_files`)."""
    session = uuid.uuid4().hex[:12]  # tasks and plugin of concurrent studies never clash
    files: dict[str, bytes] = {}
    paths: dict[str, str] = {}
    for instance, path in base.fmu_paths.items():
        content = path.read_bytes()
        copy = local_copy(content, unpacked or {})  # a local worker loads the client's copy
        paths[instance] = str(copy) if copy is not None else _carried(path.name, content, files)
    data = {
        str(path): _carried(path.name, path.read_bytes(), files, "files/") for path in data_files
    }
    name = f"auv-cosim-study-{session}"
    job = Job(base, factors, keep, check_step, paths, name, session, dict(unpacked or {}), data)
    return job, StudyPlugin(job, files)


def read_interfaces(job: Job) -> dict[str, FmuInterface]:
    """The interfaces of the job's FMU files that are this process's copies (a local
    cluster's, :func:`cosim.study.unpacked.local_copy`, named by their content's SHA-256),
    by copy: each its original's, which this process read as it checked the study, where
    the content it read it from is the copy's (an original changed since, even to the
    same size and modification time, is no longer). For the workers' fork server, which
    warms up on the copies without reading them again
    (:func:`cosim.study.fork_server.hand_over`). None for a file that cannot be read."""
    found: dict[str, FmuInterface] = {}
    for instance, copy in job.fmu_files.items():
        original = job.base.fmu_paths.get(instance)
        if original is None or not Path(copy).is_absolute():
            continue
        with suppress(CosimError, OSError):  # the run says what is wrong with it, as before
            interface = read_interface(original)
            if interface.sha256 == Path(copy).stem:
                found[copy] = interface
    return found


def _carried(name: str, content: bytes, files: dict[str, bytes], prefix: str = "") -> str:
    """Add a file's ``content`` to ``files`` under ``<prefix><sha256[:16]>/<name>``; that
    relative path."""
    relative = f"{prefix}{hashlib.sha256(content).hexdigest()[:16]}/{name}"
    files[relative] = content
    return relative


def run_on_worker(plugin_name: str, values: Mapping[str, Value]) -> RunRecord:
    """One task: one run, with the job and the FMUs the plugin brought to this worker."""
    # the StudyPlugin registered under this name before the tasks were submitted
    plugin = cast(StudyPlugin | None, get_worker().plugins.get(plugin_name))
    if plugin is None:  # removed: the study ended (a stop signal) before this task started
        return RunRecord("failed", ENDED_BEFORE_RUN, {}, 0.0, 0.0)
    job, paths = plugin.job, plugin.fmu_paths()
    plugin.warm()
    data = plugin.data_paths()
    assert plugin.in_flight is not None  # set up, as fmu_paths found
    with plugin.in_flight.run() as stop:
        return run_one(job.base, paths, job.factors, values, job.keep, job.check_step, data, stop)


def lost_run_error(exc: KilledWorker) -> str:
    """The table's one-line error of a run whose every worker died running it."""
    died = exc.allowed_failures + 1
    return (
        f"lost: {died} worker process{'es' if died > 1 else ''} died while running this run "
        f"(the last {exc.last_worker.address}); the scheduler's retries "
        f"(distributed.scheduler.allowed-failures = {exc.allowed_failures}) are exhausted: "
        "the run may crash its worker (an FMU fault, out of memory; see the workers' logs) "
        "or the cluster lost workers"
    )


def check_dashboard() -> None:
    """``--dashboard``: Dask serves its dashboard only with the bokeh it requires
    (``distributed.versions.BOKEH_REQUIREMENT``), and without it runs the study silently
    without one; raises StudyError naming what is missing, before a cluster starts."""
    from importlib import metadata

    from distributed.versions import BOKEH_REQUIREMENT

    try:
        found: str | None = metadata.version("bokeh")
    except metadata.PackageNotFoundError:
        found = None
    if found is not None and BOKEH_REQUIREMENT.specifier.contains(found, prereleases=True):
        return
    why = "it is not installed" if found is None else f"not bokeh {found}"
    raise StudyError(
        f"--dashboard: Dask's dashboard needs {BOKEH_REQUIREMENT} ({why}); "
        f'pip install "{BOKEH_REQUIREMENT}", or leave --dashboard out'
    )


def tls_security(ca_file: Path | None, cert: Path | None, key: Path | None) -> Security | None:
    """Dask ``Security`` for a ``tls://`` scheduler (None if no certificate is given)."""
    given = {"--tls-ca-file": ca_file, "--tls-cert": cert, "--tls-key": key}
    if not any(given.values()):
        return None
    missing = [flag for flag, path in given.items() if path is None]
    if missing:
        raise StudyError(
            f"TLS needs all of --tls-ca-file, --tls-cert, --tls-key; missing: {', '.join(missing)}"
        )
    for flag, path in given.items():
        if path is not None and not Path(path).is_file():
            raise StudyError(f"{flag} {path}: no such file")
    return Security(
        tls_ca_file=str(ca_file),
        tls_client_cert=str(cert),
        tls_client_key=str(key),
        require_encryption=True,
    )


def check_scheduler(address: str, security: Security | None = None) -> None:
    """Refuse, in seconds and before anything is written, a scheduler address that is not
    ``tcp://`` or ``tls://HOST:PORT``, a ``tls://`` one without certificates, or one that
    accepts no connection (a TCP connect with a PROBE_TIMEOUT_S timeout: Dask's own client
    would retry for CONNECT_TIMEOUT_S)."""
    if address.startswith("tls://") and security is None:
        raise StudyError(
            f"--scheduler {address}: a tls:// address needs --tls-ca-file, --tls-cert and --tls-key"
        )
    try:
        protocol, location = parse_address(address)
        host, port = parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise StudyError(
            f"--scheduler {address}: expected tcp://HOST:PORT or tls://HOST:PORT ({exc})"
        ) from None
    if protocol not in ("tcp", "tls"):
        raise StudyError(f"--scheduler {address}: expected tcp://HOST:PORT or tls://HOST:PORT")
    try:
        socket.create_connection((host, port), timeout=PROBE_TIMEOUT_S).close()
    except OSError as exc:
        reason = exc.strerror or str(exc) or type(exc).__name__
        raise StudyError(f"cannot reach the Dask scheduler at {address}: {reason}") from None
    _handshake(address, security)


def _handshake(address: str, security: Security | None) -> None:
    """Exchange Dask's handshake with ``address`` within PROBE_TIMEOUT_S: a server that
    accepts the connection but says nothing, or says something else (an HTTP server's
    reply read as a frame length asks for exabytes), is refused in one line. Dask's own
    ``connect`` waits for the handshake without a time limit."""
    from distributed.comm import connect

    arguments = security.get_connection_args("client") if security is not None else {}

    async def probe() -> None:
        comm = await connect(address, timeout=PROBE_TIMEOUT_S, **arguments)
        await comm.close()

    try:
        _run_apart(lambda: asyncio.wait_for(probe(), PROBE_TIMEOUT_S))
    except TimeoutError:
        raise StudyError(
            f"--scheduler {address}: the server accepts connections but sends no Dask "
            f"handshake within {PROBE_TIMEOUT_S:g} s; is it a Dask scheduler?"
        ) from None
    except MemoryError:  # a frame length read from bytes that are no Dask message
        reason = "bytes that are no Dask message; an HTTP or other server?"
        raise StudyError(
            f"--scheduler {address}: not a Dask scheduler (it answered {reason})"
        ) from None
    except Exception as exc:  # anything else a non-scheduler makes Dask raise
        reason = " ".join(f"{type(exc).__name__}: {exc}".split())[:160]
        raise StudyError(
            f"--scheduler {address}: not a Dask scheduler (its reply to Dask's handshake: {reason})"
        ) from None


def _run_apart(coroutine: Callable[[], Coroutine[Any, Any, None]]) -> None:
    """``asyncio.run`` of the coroutine ``coroutine()`` makes; in a thread of its own where
    this thread already runs an event loop (a Jupyter kernel's, an asyncio application's),
    in which ``asyncio.run`` refuses: a real scheduler was refused there as "not a Dask
    scheduler" for that RuntimeError."""
    try:
        asyncio.get_running_loop()
    except RuntimeError:  # no loop running here: the command line's case
        asyncio.run(coroutine())
        return
    with ThreadPoolExecutor(1, thread_name_prefix="auv-cosim-probe") as pool:
        pool.submit(lambda: asyncio.run(coroutine())).result()


def check_workers(client: Client, address: str) -> None:
    """Refuse, in one line, a cluster of one's own whose workers cannot run the study: a
    scheduler no worker joins within WORKER_WAIT_S (its tasks would wait forever), a
    worker that cannot import auv-cosim (the study's plugin would fail on it with a
    traceback) or one of another auv-cosim than this process's (its runs would give its
    code's rows: the table would depend on which worker ran a run)."""
    try:
        client.wait_for_workers(1, timeout=WORKER_WAIT_S)
    except TimeoutError:
        raise StudyError(
            f"the Dask scheduler at {address} has no workers (none joined within "
            f"{WORKER_WAIT_S:g} s): start one with `dask worker {address} --nthreads 1` "
            "where auv-cosim is installed"
        ) from None
    mine = _source_probe()()
    assert isinstance(mine, tuple)  # this process imports cosim
    found = client.run(_source_probe(), on_error="return")
    lacking = {w: f for w, f in found.items() if not isinstance(f, tuple)}
    other = {w: f[1] for w, f in found.items() if isinstance(f, tuple) and f[0] != mine[0]}
    where = f"of the Dask scheduler at {address}"
    if lacking:
        worker, reason = next(iter(lacking.items()))
        raise StudyError(
            f"worker {worker}{_more(lacking)} {where} cannot import auv-cosim ({reason}): "
            "install auv-cosim where the workers run, or start them from its environment"
        )
    if other:
        worker, folder = next(iter(other.items()))
        raise StudyError(
            f"worker {worker}{_more(other)} {where} runs another auv-cosim than this one "
            f"(its cosim at {folder}, this one's at {mine[1]}): start the workers from the "
            "same auv-cosim as the study"
        )


def _more(workers: Mapping[str, object]) -> str:
    """ " (and N more)" of a set of workers of which the first is named."""
    return f" (and {len(workers) - 1} more)" if len(workers) > 1 else ""


def _source_probe() -> Callable[[], tuple[str, str] | str]:
    """A function for ``client.run`` that a worker without auv-cosim, or with an older
    one, can load too (defined here, cloudpickle sends it by value, and it imports
    nothing of the project but ``cosim`` itself). It returns the SHA-256 of the ``cosim``
    package's source (every ``.py`` file, by its path in the package) and its folder,
    or why ``cosim`` cannot be imported."""

    def probe() -> tuple[str, str] | str:
        import hashlib
        import importlib
        from pathlib import Path

        try:
            folder = Path(importlib.import_module("cosim").__file__ or "").resolve().parent
        except Exception as exc:
            return " ".join(f"{type(exc).__name__}: {exc}".split())
        digest = hashlib.sha256()
        for path in sorted(folder.rglob("*.py")):
            digest.update(f"{path.relative_to(folder).as_posix()}\n".encode())
            digest.update(path.read_bytes())
        return digest.hexdigest(), str(folder)

    return probe


@contextmanager
def open_client(
    workers: int,
    scheduler: str | None = None,
    security: Security | None = None,
    dashboard: bool = False,
) -> Iterator[Client]:
    """A Dask client: of an existing cluster at ``scheduler``, else of a local cluster
    of ``workers`` single-threaded worker processes on 127.0.0.1 (closed at the end).
    Dask's settings from the environment are checked first (:mod:`cosim.study.dask_settings`)."""
    check_dask_settings()
    if scheduler is not None:
        if scheduler.startswith("tls://") and security is None:
            raise StudyError(
                f"--scheduler {scheduler}: a tls:// address needs --tls-ca-file, "
                "--tls-cert and --tls-key"
            )
        try:
            client = Client(
                scheduler, security=security, timeout=CONNECT_TIMEOUT_S, set_as_default=False
            )
        except (OSError, TimeoutError) as exc:
            raise StudyError(f"cannot reach the Dask scheduler at {scheduler}: {exc}") from None
        with client:
            check_workers(client, scheduler)
            yield client
        return
    with _quiet_dask_logs():  # until the cluster's event loop has stopped
        cluster = _local_cluster(workers, dashboard)
        with cluster, Client(cluster, set_as_default=False) as client:
            if dashboard:
                print(f"Dask dashboard: {client.dashboard_link}", file=sys.stderr)
            try:
                yield client
            finally:
                stop_heartbeats(client)


def _local_cluster(workers: int, dashboard: bool) -> LocalCluster:
    """A local cluster of ``workers`` single-threaded worker processes on 127.0.0.1."""
    # An address without a host (dask's default ":8787") would listen on every interface;
    # with the dashboard off the scheduler still serves /health on this (random) port.
    port = DASHBOARD_PORT if dashboard else 0
    # the settings are read as the scheduler, the nannies and (through its nanny) each
    # worker start; a Ctrl-C is the client's (cosim.study.signals)
    with ExitStack() as closing:
        with (
            _forked_workers() as forked,
            dask.config.set(cluster_settings(dashboard)),
            _ctrl_c_held(forked),
            _nannies_look_often(),
            environ_writes.noted(*DASK_WRITES),
        ):
            cluster = LocalCluster(
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                host=LOCALHOST,
                protocol="tcp://",
                dashboard_address=f"{LOCALHOST}:{port}",
                scheduler_kwargs={"dashboard": dashboard},
                worker_dashboard_address=None,
                silence_logs=logging.ERROR,
                preload=[PRELOAD],
            )
            closing.callback(cluster.close)  # a Ctrl-C held meanwhile raises as it ends
        closing.pop_all()
    return cluster


# the local clusters starting now in this process (threads of the Python API), under its
# lock, and Dask's own interval, which the last of them to end puts back
_nanny_looks: dict[str, Any] = {"starting": 0, "dask_own": None}
_nanny_looks_lock = threading.Lock()


@contextmanager
def _nannies_look_often() -> Iterator[None]:
    """While on (the local cluster's start), each nanny looks for its worker's word that it
    has started every NANNY_LOOK_S, not every 0.05 s: the cluster's start, and so the first
    run, waited up to 0.05 s (0.025 s on average) after the last worker had joined the
    scheduler, with one worker as with two. By hand: Dask reads it from a class attribute
    of the nanny's worker process, not from its configuration. Nothing changes where that
    attribute is missing (another Dask). Two clusters starting at once (two threads) share
    it: the first to start keeps Dask's value and the last to end puts it back."""
    from distributed.nanny import WorkerProcess

    with _nanny_looks_lock:
        dask_own = _nanny_looks["dask_own"]
        if _nanny_looks["starting"] == 0:
            dask_own = WorkerProcess.__dict__.get("_init_msg_interval")
        if not isinstance(dask_own, float):
            dask_own = None
        else:
            _nanny_looks.update(starting=_nanny_looks["starting"] + 1, dask_own=dask_own)
            WorkerProcess._init_msg_interval = min(dask_own, NANNY_LOOK_S)
    try:
        yield
    finally:
        with _nanny_looks_lock:
            if dask_own is not None:
                _nanny_looks["starting"] -= 1
                if _nanny_looks["starting"] == 0:
                    WorkerProcess._init_msg_interval = dask_own


def _ctrl_c_held(forked: bool) -> AbstractContextManager[None]:
    """While the local cluster starts: workers forked from the fork server ignore SIGINT
    already (:mod:`cosim.study.server_environ`), and a Ctrl-C (a notebook's stop button) is
    held back until the cluster has started, then stops the study; workers Dask spawns
    itself inherit it ignored from this process, where a Ctrl-C meanwhile was lost (the
    study ran on to its end): only then is it ignored here."""
    if not forked:
        return workers_ignore_sigint()
    if threading.current_thread() is threading.main_thread():
        return stop_signals_deferred()
    return nullcontext()  # a cluster started early, on a thread: the signal is the main's


@contextmanager
def _quiet_dask_logs() -> Iterator[None]:
    """Dask's messages below ERROR kept off this process's stderr until the local cluster
    has closed and its event loop stopped. LocalCluster's own ``silence_logs`` ends as soon
    as its scheduler has closed, while the loop still runs what was pending: a batched
    stream whose connection closed under it then logged "Batched Comm Closed" with a
    CommClosedError traceback (INFO) on a successful study's stderr."""
    handlers = logging.getLogger("distributed").handlers
    streams = [h for h in handlers if isinstance(h, logging.StreamHandler)]
    levels = [h.level for h in streams]
    for handler in streams:
        handler.setLevel(max(handler.level, logging.ERROR))
    try:
        yield
    finally:
        for handler, level in zip(streams, levels, strict=True):
            handler.setLevel(level)


def cluster_settings(dashboard: bool) -> dict[str, object]:
    """Dask settings of a local study cluster that keep its scheduler, nannies and
    workers nearly idle while the runs run: on a machine of as many cores as workers every
    CPU second they spend is taken from a run. Without the dashboard, which shows them, no
    statistical profile of the running task (Dask samples its stack every 10 ms, in the
    worker's event loop, against the run's thread for the interpreter) and the system
    monitor's samples (CPU, memory, network) every SYSTEM_MONITOR_INTERVAL; the event
    loop's health check every TICK_INTERVAL (it warns of a loop blocked beyond
    ``distributed.admin.tick.limit``, 3 s by default, all the same); each nanny's and
    worker's memory check every MEMORY_MONITOR_INTERVAL (a worker beyond its memory
    limit is restarted within that time instead of 100 ms)."""
    settings: dict[str, object] = {
        "distributed.admin.tick.interval": TICK_INTERVAL,
        "distributed.worker.memory.monitor-interval": MEMORY_MONITOR_INTERVAL,
    }
    if not dashboard:
        settings["distributed.worker.profile.enabled"] = False
        settings["distributed.admin.system-monitor.interval"] = SYSTEM_MONITOR_INTERVAL
    return settings


@contextmanager
def _forked_workers() -> Iterator[bool]:
    """While on, Dask starts local worker processes from the fork server
    (:mod:`cosim.study.fork_server`, started now if not yet), where the platform has one
    and it runs (yields True); else Dask starts them its own way (yields False)."""
    running = fork_server.start()
    # multiprocessing's pymp-* folder (the fork server's socket), which a study killed
    # outright leaves: the next process removes it with this one's scratch folder
    claim(Path(multiprocessing.util.get_temp_dir()))
    if not running:
        yield False
        return
    import distributed.utils

    distributed.utils._forkserver_preload_set = True  # Dask's own preload comes too late
    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        yield True


def stop_heartbeats(client: Client) -> None:
    """Before a local cluster closes: stop every worker's heartbeat to the scheduler and
    let the one in flight finish (:func:`_quiet_heartbeat`). A worker closing closes its
    connections to the scheduler while a heartbeat may still wait for its answer (Dask
    stops the heartbeat only late in ``Worker.close``), and that heartbeat then logs
    "Failed to communicate with scheduler during heartbeat" with a CommClosedError
    traceback on the study's stderr: 4 of 30 studies here, two at once on 3 workers
    each. Never raises (a broken cluster is closed all the same)."""
    with suppress(Exception):
        client.run(_quiet_heartbeat, on_error="ignore")


async def _quiet_heartbeat(dask_worker: Any) -> None:
    """On a worker: no more heartbeats, and the one in flight (a connection of the
    worker's pool to the scheduler in use) answered, or HEARTBEAT_DRAIN_S passed."""
    dask_worker.periodic_callbacks["heartbeat"].stop()
    scheduler = dask_worker.scheduler.address
    deadline = asyncio.get_running_loop().time() + HEARTBEAT_DRAIN_S
    while dask_worker.rpc.occupied.get(scheduler):
        if asyncio.get_running_loop().time() > deadline:
            return
        await asyncio.sleep(0.01)


class EarlyClient:
    """A local cluster started on a thread (:func:`early_client`): call it to wait for the
    client (it raises what starting the cluster raised); :meth:`close_soon` starts closing
    the cluster on that thread, once no more tasks will be sent."""

    def __init__(self, workers: int, dashboard: bool, end_server: bool = False) -> None:
        self._stack = ExitStack()
        self._end_server = end_server
        self._pool = ThreadPoolExecutor(1, thread_name_prefix="auv-cosim-cluster")
        self._started = self._pool.submit(
            lambda: self._stack.enter_context(open_client(workers, dashboard=dashboard))
        )
        self._closing: Future[None] | None = None

    def __call__(self) -> Client:
        return self._started.result()

    def close_soon(self) -> None:
        """Close the cluster on its thread (after it has finished starting), while the
        caller goes on; :meth:`close` waits for that. Idempotent. A fork server still
        waiting for the study is told now that none comes (here, not on the cluster's
        thread: that thread may be starting the cluster, whose workers the server forks
        only once told, and the closing would wait behind it for the server's whole wait)."""
        fork_server.hand_over(None)
        if self._closing is None:
            self._closing = self._pool.submit(self._close)

    def close(self) -> None:
        """Close the cluster (or wait for :meth:`close_soon`'s closing) and the thread."""
        self.close_soon()
        assert self._closing is not None
        try:
            self._closing.result()
        finally:
            self._pool.shutdown()

    def _close(self) -> None:
        with suppress(Exception):  # a cluster that failed to start has nothing to close
            self._started.result()
        self._stack.close()
        if self._end_server:  # its workers are gone: the server is needed no longer
            fork_server.stop()


@contextmanager
def early_client(
    workers: int, dashboard: bool = False, end_server: bool = False
) -> Iterator[EarlyClient]:
    """:func:`open_client` of a local cluster started now, on a thread, so the cluster
    starts while the caller imports and checks its study; closed at the end (after it has
    finished starting, if the caller gave up before), or earlier with
    :meth:`EarlyClient.close_soon`. ``end_server``: the workers' fork server is ended once
    the cluster has closed (:func:`cosim.study.fork_server.stop`), for a process that ends
    with the study; else it stays for the process's next study."""
    early = EarlyClient(workers, dashboard, end_server)
    try:
        yield early
    finally:
        early.close()


class ClusterLostError(StudyEndedError):
    """The cluster has had no worker for WORKER_WAIT_S while runs were left."""


def _completed(client: Client, futures: Iterable[Any]) -> Iterator[Any]:
    """``futures`` as they finish (``as_completed``); :class:`ClusterLostError` once the
    cluster has had no worker for WORKER_WAIT_S (its tasks would wait forever)."""
    found = as_completed(futures, loop=client.loop)
    seen = checked = time.monotonic()
    while not found.is_empty():
        batch = found.next_batch(block=False)
        yield from batch
        now = time.monotonic()
        if batch:
            continue
        if now - checked < WORKER_CHECK_S:
            time.sleep(POLL_S)
            continue
        checked = now
        if client.nthreads():
            seen = now
        elif now - seen >= WORKER_WAIT_S:
            address = client.scheduler.address
            raise ClusterLostError(
                f"the Dask scheduler at {address} has no workers (none for "
                f"{WORKER_WAIT_S:g} s, with runs left): start workers with "
                f"`dask worker {address} --nthreads 1`"
            )


def _owners_probe() -> Callable[..., list[str]]:
    """A function for ``client.run_on_scheduler`` (sent by value: the scheduler needs no
    auv-cosim): the study plugins still registered whose owner is no longer connected
    (their metadata entry removed); ``forget``: a plugin's entry to remove first."""

    def orphans(dask_scheduler: Any, forget: str = "") -> list[str]:
        owners = dask_scheduler.task_metadata.setdefault(OWNERS, {})
        owners.pop(forget, None)
        gone = [
            name
            for name, owner in owners.items()
            if owner not in dask_scheduler.clients and name in dask_scheduler.worker_plugins
        ]
        for name in gone:
            owners.pop(name, None)
        return gone

    return orphans


def _remove_orphans(client: Client) -> None:
    """Remove the plugins of studies whose client is gone without removing its own (killed
    with SIGKILL, its machine down): the scheduler would hand each, with its FMUs, to
    every worker that joins, for good."""
    with suppress(Exception):
        for name in client.run_on_scheduler(_owners_probe()):
            client.unregister_worker_plugin(name)


def _register(client: Client, plugin: StudyPlugin, name: str, owned: bool) -> None:
    """Register the study's plugin on every worker, its owner (this client) noted on the
    scheduler if ``owned`` (:func:`_remove_orphans`); StudyError in one line if a worker
    cannot set it up (its own reason, or Dask's as one line)."""
    try:
        if owned:
            client.set_metadata([OWNERS, name], client.id)
        client.register_plugin(plugin, name=name)
    except StudyError:
        raise
    except Exception as exc:
        reason = " ".join(f"{type(exc).__name__}: {exc}".split())
        raise StudyError(f"a worker cannot set up the study: {reason}") from None


def execute(
    client: Client,
    job: Job,
    plugin: StudyPlugin,
    runs: Sequence[PlannedRun],
    on_record: Callable[[PlannedRun, RunRecord], None],
    remote: bool = False,
) -> None:
    """Run every run as one task and hand each record to ``on_record`` as it arrives
    (in order of completion). The study's plugin is registered first and removed at the
    end. A lost worker's tasks are retried by the scheduler; a run is recorded as failed
    for that only once its retries are exhausted (:func:`lost_run_error`). On a
    ``remote`` cluster (one of the user's, which outlives the study) a cluster left
    without a worker ends the study (:class:`ClusterLostError`) and the plugins of
    studies killed before are removed; a local one restarts its workers and ends with
    the study, and its results are waited for without polling."""
    pending: dict[Any, PlannedRun] = {}
    if remote:
        _remove_orphans(client)
    try:  # a plugin a worker refused is removed too: later workers would be handed it
        _register(client, plugin, job.plugin, owned=remote)
        pending = {
            client.submit(
                run_on_worker,
                job.plugin,
                dict(run.values),
                key=f"run-{run.id}-{job.session}",
                pure=False,
            ): run
            for run in runs
        }
        finished = (
            _completed(client, pending) if remote else as_completed(pending, loop=client.loop)
        )
        for future in finished:
            run = pending.pop(future)
            try:
                record = future.result()  # run_one itself never raises
            except KilledWorker as exc:
                record = RunRecord("failed", lost_run_error(exc), {}, 0.0, 0.0)
            except (KeyboardInterrupt, SystemExit, StudyStopped):
                raise
            except BaseException as exc:  # cancelled, or the scheduler went away
                error = " ".join(f"{type(exc).__name__}: {exc}".split())
                record = RunRecord("failed", error, {}, 0.0, 0.0)
            future.release()
            on_record(run, record)
    finally:  # a broken connection must not hide the first error
        if pending:  # stopped: the scheduler hands the runs left to no worker any more
            with suppress(Exception):
                client.cancel(list(pending))
        with suppress(Exception):
            client.unregister_worker_plugin(job.plugin)
            if remote:
                client.run_on_scheduler(_owners_probe(), forget=job.plugin)
