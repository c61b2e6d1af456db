"""scripts/bench_sweep.py's end-to-end sweeps (and scripts/sweep_timeline.py's) run as a
user's installed copy does: our modules imported compiled, not compiled afresh in every
process where the machine sets PYTHONDONTWRITEBYTECODE."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from repo_paths import ROOT

# in a process of its own: importing bench_sweep sets one BLAS thread in its environment
SWEEP_LIKE = """
import os, subprocess, sys
from pathlib import Path
from bench_sweep import as_installed
env = as_installed({**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}, Path(sys.argv[1]))
subprocess.run([sys.executable, "-c", "import cosim.study.spec"], env=env, check=True)
"""


def test_a_benchmark_sweep_imports_our_modules_compiled(tmp_path: Path) -> None:
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    subprocess.run([sys.executable, "-c", SWEEP_LIKE, str(tmp_path)], env=env, check=True,
                   timeout=300)  # fmt: skip
    spec = ROOT / "cosim" / "study" / f"spec.{sys.implementation.cache_tag}.pyc"
    assert (tmp_path / "pycache" / spec.relative_to(spec.anchor)).is_file()
