"""The shape of the code: short functions, no import cycle between the project's modules,
and FMUs that ship only code an FMU runs (no analysis, plotting or master module)."""

from __future__ import annotations

import ast
import itertools
import zipfile
from pathlib import Path

import numpy as np
import pytest
from import_graph import import_closure, import_graph, package_modules
from repo_paths import ROOT
from scipy.sparse import csr_array
from scipy.sparse.csgraph import connected_components

PACKAGES = ("cosim", "plant_fmu", "controller_fmu", "fmu_runtime")
MAX_FUNCTION_LINES = 80
# Modules that belong to the offline analysis, the plots or the master, never in an FMU.
NOT_IN_FMUS = ("bifurcation", "equilibria", "closed_loop", "plots", "master", "manoeuvres")
FMU_NAMES = ("AuvPlant", "AuvAutopilot", "AuvGuidance")


def _functions(tree: ast.AST, prefix: str = ""):
    """(qualified name, node) of every function and method, nested ones included."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            yield prefix + node.name, node
            yield from _functions(node, f"{prefix}{node.name}.")
        elif isinstance(node, ast.ClassDef):
            yield from _functions(node, f"{prefix}{node.name}.")
        else:
            yield from _functions(node, prefix)


def _docstring_lines(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """How many lines of ``node`` its docstring takes (0 without one)."""
    if ast.get_docstring(node, clean=False) is None:
        return 0
    first = node.body[0]
    return first.end_lineno - first.lineno + 1


def _project_modules() -> dict[str, Path]:
    modules = {}
    for package in PACKAGES:
        modules.update(package_modules(ROOT / package, package))
    return modules


def _report(offenders: list[str], what: str) -> None:
    """Fail naming every offender."""
    assert not offenders, f"{what}: " + ", ".join(offenders)


@pytest.mark.slow
def test_no_function_is_longer_than_80_lines() -> None:
    """In the packages and in scripts/ alike; a docstring is not counted (an API
    function's Parameters and Raises sections are what its help shows, not code)."""
    offenders = []
    scripts = sorted((ROOT / "scripts").rglob("*.py"))
    assert scripts, "no scripts found: the rule would not cover them"
    for path in [*_project_modules().values(), *scripts]:
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for name, node in _functions(tree):
            length = node.end_lineno - node.lineno + 1 - _docstring_lines(node)
            if length > MAX_FUNCTION_LINES:
                offenders.append(f"{path.relative_to(ROOT)}:{name}:{length}")
    _report(offenders, f"functions over {MAX_FUNCTION_LINES} lines")


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (scipy's csgraph)."""
    names = sorted(graph)
    index = {name: i for i, name in enumerate(names)}
    edges = [(index[m], index[t]) for m, targets in graph.items() for t in targets]
    rows, cols = zip(*edges, strict=True) if edges else ((), ())
    adjacency = csr_array((np.ones(len(rows)), (rows, cols)), shape=(len(names),) * 2)
    count, labels = connected_components(adjacency, directed=True, connection="strong")
    components = [sorted(np.array(names)[labels == k].tolist()) for k in range(count)]
    return [c for c in components if len(c) > 1]


@pytest.mark.slow
def test_no_import_cycle_between_the_projects_modules() -> None:
    modules = _project_modules()
    offenders = [
        f"{modules[name].relative_to(ROOT)}:{' <-> '.join(cycle)}"
        for cycle in _cycles(import_graph(modules))
        for name in cycle
    ]
    _report(offenders, "modules importing each other")


def test_the_cycle_check_finds_a_cycle_closed_by_a_lazy_import(tmp_path: Path) -> None:
    _write_package(
        tmp_path / "p",
        {
            "__init__.py": "",
            "x.py": "import p.y\n",
            "y.py": "import p.z\n",
            "z.py": "def f():\n    from p.x import g\n",
            "w.py": "import p.x\n",
        },
    )
    assert _cycles(import_graph(package_modules(tmp_path / "p", "p"))) == [["p.x", "p.y", "p.z"]]


def _write_package(root: Path, files: dict[str, str]) -> None:
    for name, text in files.items():
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        (root / name).write_text(text)


def test_a_scripts_closure_holds_what_it_runs_and_no_more(tmp_path: Path) -> None:
    """Relative, lazy and ``from package import module`` imports are followed; other
    packages (numpy) and modules nothing imports are left out."""
    _write_package(
        tmp_path / "p",
        {
            "__init__.py": "",
            "a.py": "import numpy\nfrom . import b\n",
            "b.py": "def later():\n    from .sub import c\n",
            "sub/__init__.py": "",
            "sub/c.py": "from .. import d\n",
            "d.py": "",
            "unused.py": "import p.a\n",
        },
    )
    (tmp_path / "script.py").write_text("from p.a import x\n")
    closure = import_closure(tmp_path / "script.py", "script", package_modules(tmp_path / "p", "p"))
    assert closure == {"p", "p.a", "p.b", "p.sub", "p.sub.c", "p.d"}


@pytest.fixture(scope="module")
def unzipped(fmu_paths, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """FMU name -> the ``resources/`` folder of the built FMU, unzipped."""
    folders = {}
    for name in FMU_NAMES:
        folder = tmp_path_factory.mktemp(name)
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            archive.extractall(folder)
        folders[name] = folder / "resources"
    return folders


def _script(resources: Path) -> tuple[Path, str]:
    """The FMU's pythonfmu script and its module name."""
    module = (resources / "slavemodule.txt").read_text().strip()
    return resources / f"{module}.py", module


def _shipped_modules(resources: Path) -> dict[str, Path]:
    """Our modules in an FMU: its build package's (pythonfmu's own runtime, which the
    build copies into it, is not ours)."""
    modules = {}
    for folder in sorted(resources.iterdir()):
        if (folder / "__init__.py").is_file():
            found = package_modules(folder, folder.name)
            modules.update({m: p for m, p in found.items() if m.split(".")[1:2] != ["pythonfmu"]})
    return modules


@pytest.mark.parametrize("name", FMU_NAMES)
def test_fmus_ship_no_analysis_plotting_or_master_module(name: str, unzipped) -> None:
    resources = unzipped[name]
    ours = sorted(
        p.relative_to(resources).as_posix()
        for p in resources.rglob("*.py")
        if p.relative_to(resources).parts[1:2] != ("pythonfmu",)
    )
    assert [_script(resources)[0].name] == [f for f in ours if "/" not in f]
    inside = [f.split("/", 1)[1] for f in ours if "/" in f]  # below the build package
    assert not [f for f in inside if f.startswith("cosim/")], ours
    assert not [f for f in ours if Path(f).stem in NOT_IN_FMUS], ours
    plotting = [f for f in ours if "matplotlib" in _imported_names(resources / f)]
    assert not plotting, f"{name} ships modules that import matplotlib: {plotting}"


def test_every_shipped_module_is_imported_by_an_fmu_script(unzipped) -> None:
    """Each module an FMU ships is imported, directly or not, by its own script or, for a
    package several FMUs ship, by another FMU's script: a shared package ships whole, the
    same files in each, because a host running the FMUs in one process (libcosim, ecos)
    imports it once, from whichever FMU loads first, and the others must find its modules
    there."""
    shipped = {name: _shipped_modules(resources) for name, resources in unzipped.items()}
    run = set()
    for name, resources in unzipped.items():
        run |= import_closure(*_script(resources), shipped[name])
    for name, modules in shipped.items():
        unused = sorted(set(modules) - run)
        assert not unused, f"{name} ships modules no FMU script imports: {unused}"
    for (name, modules), (other, other_modules) in itertools.combinations(shipped.items(), 2):
        for package in {m.split(".")[0] for m in set(modules) & set(other_modules)}:
            ours = {m for m in modules if m.split(".")[0] == package}
            theirs = {m for m in other_modules if m.split(".")[0] == package}
            assert ours == theirs, f"{package} differs between {name} and {other}"


def _imported_names(path: Path) -> set[str]:
    """Top-level package names a file imports anywhere in it."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names
