"""A run folder, owned by one run at a time.

:meth:`RunFolder.claim` creates the folder (or refuses a path that cannot be one), takes an
exclusive lock on it (a second run into a locked folder fails at once, naming the process
that holds it), and refuses a folder holding an earlier run unless ``overwrite`` (or the
folder is the scenario's default one and holds nothing but an earlier run of the same
scenario, and a report made from it); once the run is known to be valid,
:meth:`RunFolder.clear_earlier_run` removes that run's files and says which. A folder
holding other files, with no earlier run, is refused: a run never mixes its files with
someone else's. This module imports nothing heavy, so a refusal comes before numpy, fmpy
or any FMU is loaded.

What a run wrote is known from its manifest, :data:`MANIFEST_FILE`: each file it created
(results.csv, scenario.toml, the recording) with its device and inode, written by
:meth:`RunFolder.wrote`. Replacing the run removes exactly those files that are still
regular files with the same inode, inside the folder and reached through no link, plus
its summary.json and manifest: never a folder (a ``report/`` made from the run stays),
never what summary.json's ``outputs`` merely lists, never a file outside the folder (a
``--rrd`` elsewhere stays). A summary.json without a manifest is no run of ours to
replace. The recording file is locked like the folder (:meth:`RunFolder.lock_recording`).

The lock is ``flock`` on :data:`LOCK_FILE` in the folder (holding the locking process's
pid and command line, for the message), removed again when the run ends. The kernel
releases it when the process dies, however it dies.

:meth:`RunFolder.start_guard` starts the tail guard (:mod:`cosim.outputs.tail_guard`) for
results.csv and the recording: a tiny process that outlives a killed run just long enough
to cut a torn last row off and the recording back to its last flush
(:meth:`RunFolder.recording_flushed` tells it where). It inherits the lock, so the folder
stays locked until the files are whole.
"""

from __future__ import annotations

import contextlib
import json
import os
import stat
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

from cosim.errors import CosimError

try:
    import fcntl
except ImportError:  # Windows: msvcrt's byte-range lock instead
    fcntl = None  # type: ignore[assignment]
    import msvcrt

RESULTS_FILE = "results.csv"  # formats: cosim.outputs.results
SCENARIO_FILE = "scenario.toml"  # the resolved scenario
SUMMARY_FILE = "summary.json"
RECORDING_FILE = "recording.rrd"  # the Rerun recording (cosim.viz.recording)
REPORT_FOLDER = "report"  # what `auv-cosim report` adds (cosim.viz.report)
LOCK_FILE = ".auv-cosim.lock"
MANIFEST_FILE = ".auv-cosim-run.json"  # the files a run wrote, each with its identity
OUTPUT_NAMES = (RESULTS_FILE, SCENARIO_FILE, SUMMARY_FILE, RECORDING_FILE)
RUN_STATUSES = ("running", "complete", "incomplete")  # in a summary.json of ours
GUARD_SCRIPT = Path(__file__).with_name("tail_guard.py")
GUARD_TIMEOUT_S = 10.0


class RunFolderError(CosimError):
    """A run folder that cannot be used; the message names it and what to do."""


class RunFolder:
    """A claimed run folder: use :meth:`claim`, then :meth:`release` (never raises)."""

    def __init__(self, path: Path, lock_fd: int, created: bool, tail_guard: bool = True) -> None:
        self.path = path
        self.tail_guard = tail_guard  # start_guard starts one (else it does nothing)
        self.created = created  # the folder did not exist before the claim
        self.earlier: EarlierRun | None = None  # an earlier run to replace
        self._lock_fd = lock_fd
        self._written: list[list] = []  # [path, device, inode] of each file this run wrote
        self._rrd_fd = -1  # the lock on the recording, if one is written
        self._rrd_created: Path | None = None  # the recording file the lock created
        self._guard: subprocess.Popen[bytes] | None = None

    @classmethod
    def claim(
        cls,
        path: Path,
        overwrite: bool = False,
        tail_guard: bool = True,
        default_for: str | None = None,
    ) -> RunFolder:
        """Create and lock ``path``; an earlier run there needs ``overwrite``, unless
        ``path`` is the default folder of scenario ``default_for`` and holds nothing but an
        earlier run of that scenario (and a report made from it). Without ``tail_guard``,
        :meth:`start_guard` starts no guard process (for a caller that discards a killed
        run's folder anyway: a study's task, whose run is run again).

        Raises:
            RunFolderError: not creatable, not a folder, locked by another run, holding an
                earlier run without ``overwrite``, holding files of no run, or holding an
                output name that is not the earlier run's own file.
        """
        path = Path(path)
        created = not path.exists()
        try:
            path.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise RunFolderError(f"--out {path}: exists and is not a folder") from None
        except OSError as exc:
            raise RunFolderError(
                f"--out {path}: cannot create the run folder: {exc.strerror or exc}"
            ) from None
        if not path.is_dir():
            raise RunFolderError(f"--out {path}: exists and is not a folder")
        try:
            lock_fd = lock_folder(path)
        except RunFolderError:
            if created:
                with contextlib.suppress(OSError):
                    path.rmdir()
            raise
        folder = cls(path, lock_fd, created, tail_guard)
        try:
            folder.earlier = _earlier_run(path, overwrite, default_for)
        except BaseException:
            folder.release()
            raise
        return folder

    def clear_earlier_run(self) -> str | None:
        """Remove the files of the earlier run :meth:`claim` found: only the regular files
        that run wrote (its manifest names each with its inode), never a folder, never
        through a link. Returns the one line saying what went and what stays (None if
        there was no earlier run)."""
        if self.earlier is None:
            return None
        removed = []
        try:
            for target in self.earlier.remove:
                target.unlink(missing_ok=True)
                removed.append(str(target.relative_to(self.path)))
        except OSError as exc:
            raise RunFolderError(
                f"--out {self.path}: cannot remove the earlier run's files: {exc.strerror or exc}"
            ) from None
        shown = sorted(n for n in removed if not n.startswith("."))
        kept = self.earlier.kept
        self.earlier = None
        return f"replaced the earlier run in {self.path}: removed {', '.join(shown)}" + (
            f"; kept {', '.join(kept)}" if kept else ""
        )

    def wrote(self, path: Path) -> None:
        """Record that this run created ``path`` (in the folder's manifest, with its inode:
        a later run removes it only if it is still that file). Raises RunFolderError."""
        try:
            st = os.stat(path)
            resolved, root = Path(path).resolve(), self.path.resolve()
            name = resolved.relative_to(root) if resolved.is_relative_to(root) else resolved
            self._written.append([str(name), st.st_dev, st.st_ino])
            _write_atomically(self.path / MANIFEST_FILE, json.dumps({"files": self._written}))
        except OSError as exc:
            raise RunFolderError(
                f"cannot write {self.path / MANIFEST_FILE}: {exc.strerror or exc}"
            ) from None

    def lock_recording(self, rrd: Path) -> None:
        """Lock the recording file as the folder is locked: a second run writing the same
        file is refused at once. Raises RunFolderError."""
        rrd = Path(rrd)
        existed = os.path.lexists(rrd)
        try:
            rrd.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(rrd, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise RunFolderError(f"--rrd {rrd}: cannot create it: {exc.strerror or exc}") from None
        if not _try_lock(fd):
            os.close(fd)
            raise RunFolderError(
                f"--rrd {rrd}: another run is writing this recording; wait for it to end or "
                "choose another file"
            )
        self._rrd_fd = fd
        self._rrd_created = None if existed else rrd

    def start_guard(self, results: Path, recording: Path | None) -> None:
        """Start the tail guard for these files (see the module docstring), if the folder
        was claimed with one."""
        if not self.tail_guard:
            return
        kwargs: dict = {"start_new_session": True}
        if fcntl is not None:  # the guard keeps the folder and the recording locked
            kwargs["pass_fds"] = tuple(fd for fd in (self._lock_fd, self._rrd_fd) if fd >= 0)
        files = [str(results)] + ([str(recording)] if recording is not None else [])
        self._guard = subprocess.Popen(
            [sys.executable, "-I", "-S", str(GUARD_SCRIPT), *files],
            stdin=subprocess.PIPE,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
            **kwargs,
        )

    def recording_flushed(self, size: int) -> None:
        """The recording holds whole messages up to ``size`` bytes (tell the guard)."""
        self._tell_guard(f"rrd {size}\n")

    def release(self, unused: bool = False) -> None:
        """Tell the tail guard the files are complete, remove the lock file and unlock;
        never raises. With ``unused`` (the run never stepped) a folder the claim created
        goes too if empty."""
        if self._guard is not None:
            self._tell_guard("done\n")
            with contextlib.suppress(OSError, subprocess.TimeoutExpired):
                if self._guard.stdin is not None:
                    self._guard.stdin.close()
                self._guard.wait(timeout=GUARD_TIMEOUT_S)
            self._guard = None
        if self._lock_fd >= 0:
            unlock_folder(self.path, self._lock_fd)
            self._lock_fd = -1
        self._release_recording(unused)
        if unused and self._written:
            with contextlib.suppress(OSError):
                (self.path / MANIFEST_FILE).unlink()
        if unused and self.created:
            with contextlib.suppress(OSError):
                self.path.rmdir()  # only if empty

    def _release_recording(self, unused: bool) -> None:
        if self._rrd_fd < 0:
            return
        created = self._rrd_created
        with contextlib.suppress(OSError):
            if unused and created is not None and os.fstat(self._rrd_fd).st_size == 0:
                created.unlink()
        with contextlib.suppress(OSError):
            os.close(self._rrd_fd)
        self._rrd_fd = -1

    def _tell_guard(self, line: str) -> None:
        if self._guard is None or self._guard.stdin is None:
            return
        with contextlib.suppress(OSError, ValueError):  # a guard gone is no reason to stop
            self._guard.stdin.write(line.encode())
            self._guard.stdin.flush()


def check_recording_path(out_dir: Path, rrd: Path, overwrite: bool) -> None:
    """Refuse a recording path that is another output of the run, a folder, or an
    existing file (outside the run folder's own recording) without ``overwrite``."""
    target = Path(rrd).resolve()
    for name in (RESULTS_FILE, SCENARIO_FILE, SUMMARY_FILE, LOCK_FILE, REPORT_FOLDER):
        if target == (out_dir / name).resolve():
            raise RunFolderError(
                f"--rrd {rrd}: that is the run's {name}; choose another file for the recording"
            )
    if target.is_dir():
        raise RunFolderError(f"--rrd {rrd}: is a folder; expected the path of a .rrd file")
    own = (out_dir / RECORDING_FILE).resolve()
    if target.exists() and target != own and not overwrite:
        raise RunFolderError(f"--rrd {rrd}: exists; pass --overwrite to replace it")


def _write_atomically(path: Path, text: str) -> None:
    """``text`` to ``path`` through a temporary file and a rename (raises OSError)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        raise


def lock_folder(path: Path, kind: str = "run") -> int:
    """Lock the folder ``path`` (a ``kind`` folder: "run" or "study") without waiting;
    return the lock's descriptor (:func:`unlock_folder` releases it). Raises
    RunFolderError naming the process holding it."""
    lock = path / LOCK_FILE
    for _ in range(5):  # a previous holder may remove the file between open and lock
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise RunFolderError(
                f"--out {path}: cannot write in the {kind} folder: {exc.strerror or exc}"
            ) from None
        if not _try_lock(fd):
            holder = _holder(fd)
            os.close(fd)
            raise RunFolderError(
                f"{kind} folder {path} is in use by {holder}: wait for that {kind} to end or "
                "choose another --out"
            )
        try:
            current = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            current = False
        if current:
            try:
                os.ftruncate(fd, 0)
                os.write(fd, f"{os.getpid()} {' '.join(sys.argv)}\n".encode())
            except OSError as exc:  # a full disk: no lock file left behind
                unlock_folder(path, fd)
                raise RunFolderError(
                    f"--out {path}: cannot write {lock}: {exc.strerror or exc}"
                ) from None
            return fd
        os.close(fd)
    raise RunFolderError(f"{kind} folder {path}: cannot take its lock (it keeps changing)")


def unlock_folder(path: Path, fd: int) -> None:
    """Remove the lock file :func:`lock_folder` made and release the lock; never raises."""
    with contextlib.suppress(OSError):
        (path / LOCK_FILE).unlink()
    with contextlib.suppress(OSError):
        os.close(fd)  # closing the last descriptor releases the lock


def _try_lock(fd: int) -> bool:
    try:
        if fcntl is not None:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        else:
            msvcrt.locking(fd, msvcrt.LK_NBLCK, 1)
    except OSError:
        return False
    return True


def _holder(fd: int) -> str:
    """'process PID (command line)' from a lock file, as its holder wrote it."""
    try:
        os.lseek(fd, 0, os.SEEK_SET)
        text = os.read(fd, 4096).decode("utf-8", "replace").strip()
    except OSError:
        text = ""
    pid, _, command = text.partition(" ")
    if not pid.isdigit():
        return "another process"
    return f"process {pid}" + (f" ({command})" if command else "")


@dataclass
class EarlierRun:
    """An earlier run of ours in a run folder: its summary, the files of its own to remove
    (each checked to be the regular file that run wrote) and what stays (said)."""

    summary: dict
    remove: list[Path]
    kept: list[str] = field(default_factory=list)


def _earlier_run(path: Path, overwrite: bool, default_for: str | None) -> EarlierRun | None:
    """The earlier run in ``path`` (None if there is none); refusals as documented."""
    entries = sorted(e.name for e in path.iterdir() if e.name not in (LOCK_FILE, MANIFEST_FILE))
    if not entries:
        return None
    summary_path = path / SUMMARY_FILE
    if not _regular(summary_path):
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise RunFolderError(
            f"--out {path}: the folder is not empty ({shown}) and holds no earlier run "
            f"(no {SUMMARY_FILE}); choose a new or empty folder"
        )
    summary = _read_summary(summary_path)
    if summary.get("status") not in RUN_STATUSES or not isinstance(summary.get("scenario"), str):
        raise RunFolderError(
            f"--out {path}: its {SUMMARY_FILE} is not the summary of an auv-cosim run; "
            "choose a new or empty folder"
        )
    files = _read_manifest(path)
    if files is None:
        raise RunFolderError(
            f"--out {path}: holds a {SUMMARY_FILE} but no {MANIFEST_FILE} (the list of the "
            "files its run wrote), so none of its files is known to be a run's; move them "
            "away or choose another folder"
        )
    own = _own_files(path, files)
    extra = [path / SUMMARY_FILE, path / MANIFEST_FILE, *path.glob(f".{SUMMARY_FILE}.*.tmp")]
    own += [p for p in extra if _regular(p) and p not in own]
    tops = {p.relative_to(path).parts[0] for p in own if _inside(p, path)}
    foreign = [e for e in entries if e not in tops and e != REPORT_FOLDER]
    same = default_for is not None and summary["scenario"] == default_for and not foreign
    if not (overwrite or same):
        what = f"scenario {summary['scenario']!r}, status {summary['status']!r}"
        raise RunFolderError(
            f"--out {path}: the folder holds an earlier run ({what}); pass --overwrite to "
            "replace it, or choose another folder"
        )
    for name in OUTPUT_NAMES:  # the new run would write over these: they must be the run's
        if os.path.lexists(path / name) and path / name not in own:
            raise RunFolderError(
                f"--out {path}: {name} is not a file the earlier run wrote (replaced, or a "
                "link); move it away or choose another folder"
            )
    kept = [f"{REPORT_FOLDER}/"] if (path / REPORT_FOLDER).exists() else []
    kept += [str(p) for p, _, _ in files if p.is_absolute() and os.path.lexists(p)]
    return EarlierRun(summary, own, kept)


def _read_summary(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {"status": "unreadable"}
    return data if isinstance(data, dict) else {"status": "unreadable"}


def _read_manifest(path: Path) -> list[tuple[Path, int, int]] | None:
    """The manifest's (path, device, inode) entries; None if missing or not ours."""
    manifest = path / MANIFEST_FILE
    if not _regular(manifest):
        return None
    try:
        data = json.loads(manifest.read_text(encoding="utf-8"))
        return [(Path(str(p)), int(dev), int(ino)) for p, dev, ino in data["files"]]
    except (OSError, ValueError, KeyError, TypeError):
        return None


def _own_files(path: Path, files: list[tuple[Path, int, int]]) -> list[Path]:
    """The manifest's files inside ``path`` that are still the regular files the run
    wrote (same device and inode), reached through no link below ``path``."""
    own = []
    for name, dev, ino in files:
        if name.is_absolute() or ".." in name.parts or not name.parts:
            continue  # outside the folder: never removed
        target = path / name
        if any(os.path.islink(path.joinpath(*name.parts[:i])) for i in range(1, len(name.parts))):
            continue
        try:
            st = os.lstat(target)
        except OSError:
            continue
        if stat.S_ISREG(st.st_mode) and (st.st_dev, st.st_ino) == (dev, ino):
            own.append(target)
    return own


def _regular(path: Path) -> bool:
    """``path`` is a regular file itself (not a link to one)."""
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def _inside(target: Path, folder: Path) -> bool:
    return target.is_relative_to(folder)
