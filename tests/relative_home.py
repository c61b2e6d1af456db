"""The start of a script a test runs in a fresh interpreter under a relative HOME
(``HOME=home``), for what a command or the Python API then writes in its working folder:
argv[1] is its TMPDIR, argv[2] the folder it works in; numba's kernels stay the session's,
and no XDG or matplotlib folder of the test's environment is inherited."""

PREAMBLE = """
import os, sys
from plant_fmu.model.jit import default_cache_dir

os.environ.setdefault("NUMBA_CACHE_DIR", str(default_cache_dir()))  # the session's kernels
for name in ("XDG_CONFIG_HOME", "XDG_CACHE_HOME", "MPLCONFIGDIR"):
    os.environ.pop(name, None)
os.environ["HOME"], os.environ["TMPDIR"] = "home", sys.argv[1]
os.chdir(sys.argv[2])
"""
