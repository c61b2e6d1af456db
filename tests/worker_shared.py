"""What the session's pytest-xdist workers build once between them: a folder they share
and a lock around what is built into it.

Each worker of ``pytest -n 2`` set up the session's FMUs on its own (the plant and the
autopilot of ``fmu_paths``, the master tests' FMUs of ``test_fmu_dir``): the same files
built twice, in the CPU time the other worker's tests wait for on two cores. A worker's
temporary folder (``popen-gw<N>``) lies in pytest's folder of the session, removed as the
retention policy says; a folder beside them is the session's, seen by every worker and
by no later session. Without xdist, the folder is the process's own, as before.
"""

from __future__ import annotations

import fcntl
import os
from collections.abc import Callable, Iterable
from pathlib import Path

import pytest

DONE = ".built"  # written in the folder once its build returned


def shared_folder(tmp_path_factory: pytest.TempPathFactory, name: str) -> Path:
    """The folder ``name`` of this session's xdist workers (made by the first asking),
    or a new temporary folder of this process's when it is no worker."""
    if "PYTEST_XDIST_WORKER" not in os.environ:
        return tmp_path_factory.mktemp(name)
    folder = tmp_path_factory.getbasetemp().parent / name
    folder.mkdir(exist_ok=True)
    return folder


def in_worker_order(names: Iterable[str]) -> list[str]:
    """``names`` in the order this worker builds them: reversed on every second worker
    (gw1, gw3, ...), so that two workers build two of them at once, each under its own
    lock (``cosim.fmus.build.fmu_lock``), rather than queue at the first one's."""
    number = os.environ.get("PYTEST_XDIST_WORKER", "gw0").removeprefix("gw")
    names = list(names)
    return names[::-1] if number.isdigit() and int(number) % 2 else names


def build_once(folder: Path, build: Callable[[Path], None]) -> None:
    """Run ``build(folder)`` unless a process of the session did it whole already; one
    asking meanwhile waits for it. A build that raised is not done: the next asking runs
    it again (and gets that error too, as each worker did when it built alone)."""
    # flock: the system releases it if the holder dies (a worker killed by a timeout)
    with open(folder / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (folder / DONE).exists():
            build(folder)
            (folder / DONE).touch()
