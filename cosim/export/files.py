"""Writing an export without leaving anything partial: build beside, then rename into place."""

from __future__ import annotations

import os
import secrets
import shutil
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from cosim.errors import CosimError

SSP_GENERATOR = b'generationTool="auv-cosim export'  # in the SSD of an archive we wrote


def written_by_export(path: Path) -> bool:
    """``path`` is an SSP archive an earlier ``auv-cosim export`` wrote (its SSD says so)."""
    try:
        with zipfile.ZipFile(path) as archive:
            return SSP_GENERATOR in archive.read("SystemStructure.ssd")[:4096]
    except (OSError, KeyError, zipfile.BadZipFile, ValueError):
        return False


@contextmanager
def replacing_file(path: Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield a new temporary file beside ``path``; on success it replaces ``path`` atomically.

    An existing ``path`` is replaced only if an earlier export wrote it, or ``overwrite``.
    (Not ``tempfile.mkstemp``: its files are private (0600); this one gets the umask's
    permissions like any file the user writes.)

    Raises:
        CosimError: ``path`` is a folder, another file (without ``overwrite``) or cannot be
            written (nothing is left behind).
    """
    if path.is_dir():
        raise CosimError(f"cannot write {path}: it is a folder")
    if os.path.lexists(path) and not overwrite and not written_by_export(path):
        raise CosimError(
            f"cannot write {path}: it exists and is not an archive auv-cosim export wrote; "
            "pass --force to replace it, or choose another file"
        )
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.open("xb").close()
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def replacing_folder(folder: Path, marker: str) -> Iterator[Path]:
    """Yield a new temporary folder beside ``folder``; on success it takes ``folder``'s place.

    An earlier export there (a folder holding the file ``marker`` and FMUs, nothing else)
    is replaced; an empty folder is used; anything else there is an error (an export
    never removes a file it did not write).

    Raises:
        CosimError: ``folder`` holds something else or cannot be written (nothing is left
            behind, an earlier export stays).
    """
    if folder.exists():
        if not folder.is_dir():
            raise CosimError(f"cannot write {folder}: it exists and is not a folder")
        entries = list(folder.iterdir())
        if entries and not (folder / marker).is_file():
            raise CosimError(
                f"cannot write {folder}: it is not empty and holds no {marker} from an "
                "earlier export; choose a new or empty folder"
            )
        other = sorted(p.name for p in entries if p.name != marker and p.suffix != ".fmu")
        if other or any(p.is_symlink() or not p.is_file() for p in entries):
            shown = ", ".join(other[:3]) or "a folder or link"
            raise CosimError(
                f"cannot write {folder}: it holds files an export does not write ({shown}); "
                "move them away or choose a new or empty folder"
            )
    tag = secrets.token_hex(4)
    tmp = folder.parent / f".{folder.name}.{tag}.tmp"
    old = folder.parent / f".{folder.name}.{tag}.old"
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp.mkdir()
        yield tmp
        if folder.exists():
            folder.rename(old)
        tmp.rename(folder)
    except OSError as exc:
        if old.exists() and not folder.exists():
            old.rename(folder)
        raise CosimError(f"cannot write {folder}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)
