"""The files of a run folder and the manifest that says which of them a run wrote.

The manifest, :data:`MANIFEST_FILE`, lists each file a run wrote -- results.csv,
scenario.toml, summary.json, the recording -- with what identifies it
(:func:`cosim.outputs.tail_guard.file_identity`: device, inode, size, modification time
and the SHA-256 of its content), updated each time the run finishes writing one, and by
the tail guard after a killed run's files are cut whole. A file is the run's own only if
it is still a regular file with exactly that identity: one deleted and written again (the
inode often comes back), rewritten in place, or touched since, is not. Paths are relative
to the folder, or absolute for a recording outside it; ``pid`` is the process that ran;
``folder`` the folder's absolute path as the run saw it (a copy of the folder keeps it).

Each checkpoint (:data:`CHECKPOINT_FILE`) is recorded together with results.csv and the
recording as of it, in one save (:meth:`Manifest.record_checkpoint`): their entries get
``checkpoint``, the ``size`` and ``sha256`` of their first bytes (results.csv up to the
checkpoint's last row; the recording's first :data:`RECORDING_HEAD` bytes, which hold its
random recording id) and the ``checkpoint_sha256`` of the checkpoint.json they go with.
A run killed together with its tail guard (a job's cgroup killed, a power cut) leaves
them longer than their entries say, perhaps torn; a resume from that checkpoint still
knows them as the run's (:func:`cosim.outputs.earlier_run.find_earlier_run`) and writes
them again whole.

Standard library only: a run's refusal comes before numpy, fmpy or any FMU is loaded.
"""

from __future__ import annotations

import json
import os
import stat
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cosim.errors import FLAGS, CosimError, OptionNames
from cosim.outputs.tail_guard import IDENTITY_KEYS, READ_FLAGS, file_identity
from cosim.whole_file import write_whole

RESULTS_FILE = "results.csv"  # formats: cosim.outputs.results
SCENARIO_FILE = "scenario.toml"  # the resolved scenario
SUMMARY_FILE = "summary.json"
RECORDING_FILE = "recording.rrd"  # the Rerun recording (cosim.viz.recording)
REPORT_FOLDER = "report"  # what `auv-cosim report` adds (cosim.viz.report)
LOCK_FILE = ".auv-cosim.lock"
MANIFEST_FILE = ".auv-cosim-run.json"  # the files a run wrote, each with its identity
CHECKPOINT_FILE = "checkpoint.json"  # formats: cosim.outputs.checkpoint_file
CHECKPOINT_KEYS = ("size", "sha256", "checkpoint_sha256")  # of an entry's ``checkpoint``
MANIFEST_FORMAT = 2  # 1 (no "format" key): inodes only, which do not identify a file
OUTPUT_NAMES = (RESULTS_FILE, SCENARIO_FILE, SUMMARY_FILE, RECORDING_FILE)
RUN_STATUSES = ("running", "complete", "incomplete")  # in a summary.json of ours
RECORDING_MAGIC = b"RRF"  # the first bytes of a Rerun .rrd file (RRF2 in rerun 0.41)
RECORDING_APPLICATION = "auv-cosim"  # the application id of every recording we write
RECORDING_HEAD = 4096  # bytes of a recording in which its application id appears


class RunFolderError(CosimError):
    """A run folder that cannot be used; the message names it and what to do."""


@dataclass
class Manifest:
    """The manifest a run keeps in its folder: :meth:`record` a file it wrote (again
    after each change), :meth:`save` it."""

    folder: Path
    pid: int = field(default_factory=os.getpid)
    entries: dict[str, dict[str, Any]] = field(default_factory=dict)  # path -> identity
    # where the manifest read was saved (absolute): another folder in a copy of it; None
    # in one saved by a version that did not say
    saved_in: Path | None = None

    @property
    def path(self) -> Path:
        return self.folder / MANIFEST_FILE

    def name_of(self, path: Path) -> str:
        """``path`` as the manifest names it: relative inside the folder, else absolute."""
        resolved, root = Path(path).absolute(), self.folder.absolute()
        return str(resolved.relative_to(root)) if resolved.is_relative_to(root) else str(resolved)

    def record(self, path: Path) -> None:
        """Record what ``path`` holds now and save. Raises RunFolderError."""
        identity = file_identity(path)
        if identity is None:
            raise RunFolderError(f"cannot record {path}: it is not a regular file any more")
        self.entries[self.name_of(path)] = identity
        self.save()

    def record_checkpoint(
        self,
        path: Path,
        heads: dict[Path, tuple[int, str] | None],
        content: Path | None = None,
    ) -> None:
        """Record the checkpoint ``path`` the run wrote (held in ``content`` until it is
        renamed to ``path``, if given: a rename keeps what identifies it) and, in the same
        save, that each file of ``heads`` (recorded already) is the run's as long as its
        first ``size`` bytes hold SHA-256 ``sha256`` (``(size, sha256)``; None: not known,
        and no longer an earlier checkpoint's). Raises RunFolderError."""
        identity = file_identity(content or path)
        if identity is None:
            raise RunFolderError(f"cannot record {path}: it is not a regular file any more")
        self.entries[self.name_of(path)] = identity
        for file, head in heads.items():
            entry = self.entries.get(self.name_of(file))
            if entry is None:
                continue
            entry.pop("checkpoint", None)
            if head is not None:
                size, sha256 = head
                entry["checkpoint"] = {"size": size, "sha256": sha256,
                                       "checkpoint_sha256": identity["sha256"]}  # fmt: skip
        self.save()

    def save(self) -> None:
        """Write the manifest atomically. Raises RunFolderError."""
        files = [{"path": name, **identity} for name, identity in self.entries.items()]
        folder = str(self.folder.absolute())
        text = json.dumps(
            {"format": MANIFEST_FORMAT, "pid": self.pid, "folder": folder, "files": files}
        )
        try:
            write_atomically(self.path, text)
        except OSError as exc:
            raise RunFolderError(f"cannot write {self.path}: {exc.strerror or exc}") from None


def read_manifest(folder: Path, names: OptionNames = FLAGS, option: str = "out") -> Manifest:
    """The manifest in ``folder``. Raises RunFolderError saying whether it is missing,
    unreadable (truncated, not JSON, not ours) or of the older format that named files by
    inode alone (naming the folder as ``names`` name ``option``: out, or resume)."""
    out = names.given(option, folder)
    path = folder / MANIFEST_FILE
    if not os.path.lexists(path):
        raise RunFolderError(
            f"{out}: holds a {SUMMARY_FILE} but no {MANIFEST_FILE} (the list of the "
            "files its run wrote), so none of its files is known to be a run's; move them "
            "away or choose another folder"
        )
    try:
        if not regular(path):
            raise ValueError("not a regular file")
        data = json.loads(path.read_text(encoding="utf-8"))
        if isinstance(data, dict) and "format" not in data:
            raise RunFolderError(
                f"{out}: its {MANIFEST_FILE} was written by an older auv-cosim that "
                "recorded no content of the files, so none is known to be the run's any "
                "more; move them away or choose another folder"
            )
        if data["format"] != MANIFEST_FORMAT:
            raise ValueError(f"format {data['format']!r}")
        entries = {str(e["path"]): _entry(e) for e in data["files"]}
        saved_in = Path(data["folder"]) if "folder" in data else None
        return Manifest(folder, int(data["pid"]), entries, saved_in)
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise RunFolderError(
            f"{out}: its {MANIFEST_FILE} is unreadable ({_short(exc)}: truncated "
            "or not written by auv-cosim), so none of the files is known to be the run's; "
            "move them away or choose another folder"
        ) from None


def _entry(data: dict[str, Any]) -> dict[str, Any]:
    """A manifest's entry as read: the identity, and its ``checkpoint`` if that holds the
    keys it needs (their values are checked where they are used)."""
    entry = {k: data[k] for k in IDENTITY_KEYS}
    upto = data.get("checkpoint")
    if isinstance(upto, dict) and all(k in upto for k in CHECKPOINT_KEYS):
        entry["checkpoint"] = {k: upto[k] for k in CHECKPOINT_KEYS}
    return entry


def unchanged(path: Path, identity: dict[str, Any]) -> bool:
    """``path`` is still the regular file ``identity`` describes (read now)."""
    now = file_identity(path)
    return now is not None and all(now[k] == identity[k] for k in IDENTITY_KEYS)


def regular(path: Path) -> bool:
    """``path`` is a regular file itself (not a link to one)."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def is_our_recording(path: Path) -> bool:
    """``path`` is a regular file (not a link) that is empty or a Rerun recording this
    tool wrote: the magic bytes, then our application id in its first message."""
    try:
        fd = os.open(path, READ_FLAGS)  # a FIFO does not block, a link is not followed
    except OSError:
        return False
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return False
        head = os.read(fd, RECORDING_HEAD)
    except OSError:
        return False
    finally:
        os.close(fd)
    return not head or (head.startswith(RECORDING_MAGIC) and RECORDING_APPLICATION.encode() in head)


def write_atomically(path: Path, text: str) -> None:
    """``text`` to ``path``, whole or not at all (raises OSError)."""
    write_whole(path, lambda tmp: tmp.write_text(text, encoding="utf-8"))


def _short(exc: BaseException) -> str:
    text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return text[:80]
