"""What ``pip install .`` (not editable) installs: pyproject.toml's package-data names every
file of the packages that is not Python source, py.typed markers included."""

import fnmatch
import importlib.util
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import tomllib
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT
from venvs import make_venv

PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
PACKAGES = ("cosim", "plant_fmu", "controller_fmu", "fmu_runtime")
_IGNORED = ("__pycache__", ".mypy_cache", ".pytest_cache")


def _installed(path: Path) -> bool:
    """Whether a package-data pattern of the package holding ``path`` names it."""
    data = PYPROJECT["tool"]["setuptools"]["package-data"]
    for package, patterns in data.items():
        folder = ROOT / package.replace(".", "/")
        if folder in path.parents:
            relative = path.relative_to(folder).as_posix()
            if any(fnmatch.fnmatchcase(relative, pattern) for pattern in patterns):
                return True
    return False


def test_every_package_ships_a_py_typed_marker():
    """Without it a user's mypy skips the installed package ("module is installed, but
    missing library stubs or py.typed marker") and checks no call into ``cosim.run``."""
    for package in PACKAGES:
        marker = ROOT / package / "py.typed"
        assert marker.is_file(), marker
        assert _installed(marker), f"{package}/py.typed is not in package-data"


def test_every_data_file_of_the_packages_is_in_package_data():
    """A scenario, a vehicle set, a C source the build compiles: a file the wheel left out
    is missing only once installed, never in the source tree the other tests run in."""
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*"):
            if path.is_dir() or path.suffix in (".py", ".pyc"):
                continue
            if any(part in _IGNORED for part in path.relative_to(ROOT).parts):
                continue
            assert _installed(path), f"{path.relative_to(ROOT)} is not in package-data"


def _tracked(folder: str) -> set[str]:
    """The files git tracks under ``folder`` of the repository, relative to its root."""
    listed = subprocess.run(
        ["git", "ls-files", "-z", "--", folder], cwd=ROOT, capture_output=True, check=True
    )
    return {name for name in listed.stdout.decode().split("\0") if name}


@pytest.fixture(scope="module")
def sdist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The sdist setuptools builds from a copy of the repository's tracked files (its
    ``build-system.requires`` installed in a venv of its own); a skip when pip cannot
    install them."""
    work = tmp_path_factory.mktemp("sdist")
    tree, dist = work / "tree", work / "dist"
    for name in _tracked("."):
        if (ROOT / name).is_file():
            (tree / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, tree / name)
    venv = make_venv(work / "venv", sys.executable, *PYPROJECT["build-system"]["requires"])
    python = venv / "bin" / "python"
    code = "import sys; from setuptools import build_meta; build_meta.build_sdist(sys.argv[1])"
    built = run_in_group([python, "-c", code, dist], timeout=300, cwd=tree)
    assert built.returncode == 0, built.stderr[-2000:]
    (archive,) = dist.glob("*.tar.gz")
    return archive


@pytest.fixture(scope="module")
def sdist_members(sdist: Path) -> set[str]:
    """The files of :func:`sdist`, relative to its top folder."""
    with tarfile.open(sdist) as archive:
        return {name.split("/", 1)[1] for name in archive.getnames() if "/" in name}


@pytest.mark.slow
def test_the_sdist_holds_the_docs_the_readme_and_the_messages_point_to(sdist_members):
    """A packager building from the sdist, or a user unpacking it, found no docs/: the
    README's links, the example scenario and study files (``auv-cosim sweep
    docs/study-example.toml``), and the docs/*.md every error message names."""
    missing = sorted(_tracked("docs") - sdist_members)
    assert not missing, f"{len(missing)} tracked files of docs/ not in the sdist: {missing[:5]}"
    assert {"README.md", "LICENSE", "CHANGELOG.md"} <= sdist_members


@pytest.mark.slow
def test_the_sdist_installs_and_runs_a_scenario_on_a_machine_without_a_compiler(
    sdist: Path, tmp_path: Path
) -> None:
    """What a user of the published sdist gets: installed by pip into a fresh virtual
    environment and run from an empty folder with nothing but that environment on PATH
    (no ``cc``), ``auv-cosim run`` builds the FMUs it needs, says once that they keep
    pythonfmu's binary (unless ziglang is there to compile the runtime), and completes a
    run stating the released version. The package comes from the sdist alone
    (``--no-deps``); its dependencies are this interpreter's, reached through a .pth file
    after the venv's own site-packages (whose .pth files, this tree's editable install
    among them, are not read): what is checked is the sdist's content, not pip's
    resolution of ~1.5 GB of dependencies again."""
    venv = make_venv(tmp_path / "venv", sys.executable, "--no-deps", str(sdist))
    (site,) = (venv / "lib").glob("python3.*/site-packages")
    (site / "zz_dependencies.pth").write_text(sysconfig.get_paths()["purelib"] + "\n")
    folder = tmp_path / "empty"
    folder.mkdir()
    environment = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    environment["PATH"] = str(venv / "bin")
    command = [venv / "bin" / "auv-cosim", "run", "bs-3", "--no-rrd", "--stop-time", "2"]
    done = run_in_group([*command, "--quiet"], timeout=600, cwd=folder, env=environment)
    assert done.returncode == 0, done.stderr[-2000:]
    # the build falls back to ziglang where the dependencies hold it (the extra `zig`)
    told = 0 if importlib.util.find_spec("ziglang") is not None else 1
    assert done.stderr.count("no C compiler (cc)") == told, done.stderr[-2000:]
    summary = json.loads((folder / "runs" / "bs-3" / "summary.json").read_text())
    assert summary["complete"] and summary["time_reached"] == pytest.approx(2.0)
    assert summary["versions"]["auv-cosim"] == PYPROJECT["project"]["version"]
    installed = run_in_group(
        [venv / "bin" / "python", "-c", "import cosim; print(cosim.__file__)"],
        timeout=120, cwd=folder, env=environment,
    )  # fmt: skip
    assert Path(installed.stdout.strip()).is_relative_to(venv)  # not this source tree


def test_the_pythons_it_was_run_on_are_its_classifiers_from_the_floor_up():
    """pyproject.toml names each CPython minor the suite was run on as a Trove classifier,
    from requires-python's floor up without a gap, and the README names the same range: a
    user choosing a Python (or pip's index page) sees which were measured, while
    requires-python, without an upper bound, lets a newer one install."""
    floor = PYPROJECT["project"]["requires-python"].removeprefix(">=")
    measured = [
        c.rsplit(" :: ", 1)[1]
        for c in PYPROJECT["project"].get("classifiers", [])
        if c.startswith("Programming Language :: Python :: 3.")
    ]
    assert measured, "pyproject.toml names no 'Programming Language :: Python :: 3.x' classifier"
    minors = [int(version.split(".")[1]) for version in measured]
    assert measured[0] == floor, f"the classifiers start at {measured[0]}, not at {floor}"
    assert minors == list(range(minors[0], minors[0] + len(minors))), measured
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert f"CPython {measured[0]} to {measured[-1]}" in readme, "README names other Pythons"
