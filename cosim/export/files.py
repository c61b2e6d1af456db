"""Writing an export without leaving anything partial: build beside, then rename into place."""

from __future__ import annotations

import os
import secrets
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from cosim.errors import CosimError


@contextmanager
def replacing_file(path: Path) -> Iterator[Path]:
    """Yield a new temporary file beside ``path``; on success it replaces ``path`` atomically.

    (Not ``tempfile.mkstemp``: its files are private (0600); this one gets the umask's
    permissions like any file the user writes.)

    Raises:
        CosimError: ``path`` is a folder or cannot be written (nothing is left behind).
    """
    if path.is_dir():
        raise CosimError(f"cannot write {path}: it is a folder")
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

    An earlier export there (a folder holding the file ``marker``) is replaced; an empty
    folder is used; anything else there is an error.

    Raises:
        CosimError: ``folder`` holds something else or cannot be written (nothing is left
            behind, an earlier export stays).
    """
    if folder.exists():
        if not folder.is_dir():
            raise CosimError(f"cannot write {folder}: it exists and is not a folder")
        if any(folder.iterdir()) and not (folder / marker).is_file():
            raise CosimError(
                f"cannot write {folder}: it is not empty and holds no {marker} from an "
                "earlier export; choose a new or empty folder"
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
