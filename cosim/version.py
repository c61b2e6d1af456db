"""This package's version, from its one source: ``version`` in pyproject.toml.

Everything that states the version reads it here: ``auv-cosim --version``,
``cosim.__version__``, the FMUs' ``modelDescription.xml`` (``version`` and
``generationTool``, and through the build's source hash their GUID), and a run's
summary.json (``versions``). Run from a source tree (a checkout, installed editable or not
installed at all), the pyproject.toml beside the packages is read: an editable install's
metadata keeps the version it was installed at, so a version bumped since would otherwise
be stated as the old one (and the FMUs built with it). Installed from a wheel or an sdist,
it is the distribution's metadata, which the build wrote from that same pyproject.toml.
"""

from __future__ import annotations

import functools
import importlib.metadata
import tomllib
from pathlib import Path

DISTRIBUTION = "auv-cosim"
# pyproject.toml of the source tree this package is imported from, if it is one
_PYPROJECT = Path(__file__).resolve().parent.parent / "pyproject.toml"


@functools.cache
def version() -> str | None:
    """This package's version (``"0.1.0"``), or None where neither a source tree's
    pyproject.toml nor an installed distribution states one."""
    declared = _source_tree_version()
    if declared is not None:
        return declared
    try:
        return importlib.metadata.version(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return None


def _source_tree_version() -> str | None:
    """``project.version`` of the pyproject.toml beside the packages when it is this
    project's (a site-packages folder may hold another's), else None."""
    try:
        project = tomllib.loads(_PYPROJECT.read_text(encoding="utf-8")).get("project", {})
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None
    declared = project.get("version")
    if project.get("name") != DISTRIBUTION or not isinstance(declared, str):
        return None
    return declared
