"""Zip archives that declare more bytes than they hold: what a zip bomb tells its reader
before it is unpacked, made in milliseconds (a real one takes seconds per GiB to deflate)."""

from __future__ import annotations

import zipfile
from collections.abc import Mapping
from pathlib import Path

FMI2_DESCRIPTION = '<fmiModelDescription fmiVersion="2.0" modelName="Bomb" guid="{0}"/>'


def declaring_archive(
    path: Path, sizes: Mapping[str, int], description: bytes = FMI2_DESCRIPTION.encode()
) -> Path:
    """A zip at ``path`` holding ``modelDescription.xml`` (``description``) and one entry
    per name in ``sizes`` (one byte each; the description's own text if it is named) whose
    central directory declares that many bytes unpacked (zip64 above 4 GiB): a reader that
    trusts the declaration can refuse it before reading anything."""
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        if "modelDescription.xml" not in sizes:
            archive.writestr("modelDescription.xml", description)
        for name, size in sizes.items():
            archive.writestr(name, description if name == "modelDescription.xml" else b"\0")
            archive.getinfo(name).file_size = size  # the central directory, written at close
    return path
