"""The workers' fork server initialises numba's compiler target with SciPy's BLAS table
alone, not all of scipy.linalg (~0.1 s of its CPU before every study's first run), and
leaves numba's BLAS and scipy.linalg working in the workers it forks."""

from __future__ import annotations

import ast
import sys

import pytest
from process_group import run_in_group

PRELOAD_THEN_BLAS = """
import importlib, sys
import numpy as np
from cosim.study.fork_server import PRELOAD
for name in PRELOAD[:-1]:  # the last one makes the server's exit skip the teardown
    importlib.import_module(name)
import numba
import numba.np.arraymath
found = ["scipy.linalg" in sys.modules, "numba.np.arraymath" in sys.modules,
         numba.np.arraymath._HAVE_BLAS]

@numba.njit(cache=False)
def solved(a, b):
    return np.linalg.inv(a) @ b

a = np.array([[2.0, 1.0], [1.0, 3.0]])
b = np.array([1.0, 2.0])
found.append(bool(np.allclose(solved(a, b), np.linalg.solve(a, b), rtol=1e-12)))
import scipy.linalg.cython_blas
found += [callable(scipy.linalg.solve), scipy.linalg.cython_blas.__name__]
print(repr(found))
"""


@pytest.mark.slow
@pytest.mark.skipif(sys.platform == "win32", reason="no fork server on Windows")
def test_the_fork_server_loads_the_blas_table_alone_and_blas_still_works() -> None:
    done = run_in_group([sys.executable, "-c", PRELOAD_THEN_BLAS], timeout=600)
    assert done.returncode == 0, done.stderr.strip().splitlines()[-3:]
    linalg, target, blas, solved, whole, table = ast.literal_eval(
        done.stdout.strip().splitlines()[-1]
    )
    assert not linalg, "the fork server imported all of scipy.linalg"
    assert target and blas, "numba's target is not initialised, or found no BLAS"
    assert solved, "a kernel calling BLAS and LAPACK gave another result than numpy"
    assert whole and table == "scipy.linalg.cython_blas"
