"""A study worker's warm-up (before its first run) leaves the FMUs' libraries loaded and
idle for that run, and their plant code compiled; it never raises; it runs in each
worker's first task, not when the study plugin is registered. Local workers are forked
from a server that imported the run's modules once."""

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
    loaded = ("cosim.study.task", "cosim.engine.master", "numba")
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
    modules once (not each worker again) -- the engine and numba too, which a
    worker's warm-up imported before -- and froze them out of the garbage collector's
    reach, with Dask's pre-spawn environment (one BLAS thread), and nothing of an FMU
    (each worker loads its FMUs' packages after the fork)."""
    script = tmp_path / "forked.py"
    script.write_text(FORKED, encoding="utf-8")
    done = run_python(f"import runpy; runpy.run_path({str(script)!r}, run_name='__main__')")
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == str([("1", True, True, [], True)] * 2)


FIRST_TASK = """
import sys
from pathlib import Path
from cosim.study.design import PlannedRun
from cosim.study.execution import execute, make_job, open_client
from cosim.study.task import prepare

def fmus_loaded():
    return any(name.startswith("auvfmu_") for name in sys.modules)

if __name__ == "__main__":
    base, _ = prepare("bs-3", 1.0, Path(sys.argv[1]))
    job, plugin = make_job(base, {}, "none")
    with open_client(2) as client:
        client.register_plugin(plugin, name=job.plugin)
        print(sorted(client.run(fmus_loaded).values()))
        client.unregister_worker_plugin(job.plugin)
        records = []
        runs = [PlannedRun(f"r{k}", {}) for k in range(4)]
        execute(client, job, plugin, runs, lambda run, record: records.append(record.status))
        print(records, sorted(client.run(fmus_loaded).values()))
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_workers_warm_up_in_their_first_task_not_at_registration(
    fmu_paths, run_python, tmp_path
) -> None:
    """Registering the study plugin (which every worker must finish before the client
    submits a task) loads no FMU: a worker loads its FMUs in its first task, so a worker
    that is ready starts its runs without waiting for the others to warm up; the runs
    still complete and the FMUs stay loaded in each worker that ran one."""
    script = tmp_path / "first_task.py"
    script.write_text(FIRST_TASK, encoding="utf-8")
    folder = fmu_paths["AuvPlant"].parent
    done = run_python(
        "import runpy, sys; sys.argv[1:] = [sys.argv[1]]; "
        f"runpy.run_path({str(script)!r}, run_name='__main__')",
        folder,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    registered, ran = done.stdout.strip().splitlines()[-2:]
    assert registered == "[False, False]"
    assert ran.startswith("['complete', 'complete', 'complete', 'complete'] ")
    assert "True" in ran.split("] ", 1)[1]


SERVER_FIRST = """
import os, sys
from multiprocessing import forkserver

def ensure_running():
    heavy = ("cosim.api", "cosim.runner", "dask", "http.server", "numpy", "pydantic")
    print(sorted(name for name in heavy if name in sys.modules), flush=True)
    os._exit(0)

forkserver.ensure_running = ensure_running
from cosim.cli import main
main(["sweep", "no-such-study.toml", "--workers", "1"])
"""


@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_the_sweep_command_starts_the_fork_server_before_heavy_imports(run_python) -> None:
    """`auv-cosim sweep` starts its workers' fork server before it imports the API, the
    runner, Dask, numpy or the web viewer's HTTP server (each worker's imports, ~2 s, are
    the longest chain before the first run, and they start with the server); the server
    itself sets Dask's pre-spawn environment (tested above: one BLAS thread in each
    worker)."""
    done = run_python(SERVER_FIRST)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "[]"


CLIENT = """
import sys
from pathlib import Path
import cosim
fmus = Path(sys.argv[1])
study = {"scenario": "bs-3", "stop_time": 0.05, "grid": {"plant.v_0": [0.0, 0.05]}}
table = cosim.sweep(study, workers=1, fmu_dir=fmus).table
print(list(table["status"]), sorted(n for n in ("numba", "llvmlite") if n in sys.modules))
"""


@pytest.mark.slow
def test_a_study_client_never_imports_the_compiler(run_python, fmu_paths) -> None:
    """A local study's client steps no FMU: numba (~0.15 s of CPU to import) is the
    workers' (their fork server imports it), not on the client's way to its cluster, the
    last thing the first run waits for on a machine of as many cores as workers."""
    done = run_python(CLIENT, str(fmu_paths["AuvPlant"].parent))
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "['complete', 'complete'] []"
