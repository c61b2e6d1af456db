"""A local study's FMUs are extracted once for every later study of the same FMU files
(kept in the user's cache folder), safely while other studies run: a set another study
uses is never removed, two studies extracting the same set at once both use one whole
copy, and at most KEPT sets are kept."""

from __future__ import annotations

import errno
import fcntl
import hashlib
import os
import shutil
import stat
import zipfile
from contextlib import ExitStack
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from cosim import user_cache
from cosim.study import fmu_store, unpacked
from cosim.study.fmu_store import kept_unpacked, store_folder
from cosim.study.runner import _Session
from cosim.study.unpacked import unpack


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The user's cache folder, in the test's own folder."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    return tmp_path / "cache"


def _stamps(unpacked: dict[str, str]) -> dict[str, int]:
    return {f: (Path(f) / "modelDescription.xml").stat().st_mtime_ns for f in unpacked.values()}


def _local_session(stack: ExitStack) -> _Session:
    return _Session(SimpleNamespace(scheduler=None), stack)  # type: ignore[arg-type]


def test_a_second_study_of_the_same_fmus_extracts_nothing(fmu_paths, cache: Path) -> None:
    """Every local study's client extracted its FMUs afresh (~0.06-0.1 s of its CPU on a
    2-core machine whose cores are both busy before the first run)."""
    base = SimpleNamespace(fmu_paths={n: fmu_paths[n] for n in ("AuvPlant", "AuvAutopilot")})
    with ExitStack() as stack:
        first = _local_session(stack).unpacked(base)  # type: ignore[arg-type]
        stamps = _stamps(first)
    with ExitStack() as stack:
        again = _local_session(stack).unpacked(base)  # type: ignore[arg-type]
        assert again == first, "the second study extracted its FMUs again"
        assert _stamps(again) == stamps
        for fmu in base.fmu_paths.values():  # each FMU's folder by its content's SHA-256
            folder = again[hashlib.sha256(fmu.read_bytes()).hexdigest()]
            with zipfile.ZipFile(fmu) as archive:
                for name in archive.namelist():
                    if not name.endswith("/"):
                        assert (Path(folder) / name).read_bytes() == archive.read(name), name
    assert all(Path(f).is_relative_to(store_folder()) for f in first.values())
    assert not list(store_folder().glob(".new-*"))


def test_the_second_of_two_studies_extracting_at_once_uses_the_firsts(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    paths = {"plant": fmu_paths["AuvPlant"]}
    rename = os.rename

    def other_study_first(source: str | Path, target: str | Path) -> None:
        """Another study renames its whole copy of the same set into place first."""
        other = Path(target).with_name("other")
        unpack(paths, other)
        rename(other, target)
        rename(source, target)  # refused: the target is taken

    monkeypatch.setattr(fmu_store.os, "rename", other_study_first)
    with ExitStack() as stack:
        found = kept_unpacked(paths, stack)
    assert found is not None and all(
        (Path(f) / "modelDescription.xml").is_file() for f in found.values()
    )
    assert sorted(p.name for p in store_folder().iterdir() if p.is_dir()) == [
        Path(next(iter(found.values()))).parent.name
    ], "this study's own copy was left beside the one it uses"


def test_sets_beyond_the_kept_are_removed_unless_a_study_uses_them(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(fmu_store, "KEPT", 2)  # fewer sets to extract than the 4 kept
    names = ("AuvPlant", "AuvAutopilot", "AuvGuidance")
    sets = [{n: fmu_paths[n]} for n in names] + [{n: fmu_paths[n] for n in names[:2]}]
    most = fmu_store.KEPT
    with ExitStack() as in_use:
        oldest = kept_unpacked(sets[0], in_use)  # another study runs on it all along
        assert oldest is not None
        _used_at(oldest, 0)
        for k, fmus in enumerate(sets[1:], 1):
            with ExitStack() as stack:
                found = kept_unpacked(fmus, stack)
                assert found is not None
                _used_at(found, k)
        kept = {p.name for p in store_folder().iterdir() if p.is_dir()}
        assert len(kept) == most + 1, kept  # the KEPT last used, and the one in use
        assert all((Path(f) / "modelDescription.xml").is_file() for f in oldest.values())
    with ExitStack() as stack:
        assert kept_unpacked(sets[-1], stack) is not None  # nobody uses the oldest now
    kept = {p.name for p in store_folder().iterdir() if p.is_dir()}
    assert len(kept) == most, kept
    locks = {p.stem for p in store_folder().glob("*.lock")}
    assert locks == kept, "a removed set's lock file was left, or a kept set's removed"


def _used_at(found: dict[str, str], second: int) -> None:
    """Date the last use of the set of ``found`` (its lock file's time) ``second``."""
    key = Path(next(iter(found.values()))).parent.name
    os.utime(store_folder() / f"{key}.lock", ns=(second * 10**9, second * 10**9))


def _extracts_into_its_own_folder(fmu_paths: dict[str, Path]) -> None:
    """A local study's session extracts the plant into its own scratch folder, whole."""
    base = SimpleNamespace(fmu_paths={"plant": fmu_paths["AuvPlant"]})
    with ExitStack() as stack:
        session = _local_session(stack)
        found = session.unpacked(base)  # type: ignore[arg-type]
        assert session.folder is not None
        assert all(Path(f).parent == session.folder for f in found.values())
        assert all((Path(f) / "modelDescription.xml").is_file() for f in found.values())


def test_without_flock_a_study_extracts_into_its_own_folder(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(user_cache, "fcntl", None)
    _extracts_into_its_own_folder(fmu_paths)
    assert not store_folder().exists()


def test_a_cache_without_room_for_the_set_leaves_the_study_its_own_folder(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cache's disk too full for the set is no reason to refuse a study whose own
    temporary folder has room: it extracts there, and leaves nothing in the cache."""
    usage = shutil.disk_usage

    def full_cache(path: str | Path) -> Any:
        found = usage(path)
        return found._replace(free=1024) if Path(path).is_relative_to(cache) else found

    monkeypatch.setattr(shutil, "disk_usage", full_cache)
    _extracts_into_its_own_folder(fmu_paths)
    assert not [p for p in store_folder().iterdir() if p.is_dir()]


def _kept_plant(fmu_paths: dict[str, Path]) -> tuple[dict[str, Path], Path]:
    """The plant's and the autopilot's set kept by an earlier study (the autopilot's
    resource folders links to the plant's), and the plant's folder in it."""
    paths = {n: fmu_paths[n] for n in ("AuvPlant", "AuvAutopilot")}
    with ExitStack() as stack:
        found = kept_unpacked(paths, stack)
    assert found is not None
    return paths, Path(found[hashlib.sha256(paths["AuvPlant"].read_bytes()).hexdigest()])


def _assert_whole(paths: dict[str, Path], found: dict[str, str]) -> None:
    """Every FMU's folder in ``found`` holds its archive's files, and its file's copy."""
    for fmu in paths.values():
        folder = Path(found[hashlib.sha256(fmu.read_bytes()).hexdigest()])
        assert folder.with_name(f"{folder.name}.fmu").read_bytes() == fmu.read_bytes()
        with zipfile.ZipFile(fmu) as archive:
            for name in archive.namelist():
                if not name.endswith("/"):
                    assert (folder / name).read_bytes() == archive.read(name), name
                    assert (folder / name).stat().st_mode & stat.S_IRUSR, name  # not root


def _cut_short(folder: Path) -> None:
    """A file of the kept plant cut short (a power cut after the rename, a full disk)."""
    source = next(p for p in sorted((folder / "resources").rglob("*.py")) if p.stat().st_size)
    with source.open("r+b") as file:
        file.truncate(source.stat().st_size // 2)


def _dangle(folder: Path) -> None:
    """The folder a link of the kept set names removed (the link dangles)."""
    links = [p for p in sorted(folder.parent.rglob("*")) if p.is_symlink()]
    assert links, "the kept set has no links to break"
    shutil.rmtree(links[0].resolve())


def _copy_cut_short(folder: Path) -> None:
    """The FMU file's copy beside its folder, which local workers load, cut short."""
    with folder.with_name(f"{folder.name}.fmu").open("r+b") as file:
        file.truncate(100)


def _flip_a_byte(path: Path) -> None:
    """One byte of ``path`` flipped in place, its size and modification time as they were
    (a disk's error, an editor keeping the time, ``touch -r``)."""
    before = path.stat()
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF
    with path.open("r+b") as file:
        file.write(data)
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns))


def _byte_flipped(folder: Path) -> None:
    """A byte of a file of the kept plant flipped: the same size, another content."""
    _flip_a_byte(next(p for p in sorted((folder / "resources").rglob("*.py")) if p.stat().st_size))


def _copy_byte_flipped(folder: Path) -> None:
    """A byte of the FMU file's copy beside its folder flipped."""
    _flip_a_byte(folder.with_name(f"{folder.name}.fmu"))


def _file_instead(folder: Path) -> None:
    """A file where the set's folder should be."""
    shutil.rmtree(folder.parent)
    folder.parent.write_text("junk")


def _unreadable(folder: Path) -> None:
    """A file of the kept plant its owner may not read (a umask or a hand)."""
    (folder / "modelDescription.xml").chmod(0)


@pytest.mark.parametrize(
    "damage",
    [_cut_short, _dangle, _copy_cut_short, _file_instead, _unreadable, _byte_flipped,
     _copy_byte_flipped],
)  # fmt: skip
def test_a_damaged_kept_set_is_replaced_by_a_whole_one(fmu_paths, cache: Path, damage: Any) -> None:
    """A kept set whose files were cut short or removed was used as it was (a plant FMU
    whose code is half a file, a worker loading a truncated copy); a file in its place
    made every later study extract into its own folder; one a byte of whose files was
    changed in place (the same size) was used too, sizes alone compared. It is replaced,
    saying so in one line."""
    paths, folder = _kept_plant(fmu_paths)
    damage(folder)
    with ExitStack() as stack, pytest.warns(RuntimeWarning, match=r"^the kept FMUs \S+ were"):
        found = kept_unpacked(paths, stack)
        assert found is not None, "the damaged set was not replaced"
        _assert_whole(paths, found)
    assert not [p for p in store_folder().iterdir() if p.name.startswith((".new-", ".old-"))]


def test_a_damaged_set_another_study_uses_is_left_with_one_line(fmu_paths, cache: Path) -> None:
    """Another study holds the damaged set: this one says why in one line and leaves the
    set (its caller extracts into a folder of its own) to the next study to replace."""
    paths, folder = _kept_plant(fmu_paths)
    _cut_short(folder)
    other = os.open(store_folder() / f"{folder.parent.name}.lock", os.O_RDWR)
    try:
        fcntl.flock(other, fcntl.LOCK_SH)  # another study's, on an open file of its own
        damaged = r"damaged \(\w+/resources/\S+ is \d+ bytes, not \d+\)"
        with pytest.warns(RuntimeWarning, match=damaged), ExitStack() as stack:
            assert kept_unpacked(paths, stack) is None
    finally:
        os.close(other)
    with ExitStack() as stack, pytest.warns(RuntimeWarning, match="extracted again"):
        found = kept_unpacked(paths, stack)  # the other study over: the next one replaces it
        assert found is not None
        _assert_whole(paths, found)


def test_a_set_not_written_whole_is_not_kept(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The cache's disk full as the FMU's copy is written (the extraction written): the
    set was renamed into the cache without it, for good."""

    def disk_full(path: Path, write: Any) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))

    monkeypatch.setattr(unpacked, "write_whole", disk_full)
    with ExitStack() as stack:
        assert kept_unpacked({"plant": fmu_paths["AuvPlant"]}, stack) is None
    assert not list(store_folder().glob("[!.]*[!k]")), "a set without its copy was kept"
    assert not [p for p in store_folder().iterdir() if p.is_dir()]


def test_a_relative_xdg_cache_home_is_ignored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """XDG_CACHE_HOME=cache (relative, which the XDG base directory specification says to
    ignore) put the cache in whatever folder the study was started from."""
    monkeypatch.setenv("XDG_CACHE_HOME", "relative-cache")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.chdir(tmp_path)
    assert store_folder().is_absolute(), store_folder()
    assert store_folder().is_relative_to(tmp_path / "home" / ".cache")


def test_a_cache_without_flock_leaves_the_study_its_own_folder(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A file system without flock (NFS without its lock daemon: ENOLCK)."""

    def no_locks(fd: int, operation: int) -> None:
        raise OSError(errno.ENOLCK, os.strerror(errno.ENOLCK))

    monkeypatch.setattr(fcntl, "flock", no_locks)
    _extracts_into_its_own_folder(fmu_paths)
    assert not [p for p in store_folder().iterdir() if p.is_dir()]


@pytest.mark.parametrize("refusal", [errno.EACCES, errno.EROFS], ids=["denied", "read-only"])
def test_a_read_only_cache_holding_the_whole_set_is_used(
    fmu_paths, cache: Path, monkeypatch: pytest.MonkeyPatch, refusal: int
) -> None:
    """A cache the user may read but not write (a read-only mount, a shared cache of
    another's): the whole set kept there is used, under a shared lock on its lock file
    opened for reading, instead of extracted into the study's own folder. The tests run
    as root, which no permission stops: the system's refusal to open for writing is
    simulated."""
    paths, folder = _kept_plant(fmu_paths)
    real_open = os.open

    def read_only(path: Any, flags: int, *args: Any, **kwargs: Any) -> int:
        if flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT):
            raise OSError(refusal, os.strerror(refusal), str(path))
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(user_cache.os, "open", read_only)
    with ExitStack() as stack:
        found = kept_unpacked(paths, stack)
        assert found is not None, "the whole set in a read-only cache was not used"
        assert Path(found[hashlib.sha256(paths["AuvPlant"].read_bytes()).hexdigest()]) == folder
        _assert_whole(paths, found)
        lock = store_folder() / f"{folder.parent.name}.lock"
        probe = real_open(lock, os.O_RDONLY)  # the set is held: no remover may take it
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(probe, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(probe)
