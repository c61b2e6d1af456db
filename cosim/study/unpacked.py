"""A local study's FMUs extracted once, by its client, for every worker.

Each worker process extracted each FMU (~0.02 s). A local cluster's workers share the
client's disk, so the client extracts each FMU (by content) into a folder of its own while
it waits for its cluster to start (:func:`unpack`); each worker then uses that folder
(:func:`use_unpacked`, from the study plugin's set-up). A worker elsewhere (a remote
cluster) gets no folders and extracts its FMUs itself, as before. Our FMUs carry their
code compiled (:mod:`cosim.fmus.bytecode`), so neither the client nor a worker compiles
it (that was ~0.2 s of the client's CPU before its workers could start).
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from pathlib import Path

MODEL_DESCRIPTION = "modelDescription.xml"


def unpack(fmu_paths: Mapping[str, Path], folder: Path) -> dict[str, str]:
    """Extract each FMU into ``folder``/<SHA-256 of its file>/ (once per content);
    returns SHA-256 -> that folder (absolute). An FMU larger than the limit or the free
    space there is refused before a byte is written
    (:class:`cosim.fmus.interface.FmuInterfaceError`, from
    :func:`cosim.fmus.interface.extract_fmu`)."""
    from cosim.fmus.interface import extract_fmu

    found: dict[str, str] = {}
    for path in fmu_paths.values():
        digest = hashlib.sha256(path.read_bytes()).hexdigest()
        target = (folder / digest).resolve()
        if not (target / MODEL_DESCRIPTION).is_file():
            extract_fmu(path, target)
        found[digest] = str(target)
    return found


def use_unpacked(unpacked: Mapping[str, str]) -> None:
    """In a worker: use the folders :func:`unpack` made (those that exist here) for the
    FMUs of that content, instead of extracting them again."""
    from cosim.engine.slave import share_unzipped

    for digest, folder in unpacked.items():
        if (Path(folder) / MODEL_DESCRIPTION).is_file():
            share_unzipped(digest, Path(folder))
