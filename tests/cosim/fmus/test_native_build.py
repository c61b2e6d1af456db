"""The FMU's binaries: the runtime loads on glibc 2.17 (manylinux2014: CentOS 7, RHEL 8,
Ubuntu 18.04 and later), compiles without a warning, and pythonfmu's binary, the fallback,
is shipped unchanged (it needs glibc 2.32: docs/hosts.md says so)."""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import pytest
import pythonfmu
from elf_symbols import glibc_versions, unresolvable

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
