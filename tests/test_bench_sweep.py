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


# a two-worker sweep's marks (seconds, pid, what, CPU s): client 1, fork server 2, workers 3, 4
TIMELINE = """
import json, sys
from sweep_timeline import cpu_phases
marks = [(0.1, 1, "fork server call begin", 0.09), (0.2, 2, "process start", 0.02),
         (1.3, 2, "preload end", 1.2), (1.4, 1, "client ready", 1.0),
         (1.4, 1, "execute begin", 1.0), (1.5, 3, "task begin", 0.05),
         (1.5, 3, "warm-up begin", 0.05), (1.7, 3, "warm-up end", 0.25),
         (1.6, 4, "task begin", 0.07), (1.6, 4, "warm-up begin", 0.07),
         (1.8, 4, "warm-up end", 0.27), (2.0, 3, "task end", 0.75),
         (2.1, 4, "task end", 0.77), (2.2, 1, "execute end", 1.3)]
print(json.dumps(cpu_phases({"marks": marks, "exit": 2.5, "pipes": 2.6, "cpu": 1.6})))
"""


def test_the_timeline_sets_the_clients_readiness_against_the_fork_servers_chain() -> None:
    """The chain before the first warm-up that the client's readiness races, in CPU s:
    the client's CPU until it calls the fork server, the server's imports and the first
    worker's start; the longer of it and "client until ready" is what the first run
    waits for on an idle machine (docs/performance.md)."""
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run([sys.executable, "-c", TIMELINE], env=env, check=True,
                          timeout=300, capture_output=True, text=True)  # fmt: skip
    rows = dict(json.loads(done.stdout))
    assert rows["client until server call"] == 0.09
    assert abs(rows["server chain to warm-up"] - (0.09 + 1.2 + 0.05)) < 1e-9  # worker 3 first
    assert rows["client until ready"] == 1.0
    assert abs(rows["client during runs"] - 0.3) < 1e-9


# the client's threads' own CPU clocks at the ends of its execute (1.4 s and 2.2 s): the
# page's first prefetch thread ends while the runs run, its second is alive at the end
THREADS = TIMELINE.replace(
    '(2.2, 1, "execute end", 1.3)]',
    """(2.2, 1, "execute end", 1.3),
         (1.4, 1, "execute begin thread MainThread#11", 0.50),
         (1.4, 1, "execute begin thread IO loop#12", 0.20),
         (1.4, 1, "execute begin thread auv-cosim-prefetch#13", 0.30),
         (1.45, 1, "thread end auv-cosim-prefetch#13", 0.32),
         (2.2, 1, "execute end thread MainThread#11", 0.53),
         (2.2, 1, "execute end thread IO loop#12", 0.31),
         (2.2, 1, "execute end thread auv-cosim-prefetch#14", 0.10),
         (2.4, 1, "thread end auv-cosim-prefetch#14", 0.14)]""",
)


def test_the_timeline_splits_the_clients_cpu_during_the_runs_by_thread() -> None:
    """The client's CPU while the runs run (what two workers on two cores share their
    cores with) split into its main thread, the page's matplotlib on its own threads
    (counted to a thread's end if it ends first) and Dask's threads (the rest), so a cut
    can be aimed at the part that costs."""
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run([sys.executable, "-c", THREADS], env=env, check=True,
                          timeout=300, capture_output=True, text=True)  # fmt: skip
    rows = dict(json.loads(done.stdout))
    assert abs(rows["  main thread"] - 0.03) < 1e-9
    assert abs(rows["  page's matplotlib"] - (0.02 + 0.10)) < 1e-9
    assert abs(rows["  Dask's threads (the rest)"] - (0.3 - 0.03 - 0.12)) < 1e-9


ESTIMATE = TIMELINE.replace(
    "from sweep_timeline import cpu_phases", "from sweep_timeline import cpu_phases, idle_estimate"
)
ESTIMATE = ESTIMATE.replace(
    "print(json.dumps(cpu_phases(",
    "print(json.dumps(idle_estimate(dict(cpu_phases(",
).replace('"cpu": 1.6})))', '"cpu": 1.6})), 2)))')


def test_the_idle_estimate_shares_the_cores_between_the_runs_and_the_client() -> None:
    """An idle machine's sweep estimated from CPU seconds: the start's longer chain (the
    fork server's here), the workers' warm-ups side by side, two workers' runs and the
    client's CPU beside them shared by two cores, then the client alone after the last
    run; what the benchmark's goal is about when the machine's load hides it."""
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run([sys.executable, "-c", ESTIMATE], env=env, check=True,
                          timeout=300, capture_output=True, text=True)  # fmt: skip
    rows = dict(json.loads(done.stdout))
    assert abs(rows["start (the longer chain)"] - (0.09 + 1.2 + 0.05)) < 1e-9
    assert abs(rows["warm-up"] - 0.2) < 1e-9
    assert abs(rows["runs"] - (0.5 + 0.5 + 0.3) / 2) < 1e-9  # not one worker's 0.5
    assert abs(rows["after the last run"] - 0.3) < 1e-9
    assert abs(rows["command to prompt"] - (1.34 + 0.2 + 0.65 + 0.3)) < 1e-9


# a command that waits for a child of its own which takes ~0.4 s of CPU, takes little CPU
# itself and ends as auv-cosim sweep ends, by os._exit
BUSY_CHILD = "import time\nt = time.process_time()\nwhile time.process_time() - t < 0.4: pass"
COMMAND = f"""
import os, subprocess, sys
subprocess.run([sys.executable, "-c", {BUSY_CHILD!r}], check=True)
os._exit(3)
"""
REAPED = """
import json, subprocess, sys
from sweep_timeline import reaped
process = subprocess.Popen([sys.executable, "-c", sys.argv[1]])
print(json.dumps(reaped(process.pid)))
"""


def test_the_timeline_counts_the_commands_own_cpu_not_its_childrens() -> None:
    """The command's CPU seconds ("client in all", "client after runs") are its own
    process's: not those of the children it waited for (the kernel adds them to what
    ``wait4`` reports), which put the workers' runs into "client after runs"."""
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run([sys.executable, "-c", REAPED, COMMAND], env=env, check=True,
                          timeout=300, capture_output=True, text=True)  # fmt: skip
    status, cpu = json.loads(done.stdout)
    assert os.waitstatus_to_exitcode(status) == 3
    assert cpu < 0.3, f"the command's own CPU {cpu:.2f} s counts its child's 0.4 s"


MARKS = TIMELINE.replace(
    "from sweep_timeline import cpu_phases", "from sweep_timeline import start_marks"
).replace("print(json.dumps(cpu_phases(", "print(json.dumps(start_marks(")


def test_the_timeline_lists_the_starts_marks_by_process_until_the_first_run() -> None:
    """``--marks``: the start's marks at the millisecond, each named by its process (the
    client, the fork server, worker k in the order of their warm-ups), none after the
    first run has started."""
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run([sys.executable, "-c", MARKS], env=env, check=True,
                          timeout=300, capture_output=True, text=True)  # fmt: skip
    lines = [" ".join(line.split()) for line in json.loads(done.stdout)]
    assert lines[0] == "100.0 client 90.0 fork server call begin"
    assert "1300.0 server 1200.0 preload end" in lines
    assert lines[-1] == "1700.0 worker 1 250.0 warm-up end"  # the first run starts
    assert not [line for line in lines if line.endswith("task end")]  # after it


# two workers (pids 3, 4) of two tasks each, the page's figures drafted beside the last run
RUNS_PHASE = """
import json
from sweep_timeline import runs_phase
marks = [(1.4, 1, "client ready", 1.0), (1.5, 3, "warm-up begin", 0.1),
         (1.5, 3, "task begin", 0.1), (2.0, 3, "task end", 0.6), (2.01, 3, "task begin", 0.6),
         (2.5, 3, "task end", 1.1), (1.53, 4, "warm-up begin", 0.1), (1.53, 4, "task begin", 0.1),
         (2.1, 4, "task end", 0.6), (2.13, 4, "task begin", 0.6), (2.6, 4, "task end", 1.1),
         (2.52, 1, "draft begin", 1.25), (2.57, 1, "draft end", 1.29),
         (2.61, 1, "execute end", 1.30), (2.70, 1, "page end", 1.38)]
print(json.dumps(runs_phase({"marks": marks})))
"""


def test_the_timeline_shows_where_the_workers_wait_and_the_draft_beside_the_last_run() -> None:
    """Where two workers wait in the runs' phase (the later first task, the gaps between
    tasks, the idle core before the last run ends) and when the page's figures were
    drafted, from the last run's end; then the client's wall and CPU to the page."""
    path = os.pathsep.join([str(ROOT / "scripts"), str(ROOT)])
    env = {**os.environ, "PYTHONPATH": path}
    done = subprocess.run([sys.executable, "-c", RUNS_PHASE], env=env, check=True,
                          timeout=300, capture_output=True, text=True)  # fmt: skip
    rows = dict(json.loads(done.stdout))
    expected = {
        "worker 1 first task at": 0.0, "worker 1 gaps (sum)": 0.01,
        "worker 1 idle at the end": 0.1, "worker 2 first task at": 0.03,
        "worker 2 gaps (sum)": 0.03, "worker 2 idle at the end": 0.0,
        "drafting begins": -0.08, "drafting ends": -0.03, "last result to page": 0.09,
        "  the client's CPU": 0.08,
    }  # fmt: skip
    assert {name: round(rows[name], 6) for name in expected} == expected
