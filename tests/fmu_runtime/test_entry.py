"""The generated pythonfmu entry module and the workarounds for pythonfmu 0.7's
instantiation (fmu_runtime/entry.py), replayed in-process the way its C++ does it."""

from __future__ import annotations

import sys
import types

from fmu_runtime import entry
from fmu_runtime.safe_slave import SafeSlave


def test_re_executing_the_entry_creates_no_class_and_keeps_its_namespace_alive():
    source = entry.entry_source("Toy", "fmu_runtime.safe_slave", "SafeSlave", ["fmu_runtime"])
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


def test_search_path_entry_is_removed_only_when_it_is_the_instance_s(monkeypatch, tmp_path):
    monkeypatch.setattr(sys, "path", [str(tmp_path), "/elsewhere"])
    assert entry.release_search_path(tmp_path) is True
    assert sys.path == ["/elsewhere"]
    assert entry.release_search_path(tmp_path) is False
    assert sys.path == ["/elsewhere"]
