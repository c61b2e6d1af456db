"""The workers' fork server imports with the garbage collector off (its imports make ~10^6
objects and no garbage, and the full collections they set off walked them all again before
the first worker could be forked) and turns it on again for the workers it forks."""

from __future__ import annotations

import ast
import subprocess
import sys

import pytest
from process_group import run_in_group

from cosim.study import fork_server

PRELOAD_THEN_REPORT = """
import gc, importlib, sys
from cosim.study.fork_server import PRELOAD
for name in PRELOAD[:-1]:  # the last one makes the server's exit skip the teardown
    importlib.import_module(name)
print(repr((gc.isenabled(), [s["collections"] for s in gc.get_stats()])))
"""


@pytest.mark.slow
def test_the_fork_server_imports_without_full_collections_and_forks_with_the_collector_on() -> None:
    done = subprocess.run(
        [sys.executable, "-c", PRELOAD_THEN_REPORT],
        capture_output=True, text=True, timeout=300, check=True,
    )  # fmt: skip
    enabled, collections = ast.literal_eval(done.stdout.strip().splitlines()[-1])
    assert enabled, "the workers forked from the server would never collect"
    assert collections[2] == 0, f"full collections while the server imported: {collections}"
    assert fork_server.PRELOAD[0] == "cosim.study.server_environ"  # which turns it off first


PRELOAD_THEN_THREADS = """
import importlib, os
from cosim.study.fork_server import PRELOAD
for name in PRELOAD[:-1]:  # the last one makes the server's exit skip the teardown
    importlib.import_module(name)
tasks = os.listdir("/proc/self/task")
print(sorted(open(f"/proc/self/task/{task}/comm").read().strip() for task in tasks))
"""


@pytest.mark.slow
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/task")
def test_the_fork_server_has_one_thread_when_it_forks() -> None:
    """A process forked from one with other threads holds their locks as they were; CPython
    3.12 and later warn of it ("This process is multi-threaded, use of fork() may lead to
    deadlocks in the child") at each worker the server forked: pyarrow, which pandas
    imports, started jemalloc's background thread in the server."""
    done = run_in_group([sys.executable, "-c", PRELOAD_THEN_THREADS], timeout=300)
    assert done.returncode == 0, done.stderr.strip().splitlines()[-1:]
    threads = ast.literal_eval(done.stdout.strip().splitlines()[-1])
    assert len(threads) == 1, f"the fork server's threads: {threads}"
