"""The generated pythonfmu entry module and the workarounds for pythonfmu 0.7's
instantiation (fmu_runtime/entry.py), replayed in-process the way its C++ does it."""

from __future__ import annotations

import sys
import types
import warnings

from numba_warnings import NUMBA_PARSE_WARNING

from fmu_runtime import entry
from fmu_runtime.safe_slave import SafeSlave


def _build_package(folder, name: str) -> None:
    """A build package ``name`` in ``folder`` holding this fmu_runtime (a link)."""
    (folder / name).mkdir()
    (folder / name / "__init__.py").write_text("")
    (folder / name / "fmu_runtime").symlink_to(sys.modules["fmu_runtime"].__path__[0])


def _forget(package: str) -> None:
    for name in [m for m in sys.modules if m.split(".")[0] == package]:
        del sys.modules[name]


def test_re_executing_the_entry_creates_no_class_and_keeps_its_namespace_alive(
    tmp_path, monkeypatch
):
    _build_package(tmp_path, "auvfmu_000000000001")
    monkeypatch.syspath_prepend(str(tmp_path))
    source = entry.entry_source("Toy", "auvfmu_000000000001", "fmu_runtime.safe_slave", "SafeSlave")
    code = compile(source, "toy_entry.py", "exec")
    module = types.ModuleType("toy_entry")
    exec(code, module.__dict__)  # the first import
    for _ in range(3):  # each fmi2Instantiate runs the text again with fresh locals
        fresh: dict = {}
        before = sys.getrefcount(module.__dict__)
        exec(code, module.__dict__, fresh)
        gained = sys.getrefcount(module.__dict__) - before
        assert gained == 1  # the one pythonfmu then releases without having taken it
        classes = {name: value for name, value in fresh.items() if isinstance(value, type)}
        assert classes == {"SafeSlave": SafeSlave}  # the class itself, not a new one
    assert module.SafeSlave is SafeSlave
    _forget("auvfmu_000000000001")


def test_the_build_package_imports_every_module_of_its_packages_at_once(tmp_path, monkeypatch):
    """While the extraction exists: a later instance never looks for a module in an
    extraction a host may have deleted."""
    _build_package(tmp_path, "auvfmu_000000000002")
    root = tmp_path / "auvfmu_000000000002"
    (root / "pkg" / "sub").mkdir(parents=True)
    (root / "__init__.py").write_text(entry.package_init_source("Toy", ["pkg"], ["pkg"]))
    (root / "pkg" / "__init__.py").write_text("")
    (root / "pkg" / "sub" / "__init__.py").write_text("")
    (root / "pkg" / "sub" / "leaf.py").write_text("VALUE = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import auvfmu_000000000002  # noqa: F401

    assert "auvfmu_000000000002.pkg.sub.leaf" in sys.modules
    _forget("auvfmu_000000000002")


def test_search_path_entry_is_removed_only_when_it_is_an_fmu_extraction(monkeypatch, tmp_path):
    monkeypatch.setattr(sys, "path", [str(tmp_path), "/elsewhere"])
    assert entry.release_search_path(tmp_path) is False  # pythonfmu's builder's folder
    (tmp_path / entry.RECORD_FILE).write_text("guid=x\n")
    assert entry.release_search_path(tmp_path) is True
    assert sys.path == ["/elsewhere"]
    assert entry.release_search_path(tmp_path) is False
    assert sys.path == ["/elsewhere"]


def test_an_import_warning_is_kept_for_the_logger_under_a_hosts_error_filter(tmp_path, monkeypatch):
    """Guards a host's ``-W error`` (or pytest's ``filterwarnings = error``) turning a
    warning of the FMU's imports (numba's cache folder that cannot be written), which the
    next instance logs, into an exception that fails fmi2Instantiate."""
    (tmp_path / "warnpkg" / "sub").mkdir(parents=True)
    (tmp_path / "warnpkg" / "__init__.py").write_text("")
    (tmp_path / "warnpkg" / "sub" / "__init__.py").write_text(
        "import warnings\nwarnings.warn('cache folder cannot be written', RuntimeWarning)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    entry.take_import_warnings()  # none of an earlier test's
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            entry.import_packages("warnpkg", ["sub"])
            assert warnings.filters[0][0] == "error"  # the host's filters as they were
    finally:
        _forget("warnpkg")
    assert entry.take_import_warnings() == ["cache folder cannot be written"]


def test_an_import_warning_carrying_a_traceback_is_kept_as_one_line(tmp_path, monkeypatch):
    """numba's warning of a setting it cannot parse (NUMBA_OPT=9) holds a whole Python
    traceback, which the FMU logged to its host as it was: nine lines, or one joined by
    " | " in auv-cosim's output. Kept: what it says before the traceback and its last
    line, the exception, on one line."""
    (tmp_path / "tbpkg" / "sub").mkdir(parents=True)
    (tmp_path / "tbpkg" / "__init__.py").write_text("")
    (tmp_path / "tbpkg" / "sub" / "__init__.py").write_text(
        f"import warnings\nwarnings.warn({NUMBA_PARSE_WARNING!r}, UserWarning)\n"
    )
    monkeypatch.syspath_prepend(str(tmp_path))
    entry.take_import_warnings()  # none of an earlier test's
    try:
        entry.import_packages("tbpkg", ["sub"])
    finally:
        _forget("tbpkg")
    assert entry.take_import_warnings() == [
        "Environment variable 'NUMBA_OPT' is defined but its associated value '9' could "
        "not be parsed. The parse failed with exception: ValueError: Environment variable "
        "`NUMBA_OPT` is set to an unsupported value '9', supported values are 0, 1, 2, 3, "
        "and 'max'"
    ]


TWO_BUILDS = """
import sys, threading, warnings
from pathlib import Path
from fmu_runtime import entry

folder = Path(sys.argv[1])
(folder / "sync.py").write_text("import threading\\nb_importing = threading.Event()\\n")
# pa's import waits for pb's to start; pb's ends after pa's has ended (0.5 s later)
waits = {"pa": "sync.b_importing.wait(1)", "pb": "sync.b_importing.set(); time.sleep(0.5)"}
for name, wait in waits.items():
    (folder / name / "sub").mkdir(parents=True)
    (folder / name / "__init__.py").write_text("")
    (folder / name / "sub" / "__init__.py").write_text(
        f"import sync, time, warnings\\n{wait}\\nwarnings.warn('{name} says', RuntimeWarning)\\n"
    )
sys.path.insert(0, str(folder))
threads = [threading.Thread(target=entry.import_packages, args=(n, ["sub"])) for n in waits]
for thread in threads:
    thread.start()
for thread in threads:
    thread.join()
kept = sorted(entry.take_import_warnings())
shown = []
warnings.showwarning = lambda message, *rest: shown.append(str(message))
warnings.warn("the host's own warning, later", UserWarning)
print(kept, shown)
"""


def test_two_builds_imported_at_once_leave_the_hosts_warnings_as_they_were(tmp_path, run_python):
    """Guards two FMU builds imported from two threads at once (each keeps its imports'
    warnings with catch_warnings, which is process-wide): the later one to finish put the
    first one's recorder back for good, and every later warning of the host went into a
    list no one read."""
    done = run_python(TWO_BUILDS, str(tmp_path))
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip().splitlines()[-1] == (
        "['pa says', 'pb says'] [\"the host's own warning, later\"]"
    ), done.stdout + done.stderr
