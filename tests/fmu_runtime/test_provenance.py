"""Stale-code detection (fmu_runtime/provenance.py) on small packages written here: a
module imported from another build is named, the same code under another GUID is not,
data files and modules not imported yet do not count."""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path

import pytest

from fmu_runtime import provenance

SOURCES = {
    "toy_entry.py": b"from toy_pkg.core import VALUE\n",
    "toy_pkg/__init__.py": b"",
    "toy_pkg/core.py": b"VALUE = 1\n",
    "toy_pkg/later.py": b"LATER = 1\n",
    "toy_pkg/data.toml": b"x = 1\n",
}


def _extract(folder: Path, files: dict[str, bytes], guid: str = "guid-a") -> Path:
    """An FMU-like resources folder holding ``files`` and their manifest."""
    for relative, data in files.items():
        (folder / relative).parent.mkdir(parents=True, exist_ok=True)
        (folder / relative).write_bytes(data)
    (folder / provenance.MANIFEST).write_bytes(provenance.manifest("Toy", guid, files))
    return folder


@pytest.fixture
def imported(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """Build A's resources, imported as a host would (``toy_entry`` and ``toy_pkg``)."""
    resources = _extract(tmp_path / "a", SOURCES)
    monkeypatch.syspath_prepend(str(resources))
    monkeypatch.setattr(provenance, "_loaded", {})
    for name in ("toy_entry", "toy_pkg", "toy_pkg.core", "toy_pkg.later"):
        monkeypatch.delitem(sys.modules, name, raising=False)
    importlib.import_module("toy_entry")
    yield resources
    for name in ("toy_entry", "toy_pkg", "toy_pkg.core", "toy_pkg.later"):
        sys.modules.pop(name, None)


def test_the_same_build_again_is_accepted_after_its_first_extraction_is_gone(imported, tmp_path):
    build = provenance.read_build(imported)
    assert provenance.stale_code(build) is None  # reads the loaded sources once
    for path in sorted(imported.rglob("*"), reverse=True):  # the host deletes extraction A
        path.unlink() if path.is_file() else path.rmdir()
    again = provenance.read_build(_extract(tmp_path / "b", SOURCES))
    assert provenance.stale_code(again) is None


def test_a_rebuild_of_the_same_sources_with_a_new_guid_is_accepted(imported, tmp_path):
    rebuilt = _extract(tmp_path / "b", SOURCES, guid="guid-b")
    assert provenance.stale_code(provenance.read_build(rebuilt)) is None


def test_another_build_is_refused_naming_the_imported_module(imported, tmp_path):
    changed = {**SOURCES, "toy_pkg/core.py": b"VALUE = 2\n"}
    problem = provenance.stale_code(provenance.read_build(_extract(tmp_path / "b", changed)))
    assert problem is not None
    assert problem.startswith("stale code: this process already imported toy_pkg.core (from ")
    assert str(imported / "toy_pkg" / "core.py") in problem
    assert "Toy.fmu (GUID guid-a)" in problem and "new process" in problem


def test_data_files_and_modules_not_imported_yet_do_not_count(imported, tmp_path):
    changed = {**SOURCES, "toy_pkg/data.toml": b"x = 2\n", "toy_pkg/later.py": b"LATER = 2\n"}
    build = provenance.read_build(_extract(tmp_path / "b", changed))
    assert provenance.stale_code(build) is None


def test_no_manifest_means_nothing_to_check_and_a_bad_one_is_reported(tmp_path):
    assert provenance.read_build(None) is None
    assert provenance.read_build(tmp_path) is None  # pythonfmu's builder, in-process use
    (tmp_path / provenance.MANIFEST).write_text(json.dumps({"format": 99}))
    with pytest.raises(ValueError, match=r"fmu_sources.json is not a usable manifest: format 99"):
        provenance.read_build(tmp_path)
