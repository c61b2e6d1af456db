"""cosim.fmus.imports: the project-module import graph read with ast, on a small package
written for the test (lazy, relative and ``from package import module`` imports)."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.fmus.imports import import_closure, import_graph, package_modules

FILES = {
    "__init__.py": "",
    "a.py": "import numpy\nfrom pkg import b\n",
    "b.py": "from .sub import c\n\ndef later():\n    from pkg.a import something  # lazy\n",
    "sub/__init__.py": "",
    "sub/c.py": "from .. import d\nimport pkg.sub\n",
    "d.py": "import os\n",
    "unused.py": "import pkg.a\n",
    "data/values.toml": "x = 1\n",
}


@pytest.fixture
def pkg(tmp_path: Path) -> Path:
    root = tmp_path / "pkg"
    for name, text in FILES.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)
    return root


def test_modules_are_named_by_their_place_in_the_package(pkg: Path) -> None:
    modules = package_modules(pkg, "pkg")
    assert sorted(modules) == [
        "pkg",
        "pkg.a",
        "pkg.b",
        "pkg.d",
        "pkg.sub",
        "pkg.sub.c",
        "pkg.unused",
    ]
    assert modules["pkg.sub"] == pkg / "sub" / "__init__.py"


def test_graph_counts_lazy_relative_and_submodule_imports(pkg: Path) -> None:
    graph = import_graph(package_modules(pkg, "pkg"))
    assert graph["pkg.a"] == {"pkg", "pkg.b"}  # numpy is not ours; `from pkg import b` runs both
    assert graph["pkg.b"] == {"pkg.sub", "pkg.sub.c", "pkg.a"}  # the one in a function counts
    assert graph["pkg.sub.c"] == {"pkg.d", "pkg.sub", "pkg"}
    assert graph["pkg.d"] == set()


def test_closure_of_a_script_holds_what_it_runs_and_nothing_else(pkg: Path) -> None:
    script = pkg.parent / "script.py"
    script.write_text("from pkg.a import x\n")
    needed = import_closure(script, "script", package_modules(pkg, "pkg"))
    assert needed == {"pkg", "pkg.a", "pkg.b", "pkg.sub", "pkg.sub.c", "pkg.d"}
