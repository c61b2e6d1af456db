"""What ``pip install .`` (not editable) installs: pyproject.toml's package-data names every
file of the packages that is not Python source, py.typed markers included."""

import fnmatch
import tomllib
from pathlib import Path

from repo_paths import ROOT

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
