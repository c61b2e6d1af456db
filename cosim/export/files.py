"""Writing an export without leaving anything partial (build beside, then rename into
place), and without writing over anything an export did not write.

What an export wrote is known by content: an SSP archive carries, as its zip comment,
:data:`ARCHIVE_SEAL` and the SHA-256 of its members (names and contents,
:func:`members_digest`); an OSP folder holds :data:`EXPORT_RECORD`, each file the export
wrote with its SHA-256. A copy a user changed since -- a parameter edited in the SSD, an
FMU of their own -- no longer matches, and is refused like any other file.
"""

from __future__ import annotations

import hashlib
import json
import os
import secrets
import shutil
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from cosim.errors import CosimError
from cosim.limits import unwritten

ARCHIVE_SEAL = b"auv-cosim export, members' SHA-256: "  # then the digest, as the zip comment
EXPORT_RECORD = ".auv-cosim-export.json"  # in an OSP folder: {"files": {name: SHA-256}}


def members_digest(archive: zipfile.ZipFile) -> str:
    """The SHA-256 over every member's name and the SHA-256 of its content, in order."""
    digest = hashlib.sha256()
    for info in archive.infolist():
        content = hashlib.sha256(archive.read(info)).hexdigest()
        digest.update(f"{info.filename}\0{content}\n".encode())
    return digest.hexdigest()


def written_by_export(path: Path) -> bool:
    """``path`` is an SSP archive an ``auv-cosim export`` wrote, unchanged since (its seal
    matches its members)."""
    try:
        with zipfile.ZipFile(path) as archive:
            seal = archive.comment
            return seal.startswith(ARCHIVE_SEAL) and seal[len(ARCHIVE_SEAL) :].decode() == (
                members_digest(archive)
            )
    except (OSError, UnicodeDecodeError, zipfile.BadZipFile, ValueError):
        return False


def _seal(path: Path) -> None:
    """Put the seal of the complete archive at ``path`` in its zip comment."""
    with zipfile.ZipFile(path, "a") as archive:
        archive.comment = ARCHIVE_SEAL + members_digest(archive).encode()


@contextmanager
def replacing_file(path: Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield a new temporary file beside ``path`` for a zip archive; on success it is sealed
    and replaces ``path`` atomically.

    An existing ``path`` is replaced only if an earlier export wrote it (unchanged), or
    ``overwrite``. (Not ``tempfile.mkstemp``: its files are private (0600); this one gets
    the umask's permissions like any file the user writes.)

    Raises:
        CosimError: ``path`` is a folder, another file (without ``overwrite``) or cannot be
            written (nothing is left behind).
    """
    if path.is_dir():
        raise CosimError(f"cannot write {path}: it is a folder")
    if os.path.lexists(path) and not overwrite and not written_by_export(path):
        raise CosimError(
            f"cannot write {path}: it exists and is not an archive auv-cosim export wrote "
            "(or it was changed since); pass --force to replace it, or choose another file"
        )
    _refuse_file_on_the_way(path, path)
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.open("xb").close()
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
    try:
        yield tmp
        _seal(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
    finally:
        tmp.unlink(missing_ok=True)


def _refuse_file_on_the_way(path: Path, shown: Path) -> None:
    """Refuse ``path`` (named ``shown``) when a folder it lies in is a file: the folders
    made for it would fail with the system's bare "File exists" or "Not a directory"."""
    for parent in reversed(path.parents):
        if parent.exists() and not parent.is_dir():
            raise CosimError(f"cannot write {shown}: {parent} is a file, not a folder")


def _check_earlier_export(folder: Path, shown: Path | None = None) -> None:
    """Refuse ``folder`` unless it is empty or holds an earlier export, unchanged: every
    entry a regular file its record lists with that content. Raises CosimError, naming
    the folder as ``shown`` (as the user wrote it; ``folder`` by default)."""
    shown = folder if shown is None else shown
    entries = sorted(p.name for p in folder.iterdir() if p.name != EXPORT_RECORD)
    if not entries:
        return
    try:
        record = json.loads((folder / EXPORT_RECORD).read_text(encoding="utf-8"))["files"]
        if os.path.islink(folder / EXPORT_RECORD) or not isinstance(record, dict):
            raise ValueError("not a record")
    except (OSError, ValueError, KeyError, TypeError):
        raise CosimError(
            f"cannot write {shown}: it is not empty and holds no record of an earlier export "
            f"({', '.join(entries[:3])}); choose a new or empty folder"
        ) from None
    for name in entries:
        path = folder / name
        if path.is_symlink() or not path.is_file() or record.get(name) != _sha256(path):
            raise CosimError(
                f"cannot write {shown}: {name} is not a file an export wrote (yours, or "
                "changed since); move it away or choose a new or empty folder"
            )


def _sha256(path: Path) -> str:
    with path.open("rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def _check_again(old: Path, folder: Path, shown: Path) -> None:
    """The earlier export, just moved from ``folder`` to ``old``, is still only that (no
    file came in since the first check); else it goes back and CosimError is raised."""
    try:
        _check_earlier_export(old, shown)
    except CosimError:
        old.rename(folder)
        raise


def _is_working_folder(folder: Path) -> bool:
    try:
        return os.path.samefile(folder, os.getcwd())
    except OSError:  # no working folder (removed since): not this one
        return False


@contextmanager
def replacing_folder(folder: Path) -> Iterator[Path]:
    """Yield a new temporary folder beside ``folder``; on success it is recorded
    (:data:`EXPORT_RECORD`) and takes ``folder``'s place.

    An earlier export there (every file one an export wrote, unchanged) is replaced; an
    empty folder is used; anything else there is an error (an export never removes a file
    it did not write).

    Raises:
        CosimError: ``folder`` holds something else, is the working folder or cannot be
            written (nothing is left behind, an earlier export stays).
    """
    given = folder
    try:  # the folder a name like "." or "out/.." points to: its temporary sibling goes
        # beside that folder, not beside one named "." or ".."
        folder = Path(os.path.abspath(folder))
    except OSError as exc:  # a relative name, and the working folder was removed
        raise CosimError(f"cannot write {given}: {unwritten(exc)}") from None
    if folder.is_symlink() or (folder.exists() and not folder.is_dir()):
        raise CosimError(f"cannot write {given}: it exists and is not a folder")
    if folder.exists():
        if _is_working_folder(folder):
            raise CosimError(
                f"cannot write {given}: it is the working folder, which an export would "
                "replace as a whole; give a folder inside it or beside it (--osp NAME)"
            )
        _check_earlier_export(folder, given)
    _refuse_file_on_the_way(given, given)
    tag = secrets.token_hex(4)
    tmp = folder.parent / f".{folder.name}.{tag}.tmp"
    old = folder.parent / f".{folder.name}.{tag}.old"
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp.mkdir()
        yield tmp
        files = {p.name: _sha256(p) for p in sorted(tmp.iterdir())}
        (tmp / EXPORT_RECORD).write_text(json.dumps({"files": files}, indent=1) + "\n")
        if folder.exists():
            folder.rename(old)
            _check_again(old, folder, given)
        tmp.rename(folder)
    except OSError as exc:
        if old.exists() and not folder.exists():
            old.rename(folder)
        raise CosimError(f"cannot write {given}: {unwritten(exc)}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        if old.exists() and folder.exists():
            shutil.rmtree(old, ignore_errors=True)
