"""numba's own environment variables set to values numba cannot use
(plant_fmu/model/jit.py): the compiled paths are turned off with a warning naming the
variable, never a host process aborted nor a reinstall of numba advised for a setting."""

from __future__ import annotations

import pytest

LOAD_AND_COMPILE = """
import os, sys
os.environ[sys.argv[1]] = sys.argv[2]  # before numba is imported: it reads them then
from plant_fmu.model import jit
numba, reason = jit.load_numba()
if numba is not None:  # what every FMU then does: compile its kernels
    print(numba.njit(lambda x: 2.0 * x + 1.0)(1.5))
print("REASON", reason)
print("FIX", jit.numba_fix(reason) if reason else "")
"""


def _load(run_python, name: str, value: str) -> dict[str, str]:
    done = run_python(LOAD_AND_COMPILE, name, value)
    assert done.returncode == 0, f"exit {done.returncode}: {done.stderr[-2000:]}"
    lines = done.stdout.splitlines()
    return {key: text for key, _, text in (line.partition(" ") for line in lines)}


@pytest.mark.parametrize("features", ["avx", " +avx", "+avx,sse"])
def test_cpu_features_without_a_sign_turn_the_compiled_path_off_not_abort(run_python, features):
    """NUMBA_CPU_FEATURES whose items do not each start with + or - made LLVM abort the
    whole process (an assertion in MCSubtargetInfo.cpp) at the first compilation: the run,
    or the FMU's host. The compiled path is off, the reason naming the variable."""
    said = _load(run_python, "NUMBA_CPU_FEATURES", features)
    assert "NUMBA_CPU_FEATURES" in said["REASON"] and repr(features) in said["REASON"]
    assert "NUMBA_CPU_FEATURES" in said["FIX"]


@pytest.mark.slow
def test_cpu_features_numba_accepts_keep_the_compiled_path(run_python):
    """The check refuses only what LLVM aborts on: signed features, one of them the host
    CPU may lack, compile."""
    said = _load(run_python, "NUMBA_CPU_FEATURES", "+avx,-fma")
    assert said["4.0"] == "" and said["REASON"] == ""


def test_a_numba_setting_numba_refuses_on_import_is_named_not_a_reinstall(run_python):
    """NUMBA_NUM_THREADS=0 makes ``import numba`` raise ValueError; the warning advised
    reinstalling numba (``pip install --force-reinstall numba``), which changes nothing.
    It names the variable to correct instead."""
    said = _load(run_python, "NUMBA_NUM_THREADS", "0")
    assert "NUMBA_NUM_THREADS='0'" in said["REASON"]
    assert said["FIX"].startswith("correct or unset NUMBA_NUM_THREADS"), said["FIX"]
