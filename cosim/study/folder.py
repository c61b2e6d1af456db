"""The study folder: what study it holds (``study.json``), and the kept per-run folders.

``study.json`` records what the table's rows depend on: the study file's settings, the
resolved scenario, the FMUs' content hashes and those of every other file the scenario
reads (a vehicle set, a series CSV). A new study needs a new or empty folder (a folder
holding anything else is refused: a study never writes over a user's ``index.html`` or
into their ``figures/``) and refuses one that already holds a study; ``--resume`` refuses
a folder whose study differs (another scenario, other factors or metrics, rebuilt FMUs, a
changed vehicle file), so a table never mixes two studies; a ``study.json`` an older
auv-cosim wrote is read as this version writes it (:func:`_as_written_now`). A study
locks its folder for as long as it runs (:func:`lock`, the run folder's lock): a second
study into it, resumed or not, is refused at once.

Per-run folders ``runs/<run id>/`` (only with ``keep = "all"`` or ``"failed"``) hold the
scenario the run ran (``scenario.toml``, for ``auv-cosim run``), its ``results.csv`` and
``summary.json`` when it got that far, and ``error.txt`` when it failed.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import stat
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

from cosim.errors import FLAGS, CosimError, OptionNames
from cosim.outputs.folder import LOCK_FILE, lock_folder, unlock_folder
from cosim.study.spec import StudyError
from cosim.viz.rrd_file import STUDY_FILE
from cosim.whole_file import write_whole

STUDY_JSON = STUDY_FILE
RUNS_FOLDER = "runs"


@contextlib.contextmanager
def lock(out_dir: Path, names: OptionNames = FLAGS) -> Iterator[bool]:
    """Create (if needed) and lock ``out_dir`` while the study runs; yields whether it was
    created. A folder this made is removed again if the study left nothing in it.
    ``names``: how a refusal names the options (the command's flags or the API's
    keywords)."""
    created = not out_dir.exists()
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        why = "exists and is not a folder" if out_dir.exists() else exc.strerror or str(exc)
        shown = names.given("out", out_dir)
        raise StudyError(f"{shown}: cannot create the study folder: {why}") from None
    try:
        fd = lock_folder(out_dir, "study")
    except CosimError as exc:
        if created:
            with contextlib.suppress(OSError):
                out_dir.rmdir()
        raise StudyError(str(exc)) from None
    try:
        yield created
    finally:
        unlock_folder(out_dir, fd)
        if created:
            with contextlib.suppress(OSError):
                out_dir.rmdir()  # only if empty


def claim(
    out_dir: Path,
    identity: Mapping[str, Any],
    resume: bool,
    table: str,
    names: OptionNames = FLAGS,
) -> None:
    """Make the locked ``out_dir`` this study's folder, or check it already is
    (``resume``). ``table``: the table's file name (a folder holding one holds a study);
    ``names``: how a refusal names the options (``--resume``, or ``resume=True``)."""
    marker = out_dir / STUDY_JSON
    identity = json.loads(json.dumps(identity))  # as it reads back from the file
    resuming, out = names.switch("resume"), names.option("out")
    if resume:
        if not marker.is_file():
            raise StudyError(f"{resuming}: {out_dir} holds no study ({STUDY_JSON} is missing)")
        link = _first_link(out_dir)
        if link is not None:
            raise StudyError(
                f"{resuming}: {out_dir} holds {link[0]}, a {link[1]} (from wherever the folder "
                "came): the study would write over what it names; remove it, or give another "
                f"{out} to start this study"
            )
        stored = _as_written_now(json.loads(marker.read_text(encoding="utf-8")), identity)
        differ = sorted(k for k in {*stored, *identity} if stored.get(k) != identity.get(k))
        if differ:
            changes = [_with_keys(k, stored.get(k), identity.get(k)) for k in differ]
            raise StudyError(
                f"{resuming}: {out_dir} holds another study (it differs from this one in: "
                f"{', '.join(changes)}{_changed_files(stored, identity)}); give another "
                f"{out} to start this study"
            )
        return
    if marker.exists() or (out_dir / table).exists():
        raise StudyError(
            f"{out_dir} already holds a study: add {resuming} to continue it, or give another {out}"
        )
    entries = sorted(p.name for p in out_dir.iterdir() if p.name != LOCK_FILE)
    if entries:
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise StudyError(
            f"{names.given('out', out_dir)}: the folder is not empty ({shown}) and holds no "
            "study; choose a new or empty folder"
        )
    text = json.dumps(identity, indent=2) + "\n"
    write_whole(marker, lambda tmp: tmp.write_text(text, encoding="utf-8"))  # never a part


def _as_written_now(stored: dict[str, Any], identity: Mapping[str, Any]) -> dict[str, Any]:
    """A ``study.json`` an older auv-cosim wrote, with what it left out as this version
    writes it, so that only what changed the rows differs: before the scenario's files were
    recorded (``files``), a study whose scenario reads none besides its FMUs recorded no
    key; before ``[coupling] extrapolation`` existed, the master held every exchanged value
    across a step (``"none"``)."""
    upgraded = dict(stored)
    if "files" not in upgraded and identity.get("files", None) == {}:
        upgraded["files"] = {}
    scenario = upgraded.get("scenario")
    coupling = scenario.get("coupling") if isinstance(scenario, dict) else None
    if (
        isinstance(scenario, dict)
        and isinstance(coupling, dict)
        and "extrapolation" not in coupling
    ):
        upgraded["scenario"] = {**scenario, "coupling": {**coupling, "extrapolation": "none"}}
    return upgraded


def _first_link(out_dir: Path) -> tuple[str, str] | None:
    """The first entry below ``out_dir`` (its relative path, and "symbolic link" or "hard
    link") that a resumed study would write through: a symbolic link, or a file of more
    than one name; None if there is none. Links are not followed."""
    for folder, dirs, files in os.walk(out_dir):
        dirs.sort()
        for name in sorted(dirs + files):
            path = Path(folder, name)
            info = path.lstat()
            kind = "symbolic link" if stat.S_ISLNK(info.st_mode) else None
            if kind is None and stat.S_ISREG(info.st_mode) and info.st_nlink > 1:
                kind = "hard link"
            if kind is not None:
                return path.relative_to(out_dir).as_posix(), kind
    return None


SHOWN_KEYS = 3  # differing keys a --resume refusal names
SHOWN_VALUE_CHARS = 40  # a value longer than that is cut in the refusal


def _with_keys(section: str, old: Any, new: Any) -> str:
    """A differing section of study.json as the refusal names it: the study file's and
    the resolved scenario's differing keys with both values (``study (random.seed: 11
    in the folder, 12 now)``); the FMUs by instance, and why they differ; the files by name
    alone."""
    if section == "fmus":
        return _changed_fmus(old, new)
    if section not in ("study", "scenario"):
        return section
    keys = _differing_keys(old, new)
    shown = "; ".join(
        f"{key}: {_value(a)} in the folder, {_value(b)} now" for key, a, b in keys[:SHOWN_KEYS]
    )
    return f"{section} ({shown}{'; ...' if len(keys) > SHOWN_KEYS else ''})" if keys else section


def _changed_fmus(old: Any, new: Any) -> str:
    """The instances whose FMU is not the build the folder's runs used, and why that is
    likely: ``fmus (controller, plant: ...)``."""
    old, new = (value if isinstance(value, dict) else {} for value in (old, new))
    changed = sorted(k for k in {*old, *new} if old.get(k) != new.get(k))
    return (
        f"fmus ({', '.join(changed)}: not the builds its runs used, as after an upgrade of "
        "auv-cosim, which rebuilds its FMUs)"
    )


def _differing_keys(old: Any, new: Any, prefix: str = "") -> list[tuple[str, Any, Any]]:
    """(dotted key, old value, new value) for each leaf that differs (absent: None)."""
    if not (isinstance(old, dict) and isinstance(new, dict)):
        return [] if old == new else [(prefix.rstrip("."), old, new)]
    return [
        difference
        for key in sorted({*old, *new})
        for difference in _differing_keys(old.get(key), new.get(key), f"{prefix}{key}.")
    ]


def _value(value: Any) -> str:
    text = "absent" if value is None else json.dumps(value, ensure_ascii=False)
    return text if len(text) <= SHOWN_VALUE_CHARS else f"{text[: SHOWN_VALUE_CHARS - 3]}..."


def _changed_files(stored: Mapping[str, Any], identity: Mapping[str, Any]) -> str:
    """'; changed: <file>' naming the scenario's files whose content changed."""
    old, new = stored.get("files") or {}, identity.get("files") or {}
    changed = sorted(k for k in {*old, *new} if old.get(k) != new.get(k))
    return f"; changed: {', '.join(changed[:3])}" if changed else ""


def discard_new(out_dir: Path, table: str) -> None:
    """Remove what a new study that ran nothing wrote (its study.json and empty table),
    so the next attempt is not refused as a study already there."""
    for name in (STUDY_JSON, table):
        with contextlib.suppress(OSError):
            (out_dir / name).unlink()


def keep_run(
    out_dir: Path, run_id: str, scenario: str, files: Mapping[str, bytes], error: str | None
) -> Path:
    """Write one run's folder: its scenario, the files it returned, its error; each file
    whole or not at all. Raises OSError naming the file that could not be written."""
    folder = out_dir / RUNS_FOLDER / run_id
    folder.mkdir(parents=True, exist_ok=True)
    contents = {"scenario.toml": scenario.encode("utf-8"), **files}
    if error is not None:
        contents["error.txt"] = (error + "\n").encode("utf-8")
    for name, content in contents.items():
        write_whole(folder / name, functools.partial(Path.write_bytes, data=content))
    return folder
