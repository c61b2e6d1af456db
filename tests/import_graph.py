"""Which of the project's modules a Python file imports, read with ast (nothing is run).

For tests/test_code_shape.py: the import graph of our packages (no two modules may import
each other) and the modules an FMU's script imports, directly or through each other (what
a built FMU runs). Every import statement counts, at module level or inside a function (a
lazy import is still an import); relative imports are resolved, and ``from package import
name`` counts the package and the submodule ``package.name`` when there is one (importing
it runs both).

(Written with ast rather than the standard library's ``modulefinder``: that one compiles
and follows every module on the path, numpy, scipy and the rest included, where only the
import statements of our own packages matter here.)
"""

from __future__ import annotations

import ast
from collections.abc import Mapping
from pathlib import Path

ModuleFiles = Mapping[str, Path]
"""Dotted module name -> its file (a package's ``__init__.py`` for the package)."""


def package_modules(package_dir: Path, package: str) -> dict[str, Path]:
    """Every ``.py`` module under ``package_dir`` (the package ``package``), by name."""
    modules = {}
    for path in sorted(package_dir.rglob("*.py")):
        relative = path.relative_to(package_dir)
        if "__pycache__" in relative.parts:
            continue
        parts = [package, *relative.parent.parts]
        if path.name != "__init__.py":
            parts.append(path.stem)
        modules[".".join(parts)] = path
    return modules


def imported_modules(path: Path, module: str, known: ModuleFiles) -> set[str]:
    """The modules of ``known`` that ``path`` (the file of module ``module``) imports."""
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = _absolute(node, package)
            names = [base] + [f"{base}.{alias.name}" for alias in node.names]
        else:
            continue
        found.update(m for m in (_longest_known(n, known) for n in names) if m is not None)
    found.discard(module)
    return found


def import_graph(known: ModuleFiles) -> dict[str, set[str]]:
    """Each module of ``known`` -> the modules of ``known`` it imports."""
    return {module: imported_modules(path, module, known) for module, path in known.items()}


def import_closure(path: Path, module: str, known: ModuleFiles) -> set[str]:
    """Every module of ``known`` that importing ``module`` (file ``path``, which need not be
    in ``known``, e.g. an FMU's top-level script) imports, with the packages holding them
    (importing ``a.b.c`` runs ``a`` and ``a.b`` first)."""
    needed: set[str] = set()
    todo = sorted(imported_modules(path, module, known))
    while todo:
        name = todo.pop()
        if name in needed:
            continue
        needed.add(name)
        parents = [name.rsplit(".", k)[0] for k in range(1, name.count(".") + 1)]
        todo += [p for p in parents if p in known]
        todo += sorted(imported_modules(known[name], name, known))
    return needed


def _absolute(node: ast.ImportFrom, package: str) -> str:
    """The absolute module name ``from <...> import`` refers to."""
    if node.level == 0:
        return node.module or ""
    parts = package.split(".")
    base = ".".join(parts[: len(parts) - (node.level - 1)])
    return f"{base}.{node.module}" if node.module else base


def _longest_known(name: str, known: ModuleFiles) -> str | None:
    """``name`` or its longest prefix that is a known module (None for other packages)."""
    parts = name.split(".")
    for end in range(len(parts), 0, -1):
        candidate = ".".join(parts[:end])
        if candidate in known:
            return candidate
    return None
