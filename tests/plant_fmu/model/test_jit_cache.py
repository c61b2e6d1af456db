"""numba's cache of the compiled kernels (plant_fmu/model/jit.py): one folder per top-level
package (an FMU build's, the source tree's), so a build and the source tree never load
each other's cached code (which imports its module by name); a stamp over every kernel
file, so a change to any of them recompiles the functions that hold its code."""

from __future__ import annotations

import ast
import importlib
import json
import os
from pathlib import Path
from typing import Any

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
    # no folder warned of yet; set, not deleted, so that monkeypatch removes what the
    # warning sets (a variable deleted while unset is not recorded, and stayed set)
    monkeypatch.setenv("AUV_COSIM_NUMBA_CACHE_WARNED", "")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        problems = [copy.cache_problem() for copy in copies]
    assert problems[0] == problems[1] and "NUMBA_CACHE_DIR" in problems[0]
    assert [str(w.message) for w in caught] == [problems[0]]


# what each script below ends with: the cache folder the jit module chose and its problem
CHOSEN_CACHE_FOLDER = """
from plant_fmu.model import jit

with warnings.catch_warnings(record=True) as caught:
    warnings.simplefilter("always")
    numba, why = jit.load_numba()
    problem = jit.cache_problem()
print(json.dumps({"cache": os.environ["NUMBA_CACHE_DIR"], "problem": problem,
                  "warnings": [str(w.message) for w in caught]}))
"""


CACHE_FOLDER_OF_A_UID_WITHOUT_HOME = (
    """
import json, os, pwd, sys, warnings
for name in ("HOME", "XDG_CACHE_HOME", "NUMBA_CACHE_DIR", "AUV_COSIM_NUMBA_CACHE_WARNED"):
    os.environ.pop(name, None)
os.environ["TMPDIR"] = sys.argv[1]
uid = int(sys.argv[2]) if len(sys.argv) > 2 else os.getuid()
os.getuid = lambda: uid  # the uid the folder is named after and must belong to


def no_entry(number):  # as for `docker run -u 12345`: a uid /etc/passwd does not list
    raise KeyError(f"getpwuid(): uid not found: {number}")


pwd.getpwuid = no_entry
"""
    + CHOSEN_CACHE_FOLDER
)


def _cache_folder_without_home(run_python, tmp_path: Path, *uid: int) -> dict:
    """What the jit module chose as numba's cache folder, and the problem it saw, in a
    process with no HOME, no XDG_CACHE_HOME, no passwd entry and TMPDIR = ``tmp_path``."""
    done = run_python(CACHE_FOLDER_OF_A_UID_WITHOUT_HOME, tmp_path, *map(str, uid))
    assert done.returncode == 0, done.stderr[-3000:]
    result: dict = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def test_a_uid_without_home_or_passwd_entry_caches_in_a_private_temporary_folder(
    run_python, tmp_path
):
    """A container started as a uid /etc/passwd does not list (``docker run -u 12345``)
    with HOME unset: ``Path.home()`` raised "Could not determine home directory." as the
    plant's kernels were imported, and every run failed with that line. The cache goes to
    a folder of the user's own in the temporary folder, made private (mode 0700)."""
    result = _cache_folder_without_home(run_python, tmp_path)
    cache = Path(result["cache"])
    assert cache.is_relative_to(tmp_path) and result["problem"] == "", result
    assert (cache.parent.stat().st_mode & 0o777) == 0o700


def test_a_temporary_cache_folder_another_user_made_is_not_used(run_python, tmp_path):
    """Where the temporary folder is shared (/tmp), the fallback cache folder named for
    this uid may have been made by another user, who could then put compiled code there
    for this user's processes to load: it is refused (compiled without a cache, with a
    warning naming the folder and what to set), never used."""
    other_uid = os.getuid() + 4321  # the folder below is this process's, not that uid's
    (tmp_path / f"auv-cosim-cache-{other_uid}" / "numba").mkdir(parents=True)
    result = _cache_folder_without_home(run_python, tmp_path, other_uid)
    assert "NUMBA_CACHE_DIR" in result["problem"], result
    assert f"auv-cosim-cache-{other_uid}" in result["problem"]
    assert result["warnings"] == [result["problem"]]


CACHE_FOLDER_OF_AN_UNWRITABLE_HOME = (
    """
import json, os, sys, warnings
for name in ("XDG_CACHE_HOME", "NUMBA_CACHE_DIR", "AUV_COSIM_NUMBA_CACHE_WARNED"):
    os.environ.pop(name, None)
os.environ["HOME"], os.environ["TMPDIR"] = sys.argv[1:3]
"""
    + CHOSEN_CACHE_FOLDER
)


def test_a_home_that_cannot_be_written_caches_in_a_private_temporary_folder(run_python, tmp_path):
    """A home folder the user cannot write (``docker run -u 12345`` sets HOME=/, a
    service account's HOME=/nonexistent) and neither XDG_CACHE_HOME nor NUMBA_CACHE_DIR
    set: every process compiled the kernels again (30 s of a bs-3 run's start-up on a
    busy machine) and every command warned of it. The cache goes to the user's private
    temporary folder instead, as where there is no home at all, without a warning."""
    blocker = tmp_path / "a-file"  # no folder can be made under a file, not even by root
    blocker.write_text("")
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    done = run_python(CACHE_FOLDER_OF_AN_UNWRITABLE_HOME, blocker / "home", scratch)
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(result["cache"]).is_relative_to(scratch), result
    assert result["problem"] == "" and result["warnings"] == [], result


CACHE_FOLDER_OF_A_RELATIVE_HOME = (
    """
import json, os, sys, warnings
for name in ("XDG_CACHE_HOME", "NUMBA_CACHE_DIR", "AUV_COSIM_NUMBA_CACHE_WARNED"):
    os.environ.pop(name, None)
os.environ["HOME"], os.environ["TMPDIR"] = "rel", sys.argv[1]
os.chdir(sys.argv[2])
"""
    + CHOSEN_CACHE_FOLDER
)


def test_a_relative_home_caches_in_a_private_temporary_folder(run_python, tmp_path):
    """HOME=rel (a relative home, which Python's ``expanduser`` returns as it is): the
    cache went to ``rel/.cache/auv-cosim`` below whatever folder a command ran in, a
    cache of its own in every working folder, the FMUs kept there too. A relative HOME
    is ignored as the XDG specification has a relative XDG_CACHE_HOME ignored: the cache
    goes to the user's private temporary folder, as where there is no home at all, and
    nothing is written in the working folder."""
    scratch, working = tmp_path / "tmp", tmp_path / "work"
    scratch.mkdir()
    working.mkdir()
    done = run_python(CACHE_FOLDER_OF_A_RELATIVE_HOME, scratch, working)
    assert done.returncode == 0, done.stderr[-3000:]
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert Path(result["cache"]).is_absolute(), result
    assert Path(result["cache"]).is_relative_to(scratch), result
    assert result["problem"] == "" and result["warnings"] == [], result
    assert list(working.iterdir()) == []


def _kernel_tree(root: Path, version: str) -> Path:
    """The kernel files under ``root``, one of them of ``version``; its compiled.py."""
    for relative in KERNEL_FILES:
        (root / relative).parent.mkdir(parents=True, exist_ok=True)
        (root / relative).write_text("x = 1\n")
    (root / KERNEL_FILES[-1]).write_text(f"x = {version}\n")
    return root / KERNEL_FILES[0]


def test_processes_with_other_kernel_sources_never_share_cache_files(tmp_path, monkeypatch):
    """numba names a function's data files by their order in the index (``.1.nbc``) and
    checks only the index against the source stamp: a process still compiling the
    kernels as they were before an edit and one compiling the edited kernels, writing the
    same folder at once, could leave one's index naming the other's compiled code, which
    every later process then ran. Each version of the kernels caches in a folder of its
    own; the same version in one folder, from any copy of the files."""
    from plant_fmu.model import jit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    numba, why = jit.load_numba()
    if numba is None:
        pytest.skip(why)
    from numba.core import caching

    locator = next(c for c in caching.CacheImpl._locator_classes if "Content" in c.__name__)

    def kernel() -> None:
        """A kernel of plant_fmu, as numba sees it."""

    kernel.__module__ = "plant_fmu.model.compiled"
    before, edited, copy = (
        locator(kernel, str(_kernel_tree(tmp_path / name, version))).get_cache_path()
        for name, version in (("before", "1"), ("edited", "2"), ("copy", "1"))
    )
    assert before != edited
    assert before == copy


def test_numba_0_60_whose_user_folder_locator_is_private_gets_the_content_locator(
    tmp_path, monkeypatch
):
    """numba 0.60 and 0.61 (pyproject's floor, and what an FMU's host may hold) name the
    locator the content-keyed one extends ``_UserProvidedCacheLocator``, without the
    public name numba 0.62 gave it: importing the compiled kernels failed there with an
    AttributeError, in the master and in every FMU. With numba's caching module as 0.60
    has it, the content locator is installed first and keys a kernel's folder by its
    package."""
    from plant_fmu.model import jit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    numba, why = jit.load_numba()
    if numba is None:
        pytest.skip(why)
    from numba.core import caching

    public = getattr(caching, "UserProvidedCacheLocator", None)
    if public is None:
        pytest.skip("this numba has no public UserProvidedCacheLocator to hide")
    monkeypatch.delattr(caching, "UserProvidedCacheLocator")
    monkeypatch.setattr(caching, "_UserProvidedCacheLocator", public, raising=False)
    others = [c for c in caching.CacheImpl._locator_classes if "Content" not in c.__name__]
    monkeypatch.setattr(caching.CacheImpl, "_locator_classes", others)
    # numba read NUMBA_CACHE_DIR when first imported, maybe before this test
    monkeypatch.setattr(caching.config, "CACHE_DIR", str(tmp_path / "cache"))

    jit._install_locator()

    locator = caching.CacheImpl._locator_classes[0]
    assert locator.__name__ == "_ContentCacheLocator" and issubclass(locator, public)

    def kernel() -> None:
        """A kernel of plant_fmu, as numba sees it."""

    kernel.__module__ = "plant_fmu.model.compiled"
    folder = Path(locator(kernel, str(_kernel_tree(tmp_path / "tree", "1"))).get_cache_path())
    assert folder.parent == tmp_path / "cache" / "auv_cosim" / "plant_fmu"


def _kernel_cache_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Any:
    """numba's index and data files of a kernel, in a folder of ours (``auv_cosim/...``)."""
    from plant_fmu.model import jit

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    numba, why = jit.load_numba()
    if numba is None:
        pytest.skip(why)
    from numba.core import caching

    folder = tmp_path / "cache" / "auv_cosim" / "plant_fmu" / "0123456789abcdef"
    folder.mkdir(parents=True)
    return caching.IndexDataCacheFile(str(folder), "compiled.step_into-701.py311", "stamp")


@pytest.mark.parametrize("cut", ["*.nbi", "*.nbc"])
def test_a_cache_file_cut_short_is_compiled_again(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, cut: str
) -> None:
    """A kernel's cache file cut short (a power cut after numba's rename, a full disk, a
    hand) made every later run of the plant end in numba's ``EOFError: Ran out of input``,
    until the user found and removed the file: it is a miss now, compiled and written
    again."""
    cache_file = _kernel_cache_file(tmp_path, monkeypatch)
    cache_file.save("signature", ("compiled", "code"))
    assert cache_file.load("signature") == ("compiled", "code")
    for path in Path(cache_file._cache_path).glob(cut):
        path.write_bytes(b"")
    assert cache_file.load("signature") is None
    cache_file.save("signature", ("compiled", "again"))
    assert cache_file.load("signature") == ("compiled", "again")
