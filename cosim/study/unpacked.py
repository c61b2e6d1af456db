"""A local study's FMUs extracted once, by its client, for every worker.

Each worker process extracted each FMU (~0.02 s). A local cluster's workers share the
client's disk, so the client extracts each FMU (by content) into a folder of its own while
it waits for its cluster to start (:func:`unpack`); each worker then uses that folder
(:func:`use_unpacked`, from the study plugin's set-up); that folder is kept for later
studies of the same FMUs where it can be (:mod:`cosim.study.fmu_store`). A worker
elsewhere (a remote cluster) gets no folders and extracts its FMUs itself, as before.
Our FMUs carry their code compiled (:mod:`cosim.fmus.bytecode`), so neither the client
nor a worker compiles it (that was ~0.2 s of the client's CPU before its workers could
start).

The client also leaves a copy of each FMU file beside its extraction (:func:`local_copy`),
which a local worker loads instead of a copy of its own: the study plugin carried each
FMU's bytes (~4 MB for bs-3's three) through the scheduler to every local worker, pickled,
sent over the loopback twice and written into the worker's local directory, ~15-20 ms of
the client's CPU (its event loop serves the scheduler) and ~8-12 ms of each worker's
before its first run (``client.register_plugin``, 2 workers).
"""

from __future__ import annotations

import hashlib
import os
import zipfile
from collections.abc import Callable, Mapping
from contextlib import suppress
from pathlib import Path

from cosim.whole_file import write_whole

MODEL_DESCRIPTION = "modelDescription.xml"
RESOURCES = "resources"
Members = frozenset[tuple[str, int, int]]  # a folder's files: (name, CRC-32, size)


def unpack(fmu_paths: Mapping[str, Path], folder: Path) -> dict[str, str]:
    """Extract each FMU into ``folder``/<SHA-256 of its file>/ (once per content), its
    file copied beside it as ``<SHA-256>.fmu`` (whole or not at all: where it cannot be
    written, the workers are carried the FMU instead); returns SHA-256 -> that folder
    (absolute). An FMU larger than the limit or the free space there is refused before a
    byte is written (:class:`cosim.fmus.interface.FmuInterfaceError`, from
    :func:`cosim.fmus.interface.extract_fmu`)."""
    found: dict[str, str] = {}
    extracted: dict[tuple[str, Members], Path] = {}  # resources folders of this call's FMUs
    for path in fmu_paths.values():
        content = path.read_bytes()
        digest = hashlib.sha256(content).hexdigest()
        target = (folder / digest).resolve()
        if not (target / MODEL_DESCRIPTION).is_file():
            _extract(path, target, extracted)
            _keep_copy(target, content)
        found[digest] = str(target)
    return found


def _extract(path: Path, target: Path, extracted: dict[tuple[str, Members], Path]) -> None:
    """Extract the FMU ``path`` into ``target``; a folder of its ``resources`` that an FMU
    extracted before (``extracted``: name and members -> where) also holds, member for
    member, is a symbolic link to that one instead (extracted where the system makes no
    link). Our FMUs each ship the same package of ~120 files (``auvfmu_<hash>``), and
    making a file costs the kernel's CPU (on an ext4 ``/tmp`` far more than on a tmpfs):
    CPU of the client's before its workers can run, on a machine whose other core the
    workers' fork server fills (``docs/performance.md``)."""
    from cosim.fmus.interface import extract_fmu

    folders = _resource_folders(path)
    same = {name: extracted[(name, members)] for name, members in folders.items()
            if (name, members) in extracted}  # fmt: skip
    extract_fmu(path, target, include=lambda member: _resource_folder(member) not in same)
    for name, source in same.items():
        link = target / RESOURCES / name
        try:
            link.parent.mkdir(parents=True, exist_ok=True)
            link.symlink_to(os.path.relpath(source, link.parent), target_is_directory=True)
        except OSError:  # no symbolic links here (Windows without the privilege)
            extract_fmu(path, target, include=_inside(name))
    for name, members in folders.items():
        extracted.setdefault((name, members), target / RESOURCES / name)


def _inside(folder: str) -> Callable[[str], bool]:
    """Whether an archive's member is in ``folder`` (of :func:`_resource_folder`)."""
    return lambda member: _resource_folder(member) == folder


def _resource_folders(path: Path) -> dict[str, Members]:
    """Each folder two levels down the FMU's ``resources`` (``auvfmu_<hash>/plant_fmu``:
    the package's own ``__init__.py`` names its FMU, its subpackages are the same in all
    three): its members as (name within the folder, CRC-32, size), as its archive
    declares them."""
    folders: dict[str, set[tuple[str, int, int]]] = {}
    with zipfile.ZipFile(path) as archive:
        for info in archive.infolist():
            name = _resource_folder(info.filename)
            if name is not None:
                inner = info.filename.split("/", 3)[3]
                folders.setdefault(name, set()).add((inner, info.CRC, info.file_size))
    return {name: frozenset(members) for name, members in folders.items()}


def _resource_folder(member: str) -> str | None:
    """The folder two levels down ``resources`` (``a/b``) the archive's ``member`` is in
    (None: not in one)."""
    parts = member.split("/", 3)
    if len(parts) == 4 and parts[0] == RESOURCES and parts[1] and parts[2]:
        return f"{parts[1]}/{parts[2]}"
    return None


def _keep_copy(extraction: Path, content: bytes) -> None:
    """Write the FMU file ``content`` beside its ``extraction``, whole or not at all; no
    copy where it cannot be written (a full disk): the workers are carried the FMU."""
    with suppress(OSError):
        write_whole(_copy_path(extraction), lambda tmp: tmp.write_bytes(content))


def local_copy(content: bytes, unpacked: Mapping[str, str]) -> Path | None:
    """The client's copy of the FMU file whose bytes are ``content`` (:func:`unpack`
    wrote it beside its extraction), for local workers to load; None if there is none
    (another content: the file changed since, or a remote cluster's empty ``unpacked``)."""
    if not unpacked:
        return None
    folder = unpacked.get(hashlib.sha256(content).hexdigest())
    if folder is None or not _copy_path(Path(folder)).is_file():
        return None
    return _copy_path(Path(folder))


def _copy_path(extraction: Path) -> Path:
    """``<folder>/<SHA-256>.fmu``, beside the extraction ``<folder>/<SHA-256>/``."""
    return extraction.with_name(f"{extraction.name}.fmu")


def use_unpacked(unpacked: Mapping[str, str]) -> None:
    """In a worker: use the folders :func:`unpack` made (those that exist here) for the
    FMUs of that content, instead of extracting them again."""
    from cosim.engine.slave import share_unzipped

    for digest, folder in unpacked.items():
        if (Path(folder) / MODEL_DESCRIPTION).is_file():
            share_unzipped(digest, Path(folder))
