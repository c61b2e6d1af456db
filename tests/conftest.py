"""Shared fixtures: the session's temporary folder, the built FMUs and a fresh-process
Python runner.

* ``session_tmpdir`` (session, autouse): ``TMPDIR`` (and :mod:`tempfile`'s default) for
  the session and every process its tests start: a folder of pytest's own, removed at the
  session's end with whatever is in it. What a test or its processes put in the system's
  temporary folder without a folder of their own (fmpy's extractions, a browser's profile,
  Dask's scratch space, ecos's SSP copies, what a process killed on purpose could not
  clean up) is not left behind.
* ``fmu_paths`` (session): ``{"AuvPlant": Path, "AuvAutopilot": Path}`` built once per test
  session into a temporary folder with :mod:`cosim.fmus.build`. An FMU whose build fails
  is absent, and looking it up raises that build's error (so a broken FMU fails only the
  tests that use it). With xdist, numba's kernels (the FMUs' and the source tree's) are
  then compiled once for all the workers where the cache holds none (``tests/numba_warm.py``).
* ``test_fmu_dir`` (session): the folder holding the master tests' FMUs built from
  tests/fmus (``CosimTestIntegrator.fmu``, ``CosimTestGain.fmu``).
* Both folders are shared by the session's xdist workers (``tests/worker_shared.py``): one
  worker builds, the other waits for it and uses what it built (or builds another FMU
  meanwhile). A test copies an FMU before it changes it, as it did when only its own
  worker's tests used the folder.
* ``users_mypy_cache`` (session): mypy's cache folder the tests of a user's ``mypy
  --strict`` share (``tests/users_mypy.py``), one per test process.
* Every test using ``fmu_paths`` or ``test_fmu_dir`` is marked ``fmu``.
* Hypothesis runs without its deadline (an example over 200 ms failed as
  DeadlineExceeded): on a loaded machine that is a timed assertion, which the suite
  makes nowhere; the examples' count bounds a property test's time.
* A shared fixture's set-up (session, package, module or class scope) is not counted in
  the per-test limit of pytest-timeout (900 s) of the test that first asks for it: its
  timer is paused meanwhile (a Windows CPython set up under Wine took 498 s at load 20,
  and the test then timed out through no fault of its own), and the set-up has a limit
  of its own, the ini option ``fixture_setup_timeout`` (s, 1800 unless told; 0: none).
* Every test (an autouse guard) fails at its teardown, naming what it left, if it leaves
  its pytest process with a stop signal's handler, SIGCHLD's or SIGPIPE's changed, a
  signal newly ignored or blocked (every process started later inherits those: a Ctrl-C
  test's child once ignored Ctrl-C and timed out), or a child process still running 5 s
  after it ended (``tests/process_state.py``); the signals are then put back and the
  children killed, so that the tests after it are not blamed too. ``--leak-check`` lists
  more of what each test leaves behind (``tests/leak_check.py``).
* ``run_python`` (session): ``run_python(code, *args, timeout=300)`` runs ``code`` with
  this interpreter in a fresh process (``sys.argv[1:] == args``) and returns the
  ``subprocess.CompletedProcess`` (text mode, stdout/stderr captured), in a process group
  of its own that is killed when it returns or times out. This folder is on
  the child's ``PYTHONPATH`` after the project's packages (``from fmu_harness import
  Harness`` works, and ``tests/cosim`` does not shadow ``cosim``). Use it where
  pythonfmu's module caching or a possible crash of the host calls for a new process.
"""

from __future__ import annotations

import contextlib
import multiprocessing.util
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from deadline import deadline
from hypothesis import settings
from numba_warm import compile_once
from process_group import run_in_group
from process_state import (
    WATCHED_SIGNALS,
    child_processes,
    new_children,
    signal_changes,
    signal_state,
)
from worker_shared import build_once, in_worker_order, shared_folder

import cosim
from cosim.errors import CosimError
from cosim.fmus.build import FMUS, build_fmu, pythonfmu_build
from cosim.fmus.kept_builds import OFF_VARIABLE
from plant_fmu.model.parameters import VehicleParameters, load_vehicle

settings.register_profile("untimed", deadline=None)
settings.load_profile("untimed")


class BuiltFmus(dict):
    """``{name: path}`` of the FMUs that built; looking up one whose build failed raises
    that build's error, so a broken FMU fails only the tests that use it."""

    def __init__(self, built: dict[str, Path], failures: dict[str, Exception]) -> None:
        super().__init__(built)
        self.failures = failures

    def __missing__(self, name: str) -> Path:
        if name in self.failures:
            raise self.failures[name]
        raise KeyError(name)


@pytest.fixture(scope="session", autouse=True)
def session_tmpdir(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    """The session's temporary folder (see the module's docstring)."""
    # multiprocessing's own folder of this process stays where it was: its finalizer
    # removes it as the process ends, after the session's folder went (a traceback then)
    multiprocessing.util.get_temp_dir()
    folder = tmp_path_factory.mktemp("tmp")
    before = os.environ.get("TMPDIR"), tempfile.tempdir
    os.environ["TMPDIR"] = tempfile.tempdir = str(folder)
    try:
        yield folder
    finally:
        if before[0] is None:
            os.environ.pop("TMPDIR", None)
        else:
            os.environ["TMPDIR"] = before[0]
        tempfile.tempdir = before[1]
        for entry in folder.iterdir():
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)


@pytest.fixture(scope="session", autouse=True)
def no_kept_builds() -> Iterator[None]:
    """Every test builds the FMUs it asks for (cosim/fmus/kept_builds.py off): one served
    from the user's store of built FMUs would skip what a build test checks, and the
    tests' builds would fill the user's cache. tests/cosim/fmus/test_kept_builds.py
    turns the store on in a cache of its own."""
    before = os.environ.get(OFF_VARIABLE)
    os.environ[OFF_VARIABLE] = "1"
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(OFF_VARIABLE, None)
        else:
            os.environ[OFF_VARIABLE] = before


CHILDREN_GRACE = 5.0  # s a test's child processes have to end after its teardown


@pytest.fixture(autouse=True)
def _leaves_no_signal_state_nor_child() -> Iterator[None]:
    """The guard of the module's docstring: set up before the test's other function-scoped
    fixtures, torn down after them."""
    handlers = {name: signal.getsignal(getattr(signal, name)) for name in WATCHED_SIGNALS}
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    signals, children = signal_state(), child_processes()
    yield
    left = signal_changes(signals, signal_state())
    ends = time.monotonic() + CHILDREN_GRACE
    while new_children(children) and time.monotonic() < ends:
        time.sleep(0.05)
    alive = new_children(children)
    left += [f"child process {pid} running: {command}" for pid, command in alive.items()]
    if not left:
        return
    for name, handler in handlers.items():
        if handler is not None:  # None: not set from Python, nothing to put back
            signal.signal(getattr(signal, name), handler)
    signal.pthread_sigmask(signal.SIG_SETMASK, blocked)
    for pid in alive:  # with its process group, where it leads one
        with contextlib.suppress(OSError):
            if os.getpgid(pid) == pid:
                os.killpg(pid, signal.SIGKILL)
            os.kill(pid, signal.SIGKILL)
    pytest.fail("the test left " + "; ".join(left), pytrace=False)


@pytest.fixture(scope="session")
def fmu_paths(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    # one folder for the xdist workers: build_fmu's lock has one build and the other wait
    out = shared_folder(tmp_path_factory, "fmus")
    built: dict[str, Path] = {}
    failures: dict[str, Exception] = {}
    for name in in_worker_order(FMUS):
        try:
            built[name] = build_fmu(name, out)
        except CosimError as exc:
            failures[name] = exc
    if "AuvPlant" in built and "AuvAutopilot" in built:
        compile_once(tmp_path_factory, built["AuvPlant"])  # numba's kernels, once
    return BuiltFmus({name: built[name] for name in FMUS if name in built}, failures)


@pytest.fixture(scope="session")
def users_mypy_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """mypy's incremental cache for ``tests/users_mypy.py``, one per test process (pytest-
    xdist's workers do not share it, so no two mypy runs write it at once)."""
    return tmp_path_factory.mktemp("users_mypy_cache")


@pytest.fixture(scope="session")
def remus() -> VehicleParameters:
    """The REMUS 100's parameter set (``plant_fmu/model/vehicles/remus100.toml``), frozen."""
    return load_vehicle("remus100")


@pytest.fixture(scope="session")
def fmu_dir(fmu_paths: dict[str, Path]) -> Path:
    """The folder of the built FMUs, where a scenario finds them by name (``fmu =
    "AuvPlant"``); the plant's and the autopilot's builds failing fail the tests using it."""
    assert fmu_paths["AuvAutopilot"].parent == fmu_paths["AuvPlant"].parent
    return fmu_paths["AuvPlant"].parent


@pytest.fixture(scope="session")
def test_fmu_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The master tests' own FMUs (tests/fmus: an integrator, a sampled gain, a direct
    feedthrough, a clock with outputs of every type that can end the simulation, a clock
    with a fixed step, one allowed once per process, one with other tools' habits), built
    once per session for all its workers, in a fresh process (pythonfmu caches modules)."""
    out = shared_folder(tmp_path_factory, "test_fmus")
    build_once(out, _build_test_fmus)
    return out


def _build_test_fmus(out: Path) -> None:
    for script, model, *options in (
        ("cosim_test_integrator.py", "CosimTestIntegrator"),
        ("cosim_test_gain.py", "CosimTestGain"),
        ("cosim_test_feedthrough.py", "CosimTestFeedthrough"),
        ("cosim_test_source.py", "CosimTestSource"),
        ("cosim_test_fixed_step.py", "CosimTestFixedStep", "--no-variable-step"),
        ("cosim_test_singleton.py", "CosimTestSingleton", "--only-one-per-process"),
        ("cosim_test_foreign.py", "CosimTestForeign"),
    ):
        script_path = Path(__file__).parent / "fmus" / script
        pythonfmu_build(script_path, out, model, "--handle-state", *options)


@pytest.fixture(scope="session")
def run_python(
    tmp_path_factory: pytest.TempPathFactory,
) -> Callable[..., subprocess.CompletedProcess]:
    cwd = tmp_path_factory.mktemp("subprocess")
    # The project's packages first: tests/ mirrors them (tests/cosim, tests/plant_fmu, ...
    # without __init__.py), and those folders would shadow them as namespace packages.
    packages = Path(cosim.__file__).resolve().parents[1]
    parts = [str(packages), str(Path(__file__).parent), os.environ.get("PYTHONPATH")]
    path = os.pathsep.join(filter(None, parts))
    env = {**os.environ, "PYTHONPATH": path}

    def run(code: str, *args: str, timeout: float = 300.0) -> subprocess.CompletedProcess:
        command = [sys.executable, "-c", textwrap.dedent(code), *map(str, args)]
        return run_in_group(command, timeout=timeout, cwd=cwd, env=env)

    return run


FMU_FIXTURES = {"fmu_paths", "test_fmu_dir"}
FIXTURE_SETUP_TIMEOUT = "1800"  # s


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addini("fixture_setup_timeout", "s a fixture's set-up may take (0: no limit)",
                  default=FIXTURE_SETUP_TIMEOUT)  # fmt: skip
    parser.addoption("--leak-check", action="store_true",
                     help="list what each test leaves behind (tests/leak_check.py)")  # fmt: skip
    parser.addoption("--leak-report", metavar="FILE",
                     help="with --leak-check: append the leaks to FILE (JSON lines)")  # fmt: skip


def pytest_configure(config: pytest.Config) -> None:
    if config.getoption("--leak-check"):
        import leak_check

        leak_check.register(config)


@pytest.hookimpl(hookwrapper=True)
def pytest_fixture_setup(
    fixturedef: pytest.FixtureDef, request: pytest.FixtureRequest
) -> Iterator[None]:
    """A shared fixture's set-up with pytest-timeout's timer (SIGALRM, the process's one
    real-time timer) paused, within ``fixture_setup_timeout`` of its own: one that takes
    longer fails the test asking for it, naming the fixture."""
    if fixturedef.scope == "function":  # the test's own time
        yield
        return
    seconds = int(request.config.getini("fixture_setup_timeout"))
    left, _ = signal.setitimer(signal.ITIMER_REAL, 0)
    limit = deadline(seconds, f"fixture {fixturedef.argname}: set-up not done")
    try:
        with limit if seconds > 0 else contextlib.nullcontext():
            yield
    finally:
        if left:
            signal.setitimer(signal.ITIMER_REAL, left)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Mark every test that builds or loads FMUs (through the fixtures above) ``fmu``."""
    for item in items:
        if FMU_FIXTURES & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.fmu)
