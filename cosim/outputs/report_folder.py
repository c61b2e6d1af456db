"""A run folder's ``report/``: which of its files ``auv-cosim report`` wrote, which run it
describes, and whether that run is still the folder's.

The report writes :data:`REPORT_MANIFEST` beside its files: each file it wrote with what
identifies it (:func:`cosim.outputs.tail_guard.file_identity`) and the stamp of the run it
was made from (:func:`run_stamp`: the scenario, its status and the SHA-256 of its
results.csv). :func:`check_writable` refuses to write over a file in ``report/`` that no
report wrote, or that changed since (a user's own ``index.html``; a copy of a file it
wrote, in a run folder copied whole, is still its own: :func:`_as_written`); :func:`mark_stale` is
called when a run replaces the one a kept report was made from: the page gets a banner
saying so (only a page the report wrote, unchanged).

Standard library only (the run folder uses it before any heavy import), and the reading
of ``SOURCE_DATE_EPOCH`` (:mod:`cosim.fmus.reproducible`, itself standard library only).
"""

from __future__ import annotations

import html
import json
import os
import time
from collections.abc import Iterable
from pathlib import Path
from typing import Any

from cosim.errors import CosimError
from cosim.fmus.reproducible import source_date
from cosim.outputs.run_files import RESULTS_FILE, SUMMARY_FILE, regular, unchanged, write_atomically
from cosim.outputs.tail_guard import IDENTITY_KEYS, file_identity

REPORT_MANIFEST = ".auv-cosim-report.json"
STALE_MARK = '<p class="stale">'  # the banner's opening tag on a stale page


def local_time(strict: bool = True) -> str:
    """The local time now, as a report's page and its stale banner say it:
    ``2026-12-06 16:53:23 +0900``, its offset from UTC in digits. A zone's name comes from
    TZ and the locale: a misspelt ``TZ=Europe/Berln``, which the C library reads as UTC,
    named it "Europe". Where ``SOURCE_DATE_EPOCH`` is set (a reproducible build of pages
    that show reports), that time in UTC instead, so the same run makes the same page.
    Raises CosimError for a SOURCE_DATE_EPOCH that is no time, unless not ``strict`` (a
    run's stale banner: the run goes on, the banner dated by the clock)."""
    try:
        date = source_date()
    except CosimError:
        if strict:
            raise
        date = None
    return (
        time.strftime("%Y-%m-%d %H:%M:%S %z") if date is None else f"{date:%Y-%m-%d %H:%M:%S} +0000"
    )


def run_stamp(run_dir: Path) -> dict[str, Any]:
    """Which run a report describes: scenario, status and the SHA-256 of results.csv."""
    summary: dict[str, Any] = {}
    try:
        loaded = json.loads((run_dir / SUMMARY_FILE).read_text(encoding="utf-8"))
        summary = loaded if isinstance(loaded, dict) else {}
    except (OSError, ValueError):
        pass
    results = file_identity(run_dir / RESULTS_FILE)
    return {
        "scenario": summary.get("scenario"),
        "status": summary.get("status"),
        "results_sha256": None if results is None else results["sha256"],
    }


def read_report_manifest(folder: Path) -> dict[str, Any] | None:
    """The report manifest in ``folder`` (None if missing or not ours)."""
    path = folder / REPORT_MANIFEST
    if not regular(path):
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        files = {str(k): {key: v[key] for key in IDENTITY_KEYS} for k, v in data["files"].items()}
        return {**data, "files": files}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return None


def check_writable(folder: Path, names: Iterable[str]) -> None:
    """Refuse to write ``folder`` (a run's ``report/``) if it is not a folder, or if one of
    the files ``names`` exists there and is not exactly what an earlier report wrote.
    Raises CosimError naming the file."""
    if os.path.islink(folder) or (os.path.lexists(folder) and not folder.is_dir()):
        raise CosimError(f"cannot write the report into {folder}: it is not a folder")
    manifest = read_report_manifest(folder) or {"files": {}}
    for name in names:
        path = folder / name
        if not os.path.lexists(path):
            continue
        identity = manifest["files"].get(name)
        if identity is None or not _as_written(path, identity):
            raise CosimError(
                f"cannot write the report into {folder}: {name} is not a file a report wrote "
                "(your own, or changed since); move it away and run the report again"
            )


def _as_written(path: Path, identity: dict[str, Any]) -> bool:
    """``path`` is the regular file a report wrote as ``identity`` describes it: that file
    unchanged, or a copy of it, the same bytes (a run folder copied whole, as one does to
    report a run one can only read: other device, inode and time). A run's own files are
    known by their inode too (:mod:`cosim.outputs.run_files`); a report's page or figure
    holding what the report wrote is the report's, wherever it was copied."""
    if unchanged(path, identity):
        return True
    now = file_identity(path)
    return now is not None and all(now[k] == identity[k] for k in ("size", "sha256"))


def remove_earlier(folder: Path, keep: Iterable[str]) -> None:
    """Remove the files an earlier report wrote that this one does not (unchanged ones
    only): a figure of another run stays no longer."""
    manifest = read_report_manifest(folder)
    if manifest is None:
        return
    kept = set(keep)
    for name, identity in manifest["files"].items():
        path = folder / name
        if name not in kept and "/" not in name and _as_written(path, identity):
            path.unlink(missing_ok=True)


def record(folder: Path, written: Iterable[Path], stamp: dict[str, Any]) -> None:
    """Write the report manifest: the files written (with their identities) and the stamp.
    Raises OSError."""
    files = {p.name: identity for p in written if (identity := file_identity(p)) is not None}
    write_atomically(folder / REPORT_MANIFEST, json.dumps({"run": stamp, "files": files}))


def mark_stale(folder: Path, note: str) -> bool:
    """Put a banner saying ``note`` (the report describes a run that was replaced) at the
    top of the report's page, if the report wrote it and it is unchanged; whether it did.
    Never raises."""
    manifest = read_report_manifest(folder)
    page = folder / "index.html"
    if manifest is None or "index.html" not in manifest["files"]:
        return False
    if not _as_written(page, manifest["files"]["index.html"]):
        return False
    try:
        text = page.read_text(encoding="utf-8")
        if STALE_MARK not in text:
            banner = f"{STALE_MARK}<strong>Stale: {html.escape(note)}</strong></p>\n"
            text = text.replace("<body>\n", f"<body>\n{banner}", 1)
            write_atomically(page, text)
        manifest["run"]["stale"] = note
        record(folder, [folder / name for name in manifest["files"]], manifest["run"])
    except (OSError, KeyError, TypeError):
        return False
    return True
