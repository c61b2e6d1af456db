"""numba's cache of the compiled kernels (plant_fmu/model/jit.py): one folder per top-level
package (an FMU build's, the source tree's), so a build and the source tree never load
each other's cached code (which imports its module by name); a stamp over every kernel
file, so a change to any of them recompiles the functions that hold its code."""

from __future__ import annotations

import ast
import importlib
import json
from pathlib import Path

import pytest
from repo_paths import ROOT

from plant_fmu.model.jit import KERNEL_FILES, kernel_stamp

PLANT_IN_FMU = """
import json, os, sys
os.environ["NUMBA_CACHE_DIR"] = sys.argv[2]
from fmu_harness import Harness
h = Harness(sys.argv[1], "plant")
h.step(0.01)
stepper = [m for n, m in sys.modules.items() if n.endswith("plant_fmu.model.compiled")][0]
print(json.dumps({"hits": sum(stepper.step_into.stats.cache_hits.values()),
                  "errors": h.messages(3)}))
h.close()
"""

PLANT_IN_SOURCE_TREE = """
import json, os, sys
os.environ["NUMBA_CACHE_DIR"] = sys.argv[1]
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import stepping_state
import numpy as np

fast = compiled.CompiledPlant(PlantModel(load_vehicle("remus100"), Variant.FULL))
inputs = np.zeros(8)
inputs[0] = 9.0
fast.warm_up(stepping_state(np.zeros(14)), inputs)
print(json.dumps({"module": compiled.step_into.py_func.__module__}))
"""


@pytest.mark.slow
def test_an_fmu_and_the_source_tree_keep_caches_of_their_own(fmu_paths, run_python, tmp_path):
    """The FMU compiles into its package's folder and loads from it next time; the source
    tree, run between the two, compiles into its own and loads nothing of the FMU's (it
    failed to import the FMU's package when both shared one cache)."""
    first = run_python(PLANT_IN_FMU, fmu_paths["AuvPlant"], tmp_path)
    assert first.returncode == 0, first.stderr[-3000:]
    tree = run_python(PLANT_IN_SOURCE_TREE, tmp_path)
    assert tree.returncode == 0, tree.stderr[-3000:]
    again = run_python(PLANT_IN_FMU, fmu_paths["AuvPlant"], tmp_path)
    assert again.returncode == 0, again.stderr[-3000:]
    first_run, later = (json.loads(r.stdout.strip().splitlines()[-1]) for r in (first, again))
    assert first_run["errors"] == later["errors"] == ""
    assert first_run["hits"] == 0 and later["hits"] >= 1  # compiled, then loaded
    folders = sorted(p.name for p in (tmp_path / "auv_cosim").iterdir())
    assert "plant_fmu" in folders and any(f.startswith("auvfmu_") for f in folders), folders


def _imported_names(relative: str) -> dict[str, str]:
    """Name -> the project module a kernel file imports it from."""
    package = Path(relative).parent.as_posix().replace("/", ".")
    names = {}
    for node in ast.walk(ast.parse((ROOT / relative).read_text())):
        if not isinstance(node, ast.ImportFrom) or node.module in (None, "__future__"):
            continue
        base = package.rsplit(".", node.level - 1)[0] if node.level > 1 else package
        module = f"{base}.{node.module}" if node.level else node.module
        if module.split(".")[0] in ("plant_fmu", "controller_fmu", "fmu_runtime"):
            names.update({alias.asname or alias.name: module for alias in node.names})
    return names


def test_the_stamp_covers_every_project_module_a_compiled_function_uses():
    """A compiled function holds the code of the jitted functions it calls and the values
    of the constants it reads: every project module it takes one from must be a kernel
    file, or a change there would leave its cache stale."""
    from plant_fmu.model import compiled

    if not compiled.AVAILABLE:
        pytest.skip(f"numba is off: {compiled.NO_JIT_REASON}")
    checked = 0
    for relative in KERNEL_FILES:
        imported = _imported_names(relative)
        module = importlib.import_module(relative.removesuffix(".py").replace("/", "."))
        for value in vars(module).values():
            function = getattr(value, "py_func", None)
            if function is None:
                continue
            source = function.__module__.replace(".", "/") + ".py"  # compiled from there
            assert source in KERNEL_FILES, f"{relative} compiles {source}'s {function.__name__}"
            checked += 1
            for name in function.__code__.co_names:
                if name in imported:
                    used = imported[name].replace(".", "/") + ".py"
                    assert used in KERNEL_FILES, f"{relative}: {function.__name__} uses {name}"
    assert checked >= 20


def test_a_change_to_any_kernel_file_changes_every_kernels_stamp(tmp_path):
    for relative in KERNEL_FILES:
        target = tmp_path / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        target.write_text("x = 1\n")
    stamps = {kernel_stamp(str(tmp_path / relative)) for relative in KERNEL_FILES}
    assert len(stamps) == 1  # one stamp for all of them
    (tmp_path / KERNEL_FILES[-1]).write_text("x = 2\n")
    assert kernel_stamp(str(tmp_path / KERNEL_FILES[0])) not in stamps
