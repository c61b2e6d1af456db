"""The FMU's binaries: the runtime loads on glibc 2.17 (manylinux2014: CentOS 7, RHEL 8,
Ubuntu 18.04 and later), compiles without a warning, and pythonfmu's binary, the fallback,
is shipped unchanged (it needs glibc 2.32: docs/hosts.md says so). The win64 runtime,
cross-compiled with zig when asked: no warning, the FMI 2.0 functions as its only exports,
Windows' own DLLs as its only imports."""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
import pythonfmu
from elf_symbols import glibc_versions, unresolvable
from pe_table import exported_names, imported_dlls

from cosim.fmus import native
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


def test_the_fallback_and_the_win64_binary_are_pythonfmus_unchanged(fmu_paths, tmp_path):
    """Without AUV_FMU_WIN64=1 (the test environment's build) the win64 binary is
    pythonfmu's."""
    wheel = Path(pythonfmu.__file__).parent / "resources" / "binaries"
    for name in FMUS:
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            fallback = archive.read(f"binaries/linux64/{name}{native.WRAPPER_SUFFIX}.so")
            win64 = archive.read(f"binaries/win64/{name}.dll")
        assert fallback == (wheel / "linux64" / "libpythonfmu-export.so").read_bytes()
        assert win64 == (wheel / "win64" / "pythonfmu-export.dll").read_bytes()
    glibc = glibc_versions(wheel / "linux64" / "libpythonfmu-export.so")
    assert glibc[-1] == (2, 32)  # what docs/hosts.md tells a user the fallback needs


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
def test_the_win64_runtime_goes_in_only_when_asked(monkeypatch, tmp_path):
    """``AUV_FMU_WIN64=1``: ``binaries/win64/<id>.dll`` is the runtime, pythonfmu's DLL
    beside it unchanged; without it the FMU's win64 binary is pythonfmu's. An FMU laid out
    as pythonfmu's builder lays it out, with the wheel's binaries."""
    if native.toolchain() is None or native.zig() is None:
        pytest.skip("needs a C compiler and ziglang")
    wheel = Path(pythonfmu.__file__).parent / "resources" / "binaries"
    pythonfmus = {
        "linux64": (wheel / "linux64" / "libpythonfmu-export.so").read_bytes(),
        "win64": (wheel / "win64" / "pythonfmu-export.dll").read_bytes(),
    }
    for wanted in ("1", "0"):
        monkeypatch.setenv(native.WIN64_VARIABLE, wanted)
        fmu = tmp_path / wanted / "Toy.fmu"
        fmu.parent.mkdir()
        with zipfile.ZipFile(fmu, "w") as archive:
            archive.writestr("modelDescription.xml", "<fmiModelDescription/>")
            archive.writestr("binaries/linux64/Toy.so", pythonfmus["linux64"])
            archive.writestr("binaries/win64/Toy.dll", pythonfmus["win64"])
        assert native.install_loader(fmu, "Toy") == []
        assert native.loader_in(fmu, "linux64")
        assert native.loader_in(fmu, "win64") == (wanted == "1")
        with zipfile.ZipFile(fmu) as archive:
            dll = tmp_path / wanted / "Toy.dll"
            dll.write_bytes(archive.read("binaries/win64/Toy.dll"))
            if wanted == "1":
                assert archive.read("binaries/win64/Toy_pythonfmu.dll") == pythonfmus["win64"]
                assert sorted(exported_names(dll)) == sorted(FMI2_COSIMULATION)
            else:
                assert dll.read_bytes() == pythonfmus["win64"]
                assert "binaries/win64/Toy_pythonfmu.dll" not in archive.namelist()
