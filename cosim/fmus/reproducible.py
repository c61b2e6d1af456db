"""Two builds of the same sources give the same FMU file, byte for byte.

What a build would otherwise stamp into the FMU, and what it holds instead:

* every zip entry's date: the time of the build in the local time zone (``zipfile``), or
  the modification time of an installed file (pythonfmu's binaries) -> the time
  ``SOURCE_DATE_EPOCH`` names (seconds since 1970-01-01 UTC, the variable packagers set for
  reproducible builds: https://reproducible-builds.org/specs/source-date-epoch/), else
  1980-01-01 00:00:00, the earliest date a zip entry holds;
* every entry's permission bits, from the umask or the installed file -> ``0644``, or
  ``0755`` for an entry that had an execute bit;
* ``generationDateAndTime`` of ``modelDescription.xml``: the build's time (pythonfmu) -> the
  time ``SOURCE_DATE_EPOCH`` names, or left out when it is unset (FMI 2.0 makes the
  attribute optional).

The GUID already is a function of the sources (:func:`cosim.fmus.build.guid`). What still
differs between two machines' builds: ``resources/fmu_runtime.txt`` names the Python the
FMU was built with (which its runtime starts) and the ``.pyc`` files are that Python's.
"""

from __future__ import annotations

import datetime
import os
import stat
import zipfile
from pathlib import Path

from cosim.errors import CosimError

VARIABLE = "SOURCE_DATE_EPOCH"
# The range of a zip entry's date (MS-DOS date and time), as seconds since 1970 UTC
_ZIP_FIRST = datetime.datetime(1980, 1, 1, tzinfo=datetime.UTC)
_ZIP_LAST = datetime.datetime(2107, 12, 31, 23, 59, 58, tzinfo=datetime.UTC)


def source_date() -> datetime.datetime | None:
    """The time ``SOURCE_DATE_EPOCH`` names (UTC), or None where it is unset or empty.

    Raises:
        CosimError: it is not a whole number of seconds >= 0 (naming its value).
    """
    text = os.environ.get(VARIABLE, "").strip()
    if not text:
        return None
    try:
        seconds = int(text)
        if seconds < 0:
            raise ValueError(text)
        return datetime.datetime.fromtimestamp(seconds, tz=datetime.UTC)
    except (ValueError, OverflowError, OSError):
        raise CosimError(
            f"{VARIABLE}={text!r}: expected a whole number of seconds since 1970-01-01 UTC, >= 0"
        ) from None


def stamp() -> str:
    """What a build is dated with, for the build's record beside the FMU: the seconds of
    ``SOURCE_DATE_EPOCH``, or ``none``; an FMU built under another is built again."""
    date = source_date()
    return "none" if date is None else str(int(date.timestamp()))


def generation_date() -> str | None:
    """``generationDateAndTime`` for a model description (ISO 8601, UTC), or None: left
    out where ``SOURCE_DATE_EPOCH`` is unset."""
    date = source_date()
    return None if date is None else date.strftime("%Y-%m-%dT%H:%M:%SZ")


def zip_date() -> tuple[int, int, int, int, int, int]:
    """Every entry's date: ``SOURCE_DATE_EPOCH``'s, within what a zip entry holds (1980 to
    2107), else 1980-01-01 00:00:00."""
    date = min(max(source_date() or _ZIP_FIRST, _ZIP_FIRST), _ZIP_LAST)
    return (date.year, date.month, date.day, date.hour, date.minute, date.second)


def normalize(fmu: Path) -> None:
    """Rewrite the zip ``fmu`` in place with every entry dated :func:`zip_date` and its
    permissions ``0644`` (``0755`` if it had an execute bit); names, order, content and
    compression kept."""
    when = zip_date()
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    partial = fmu.with_name(f".{fmu.name}.dated.tmp")
    try:
        with zipfile.ZipFile(partial, "w") as archive:
            for info, data in entries:
                archive.writestr(_dated(info, when), data)
        partial.replace(fmu)
    finally:
        partial.unlink(missing_ok=True)


def _dated(info: zipfile.ZipInfo, when: tuple[int, int, int, int, int, int]) -> zipfile.ZipInfo:
    """A copy of ``info`` with date ``when``, made on Unix, mode 0644 or 0755."""
    copy = zipfile.ZipInfo(info.filename, date_time=when)
    copy.compress_type = info.compress_type
    copy.create_system = 3  # Unix, whatever system builds it: the permission bits below
    executable = (info.external_attr >> 16) & 0o111
    kind = stat.S_IFDIR if info.is_dir() else stat.S_IFREG
    copy.external_attr = (kind | (0o755 if executable or info.is_dir() else 0o644)) << 16
    return copy
