"""A run folder, owned by one run at a time.

:meth:`RunFolder.claim` creates the folder (or refuses a path that cannot be one), takes an
exclusive lock on it (a second run into a locked folder fails at once, naming the process
that holds it), and refuses a folder holding an earlier run unless ``overwrite`` (or the
folder is the scenario's default one and holds nothing but an earlier run of the same
scenario file, and a report made from it; :mod:`cosim.outputs.earlier_run`). A folder
holding other files, with no earlier run, is refused: a run never mixes its files with
someone else's. This module imports nothing heavy, so a refusal comes before numpy, fmpy
or any FMU is loaded.

Nothing of an earlier run is removed before the new run has taken its first step: once
the run is known to be valid, :meth:`RunFolder.set_aside_earlier_run` renames the earlier
run's own files out of the way (each checked to be still what that run wrote);
:meth:`RunFolder.commit` removes them when the first step's rows arrive, and
:meth:`RunFolder.restore` puts them back if the run fails or stops before that. A
recording at ``--rrd`` that exists is treated the same way (:meth:`RunFolder.lock_recording`).

What a run wrote is known from its manifest (:mod:`cosim.outputs.run_files`): each file it
created with what identifies it (inode, size, time, content hash), recorded by
:meth:`RunFolder.wrote` each time the run finishes writing it.

The lock is ``flock`` on :data:`LOCK_FILE` in the folder (holding the locking process's
pid and command line, for the message), removed again when the run ends; a lock file that
is a link (a folder from elsewhere) is refused, never written through. The kernel
releases it when the process dies, however it dies. The recording file is locked the
same way.

:meth:`RunFolder.start_guard` starts the tail guard (:mod:`cosim.outputs.tail_guard`) for
results.csv and the recording: a tiny process that outlives a killed run just long enough
to cut a torn last row off and the recording back to its last flush
(:meth:`RunFolder.recording_flushed` tells it where), record what the files then hold, or
put an earlier run back if the killed one never stepped. It inherits the lock, so the
folder stays locked until the files are whole.
"""

from __future__ import annotations

import contextlib
import errno
import json
import os
import shlex
import socket
import stat
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

from cosim.errors import FLAGS, OptionNames
from cosim.outputs.earlier_run import EarlierRun, ScenarioRef, SetAside, find_earlier_run
from cosim.outputs.report_folder import local_time, mark_stale
from cosim.outputs.run_files import (
    LOCK_FILE,
    MANIFEST_FILE,
    RECORDING_FILE,
    RECORDING_HEAD,
    REPORT_FOLDER,
    RESULTS_FILE,
    SCENARIO_FILE,
    SUMMARY_FILE,
    Manifest,
    RunFolderError,
    is_our_recording,
    regular,
)
from cosim.outputs.tail_guard import file_identity, head_sha256

try:
    import fcntl
except ImportError:  # Windows: msvcrt's byte-range lock instead
    fcntl = None  # type: ignore[assignment]
    import msvcrt

__all__ = [
    "LOCK_FILE", "MANIFEST_FILE", "RECORDING_FILE", "REPORT_FOLDER", "RESULTS_FILE",
    "SCENARIO_FILE", "SUMMARY_FILE", "RunFolder", "RunFolderError", "ScenarioRef",
    "check_recording_path", "lock_folder", "unlock_folder",
]  # fmt: skip
GUARD_SCRIPT = Path(__file__).with_name("tail_guard.py")
GUARD_TIMEOUT_S = 10.0


def _end_guard(guard: subprocess.Popen[bytes]) -> None:
    """Wait up to :data:`GUARD_TIMEOUT_S` for the tail guard, told ``done``, to end, then
    kill it and reap it: the files are complete, so a guard still running (stopped, or
    slow to start under load) has nothing left to do but undo them had ``done`` not
    reached it, and a Popen dropped while its process runs leaves that process behind,
    unreaped, with a ResourceWarning. Never raises."""
    with contextlib.suppress(subprocess.TimeoutExpired):
        guard.wait(timeout=GUARD_TIMEOUT_S)
        return
    with contextlib.suppress(OSError):
        guard.kill()
    with contextlib.suppress(OSError, subprocess.TimeoutExpired):
        guard.wait(timeout=GUARD_TIMEOUT_S)  # SIGKILL: ends it at once


class RunFolder:
    """A claimed run folder: use :meth:`claim`, then :meth:`release` (never raises)."""

    def __init__(
        self,
        path: Path,
        lock_fd: int,
        created: bool,
        tail_guard: bool = True,
        names: OptionNames = FLAGS,
    ) -> None:
        self.path = path
        self.names = names  # how a refusal names the options: flags or the API's keywords
        self.option = "out"  # the option that named the folder (resume: a resumed run's)
        self.tail_guard = tail_guard  # start_guard starts one (else it does nothing)
        self.created = created  # the folder did not exist before the claim
        self.earlier: EarlierRun | None = None  # an earlier run to replace
        self.committed = False  # the run has taken its first step
        self.replaced: str | None = None  # what replacing the earlier run did (one line)
        self.manifest = Manifest(path)
        self.aside = SetAside(self._tell_guard)
        self._lock_fd = lock_fd
        self._recorded: set[str] = set()  # the files this run wrote (the manifest's names)
        self._new: list[Path] = []  # the files this run created (absolute), for the guard
        self._rrd_fd = -1  # the lock on the recording, if one is written
        self._rrd_created: Path | None = None  # the recording file the lock created
        self._rrd_flushed = 0  # bytes of whole messages in it (recording_flushed)
        self._guard: subprocess.Popen[bytes] | None = None
        self._channel: socket.socket | None = None  # to the guard (else its stdin pipe)
        # what results.csv holds now (data rows, bytes, SHA-256), if its sink keeps it
        self.results_written: Callable[[], tuple[int, int, str]] | None = None

    @classmethod
    def claim(
        cls,
        path: Path,
        overwrite: bool = False,
        tail_guard: bool = True,
        default_for: ScenarioRef | None = None,
        names: OptionNames = FLAGS,
        resuming: bool = False,
    ) -> RunFolder:
        """Create and lock ``path``; an earlier run there needs ``overwrite``, unless
        ``path`` is the default folder of the scenario ``default_for`` and holds nothing
        but an earlier run of that scenario file (and a report made from it). Without
        ``tail_guard``, :meth:`start_guard` starts no guard process (for a caller that
        discards a killed run's folder anyway: a study's task, whose run is run again).
        A refusal names the options as ``names`` does (the command line's flags, or the
        API's keywords). ``resuming``: the earlier run continues from its checkpoint
        (:func:`find_earlier_run`: its files are known by their content; the folder is
        named as ``--resume`` gave it).

        Raises:
            RunFolderError: not creatable, not a folder, locked by another run, holding an
                earlier run without ``overwrite``, holding files of no run, or holding an
                output name that is not the earlier run's own file.
        """
        path = Path(path)
        out = names.given("resume" if resuming else "out", path)
        if default_for is not None:  # no --out given: the folder is the scenario's default
            out = f"{path} (the default run folder, from the scenario's id; "
            out += f"{names.option('out')} names another)"
        created = not os.path.exists(path)  # False, not OSError, for a name too long
        try:
            path.mkdir(parents=True, exist_ok=True)
        except FileExistsError:
            raise RunFolderError(f"{out}: exists and is not a folder") from None
        except OSError as exc:
            raise RunFolderError(
                f"{out}: cannot create the run folder: {exc.strerror or exc}"
            ) from None
        if not path.is_dir():
            raise RunFolderError(f"{out}: exists and is not a folder")
        try:
            lock_fd = lock_folder(path, names=names, option="resume" if resuming else "out")
        except RunFolderError:
            if created:
                with contextlib.suppress(OSError):
                    path.rmdir()
            raise
        folder = cls(path, lock_fd, created, tail_guard, names)
        folder.option = "resume" if resuming else "out"
        try:
            folder.earlier = find_earlier_run(path, overwrite, default_for, names, resuming)
        except BaseException:
            folder.release()
            raise
        return folder

    @property
    def replacing(self) -> bool:
        """Files of an earlier run (or an earlier recording) are set aside, not yet gone."""
        return bool(self.aside.moved)

    def set_aside_earlier_run(self) -> None:
        """Rename the earlier run's own files out of the way (each checked again to be the
        file that run wrote). Raises RunFolderError, with everything put back."""
        if self.earlier is None:
            return
        for target, identity in self.earlier.files.items():
            self.aside.move(target, identity, self.names.given(self.option, self.path))

    def commit(self) -> None:
        """The run has taken its first step: remove what was set aside (checked once more)
        and say so in :attr:`replaced`. Never raises."""
        if self.committed:
            return
        self.committed = True
        moved = [(target, aside) for target, aside, _ in self.aside.moved]
        left = self.aside.commit()
        self._tell_guard("commit\n")
        if not moved:
            return
        kept = [*(self.earlier.kept if self.earlier is not None else []), *left]
        if f"{REPORT_FOLDER}/" in kept and mark_stale(
            self.path / REPORT_FOLDER, self._stale_note()
        ):
            kept[kept.index(f"{REPORT_FOLDER}/")] = (
                f"{REPORT_FOLDER}/ (marked stale: made from the earlier run)"
            )
        inside = [t for t, _ in moved if t.is_relative_to(self.path)]
        shown = sorted(str(t.relative_to(self.path)) for t in inside)
        shown = [n for n in shown if not Path(n).name.startswith(".")]
        shown += [str(t) for t, _ in moved if not t.is_relative_to(self.path)]
        self.replaced = f"replaced the earlier run in {self.path}: removed {', '.join(shown)}" + (
            f"; kept {', '.join(kept)}" if kept else ""
        )

    def _stale_note(self) -> str:
        when = local_time(strict=False)  # never fails the run replacing a reported one
        return (
            f"this report was made from an earlier run in {self.path}, replaced by another "
            f"run at {when}; run `auv-cosim report {shlex.quote(str(self.path))}` to make it again"
        )

    def restore(self) -> None:
        """The run never stepped: remove the manifest and recording it created and put
        the set-aside files back. Never raises."""
        if self.committed or not self.replacing:
            return
        with contextlib.suppress(OSError):
            if self._recorded:
                self.manifest.path.unlink()
            if self._rrd_created is not None and os.path.lexists(self._rrd_created):
                self._rrd_created.unlink()
        self._recorded.clear()
        self._new.clear()
        self._rrd_created = None
        self.aside.restore()

    def wrote(self, path: Path) -> None:
        """Record what this run's file ``path`` holds now (in the folder's manifest: a
        later run removes it only if it is still exactly that). Call again after each
        change. Raises RunFolderError."""
        name = self.manifest.name_of(path)
        if name not in self._recorded:
            self._recorded.add(name)
            self._created(Path(path))
        self.manifest.record(path)

    def checkpointed(self, path: Path, rows: int, content: Path | None = None) -> None:
        """Record the checkpoint ``path`` this run wrote (held in ``content`` until it is
        renamed to ``path``, if given), at ``rows`` data rows, with results.csv as of it
        where it holds exactly those rows (:attr:`results_written`) and the head of the
        recording once flushed (:meth:`Manifest.record_checkpoint`). Raises
        RunFolderError."""
        heads: dict[Path, tuple[int, str] | None] = {}
        if self.results_written is not None:
            written, size, sha256 = self.results_written()
            heads[self.path / RESULTS_FILE] = (size, sha256) if written == rows else None
        if self._rrd_created is not None:
            flushed = self._rrd_flushed >= RECORDING_HEAD  # (its id in it)
            head = head_sha256(self._rrd_created, RECORDING_HEAD) if flushed else None
            heads[self._rrd_created] = None if head is None else (RECORDING_HEAD, head)
        name = self.manifest.name_of(path)
        if name not in self._recorded:
            self._recorded.add(name)
            self._created(Path(path))
        self.manifest.record_checkpoint(path, heads, content)

    def _created(self, path: Path) -> None:
        """This run created ``path`` (the guard removes it if it puts an earlier run back)."""
        self._new.append(path.absolute())
        self._tell_guard(f"new {json.dumps(str(path.absolute()))}\n")

    def lock_recording(self, rrd: Path, named: str | None = None) -> None:
        """Lock the recording file as the folder is locked: a second run writing the same
        file is refused at once. An existing file there (a recording of ours, as
        :func:`check_recording_path` made sure) is set aside like the earlier run's files.
        Raises RunFolderError, naming the recording as ``named`` (default ``--rrd PATH``)."""
        rrd = Path(rrd)
        named = named or f"--rrd {rrd}"
        if os.path.lexists(rrd):
            self._set_aside_recording(rrd, named)
        try:
            rrd.parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:  # (a file where a folder is: not NotADirectoryError here)
            message = os.strerror(errno.ENOTDIR)
            raise RunFolderError(f"{named}: cannot create it: {message}") from None
        except OSError as exc:
            raise RunFolderError(f"{named}: cannot create it: {exc.strerror or exc}") from None
        try:
            fd = os.open(rrd, os.O_RDWR | os.O_CREAT | os.O_EXCL, 0o666)
        except FileExistsError:
            raise RunFolderError(f"{named}: another process created it just now") from None
        except OSError as exc:
            raise RunFolderError(f"{named}: cannot create it: {exc.strerror or exc}") from None
        self._created(rrd)
        if not _try_lock(fd):
            os.close(fd)
            raise RunFolderError(f"{named}: another run is writing this recording")
        self._rrd_fd = fd
        self._rrd_created = rrd
        self._tell_guard("lock\n", fd)  # held by the guard until the recording is whole

    def _set_aside_recording(self, rrd: Path, named: str) -> None:
        """Set an existing recording at ``rrd`` aside, once sure it is a recording of ours
        that no run is writing."""
        if not is_our_recording(rrd):
            raise RunFolderError(
                f"{named}: exists and is not a recording auv-cosim wrote; choose a new file"
            )
        try:
            fd = os.open(rrd, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0))
        except OSError as exc:
            raise RunFolderError(f"{named}: cannot open it: {exc.strerror or exc}") from None
        try:
            if not _try_lock(fd):
                raise RunFolderError(
                    f"{named}: another run is writing this recording; wait for it to end "
                    "or choose another file"
                )
            identity = file_identity(rrd)
            if identity is None:
                raise RunFolderError(f"{named}: changed while it was checked; try again")
            self.aside.move(rrd, identity, named)
        finally:
            os.close(fd)

    def start_guard(self, results: Path, recording: Path | None) -> None:
        """Start the tail guard for these files (see the module docstring), if the folder
        was claimed with one and it is not running yet. Start it before anything is set
        aside: it puts the files back if the run is killed before its first step."""
        if not self.tail_guard or self._guard is not None:
            return
        files = [str(Path(results).absolute())]
        files += [str(Path(recording).absolute())] if recording is not None else []
        command = [
            sys.executable,
            "-I",
            "-S",
            str(GUARD_SCRIPT),
            str(self.manifest.path.absolute()),
        ]
        kwargs: dict = {"start_new_session": True, "stdout": subprocess.DEVNULL,
                        "stderr": subprocess.DEVNULL}  # fmt: skip
        if fcntl is None:  # Windows: a pipe, no locks handed over
            self._guard = subprocess.Popen([*command, *files], stdin=subprocess.PIPE, **kwargs)
        else:  # a socket: the recording's lock, taken later, is handed over on it
            self._channel, theirs = socket.socketpair()
            try:
                self._guard = subprocess.Popen(
                    [*command, *files], stdin=theirs.fileno(), pass_fds=(self._lock_fd,), **kwargs
                )
            finally:
                theirs.close()
        for target, aside, _ in self.aside.moved:  # what happened before it started
            pair = [str(target.absolute()), str(aside.absolute())]
            self._tell_guard(f"aside {json.dumps(pair)}\n")
        for path in self._new:
            self._tell_guard(f"new {json.dumps(str(path))}\n")
        if self._rrd_fd >= 0:
            self._tell_guard("lock\n", self._rrd_fd)

    def recording_flushed(self, size: int) -> None:
        """The recording holds whole messages up to ``size`` bytes (tell the guard)."""
        self._rrd_flushed = size
        self._tell_guard(f"rrd {size}\n")

    def release(self, unused: bool = False) -> None:
        """Tell the tail guard the files are complete, remove the lock file and unlock;
        never raises. With ``unused`` (the run never stepped) a folder the claim created
        goes too if empty."""
        if self._guard is not None:
            self._tell_guard("done\n")
            with contextlib.suppress(OSError):
                if self._channel is not None:
                    self._channel.close()
                if self._guard.stdin is not None:
                    self._guard.stdin.close()
            _end_guard(self._guard)
            self._guard = None
        if self._lock_fd >= 0:
            unlock_folder(self.path, self._lock_fd)
            self._lock_fd = -1
        self._release_recording(unused)
        if unused and self._recorded:
            with contextlib.suppress(OSError):
                self.manifest.path.unlink()
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

    def _tell_guard(self, line: str, fd: int = -1) -> None:
        """Send the guard ``line`` (and the descriptor ``fd`` with it, over the socket)."""
        data = line.encode("utf-8", "surrogateescape")
        with contextlib.suppress(OSError, ValueError):  # a guard gone is no reason to stop
            if self._channel is not None:
                socket.send_fds(self._channel, [data], [fd] if fd >= 0 else [])
            elif self._guard is not None and self._guard.stdin is not None:
                self._guard.stdin.write(data)
                self._guard.stdin.flush()


def check_recording_path(
    out_dir: Path, rrd: Path, overwrite: bool, named: str | None = None
) -> None:
    """Refuse a recording path that is another file of the run, a folder, or anything but
    a new file or a regular file holding a recording this tool wrote; an existing one
    (outside the run folder's own recording) also needs ``overwrite``. A refusal names the
    recording as ``named`` (default ``--rrd PATH``: a resume's checkpoint names its own)."""
    named = named or f"--rrd {rrd}"
    target = Path(rrd).resolve()
    for name in (
        RESULTS_FILE,
        SCENARIO_FILE,
        SUMMARY_FILE,
        LOCK_FILE,
        MANIFEST_FILE,
        REPORT_FOLDER,
    ):
        if target == (out_dir / name).resolve():
            raise RunFolderError(
                f"{named}: that is the run's {name}; choose another file for the recording"
            )
    if target.is_dir():
        raise RunFolderError(f"{named}: is a folder; expected the path of a .rrd file")
    if not os.path.lexists(rrd):
        return
    if os.path.islink(rrd):
        raise RunFolderError(f"{named}: is a link; give the file itself, or a new path")
    if not regular(Path(rrd)):
        raise RunFolderError(
            f"{named}: is not a regular file (a device, pipe or socket); expected the "
            "path of a new .rrd file or of an earlier recording"
        )
    if not is_our_recording(Path(rrd)):
        raise RunFolderError(
            f"{named}: exists and is not a recording auv-cosim wrote (only a new file or "
            "an earlier recording is written over); choose another file"
        )
    own = (out_dir / RECORDING_FILE).resolve()
    if target != own and not overwrite:
        raise RunFolderError(f"{named}: exists; pass --overwrite to replace it")


def lock_folder(
    path: Path, kind: str = "run", names: OptionNames = FLAGS, option: str = "out"
) -> int:
    """Lock the folder ``path`` (a ``kind`` folder: "run" or "study") without waiting;
    return the lock's descriptor (:func:`unlock_folder` releases it). Raises
    RunFolderError naming the process holding it (and the folder as ``names`` name
    ``option``: out, or resume for a run resumed in its own folder)."""
    lock = path / LOCK_FILE
    for _ in range(5):  # a previous holder may remove the file between open and lock
        fd = _open_lock(path, kind, names, option)
        if not _try_lock(fd):
            holder = _holder(fd)
            os.close(fd)
            if option == "resume":  # no other folder to choose: the run is this one's
                raise RunFolderError(
                    f"{names.given(option, path)}: the run folder is in use by {holder}: "
                    "wait for that run to end, then resume again"
                )
            raise RunFolderError(
                f"{kind} folder {path} is in use by {holder}: wait for that {kind} to end or "
                f"choose another {names.option('out')}"
            )
        try:
            current = os.stat(lock).st_ino == os.fstat(fd).st_ino
        except FileNotFoundError:
            current = False
        if current:
            try:
                os.ftruncate(fd, 0)
                os.write(
                    fd, f"{os.getpid()} {' '.join(sys.argv)}\n".encode(errors="surrogateescape")
                )
            except OSError as exc:  # a full disk: no lock file left behind
                unlock_folder(path, fd)
                raise RunFolderError(
                    f"{names.given(option, path)}: cannot write {lock}: {exc.strerror or exc}"
                ) from None
            return fd
        os.close(fd)
    raise RunFolderError(f"{kind} folder {path}: cannot take its lock (it keeps changing)")


_NO_FOLLOW = getattr(os, "O_NOFOLLOW", 0)  # not on Windows


def _open_lock(path: Path, kind: str, names: OptionNames, option: str) -> int:
    """Open (or create) the lock file of the folder ``path``: a regular file of one name,
    never through a link. A folder from elsewhere (a tarball, a shared /tmp folder) may
    hold the lock file as a symbolic or hard link to one of the user's files, which the
    lock would truncate and write into: refused, naming it. Raises RunFolderError."""
    lock, refusal = path / LOCK_FILE, ""
    try:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT | _NO_FOLLOW, 0o666)
    except OSError as exc:
        if exc.errno != errno.ELOOP:
            raise RunFolderError(
                f"{names.given(option, path)}: cannot write in the {kind} folder: "
                f"{exc.strerror or exc}"
            ) from None
        refusal = "a symbolic link"
    else:
        status = os.fstat(fd)
        if not stat.S_ISREG(status.st_mode) or status.st_nlink != 1:
            os.close(fd)
            refusal = "a hard link" if stat.S_ISREG(status.st_mode) else "not a regular file"
    if refusal:
        raise RunFolderError(
            f"{kind} folder {path}: {LOCK_FILE}: {refusal}, not a lock file of ours (from "
            f"wherever the folder came); remove it{_or_another(names, option)}"
        )
    return fd


def _or_another(names: OptionNames, option: str) -> str:
    """The end of a refusal of the folder: choose another one (none for a resume)."""
    return "" if option == "resume" else f", or choose another {names.option(option)}"


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
