"""Imported once by the fork server every local study worker is forked from
(:mod:`cosim.study.fork_server`), or by each worker as it starts where there is none
(Dask's worker ``preload``), while the client still imports and checks the study: what
every run needs before its FMUs are loaded, ~2 s of CPU a worker paid in its warm-up.

* the run's modules: runner, engine, outputs, fmpy;
* numba, imported by the engine (:func:`plant_fmu.model.jit.load_numba`, which sets
  numba's cache folder first, as the FMUs do), with its compiler's target initialised
  (:func:`_numba_target`): what loading a kernel from numba's cache does first in a process.

What is specific to the study's FMUs -- their libraries, their packages (an FMU imports the
copy it ships, ``auvfmu_<hash>``), their compiled kernels -- is loaded later, in each
worker's first task (:func:`cosim.study.task.warm_up`).
"""

import gc
from contextlib import suppress

import fmpy.fmi2  # noqa: F401  (loaded once, now)

import cosim.engine.master  # the engine; numba, its cache folder set first
import cosim.outputs.run_outputs  # a run's files
import cosim.study.task  # noqa: F401  (the run itself)
from plant_fmu.model.jit import load_numba


def _numba_target() -> None:
    """Initialise numba's CPU target (its typing and lowering registries, ~1 s, imports
    scipy.linalg for BLAS), which the first kernel a process loads from numba's cache
    would do; nothing when numba is off or cannot be imported. Never raises (the worker
    then does it at its first kernel)."""
    numba, _ = load_numba()
    if numba is None:
        return
    with suppress(Exception):  # numba's internals: an optimisation, never a failure
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()


_numba_target()
# What is loaded now lives as long as the process: out of the garbage collector's reach, so
# a forked worker's collections do not walk (and copy) it, and the fork server's final
# collection at exit does not either (its exit took 0.9 s, measured with pandas loaded too).
# The collector, off while the fork server imported (cosim.study.server_environ), is on
# again for what the server and its workers do next.
gc.freeze()
gc.enable()


def dask_setup(worker: object) -> None:
    """A local worker ignores SIGINT, SIGTERM and SIGHUP: a stop signal sent to the whole
    process group (Ctrl-C in a terminal, a CI job cancelled, ``kill -- -PGID``, a hangup)
    is the client's to handle, which ends the study and its cluster in order
    (:mod:`cosim.study.signals`; Dask's nanny still ends a worker that does not stop, by
    SIGKILL). A worker ended by the signal before the client could end it made the
    scheduler print its failed broadcasts, tracebacks included. The workers of a cluster
    started on a thread (early, while the study is checked) do not inherit the client's
    ignoring.
    A worker shows a warning as one line naming itself, as the command shows its own
    (:func:`cosim.errors.one_line_warnings`)."""
    import signal
    import threading
    import warnings

    from cosim.engine.signals import STOP_SIGNALS
    from cosim.errors import one_line_warnings

    warnings.showwarning = one_line_warnings("auv-cosim study worker")
    if threading.current_thread() is threading.main_thread():
        for signum in STOP_SIGNALS:
            signal.signal(signum, signal.SIG_IGN)
