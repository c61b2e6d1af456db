"""Which build's code an FMU instance runs: detect stale code instead of running it.

pythonfmu keeps an FMU's Python modules imported for the life of the process (see
:mod:`fmu_runtime.entry`): a second FMU whose modules have the same names (``plant_fmu``,
``fmu_runtime``, ...) runs the code the process imported first, whatever its own
extraction holds. That is right for a second load of the same build and wrong for any
other build. So every FMU carries a manifest, ``resources/fmu_sources.json``, written by
the build: its model identifier, its GUID and the SHA-256 of every Python and data file it
ships (``{"auv_plant.py": ..., "plant_fmu/model/dynamics.py": ...}``). At instantiation,
:func:`stale_code` compares every Python module the manifest names with the module of
that name in ``sys.modules`` and names every one whose source differs.

The digest of a loaded module is read from its source file the first time an instance
meets that module object (normally the instance whose import loaded it, from its own
extraction) and kept for the life of the process, so later instances need not read files
a host may since have deleted. Two builds of identical sources (a rebuild gives a new
GUID) run the same code and are accepted.
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

MANIFEST = "fmu_sources.json"
_FORMAT = 1


@dataclass(frozen=True)
class Build:
    """What a manifest says about one FMU build."""

    model: str  # model identifier
    guid: str
    sha256: dict[str, str]  # path inside resources/ -> SHA-256 of its bytes


# Process-wide by nature, like sys.modules: module name -> (the module object, the SHA-256
# of the source file it was loaded from, read when an instance first met that object).
_loaded: dict[str, tuple[ModuleType, str]] = {}


def manifest(model: str, guid: str, files: Mapping[str, bytes]) -> bytes:
    """The manifest of a build shipping ``files`` (path inside resources/ -> bytes)."""
    sha256 = {path: hashlib.sha256(data).hexdigest() for path, data in sorted(files.items())}
    document = {"format": _FORMAT, "model": model, "guid": guid, "sha256": sha256}
    return (json.dumps(document, indent=1) + "\n").encode()


def read_build(resources: str | Path | None) -> Build | None:
    """The build an extraction's ``resources`` folder holds; None without a manifest (a
    class constructed in-process, or by pythonfmu's builder).

    Raises:
        ValueError: the manifest is unreadable or of another format.
    """
    if resources is None:
        return None
    path = Path(resources) / MANIFEST
    if not path.is_file():
        return None
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
        if document.get("format") != _FORMAT:
            raise ValueError(f"format {document.get('format')!r}, expected {_FORMAT}")
        return Build(document["model"], document["guid"], dict(document["sha256"]))
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise ValueError(f"{path} is not a usable manifest: {exc}") from None


def stale_code(build: Build) -> str | None:
    """Why this process cannot run ``build`` (a module of another build is imported under
    one of its module names), or None when every imported one is this build's code.

    Only Python modules count: data files an instance reads from its own ``resources``.
    A module not imported yet will be imported by the instance; a namespace package has no
    code of its own (only its submodules count).
    """
    differing = []
    for path, expected in sorted(build.sha256.items()):
        name = _module_name(path)
        module = sys.modules.get(name) if name else None
        file = getattr(module, "__file__", None)
        if name is None or module is None or file is None:
            continue
        if _loaded_sha256(name, module, file) != expected:
            differing.append(f"{name} (from {file})")
    if not differing:
        return None
    shown = ", ".join(differing[:3]) + (f" and {len(differing) - 3} more" if differing[3:] else "")
    return (
        f"stale code: this process already imported {shown} from another build than this "
        f"{build.model}.fmu (GUID {build.guid}). pythonfmu keeps an FMU's Python modules for "
        "the life of the process, so this instance would run that code instead of its own: "
        "it refuses to initialise and to step. Load this FMU in a new process."
    )


def _module_name(path: str) -> str | None:
    """``plant_fmu/model/dynamics.py`` -> ``plant_fmu.model.dynamics``, ``plant_fmu/
    __init__.py`` -> ``plant_fmu``; None for a data file."""
    if not path.endswith(".py"):
        return None
    return path.removesuffix(".py").removesuffix("/__init__").replace("/", ".")


def _loaded_sha256(name: str, module: ModuleType, file: str) -> str:
    """The SHA-256 of ``file``, the source ``module`` was loaded from, read the first time an
    instance meets this module object (a file that cannot be read gives a non-digest)."""
    known = _loaded.get(name)
    if known is not None and known[0] is module:
        return known[1]
    try:
        sha256 = hashlib.sha256(Path(file).read_bytes()).hexdigest()
    except OSError as exc:
        sha256 = f"unreadable: {exc}"
    _loaded[name] = (module, sha256)
    return sha256
