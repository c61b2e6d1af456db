"""The one exception type the command line turns into a one-line reason."""

from pathlib import Path


class CosimError(Exception):
    """A user-facing failure: bad scenario, failed FMU call, unwritable output, ..."""


def unmade_folder(folder: Path, exc: OSError) -> str:
    """Why ``folder`` could not be made (``mkdir`` raised ``exc``), in a few words."""
    return "it is not a folder" if folder.exists() else exc.strerror or str(exc)
