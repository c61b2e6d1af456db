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


MASTER_KERNEL_IN_READ_ONLY_FOLDER = """
import importlib.util, os, sys, warnings
import numpy as np
os.environ["NUMBA_CACHE_DIR"], os.environ["HOME"], copy = sys.argv[1:4]
spec = importlib.util.spec_from_file_location("extrapolation_copy", copy)
module = importlib.util.module_from_spec(spec)
spec.loader.exec_module(module)
with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    extrapolate = module._compiled_extrapolate()
inputs, past, times = np.array([2.0]), np.array([[1.0], [0.0]]), np.array([1.0, 0.0])
values = np.zeros(2)
code = extrapolate(inputs, past, times, np.zeros(1), values, 2, 2.0, 2)
print(code, values[0], "|", *(str(w.message) for w in caught))
"""


def test_a_cache_folder_nobody_can_write_compiles_without_a_cache(run_python, tmp_path):
    """A user whose home folder cannot be written (HOME=/ of a service account, a missing
    home) running the master from a read-only site-packages: numba's cache folder and
    ``__pycache__`` beside the source are both unwritable, and numba refused to compile
    the master's extrapolation kernel ("cannot cache function ... no locator available"),
    failing every run with extrapolation. The kernel is compiled without a cache, and one
    warning names the folder and what to set."""
    blocker = tmp_path / "a-file"  # no folder can be made under a file, not even by root
    blocker.write_text("")
    read_only = tmp_path / "site-packages"
    read_only.mkdir()
    (read_only / "__pycache__").write_text("")  # numba's in-tree cache cannot be made
    copy = read_only / "extrapolation_copy.py"
    copy.write_text((ROOT / "cosim/engine/extrapolation.py").read_text())
    cache = blocker / "numba"
    done = run_python(MASTER_KERNEL_IN_READ_ONLY_FOLDER, cache, blocker / "home", copy)
    assert done.returncode == 0, done.stderr[-3000:]
    result, _, warning = done.stdout.strip().splitlines()[-1].partition(" | ")
    assert result == "3 1.0"  # values computed, history moved on; slope (2 - 1) / 1 s
    assert str(cache) in warning and "NUMBA_CACHE_DIR" in warning, warning


def test_an_unwritable_cache_folder_is_warned_of_once_a_process(monkeypatch, tmp_path):
    """``auv-cosim run`` printed the same warning twice (and once more per FMU that
    compiles): the master and each FMU import their own copy of the jit module (an FMU's
    under its own package name), each with its own memory of having warned."""
    import importlib.util
    import warnings

    blocker = tmp_path / "a-file"
    blocker.write_text("")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(blocker / "numba"))
    source = ROOT / "plant_fmu" / "model" / "jit.py"
    copies = []
    for name in ("auvfmu_first_jit", "auvfmu_second_jit"):  # as two FMUs import it
        spec = importlib.util.spec_from_file_location(name, source)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        copies.append(module)
    monkeypatch.delenv("AUV_COSIM_NUMBA_CACHE_WARNED", raising=False)  # restored after it
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        problems = [copy.cache_problem() for copy in copies]
    assert problems[0] == problems[1] and "NUMBA_CACHE_DIR" in problems[0]
    assert [str(w.message) for w in caught] == [problems[0]]
