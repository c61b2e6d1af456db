"""Whether a Rerun viewer can read a recording: the version that wrote the file against the
viewer's own.

A Rerun viewer reads the recordings of its own version and of the one before (rerun's
"N+1" guarantee; older ones after ``rerun rrd migrate``, by a viewer of the next version
each time); a viewer of another version opened the file on an error inside its window,
naming no version. An ``.rrd`` file says which version wrote it: after its 4 magic bytes
(``RRF2``), the writer's major, minor and patch version, one byte each.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

Version = tuple[int, int, int]
VERSION_TIMEOUT = 30.0  # s for `rerun --version` to answer
_CLI_VERSION = re.compile(r"rerun-cli (\d+)\.(\d+)\.(\d+)")
_WRITTEN_VERSION_AT = slice(4, 7)  # the writer's major, minor, patch in the file's header


def written_by(rrd: Path) -> Version | None:
    """The Rerun version that wrote ``rrd`` (from its header), or None if unreadable or
    0.0 (no Rerun release: a file that only starts like a recording)."""
    try:
        with open(rrd, "rb") as file:
            header = file.read(8)
    except OSError:
        return None
    if len(header) < 8:
        return None
    major, minor, patch = header[_WRITTEN_VERSION_AT]
    return None if (major, minor) == (0, 0) else (major, minor, patch)


def viewer_version(executable: str) -> Version | None:
    """The version ``executable --version`` reports (``rerun-cli 0.41.0 ...``), or None
    if it does not say (it failed, timed out, or answered in another form)."""
    try:
        done = subprocess.run(
            [executable, "--version"],
            capture_output=True,
            text=True,
            timeout=VERSION_TIMEOUT,
            check=False,
        )
    except (OSError, subprocess.SubprocessError):
        return None
    found = _CLI_VERSION.search(done.stdout)
    if found is None:
        return None
    major, minor, patch = (int(part) for part in found.groups())
    return major, minor, patch


def version_problem(executable: str, rrd: Path) -> str | None:
    """One line saying why the viewer ``executable`` cannot be relied on to read ``rrd``
    (it is older than the Rerun that wrote it, or newer by more than one version), with
    what to install instead; None if it can, or if either version cannot be told."""
    written, viewer = written_by(rrd), viewer_version(executable)
    if written is None or viewer is None:
        return None
    if viewer[0] == written[0] and viewer[1] in (written[1], written[1] + 1):
        return None
    wrote, shown = _text(written), _text(viewer)
    return (
        f"{rrd} was written by Rerun {wrote} and the viewer {executable} is Rerun {shown}: "
        "a viewer reads the recordings of its own version and of the one before, so it may "
        f"show an error instead; open it with the viewer of rerun-sdk {wrote} "
        f"(`pip install rerun-sdk=={wrote}` puts `rerun` beside its Python)"
    )


def _text(version: Version) -> str:
    return ".".join(str(part) for part in version)
