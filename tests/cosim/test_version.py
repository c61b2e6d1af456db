"""One version, pyproject.toml's, stated alike by everything that states one: the command,
``cosim.__version__``, a run's summary.json, the built FMUs' descriptions; and a version
bumped there is the one stated, and the FMUs are built again, before any reinstall."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest
from process_group import run_in_group
from repo_paths import ROOT

import cosim
from cosim.cli import main
from cosim.fmus.build import FMUS
from cosim.outputs.results import versions

FMU_AND_TOOL_PACKAGES = ("cosim", "plant_fmu", "controller_fmu", "fmu_runtime")
DECLARED = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def test_the_package_states_pyproject_tomls_version(capsys: pytest.CaptureFixture[str]) -> None:
    """``cosim.__version__`` raised AttributeError: a user's script or a bug report had to
    ask importlib.metadata, which an editable install answers with the version it was
    installed at."""
    assert cosim.__version__ == DECLARED
    assert versions()["auv-cosim"] == DECLARED  # what summary.json records
    with pytest.raises(SystemExit):
        main(["--version"])
    assert capsys.readouterr().out == f"auv-cosim {DECLARED}\n"


def test_each_fmu_states_the_version_that_built_it(fmu_paths) -> None:
    """An FMI tool shows the description's ``version`` and ``generationTool``: the same
    version as the command that built the FMU."""
    for name, path in fmu_paths.items():
        with zipfile.ZipFile(path) as fmu:
            root = ET.fromstring(fmu.read("modelDescription.xml"))
        assert root.get("version") == DECLARED, name
        assert root.get("generationTool", "").startswith(f"auv-cosim {DECLARED} ("), name


def _tracked_copy(folder: Path) -> Path:
    """The packages and pyproject.toml, the files git tracks or would (not ignored), into
    ``folder`` as they are in the working tree."""
    listing = ["git", "ls-files", "-z", "--cached", "--others", "--exclude-standard", "--"]
    files = ["pyproject.toml", "LICENSE", *FMU_AND_TOOL_PACKAGES]
    listed = subprocess.run([*listing, *files], cwd=ROOT, capture_output=True, check=True)
    for name in filter(None, listed.stdout.decode().split("\0")):
        if (ROOT / name).is_file():
            (folder / name).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(ROOT / name, folder / name)
    return folder


_OUT_OF_DATE = (
    "import sys; from cosim.fmus.build import out_of_date; print(*out_of_date(sys.argv[1]))"
)


@pytest.mark.slow
def test_a_version_bumped_in_pyproject_toml_is_stated_and_rebuilds_the_fmus(
    fmu_paths, tmp_path: Path
) -> None:
    """A release bumped the version in pyproject.toml of a checkout installed editable:
    the command and the FMUs still said the old version (the install's metadata), and the
    FMUs built before the bump were taken as up to date, so the release's FMUs carried
    the old version."""
    tree = _tracked_copy(tmp_path / "tree")
    folder = next(iter(fmu_paths.values())).parent
    bumped = f"{DECLARED}.post1"

    def check(*arguments: object) -> str:
        done = run_in_group(
            [sys.executable, *arguments], timeout=300, cwd=tree,
            env={**os.environ, "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": "1"},
        )  # fmt: skip
        assert done.returncode == 0, done.stderr[-2000:]
        return done.stdout.strip()

    # the copy is these sources: the session's FMUs fit it
    assert check("-c", _OUT_OF_DATE, folder) == ""
    pyproject = tree / "pyproject.toml"
    text = pyproject.read_text()
    pyproject.write_text(re.sub(r'(?m)^version = ".*"$', f'version = "{bumped}"', text))
    assert check("-m", "cosim", "--version") == f"auv-cosim {bumped}"
    assert check("-c", _OUT_OF_DATE, folder).split() == list(FMUS)


def test_the_changelog_has_a_section_for_the_version() -> None:
    """A release bumped the version with no word for its users: CHANGELOG.md heads a
    section with the version pyproject.toml states (the newest first)."""
    headings = re.findall(r"(?m)^## (\S+)", (ROOT / "CHANGELOG.md").read_text())
    assert headings[:1] == [DECLARED], f"CHANGELOG.md's sections: {headings[:3]}"
