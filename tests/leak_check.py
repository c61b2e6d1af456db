"""An opt-in pytest plugin listing what each test leaves behind in its pytest process:
``python -m pytest --leak-check [--leak-report FILE] ...`` (tests/conftest.py registers
it; CONTRIBUTING.md).

Around each test (from before its set-up to the end of its teardown) it compares:

* the dispositions of SIGINT, SIGTERM, SIGHUP, SIGCHLD and SIGPIPE (``signal.getsignal``)
  and the process's ignored and blocked signals (``SigIgn`` and ``SigBlk`` of
  ``/proc/self/status``): an ignored signal is inherited by every process started later;
* the processes still alive: this process's descendants
  (``/proc/<pid>/task/<tid>/children``, recursively), and any process, wherever it was
  reparented, whose environment holds the test's mark (:data:`MARK`, set for the test's
  length: the processes it starts inherit it unless given an environment of their own).
  Not a child subreaper: a test waiting for an orphaned process group to end would wait
  for zombies no one reaps;
* the threads still alive (Python's by name, and the process's native count);
* the open file descriptors;
* the entries of the temporary folders: the one the session's tests get
  (``tempfile.gettempdir()``, ``session_tmpdir`` in tests/conftest.py), the one pytest
  started under (``TMPDIR``, or /tmp; its ``pytest-of-*`` left out: point ``TMPDIR`` at a
  folder of the run's own where other programs write to /tmp, and mind that xdist's
  workers share it);
* the environment variables and the working directory.

A test's differences are shown in the terminal summary (and appended as JSON lines to
``--leak-report``), with the session- and module-scoped fixtures set up or finalized
during that test, which may account for them; what is left at the session's end is
checked once more against the start. Linux only (it reads /proc).

Each entry is what one test changed; whether it is a leak is for the reader to judge (a
lazily started library thread pool stays by design, a Dask cluster must not)."""

from __future__ import annotations

import itertools
import json
import multiprocessing.process
import os
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import suppress
from pathlib import Path
from typing import Any

import pytest
from process_state import changed, child_processes, running, signal_changes, signal_state

MARK = "AUV_COSIM_LEAK_CHECK"  # the environment variable marking a test's processes
STARTING_TMPDIR = Path(tempfile.gettempdir())  # as pytest started: before session_tmpdir
KEY = "leaks"  # the name of the user property carrying a test's differences


def _fds() -> dict[int, str]:
    fds = {}
    for name in os.listdir("/proc/self/fd"):
        with suppress(OSError):
            fds[int(name)] = os.readlink(f"/proc/self/fd/{name}")
    return fds


def _entries(folder: Path) -> set[str]:
    try:
        names = os.listdir(folder)
    except OSError:
        return set()
    return {str(folder / name) for name in names if not name.startswith("pytest-of-")}


def snapshot() -> dict[str, Any]:
    """What the plugin compares, now."""
    folders = {Path(tempfile.gettempdir()), STARTING_TMPDIR}
    # this process's own folder of multiprocessing, which goes as the process ends
    own = getattr(multiprocessing.process.current_process(), "_config", {}).get("tempdir")
    return {
        "signals": signal_state(),
        "children": child_processes(),
        "threads": {t.ident: t.name for t in threading.enumerate()},
        "native_threads": len(os.listdir("/proc/self/task")),
        "fds": _fds(),
        "temporary": set().union(*map(_entries, folders)) - {own},
        "environ": dict(os.environ),
        "cwd": os.getcwd(),
    }


def differences(before: dict[str, Any], after: dict[str, Any]) -> dict[str, Any]:
    """What changed from ``before`` to ``after`` (two :func:`snapshot`); empty if nothing."""
    found: dict[str, Any] = {}
    if signals := signal_changes(before["signals"], after["signals"]):
        found["signals"] = signals
    for key in ("children", "threads", "fds"):
        new = {k: v for k, v in after[key].items() if k not in before[key]}
        if key == "fds":  # a descriptor number reused for another file is new too
            new = {k: v for k, v in after[key].items() if before[key].get(k) != v}
        if new:
            found[key] = {str(k): v for k, v in new.items()}
    if after["native_threads"] > before["native_threads"]:
        found["native_threads"] = after["native_threads"] - before["native_threads"]
    if new_entries := sorted(after["temporary"] - before["temporary"]):
        found["temporary"] = new_entries
    environ = changed(before["environ"], after["environ"])
    environ.pop("PYTEST_CURRENT_TEST", None)  # pytest's own, for each phase
    if environ:
        found["environ"] = environ
    if before["cwd"] != after["cwd"]:
        found["cwd"] = f"{before['cwd']} -> {after['cwd']}"
    return found


class LeakCheck:
    """The plugin's state in one pytest process (a controller or an xdist worker)."""

    def __init__(self, config: pytest.Config) -> None:
        self.report_path = config.getoption("--leak-report")
        self.worker = os.environ.get("PYTEST_XDIST_WORKER", "main")
        self.start: dict[str, Any] | None = None
        self.shared_fixtures: list[str] | None = None
        self.found: list[dict[str, Any]] = []

    def write(self, record: dict[str, Any]) -> None:
        self.found.append(record)
        if self.report_path:
            with open(self.report_path, "a", encoding="utf-8") as out:
                out.write(json.dumps(record, default=sorted) + "\n")

    @pytest.hookimpl(tryfirst=True)
    def pytest_sessionstart(self) -> None:
        self.start = snapshot()

    @pytest.hookimpl(hookwrapper=True)
    def pytest_fixture_setup(self, fixturedef: pytest.FixtureDef) -> Iterator[None]:
        yield
        if fixturedef.scope != "function" and self.shared_fixtures is not None:
            self.shared_fixtures.append(f"set up {fixturedef.argname} ({fixturedef.scope})")

    def compare(self, item: pytest.Item, before: dict[str, Any], marked: dict[int, str]) -> None:
        """Records what ``item`` changed since ``before``, and ``marked``, the processes
        it started still alive, if anything."""
        found = differences(before, snapshot())
        if orphans := {str(p): c for p, c in marked.items() if p not in before["children"]}:
            found["children"] = {**found.get("children", {}), **orphans}
        if found:
            record = {"test": item.nodeid, "worker": self.worker, **found}
            if self.shared_fixtures:
                record["shared_fixtures"] = list(self.shared_fixtures)
            self.write(record)
            item.user_properties.append((KEY, record))
        self.shared_fixtures = None

    @pytest.hookimpl(trylast=True)
    def pytest_sessionfinish(self) -> None:
        if self.start is not None:
            found = differences(self.start, snapshot())
            if found:
                self.write({"test": "(the whole session)", "worker": self.worker, **found})

    def pytest_runtest_logreport(self, report: pytest.TestReport) -> None:
        if report.when == "teardown" and os.environ.get("PYTEST_XDIST_WORKER") is None:
            for key, record in report.user_properties:
                if key == KEY and isinstance(record, dict) and record not in self.found:
                    self.found.append(record)

    def pytest_terminal_summary(self, terminalreporter: Any) -> None:
        if not self.found:
            terminalreporter.write_sep("=", "leak check: no test left anything behind")
            return
        terminalreporter.write_sep("=", f"leak check: {len(self.found)} records of changes")
        for record in self.found:
            terminalreporter.write_line(json.dumps(record, default=sorted, indent=1))


STATE = pytest.StashKey[LeakCheck]()


@pytest.fixture(autouse=True)
def _leak_check(request: pytest.FixtureRequest) -> Iterator[None]:
    """Set up before the test's other function-scoped fixtures (after the shared ones),
    torn down after them (before a shared one is finalized): the test's own changes."""
    state = request.config.stash[STATE]
    before = snapshot()
    mark = f"{state.worker}-{os.getpid()}-{next(_tests)}"
    os.environ[MARK] = mark
    state.shared_fixtures = []  # those set up by the test itself (getfixturevalue)
    yield
    os.environ.pop(MARK, None)
    state.compare(request.node, before, marked(mark))


_tests = itertools.count()


def marked(mark: str) -> dict[int, str]:
    """``{pid: command line}`` of the live processes whose environment holds ``mark``."""
    needle = f"{MARK}={mark}".encode() + b"\0"
    found = {}
    for name in os.listdir("/proc"):
        if not name.isdigit() or int(name) == os.getpid():
            continue
        with suppress(OSError):
            environ = Path(f"/proc/{name}/environ").read_bytes()
            if needle in environ and (said := running(int(name))) is not None:
                found[int(name)] = said
    return found


def register(config: pytest.Config) -> None:
    """Registers the plugin in ``config`` (from ``pytest_configure``)."""
    config.stash[STATE] = LeakCheck(config)
    config.pluginmanager.register(config.stash[STATE], "leak_check_state")
    config.pluginmanager.register(sys.modules[__name__], "leak_check")
