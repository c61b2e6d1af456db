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
