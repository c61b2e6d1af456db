"""A run folder, owned by one run at a time.

:meth:`RunFolder.claim` creates the folder (or refuses a path that cannot be one), takes an
exclusive lock on it (a second run into a locked folder fails at once, naming the process
that holds it), and refuses a folder holding an earlier run unless ``overwrite``; once the
run is known to be valid, :meth:`RunFolder.clear_earlier_run` removes that run's files
(and nothing else). A folder holding other files, with no earlier run, is refused: a run
never mixes its files with someone else's. This module imports nothing heavy, so a
refusal comes before numpy, fmpy or any FMU is loaded.

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
import shutil
import subprocess
import sys
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
OUTPUT_NAMES = (RESULTS_FILE, SCENARIO_FILE, SUMMARY_FILE, RECORDING_FILE, REPORT_FOLDER)
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
        self.earlier: dict | None = None  # the summary of an earlier run to replace
        self._lock_fd = lock_fd
        self._guard: subprocess.Popen[bytes] | None = None

    @classmethod
    def claim(cls, path: Path, overwrite: bool = False, tail_guard: bool = True) -> RunFolder:
        """Create and lock ``path``; an earlier run there needs ``overwrite``. Without
        ``tail_guard``, :meth:`start_guard` starts no guard process (for a caller that
        discards a killed run's folder anyway: a study's task, whose run is run again).

        Raises:
            RunFolderError: not creatable, not a folder, locked by another run, holding an
                earlier run without ``overwrite``, or holding files of no run.
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
        folder = cls(path, _lock(path), created, tail_guard)
        try:
            folder.earlier = _earlier_run(path, overwrite)
        except BaseException:
            folder.release()
            raise
        return folder

    def clear_earlier_run(self) -> None:
        """Remove the files of the earlier run :meth:`claim` found (with ``overwrite``)."""
        if self.earlier is None:
            return
        try:
            for name in _earlier_outputs(self.path, self.earlier):
                target = self.path / name
                if target.is_dir() and not target.is_symlink():
                    shutil.rmtree(target)
                else:
                    target.unlink(missing_ok=True)
        except OSError as exc:
            raise RunFolderError(
                f"--out {self.path}: cannot remove the earlier run's files: {exc.strerror or exc}"
            ) from None
        self.earlier = None

    def start_guard(self, results: Path, recording: Path | None) -> None:
        """Start the tail guard for these files (see the module docstring), if the folder
        was claimed with one."""
        if not self.tail_guard:
            return
        kwargs: dict = {"start_new_session": True}
        if fcntl is not None:
            kwargs["pass_fds"] = (self._lock_fd,)  # the guard keeps the folder locked
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
            with contextlib.suppress(OSError):
                (self.path / LOCK_FILE).unlink()
            with contextlib.suppress(OSError):
                os.close(self._lock_fd)  # closing the last descriptor releases the lock
            self._lock_fd = -1
        if unused and self.created:
            with contextlib.suppress(OSError):
                self.path.rmdir()  # only if empty

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


def _lock(path: Path) -> int:
    """Lock ``path``'s lock file without waiting; return its descriptor."""
    lock = path / LOCK_FILE
    for _ in range(5):  # a previous holder may remove the file between open and lock
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        except OSError as exc:
            raise RunFolderError(
                f"--out {path}: cannot write in the run folder: {exc.strerror or exc}"
            ) from None
        if not _try_lock(fd):
            holder = _holder(fd)
            os.close(fd)
            raise RunFolderError(
                f"run folder {path} is in use by {holder}: wait for that run to end or "
                "choose another --out"
            )
        try:
            current = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            current = False
        if current:
            os.ftruncate(fd, 0)
            os.write(fd, f"{os.getpid()} {' '.join(sys.argv)}\n".encode())
            return fd
        os.close(fd)
    raise RunFolderError(f"run folder {path}: cannot take its lock (it keeps changing)")


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


def _earlier_run(path: Path, overwrite: bool) -> dict | None:
    """The summary of the earlier run in ``path`` (None if empty); refusals as documented."""
    entries = sorted(e.name for e in path.iterdir() if e.name != LOCK_FILE)
    if not entries:
        return None
    summary = path / SUMMARY_FILE
    if not summary.is_file():
        shown = ", ".join(entries[:3]) + (", ..." if len(entries) > 3 else "")
        raise RunFolderError(
            f"--out {path}: the folder is not empty ({shown}) and holds no earlier run "
            f"(no {SUMMARY_FILE}); choose a new or empty folder"
        )
    earlier = _read_summary(summary)
    if not overwrite:
        what = f"scenario {earlier.get('scenario')!r}, status {earlier.get('status', '?')!r}"
        raise RunFolderError(
            f"--out {path}: the folder holds an earlier run ({what}); pass --overwrite to "
            "replace it, or choose another folder"
        )
    return earlier


def _read_summary(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {"status": "unreadable"}
    return data if isinstance(data, dict) else {"status": "unreadable"}


def _earlier_outputs(path: Path, earlier: dict) -> list[str]:
    """The names in ``path`` an earlier run wrote: the standard outputs, those its summary
    lists inside the folder, and its unfinished summary replacements."""
    names = set(OUTPUT_NAMES)
    listed = earlier.get("outputs")
    if isinstance(listed, dict):
        for value in listed.values():
            relative = Path(str(value))
            if not relative.is_absolute() and ".." not in relative.parts:
                names.add(relative.parts[0] if relative.parts else "")
    names.discard("")
    names.update(p.name for p in path.glob(f".{SUMMARY_FILE}.*.tmp"))
    return sorted(names)
