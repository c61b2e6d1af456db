"""The notebooks in docs/notebooks run top to bottom, are stored without outputs, and leave
the repository clean when run in place.

Each notebook is executed with nbclient on an IPython kernel in its own folder of a fresh
git repository holding it with the project's .gitignore and .gitattributes and the git filter
CONTRIBUTING.md sets up, with the session's built FMUs in ``build/fmus`` (as after ``auv-cosim
build``); the executed notebook is saved over itself (what JupyterLab's autosave does) with
a checkpoint beside it, and after ``git add --all`` (git lists a file whose size changed as
modified until it hashes it through the filter) ``git status`` must show nothing to commit.
A cell that raises fails the test, naming the cell. The kernel is shut down by nbclient,
also when a cell fails.

"Stored without outputs" reads the notebook as git holds it (the index), where the filter
and the pre-commit hook keep it clean; outside a git checkout, the file itself.
"""

from __future__ import annotations

import shutil
import signal
import subprocess
from pathlib import Path

import pytest
from repo_paths import ROOT

nbformat = pytest.importorskip("nbformat", reason="needs nbformat (test extra)")
nbclient = pytest.importorskip("nbclient", reason="needs nbclient (test extra)")

NOTEBOOKS = sorted((ROOT / "docs" / "notebooks").glob("*.ipynb"))
CELL_TIMEOUT_S = 900  # a busy machine; not a measurement


def test_there_are_notebooks() -> None:
    assert NOTEBOOKS, "docs/notebooks holds no notebook"


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_is_stored_without_outputs(path: Path) -> None:
    notebook = nbformat.reads(_as_stored(path), as_version=4)
    nbformat.validate(notebook)
    filled = [
        i
        for i, cell in enumerate(notebook.cells)
        if cell.cell_type == "code" and (cell.outputs or cell.execution_count is not None)
    ]
    assert filled == [], f"{path.name}: cells {filled} keep outputs (clear them before commit)"


def _as_stored(path: Path) -> str:
    """The notebook as git's index holds it (the file itself outside a git checkout)."""
    relative = path.relative_to(ROOT).as_posix()
    shown = subprocess.run(["git", "-C", str(ROOT), "show", f":{relative}"],
                           capture_output=True, text=True, check=False)  # fmt: skip
    return shown.stdout if shown.returncode == 0 else path.read_text(encoding="utf-8")


def _git(repo: Path, *args: str) -> str:
    done = subprocess.run(["git", "-C", str(repo), *args], capture_output=True, text=True,
                          check=True)  # fmt: skip
    return done.stdout


def _repository_with(path: Path, repo: Path) -> Path:
    """A fresh git repository holding the notebook (at its place in docs/notebooks), the
    project's .gitignore and .gitattributes, and the filter CONTRIBUTING.md sets up."""
    notebook = repo / path.relative_to(ROOT)
    notebook.parent.mkdir(parents=True)
    shutil.copyfile(path, notebook)
    for name in (".gitignore", ".gitattributes"):
        shutil.copyfile(ROOT / name, repo / name)
    _git(repo, "init", "--quiet")
    _git(repo, "config", "user.email", "test@example.invalid")
    _git(repo, "config", "user.name", "test")
    nbstripout = shutil.which("nbstripout")
    assert nbstripout, "nbstripout (test extra) is not installed"
    subprocess.run([nbstripout, "--install"], cwd=repo, check=True)
    _git(repo, "config", "filter.nbstripout.extrakeys", "metadata.language_info")
    _git(repo, "add", "-A")
    _git(repo, "commit", "--quiet", "-m", "the notebook")
    return notebook


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs_in_place_and_leaves_the_repository_clean(
    path: Path, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    notebook_file = _repository_with(path, tmp_path / "repo")
    here = notebook_file.parent
    fmus = here / "build" / "fmus"
    fmus.mkdir(parents=True)
    for fmu in fmu_paths.values():
        shutil.copyfile(fmu, fmus / fmu.name)
        shutil.copyfile(f"{fmu}.sha256", fmus / f"{fmu.name}.sha256")
    notebook = nbformat.read(notebook_file, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=CELL_TIMEOUT_S,
        kernel_name="python3",
        resources={"metadata": {"path": str(here)}},
    )
    dispositions = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as exc:
        pytest.fail(f"{path.name}: a cell raised:\n{exc}")
    finally:  # nbclient's asyncio handlers, removed, leave SIGINT at Python's default even
        # where it was ignored (a test run started in the background): put back as found
        for sig, disposition in dispositions.items():
            signal.signal(sig, disposition)
    nbformat.write(notebook, notebook_file)  # saved with its outputs, as JupyterLab does
    checkpoints = here / ".ipynb_checkpoints"
    checkpoints.mkdir()
    shutil.copyfile(notebook_file, checkpoints / f"{path.stem}-checkpoint.ipynb")
    # git lists a file whose size changed as modified until `git add` hashes it through the
    # filter: then nothing is left to commit, and nothing new is untracked
    _git(tmp_path / "repo", "add", "--all")
    assert _git(tmp_path / "repo", "status", "--porcelain") == ""
    shown = [
        i
        for i, cell in enumerate(notebook.cells)
        if cell.cell_type == "code" and "plt.show()" in cell.source
    ]
    blank = [
        i
        for i in shown
        if not any("image/png" in out.get("data", {}) for out in notebook.cells[i].outputs)
    ]
    assert shown and blank == [], f"{path.name}: cells {blank} drew no figure"
