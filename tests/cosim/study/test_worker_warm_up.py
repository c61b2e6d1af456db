"""A study worker's warm-up (the study plugin's set-up) leaves the FMUs' libraries loaded
and idle for the first task, and their plant code compiled; it never raises. Local workers
are forked from a server that imported the run's modules once."""

from __future__ import annotations

import pytest

from cosim.study import fork_server

WARM = """
import sys
from pathlib import Path
from cosim.engine import slave
from cosim.study.task import prepare, warm_up

base, _ = prepare("bs-3", 20.0, Path(sys.argv[1]))
warm_up(base, base.fmu_paths)
idle = sorted(key[1] for key, objects in slave._idle_libraries.items() if objects)
compiled = [m for n, m in sys.modules.items() if n.endswith("plant_fmu.model.compiled")]
print(idle, [bool(m.advance_into.signatures) for m in compiled])
broken = base.__class__(base.scenario_id, {**base.data, "stop_time": -1.0}, base.fmu_paths)
warm_up(broken, base.fmu_paths)  # a scenario that cannot run: no exception
print("survived")
"""


@pytest.mark.slow
def test_warm_up_loads_the_libraries_and_compiles_the_plant(fmu_paths, run_python) -> None:
    done = run_python(WARM, fmu_paths["AuvPlant"].parent)
    assert done.returncode == 0, done.stderr[-2000:]
    first, last = done.stdout.strip().splitlines()[-2:]
    assert first == "['AuvAutopilot', 'AuvPlant'] [True]", done.stdout
    assert last == "survived"


FORKED = """
import gc, os, sys
import psutil
from cosim.study.execution import open_client

def probe():
    server = " ".join(psutil.Process().parent().cmdline())
    loaded = ("cosim.study.task", "cosim.engine.master", "pandas", "numba")
    fmu = [name for name in sys.modules if name.startswith("auvfmu_")]
    return (os.environ.get("OPENBLAS_NUM_THREADS"), all(n in sys.modules for n in loaded),
            "multiprocessing.forkserver" in server, fmu, gc.get_freeze_count() > 0)

if __name__ == "__main__":
    with open_client(2) as client:
        print(sorted(client.run(probe).values()))
"""


@pytest.mark.slow
@pytest.mark.cluster
@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_local_workers_are_forked_with_the_runs_modules_imported(run_python, tmp_path) -> None:
    """A study's local workers start from a fork server that imported Dask and the run's
    modules once (not each worker again) -- the engine, pandas and numba too, which a
    worker's warm-up imported before -- and froze them out of the garbage collector's
    reach, with Dask's pre-spawn environment (one BLAS thread), and nothing of an FMU
    (each worker loads its FMUs' packages after the fork)."""
    script = tmp_path / "forked.py"
    script.write_text(FORKED, encoding="utf-8")
    done = run_python(f"import runpy; runpy.run_path({str(script)!r}, run_name='__main__')")
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == str([("1", True, True, [], True)] * 2)
