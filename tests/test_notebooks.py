"""The notebooks in docs/notebooks run top to bottom, and are stored without outputs.

Each notebook is executed with nbclient on an IPython kernel, in a working folder that
starts with the session's built FMUs in ``build/fmus`` (as after ``auv-cosim build``); a
cell that raises fails the test, naming the cell. The kernel is shut down by nbclient,
also when a cell fails.
"""

from __future__ import annotations

import shutil
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
    notebook = nbformat.read(path, as_version=4)
    nbformat.validate(notebook)
    filled = [
        i
        for i, cell in enumerate(notebook.cells)
        if cell.cell_type == "code" and (cell.outputs or cell.execution_count is not None)
    ]
    assert filled == [], f"{path.name}: cells {filled} keep outputs (clear them before commit)"


@pytest.mark.slow
@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.name)
def test_notebook_runs(path: Path, fmu_paths: dict[str, Path], tmp_path: Path) -> None:
    fmus = tmp_path / "build" / "fmus"
    fmus.mkdir(parents=True)
    for fmu in fmu_paths.values():
        shutil.copyfile(fmu, fmus / fmu.name)
        shutil.copyfile(f"{fmu}.sha256", fmus / f"{fmu.name}.sha256")
    notebook = nbformat.read(path, as_version=4)
    client = nbclient.NotebookClient(
        notebook,
        timeout=CELL_TIMEOUT_S,
        kernel_name="python3",
        resources={"metadata": {"path": str(tmp_path)}},
    )
    try:
        client.execute()
    except nbclient.exceptions.CellExecutionError as exc:
        pytest.fail(f"{path.name}: a cell raised:\n{exc}")
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
