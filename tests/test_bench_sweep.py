"""scripts/bench_sweep.py's end-to-end sweeps (and scripts/sweep_timeline.py's) run as a
user's installed copy does: our modules imported compiled, not compiled afresh in every
process where the machine sets PYTHONDONTWRITEBYTECODE, and an FMU's Python read from
the bytecode it ships (which PYTHONPYCACHEPREFIX would make Python ignore)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

from repo_paths import ROOT

# in a process of its own: importing bench_sweep sets one BLAS thread in its environment
SWEEP_LIKE = """
import os, subprocess, sys
from pathlib import Path
from bench_sweep import ROOT, installed, installed_env
site = installed(ROOT, Path(sys.argv[1]))
env = installed_env({**os.environ, "PYTHONPYCACHEPREFIX": sys.argv[1] + "/prefix"}, site)
probe = "import json, sys, cosim.study.spec as m; "
probe += "print(json.dumps([m.__file__, sys.pycache_prefix]))"
subprocess.run([sys.executable, "-c", probe], env=env, cwd=site, check=True)
"""


def test_a_benchmark_sweep_imports_our_modules_compiled_from_an_installed_copy(
    tmp_path: Path,
) -> None:
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path, "PYTHONDONTWRITEBYTECODE": "1"}
    done = subprocess.run([sys.executable, "-c", SWEEP_LIKE, str(tmp_path)], env=env,
                          check=True, timeout=300, capture_output=True, text=True)  # fmt: skip
    module, prefix = json.loads(done.stdout)
    assert Path(module) == tmp_path / "cosim" / "study" / "spec.py"  # the copy, not the tree
    compiled = tmp_path / "cosim" / "study" / "__pycache__"
    assert (compiled / f"spec.{sys.implementation.cache_tag}.pyc").is_file()
    assert prefix is None  # the FMUs' shipped __pycache__ is read
    assert not (tmp_path / "prefix").exists()
