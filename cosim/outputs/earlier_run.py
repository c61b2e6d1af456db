"""An earlier run in a run folder: found at the claim, set aside before the new run opens
its outputs, removed once the new run has taken its first step, or put back if it never
does.

:func:`find_earlier_run` reads the folder's summary.json and manifest
(:mod:`cosim.outputs.run_files`) and lists the earlier run's own files: those the manifest
names that are still regular files with the identity it records, inside the folder and
reached through no link, plus the manifest itself and the temporary files of that run's
process (``.summary.json.<pid>.tmp``...). Never a folder (a ``report/`` made from the run
stays), never what summary.json's ``outputs`` merely lists, never a file outside the
folder (a ``--rrd`` elsewhere stays). A folder holding other files beside them, with no
earlier run, is refused: a run never mixes its files with someone else's.

:class:`SetAside` renames such files to ``.<name>.<pid>.auv-cosim-earlier`` beside
themselves, checking each file's identity again just before and just after the rename (a
file changed since the claim is left where it is, and everything set aside so far goes
back); :meth:`SetAside.commit` removes them, checking once more; :meth:`SetAside.restore`
renames them back. Each move is told to the tail guard (``tell``), which puts them back
itself if the run is killed before it commits.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.errors import FLAGS, OptionNames
from cosim.outputs.run_files import (
    CHECKPOINT_FILE,
    LOCK_FILE,
    MANIFEST_FILE,
    OUTPUT_NAMES,
    REPORT_FOLDER,
    RUN_STATUSES,
    SCENARIO_FILE,
    SUMMARY_FILE,
    RunFolderError,
    read_manifest,
    regular,
    unchanged,
)
from cosim.outputs.tail_guard import file_identity, head_sha256

ASIDE_SUFFIX = ".auv-cosim-earlier"
_ASIDE = re.compile(r"^\..+\.\d+" + re.escape(ASIDE_SUFFIX) + "$")


@dataclass(frozen=True)
class ScenarioRef:
    """Which scenario a default run folder belongs to: its id and the file it was read
    from (absolute; None for a scenario made in memory)."""

    id: str
    file: str | None


@dataclass
class EarlierRun:
    """An earlier run of ours in a run folder: its summary, its own files (each with the
    identity it must still have when it is removed) and what stays (said)."""

    summary: dict
    files: dict[Path, dict[str, Any]]
    kept: list[str] = field(default_factory=list)


def find_earlier_run(
    path: Path,
    overwrite: bool,
    default: ScenarioRef | None,
    names: OptionNames = FLAGS,
    resuming: bool = False,
) -> EarlierRun | None:
    """The earlier run in ``path`` (None if the folder is empty). It may be replaced with
    ``overwrite``, or when ``path`` is the default folder of scenario ``default``, holds
    nothing but an earlier run of that same scenario file (and a report made from it).
    A refusal names the options as ``names`` does (flags or keywords), and the folder as
    ``--resume`` gave it where ``resuming``.

    ``resuming`` (the run in ``path`` continues from its checkpoint): a file the manifest
    lists is the run's own if it holds exactly what the run wrote (size and SHA-256), so a
    run folder copied whole (``cp -a``, ``rsync``: new device, inode and perhaps time)
    resumes; so is one whose first bytes are what the run wrote up to the checkpoint the
    folder holds (its entry's ``checkpoint``: results.csv of a run killed with its tail
    guard, the rows after it rewritten by the resume); it is set aside as it is now.

    Raises RunFolderError: files set aside by a run killed before it stepped, files of no
    run, a summary or manifest not ours, a run an older auv-cosim wrote without a
    manifest, an earlier run not to be replaced, or an output name that is not the earlier
    run's own file.
    """
    option = "resume" if resuming else "out"
    entries = sorted(e.name for e in path.iterdir() if e.name not in (LOCK_FILE, MANIFEST_FILE))
    left = [e for e in entries if _ASIDE.match(e)]
    if left:
        raise RunFolderError(
            f"{names.given(option, path)}: holds files a run set aside and could not put back ("
            f"{', '.join(left[:3])}): rename each back to the name between the leading dot "
            f"and .<pid>{ASIDE_SUFFIX}, or remove them"
        )
    if not entries:
        return None
    summary = _summary(path, entries, names, option)
    _refuse_older_run(path, summary, names, option)
    manifest = read_manifest(path, names, option)
    own = _own_files(path, manifest.entries, by_content=resuming)
    own[path / MANIFEST_FILE] = file_identity(path / MANIFEST_FILE) or {}
    # its partial writes, if killed
    for name in (SUMMARY_FILE, SCENARIO_FILE, MANIFEST_FILE, CHECKPOINT_FILE):
        tmp = path / f".{name}.{manifest.pid}.tmp"
        identity = file_identity(tmp) if regular(tmp) else None
        if identity is not None:
            own[tmp] = identity
    tops = {p.relative_to(path).parts[0] for p in own}
    foreign = [e for e in entries if e not in tops and e != REPORT_FOLDER]
    _check_replaceable(path, summary, overwrite, default, foreign, names)
    for name in OUTPUT_NAMES:  # the new run would write over these: they must be the run's
        if os.path.lexists(path / name) and path / name not in own:
            raise RunFolderError(
                f"{names.given(option, path)}: {name} is not a file the earlier run wrote "
                f"(changed since, replaced, or a link); {_what_to_do(resuming)}"
            )
    kept = [f"{REPORT_FOLDER}/"] if (path / REPORT_FOLDER).exists() else []
    kept += [n for n in manifest.entries if Path(n).is_absolute() and os.path.lexists(n)]
    return EarlierRun(summary, own, kept)


# what every summary.json an auv-cosim run wrote holds, from the first version on
_OLDEST_SUMMARY_KEYS = ("stop_time", "wall_clock_s", "final_values")


def _what_to_do(resuming: bool) -> str:
    """What a refusal of a file in the folder tells the user to do."""
    if resuming:  # (a copy whose content differs: the run it holds is not the one checkpointed)
        return "resume the folder it was checkpointed in, or start the run again"
    return "move it away or choose another folder"


def _refuse_older_run(path: Path, summary: dict, names: OptionNames, option: str) -> None:
    """Refuse, naming it as such, a run folder an auv-cosim wrote before runs listed their
    files (:data:`MANIFEST_FILE`): its summary is a run's, and no manifest is there."""
    if os.path.lexists(path / MANIFEST_FILE) or not all(
        key in summary for key in _OLDEST_SUMMARY_KEYS
    ):
        return
    raise RunFolderError(
        f"{names.given(option, path)}: holds an earlier run (scenario "
        f"{summary.get('scenario')!r}, status {summary.get('status')!r}) that an older "
        f"auv-cosim wrote, before runs listed their files in {MANIFEST_FILE}: none of its "
        "files is known to be the run's to replace; move the folder away or choose another "
        "folder"
    )


def _summary(path: Path, entries: list[str], names: OptionNames, option: str) -> dict:
    """The folder's summary.json, refused unless it is a run's of ours."""
    summary_path = path / SUMMARY_FILE
    if not regular(summary_path):
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise RunFolderError(
            f"{names.given(option, path)}: the folder is not empty ({shown}) and holds no "
            f"earlier run (no {SUMMARY_FILE}); choose a new or empty folder"
        )
    try:
        summary = json.loads(summary_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        summary = None
    if (
        not isinstance(summary, dict)
        or summary.get("status") not in RUN_STATUSES
        or not isinstance(summary.get("scenario"), str)
    ):
        raise RunFolderError(
            f"{names.given(option, path)}: its {SUMMARY_FILE} is not the summary of an "
            "auv-cosim run; choose a new or empty folder"
        )
    return summary


def _check_replaceable(
    path: Path,
    summary: dict,
    overwrite: bool,
    default: ScenarioRef | None,
    foreign: list[str],
    names: OptionNames,
) -> None:
    """Refuse to replace the earlier run in ``path`` unless ``overwrite`` or ``default``
    allows it (:func:`find_earlier_run`)."""
    if overwrite:
        return
    out = names.given("out", path)
    if default is not None:  # no --out was given: the folder is the scenario's default
        out = f"{path} (the default run folder of {default.id!r})"
    if default is not None and summary["scenario"] == default.id and not foreign:
        if summary.get("scenario_file") == default.file:
            return
        raise RunFolderError(
            f"{out}: the folder holds an earlier run of another scenario file with "
            f"the same id {default.id!r} ({summary.get('scenario_file') or 'unknown'}); pass "
            f"{names.switch('overwrite')} to replace it, or choose another folder with "
            f"{names.option('out')}"
        )
    what = f"scenario {summary['scenario']!r}, status {summary['status']!r}"
    others = ""  # in the scenario's default folder, what stopped it being reused
    if default is not None and summary["scenario"] == default.id:
        shown = ", ".join(foreign[:3]) + (", ..." if len(foreign) > 3 else "")
        others = f" and {shown}, which no run wrote ({names.switch('overwrite')} keeps them)"
    raise RunFolderError(
        f"{out}: the folder holds an earlier run ({what}){others}; pass "
        f"{names.switch('overwrite')} to replace it, or choose another folder"
    )


def _own_files(
    path: Path, entries: dict[str, dict[str, Any]], by_content: bool = False
) -> dict[Path, dict[str, Any]]:
    """The manifest's files inside ``path`` that are still exactly what the run wrote,
    reached through no link below ``path``, each with its identity now; ``by_content``:
    one of the same size and SHA-256 (a copy) is too, and one holding what the run wrote
    up to the folder's checkpoint (:func:`_checkpointed_content`)."""
    own = {}
    for name, identity in entries.items():
        parts = Path(name).parts
        if Path(name).is_absolute() or ".." in parts or not parts:
            continue  # outside the folder: never removed
        if any(os.path.islink(path.joinpath(*parts[:i])) for i in range(1, len(parts))):
            continue
        if unchanged(path / name, identity):
            own[path / name] = identity
        elif by_content:
            now = _same_content(path / name, identity)
            now = now or _checkpointed_content(path, name, identity)
            if now is not None:
                own[path / name] = now
    return own


def _same_content(path: Path, identity: dict[str, Any]) -> dict[str, Any] | None:
    """``path``'s identity now if it is a regular file of ``identity``'s size and SHA-256."""
    now = file_identity(path)
    if now is None or any(now[k] != identity[k] for k in ("size", "sha256")):
        return None
    return now


def _checkpointed_content(path: Path, name: str, identity: dict[str, Any]) -> dict[str, Any] | None:
    """``path / name``'s identity now if it is a regular file whose first bytes are those
    its entry's ``checkpoint`` says the run had written at a checkpoint (size, SHA-256:
    results.csv up to the checkpoint's last row, a recording's head), and that checkpoint
    is the folder's checkpoint.json (by its SHA-256)."""
    upto = identity.get("checkpoint")
    if not isinstance(upto, dict) or type(upto["size"]) is not int or upto["size"] < 0:
        return None
    saved = file_identity(path / CHECKPOINT_FILE)
    if saved is None or saved["sha256"] != upto["checkpoint_sha256"]:
        return None
    now = file_identity(path / name)
    if now is None or head_sha256(path / name, upto["size"]) != upto["sha256"]:
        return None
    return now


class SetAside:
    """Files of an earlier run renamed out of the way (see the module docstring);
    ``tell`` takes the lines for the tail guard."""

    def __init__(self, tell: Callable[[str], None]) -> None:
        self._tell = tell
        self.moved: list[tuple[Path, Path, dict[str, Any]]] = []  # original, aside, identity

    def move(self, target: Path, identity: dict[str, Any], shown: str) -> None:
        """Rename ``target`` aside if it is still the file ``identity`` describes.
        Raises RunFolderError (``shown`` names the folder) with everything put back."""
        aside = target.with_name(f".{target.name}.{os.getpid()}{ASIDE_SUFFIX}")
        changed = RunFolderError(
            f"{shown}: {target.name} changed since the run began (it is not the earlier "
            "run's file any more); it stays, and nothing was replaced"
        )
        if not unchanged(target, identity) or os.path.lexists(aside):
            self.restore()
            raise changed
        self._tell(f"aside {json.dumps([str(target.absolute()), str(aside.absolute())])}\n")
        try:
            os.rename(target, aside)
        except OSError as exc:
            self.restore()
            raise RunFolderError(f"{shown}: cannot move {target.name}: {exc.strerror}") from None
        self.moved.append((target, aside, identity))
        if not unchanged(aside, identity):  # replaced between the check and the rename
            self.restore()
            raise changed

    def commit(self) -> list[str]:
        """Remove the set-aside files that are still what they were; the names of those
        that were not (they are kept, under their set-aside names)."""
        left = []
        for _, aside, identity in self.moved:
            if unchanged(aside, identity):
                with contextlib.suppress(FileNotFoundError):
                    os.unlink(aside)
            else:
                left.append(aside.name)
        self.moved = []
        return left

    def restore(self) -> None:
        """Rename every set-aside file back (the new run never stepped); never raises."""
        for target, aside, _ in reversed(self.moved):
            if not os.path.lexists(target):
                with contextlib.suppress(OSError):
                    os.rename(aside, target)
        self.moved = []
