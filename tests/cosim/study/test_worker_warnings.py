"""A study's worker shows a warning as one line naming itself, as the command does: Python's
own form (the file, the line number and the source line that warned) reached a sweep's
stderr from each worker (the FMU's numba cache warning: two lines a worker)."""

from __future__ import annotations

WORKER = """
import warnings
from cosim.study.preload import dask_setup
dask_setup(object())  # as Dask calls it in each worker it starts
warnings.warn("the cache folder\\n  cannot be written", RuntimeWarning, stacklevel=1)
"""


def test_a_worker_warning_is_one_line_naming_the_worker(run_python) -> None:
    done = run_python(WORKER)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stderr == "auv-cosim study worker: warning: the cache folder cannot be written\n"


FORK_SERVER = """
import multiprocessing, os, sys
os.environ["NUMBA_CACHE_DIR"] = sys.argv[1]
from cosim.study import fork_server
from plant_fmu.model.jit import cache_problem

assert fork_server.start()  # as a sweep starts it, early
context = multiprocessing.get_context("forkserver")
for _ in range(3):  # three workers forked from it, each compiling its FMUs' kernels
    worker = context.Process(target=cache_problem)
    worker.start()
    worker.join()
cache_problem()  # the command's own check of the study
"""


def test_an_unwritable_numba_cache_is_said_once_for_all_the_forked_workers(
    run_python, tmp_path
) -> None:
    """With a HOME that cannot be written (a service account's, ``HOME=/nonexistent``), a
    sweep printed the same numba-cache warning once per worker: eight lines for
    ``--workers 8``, and one more from the command. The command says it once, as it starts
    the fork server, whose workers inherit that it was said."""
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    done = run_python(FORK_SERVER, blocker / "numba")  # a folder under a file: never made
    assert done.returncode == 0, done.stderr[-2000:]
    said = [line for line in done.stderr.splitlines() if "cannot be written" in line]
    assert len(said) == 1, done.stderr
