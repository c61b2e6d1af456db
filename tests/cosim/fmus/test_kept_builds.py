"""The built-in FMUs are built once per user: a second working folder gets a copy of
what the first built (cosim/fmus/kept_builds.py), checked as a folder's own FMU is; a
changed source, a damaged copy or AUV_COSIM_NO_BUILD_CACHE=1 builds again. The builder
is replaced by one that writes a file named after the sources' digest, and counted."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.fmus import build, kept_builds
from cosim.fmus.build import build_fmu

NAME = "AuvGuidance"


@pytest.fixture
def builds(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[Path]:
    """The store on, in the test's own cache folder; the FMUs each build wrote."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(kept_builds.OFF_VARIABLE, raising=False)
    built: list[Path] = []

    def fake_build(name: str, files: object, digest: str, target: Path, portable: bool) -> None:
        target.write_bytes(f"{name} built from {digest}".encode())
        built.append(target)

    monkeypatch.setattr(build, "_build", fake_build)
    return built


def _intact(folder: Path) -> bool:
    """Whether ``folder``'s FMU is one its folder would use without building."""
    return build.out_of_date(folder) == [n for n in build.FMUS if n != NAME]


def test_a_second_working_folder_gets_the_fmu_built_for_the_first(
    tmp_path: Path, builds: list[Path]
) -> None:
    """`auv-cosim run bs-3` in a second working folder built the FMUs again (~20 s)."""
    first = build_fmu(NAME, tmp_path / "one" / "build" / "fmus")
    second = build_fmu(NAME, tmp_path / "two" / "build" / "fmus")
    assert builds == [first], "the second folder built the FMU again"
    assert second.read_bytes() == first.read_bytes()
    assert _intact(second.parent)
    assert build_fmu(NAME, second.parent) == second and len(builds) == 1


def test_changed_sources_build_again(
    tmp_path: Path, builds: list[Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    build_fmu(NAME, tmp_path / "one")
    monkeypatch.setattr(build, "source_hash", lambda files: "0" * 64)  # a source edited
    again = build_fmu(NAME, tmp_path / "two")
    assert builds == [tmp_path / "one" / f"{NAME}.fmu", again]
    assert again.read_bytes() == f"{NAME} built from {'0' * 64}".encode()


def test_a_damaged_kept_fmu_is_built_again_and_replaced(tmp_path: Path, builds: list[Path]) -> None:
    """A kept FMU whose file no longer has the hash its build recorded is never copied."""
    build_fmu(NAME, tmp_path / "one")
    (kept,) = (kept_builds.store_folder() or tmp_path).glob(f"{NAME}-*/{NAME}.fmu")
    kept.write_bytes(b"cut")
    with pytest.warns(RuntimeWarning, match="is damaged"):
        second = build_fmu(NAME, tmp_path / "two")
    assert len(builds) == 2 and _intact(second.parent)
    (kept,) = (kept_builds.store_folder() or tmp_path).glob(f"{NAME}-*/{NAME}.fmu")
    assert kept.read_bytes() == second.read_bytes()
    build_fmu(NAME, tmp_path / "three")
    assert len(builds) == 2


def test_a_kept_fmu_changed_in_place_is_built_again_saying_so(
    tmp_path: Path, builds: list[Path]
) -> None:
    """A kept FMU a byte of which was flipped (the same size) is never copied: it is built
    again, and the wait for the build (~20 s) is said in one line, which nothing said."""
    build_fmu(NAME, tmp_path / "one")
    (kept,) = (kept_builds.store_folder() or tmp_path).glob(f"{NAME}-*/{NAME}.fmu")
    data = bytearray(kept.read_bytes())
    data[len(data) // 2] ^= 0xFF
    kept.write_bytes(bytes(data))
    damaged = rf"^the kept FMU {kept} is damaged \(not the file its build recorded\): building"
    with pytest.warns(RuntimeWarning, match=damaged) as said:
        second = build_fmu(NAME, tmp_path / "two")
    assert len(said) == 1 and "\n" not in str(said[0].message)
    assert len(builds) == 2 and _intact(second.parent)


def test_the_variable_turns_the_store_off(
    tmp_path: Path, builds: list[Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(kept_builds.OFF_VARIABLE, "1")
    build_fmu(NAME, tmp_path / "one")
    build_fmu(NAME, tmp_path / "two")
    assert len(builds) == 2
    assert not (tmp_path / "cache" / "auv-cosim" / kept_builds.STORE_DIR).exists()


def test_a_forced_build_builds(tmp_path: Path, builds: list[Path]) -> None:
    """`auv-cosim build --force` builds, whatever is kept."""
    build_fmu(NAME, tmp_path / "one")
    build_fmu(NAME, tmp_path / "two", force=True)
    assert len(builds) == 2
