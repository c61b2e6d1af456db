"""Imported once by the fork server every local study worker is forked from
(:mod:`cosim.study.fork_server`), or by each worker as it starts where there is none
(Dask's worker ``preload``), while the client still imports and checks the study: what
every run needs before its FMUs are loaded, ~2 s of CPU a worker paid in its warm-up.

* the run's modules: runner, engine, outputs, fmpy;
* numba, imported by the engine (:func:`plant_fmu.model.jit.load_numba`, which sets
  numba's cache folder first, as the FMUs do), with its compiler's target initialised
  (:func:`_numba_target`): what loading a kernel from numba's cache does first in a process;
  SciPy's BLAS table alone, not all of scipy.linalg (:func:`_blas_table_alone`).

What is specific to the study's FMUs -- their libraries, their packages (an FMU imports the
copy it ships, ``auvfmu_<hash>``), their compiled kernels -- is loaded later: by the server
of ``auv-cosim sweep`` once the client has handed it the study
(:mod:`cosim.study.server_warm`), else in each worker's first task
(:func:`cosim.study.task.warm_up`).
"""

import gc
import importlib
import importlib.util
import sys
import types
from collections.abc import Iterator
from contextlib import contextmanager, suppress

import fmpy.fmi2  # noqa: F401  (loaded once, now)

import cosim.engine.master  # the engine; numba, its cache folder set first
import cosim.outputs.run_outputs  # a run's files
import cosim.study.task  # noqa: F401  (the run itself)
from plant_fmu.model.jit import load_numba


def _numba_target() -> None:
    """Initialise numba's CPU target (its typing and lowering registries, ~1 s; SciPy's
    BLAS table, :func:`_blas_table_alone`), which the first kernel a process loads from
    numba's cache would do; nothing when numba is off or cannot be imported. Never raises
    (the worker then does it at its first kernel)."""
    numba, _ = load_numba()
    if numba is None:
        return
    with suppress(Exception), _blas_table_alone():  # numba's internals: never a failure
        from numba.core.registry import cpu_target

        cpu_target.target_context.refresh()


@contextmanager
def _blas_table_alone() -> Iterator[None]:
    """While on, ``scipy.linalg`` is a bare package whose only module loaded is
    ``cython_blas``, SciPy's table of BLAS functions: all numba's target asks of SciPy as it
    initialises (``numba.np.arraymath._check_blas`` imports that module to learn whether
    BLAS is there). Importing it the usual way runs ``scipy.linalg``'s ``__init__``, all of
    scipy.linalg (~0.1 s of the server's CPU, on the way to every study's first run), which
    no run of ours uses: our compiled kernels call no BLAS, and the FMUs import no SciPy.
    Afterwards every ``scipy.linalg`` module is forgotten again (the library stays loaded),
    so a later ``import scipy.linalg`` -- numba's own, at the first call of a kernel that
    uses BLAS -- imports the whole package as before. Nothing changes where scipy.linalg
    is already imported or cannot be found, or where its table cannot be loaded so."""
    try:
        spec = None if "scipy.linalg" in sys.modules else importlib.util.find_spec("scipy.linalg")
    except ImportError:  # no scipy: numba finds no BLAS, as before
        spec = None
    if spec is None or not spec.submodule_search_locations:
        yield
        return
    bare = types.ModuleType("scipy.linalg")
    bare.__path__ = list(spec.submodule_search_locations)
    sys.modules["scipy.linalg"] = bare
    try:
        importlib.import_module("scipy.linalg.cython_blas")
    except Exception:  # then numba imports scipy.linalg itself, whole
        _forget_scipy_linalg()
    try:
        yield
    finally:
        if sys.modules.get("scipy.linalg") is bare:  # not a whole one imported meanwhile
            _forget_scipy_linalg()


def _forget_scipy_linalg() -> None:
    for name in [n for n in sys.modules if n == "scipy.linalg" or n.startswith("scipy.linalg.")]:
        del sys.modules[name]


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
