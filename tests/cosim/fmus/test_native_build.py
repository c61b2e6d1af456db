"""The FMU's binaries: the runtime loads on glibc 2.17 (manylinux2014: CentOS 7, RHEL 8,
Ubuntu 18.04 and later), compiles without a warning, and pythonfmu's binary, the fallback,
is shipped unchanged (it needs glibc 2.32: docs/hosts.md says so). The win64 runtime,
prebuilt with the package (scripts/build_win64_runtime.py) and in every FMU while it was
built from today's C sources, else pythonfmu's DLL with one line said; cross-compiled with
zig afresh when asked: no warning, the FMI 2.0 functions as its only exports, Windows' own
DLLs as its only imports, byte for byte the prebuilt DLL with the recorded zig."""

from __future__ import annotations

import fnmatch
import hashlib
import importlib.util
import shutil
import subprocess
import sys
import tomllib
import zipfile
from pathlib import Path

import pytest
import pythonfmu
from elf_symbols import glibc_versions, unresolvable
from pe_table import exported_names, imported_dlls

from cosim.fmus import build, native
from cosim.fmus.build import FMUS

pytestmark = pytest.mark.skipif(shutil.which("objdump") is None, reason="no objdump")


def _binary(fmu: Path, name: str, folder: Path) -> Path:
    path = folder / Path(name).name
    with zipfile.ZipFile(fmu) as archive:
        path.write_bytes(archive.read(name))
    return path


@pytest.mark.parametrize("name", sorted(FMUS))
def test_the_runtime_needs_glibc_2_17_at_most_and_nothing_unversioned(name, fmu_paths, tmp_path):
    runtime = _binary(fmu_paths[name], f"binaries/linux64/{name}.so", tmp_path)
    versions = glibc_versions(runtime)
    assert versions and versions[-1] <= (2, 17), versions
    assert unresolvable(runtime) == []


def test_the_fallbacks_are_pythonfmus_unchanged(fmu_paths):
    wheel = Path(pythonfmu.__file__).parent / "resources" / "binaries"
    for name in FMUS:
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            fallback = archive.read(f"binaries/linux64/{name}{native.WRAPPER_SUFFIX}.so")
            win64 = archive.read(f"binaries/win64/{name}{native.WRAPPER_SUFFIX}.dll")
        assert fallback == (wheel / "linux64" / "libpythonfmu-export.so").read_bytes()
        assert win64 == (wheel / "win64" / "pythonfmu-export.dll").read_bytes()
    glibc = glibc_versions(wheel / "linux64" / "libpythonfmu-export.so")
    assert glibc[-1] == (2, 32)  # what docs/hosts.md tells a user the fallback needs


@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_default_build_carries_the_win64_runtime(name, fmu_paths, tmp_path):
    """Without AUV_FMU_WIN64 (the test environment's build) and without zig: the win64
    binary is the prebuilt runtime, pythonfmu's DLL beside it."""
    dll = _binary(fmu_paths[name], f"binaries/win64/{name}.dll", tmp_path)
    assert native.loader_in(fmu_paths[name], "win64")
    assert sorted(exported_names(dll)) == sorted(FMI2_COSIMULATION)
    imported = imported_dlls(dll)
    assert any(name.lower() == "kernel32.dll" for name in imported), imported
    assert [name for name in imported if not _is_system_dll(name)] == []


def test_the_prebuilt_win64_runtime_is_built_from_todays_sources():
    record = native.prebuilt_record()
    assert record.get("sources_sha256") == native.win64_sources_digest(), (
        "fmu_runtime/native/ changed since the prebuilt win64 runtime was built: run "
        f"python {native.PREBUILT_SCRIPT} (needs ziglang) and commit "
        "fmu_runtime/native/prebuilt/win64/"
    )
    dll = native.PREBUILT_DLL.read_bytes()
    assert record["dll_sha256"] == hashlib.sha256(dll).hexdigest()
    assert isinstance(native.prebuilt_win64(), bytes)


def test_an_edited_c_source_keeps_pythonfmus_dll_and_says_so(monkeypatch, tmp_path):
    """Sources that are not the prebuilt DLL's: the win64 binary stays pythonfmu's (today's
    behaviour before the prebuilt DLL), said in one line naming the script."""
    sources = tmp_path / "native"
    shutil.copytree(native.SOURCE_DIR, sources)
    with (sources / "loader.c").open("a") as edited:
        edited.write("/* edited */\n")
    monkeypatch.setattr(native, "SOURCE_DIR", sources)
    monkeypatch.setattr(native, "toolchain", lambda: None)  # no linux64 compile: fast
    monkeypatch.delenv(native.WIN64_VARIABLE, raising=False)
    fmu = _toy_fmu(tmp_path)
    notes = native.install_loader(fmu, "Toy")
    assert notes[0] == native.NO_COMPILER
    assert notes[1:] == [
        "the win64 binary stays pythonfmu's: the runtime's C sources changed since the "
        f"prebuilt win64 runtime was built (regenerate it: python {native.PREBUILT_SCRIPT}, "
        f"which needs ziglang; or build with {native.WIN64_VARIABLE}=1 and ziglang)"
    ]
    assert not native.loader_in(fmu, "win64")
    with zipfile.ZipFile(fmu) as archive:
        assert archive.read("binaries/win64/Toy.dll") == _pythonfmus()["win64"]


def _pythonfmus() -> dict[str, bytes]:
    wheel = Path(pythonfmu.__file__).parent / "resources" / "binaries"
    return {
        "linux64": (wheel / "linux64" / "libpythonfmu-export.so").read_bytes(),
        "win64": (wheel / "win64" / "pythonfmu-export.dll").read_bytes(),
    }


def _toy_fmu(folder: Path) -> Path:
    """An FMU laid out as pythonfmu's builder lays it out, with the wheel's binaries."""
    fmu = folder / "Toy.fmu"
    folder.mkdir(exist_ok=True)
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr("modelDescription.xml", "<fmiModelDescription/>")
        archive.writestr("binaries/linux64/Toy.so", _pythonfmus()["linux64"])
        archive.writestr("binaries/win64/Toy.dll", _pythonfmus()["win64"])
    return fmu


def test_the_runtime_compiles_with_cc_without_a_warning(tmp_path):
    chain = native.toolchain()
    if chain is None or chain.zig:
        pytest.skip("no cc")
    out = tmp_path / "runtime.so"
    done = subprocess.run(
        native.compile_command(chain, out, "-Werror"), capture_output=True, text=True
    )
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""


def test_a_runtime_that_does_not_compile_is_named_by_the_compilers_error_line(
    monkeypatch, tmp_path
):
    """A C source that did not compile was reported by the compiler's last line, GCC's
    caret under the code ("the runtime did not compile (      |          ^)"): the line
    that says what is wrong, with its file and line, is the one a developer needs."""
    chain = native.toolchain()
    if chain is None:
        pytest.skip("no C compiler")
    broken = tmp_path / "broken.c"
    broken.write_text("int broken(void) { return }\n", encoding="utf-8")
    monkeypatch.setattr(
        native,
        "compile_command",
        lambda chain, out, platform="linux64": [*chain.command, "-c", str(broken), "-o", str(out)],
    )
    problem = native.compile_runtime(chain, tmp_path / "runtime.so")
    assert problem is not None and "broken.c:1:" in problem and "error" in problem, problem


# The functions an FMI 2.0 co-simulation FMU exports (FMI 2.0.x standard, section 2.1 and
# 4.2: the common functions, the functions for FMU states and partial derivatives, and the
# co-simulation functions). Nothing else may be exported: a DLL exports what it is told.
FMI2_COSIMULATION = frozenset(
    "fmi2" + name
    for name in (
        "GetTypesPlatform",
        "GetVersion",
        "SetDebugLogging",
        "Instantiate",
        "FreeInstance",
        "SetupExperiment",
        "EnterInitializationMode",
        "ExitInitializationMode",
        "Terminate",
        "Reset",
        "GetReal",
        "GetInteger",
        "GetBoolean",
        "GetString",
        "SetReal",
        "SetInteger",
        "SetBoolean",
        "SetString",
        "GetFMUstate",
        "SetFMUstate",
        "FreeFMUstate",
        "SerializedFMUstateSize",
        "SerializeFMUstate",
        "DeSerializeFMUstate",
        "GetDirectionalDerivative",
        "SetRealInputDerivatives",
        "GetRealOutputDerivatives",
        "DoStep",
        "CancelStep",
        "GetStatus",
        "GetRealStatus",
        "GetIntegerStatus",
        "GetBooleanStatus",
        "GetStringStatus",
    )
)
# What every Windows 10/11 has: the kernel and the Universal CRT (its api-ms-win-crt-*
# forwarders, ucrtbase) or the old msvcrt. Not python3*.dll: the runtime links no
# libpython, it loads the one it finds.
_SYSTEM_DLL = ("kernel32.dll", "api-ms-win-crt-", "ucrtbase.dll", "msvcrt.dll")


def _is_system_dll(name: str) -> bool:
    return name.lower().startswith(_SYSTEM_DLL)


@pytest.fixture(scope="module")
def win64_runtime(tmp_path_factory) -> Path:
    """The runtime cross-compiled for win64 with ``-Werror``, as the build compiles it."""
    cross = native.zig()
    if cross is None:
        pytest.skip("ziglang not installed: the win64 runtime cannot be cross-compiled here")
    out = tmp_path_factory.mktemp("win64") / "runtime.dll"
    done = subprocess.run(
        native.compile_command(cross, out, "-Werror", platform="win64"),
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "warning" not in done.stderr
    return out


def test_the_linux64_runtime_exports_exactly_the_fmi2_functions(fmu_paths, tmp_path):
    runtime = _binary(fmu_paths["AuvPlant"], "binaries/linux64/AuvPlant.so", tmp_path)
    out = subprocess.run(["objdump", "-T", str(runtime)], capture_output=True, text=True).stdout
    exported = {line.split()[-1] for line in out.splitlines() if " .text" in line}
    assert exported == FMI2_COSIMULATION


@pytest.mark.slow
def test_the_win64_runtime_exports_exactly_the_fmi2_functions(win64_runtime):
    """zig's first cross-compile on a machine builds its MinGW libraries (about two
    minutes): slow."""
    names = exported_names(win64_runtime)
    assert sorted(names) == sorted(FMI2_COSIMULATION)


@pytest.mark.slow
def test_the_win64_runtime_imports_only_windows_own_dlls(win64_runtime):
    imported = imported_dlls(win64_runtime)
    assert any(name.lower() == "kernel32.dll" for name in imported), imported
    assert [name for name in imported if not _is_system_dll(name)] == []


@pytest.mark.slow
def test_the_win64_runtime_is_compiled_afresh_only_when_asked(monkeypatch, tmp_path):
    """``AUV_FMU_WIN64=1`` with zig: ``binaries/win64/<id>.dll`` is compiled afresh;
    without it, it is the prebuilt DLL; pythonfmu's DLL beside it unchanged either way."""
    if native.toolchain() is None or native.zig() is None:
        pytest.skip("needs a C compiler and ziglang")
    compiled = []
    compile_runtime = native.compile_runtime
    monkeypatch.setattr(native, "_COMPILED", {})
    monkeypatch.setattr(
        native,
        "compile_runtime",
        lambda chain, out, platform="linux64": (
            compiled.append(platform) or compile_runtime(chain, out, platform)
        ),
    )
    for wanted in ("1", "0"):
        monkeypatch.setenv(native.WIN64_VARIABLE, wanted)
        compiled.clear()
        fmu = _toy_fmu(tmp_path / wanted)
        assert native.install_loader(fmu, "Toy") == []
        assert native.loader_in(fmu, "linux64")
        assert native.loader_in(fmu, "win64")
        assert compiled == (["linux64", "win64"] if wanted == "1" else ["linux64"])
        with zipfile.ZipFile(fmu) as archive:
            dll = tmp_path / wanted / "Toy.dll"
            dll.write_bytes(archive.read("binaries/win64/Toy.dll"))
            assert archive.read("binaries/win64/Toy_pythonfmu.dll") == _pythonfmus()["win64"]
        assert sorted(exported_names(dll)) == sorted(FMI2_COSIMULATION)
        if wanted == "0" or _zig_version() == native.prebuilt_record()["zig"]:
            assert dll.read_bytes() == native.PREBUILT_DLL.read_bytes()


def _zig_version() -> str:
    zig = native.zig()
    assert zig is not None
    command = [*zig.command[:-1], "version"]  # python -m ziglang version
    return subprocess.run(command, capture_output=True, text=True, check=True).stdout.strip()


def test_the_prebuilt_dll_is_part_of_the_rebuild_key(monkeypatch, tmp_path):
    """A regenerated DLL (or record) rebuilds the FMUs."""
    before = native.source_digest()
    for name in ("PREBUILT_DLL", "PREBUILT_RECORD"):
        changed = tmp_path / name
        changed.write_bytes(getattr(native, name).read_bytes() + b"\n")
        with monkeypatch.context() as patch:
            patch.setattr(native, name, changed)
            assert native.source_digest() != before
    assert native.source_digest() == before


@pytest.mark.slow
def test_a_rebuild_with_zig_is_the_committed_dll(tmp_path):
    """zig's output does not depend on the folders (``-s``: no PDB paths): with the zig
    version the record names, scripts/build_win64_runtime.py rebuilds the committed DLL
    byte for byte; with another, the same export and import tables."""
    if native.zig() is None:
        pytest.skip("ziglang not installed")
    script = Path(__file__).parents[3] / native.PREBUILT_SCRIPT
    spec = importlib.util.spec_from_file_location("build_win64_runtime", script)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    rebuilt = module.build(tmp_path)
    committed = native.PREBUILT_DLL
    record = native.prebuilt_record()
    if module.zig_version(native.zig()) == record["zig"]:
        assert rebuilt.read_bytes() == committed.read_bytes()
        new_record = (tmp_path / native.PREBUILT_RECORD.name).read_text(encoding="utf-8")
        assert new_record == native.PREBUILT_RECORD.read_text(encoding="utf-8")
    else:
        assert exported_names(rebuilt) == exported_names(committed)
        assert imported_dlls(rebuilt) == imported_dlls(committed)


def test_the_package_data_carries_the_prebuilt_dll():
    """``pip install .`` (not editable) installs what pyproject's package-data names."""
    root = Path(__file__).parents[3]
    patterns = tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"
    ]["fmu_runtime"]
    package = native.SOURCE_DIR.parent
    for path in (native.PREBUILT_DLL, native.PREBUILT_RECORD):
        relative = path.relative_to(package).as_posix()
        assert any(fnmatch.fnmatch(relative, pattern) for pattern in patterns), relative


def test_the_names_of_one_python_give_one_rebuild_key(monkeypatch, tmp_path):
    """`auv-cosim` runs the environment's python3, `python -m cosim.cli` its python: one
    interpreter in one environment, which recorded a different build Python, so every
    command run the other way rebuilt every FMU (~3 s; ~10 s more where numba cannot
    cache). A Python of another environment still changes the key."""
    folder = Path(sys.executable).parent
    names = [folder / n for n in ("python", "python3") if (folder / n).exists()]
    if len(names) < 2 or names[0].resolve() != names[1].resolve():
        pytest.skip(f"{folder} has not python and python3 as one interpreter")
    keys = set()
    for name in names:
        monkeypatch.setattr(sys, "executable", str(name))
        keys.add(build.recorded_python(portable=False))
    assert len(keys) == 1
    elsewhere = tmp_path / "env" / "bin" / "python"
    elsewhere.parent.mkdir(parents=True)
    elsewhere.symlink_to(names[0].resolve())
    monkeypatch.setattr(sys, "executable", str(elsewhere))
    assert build.recorded_python(portable=False) not in keys
