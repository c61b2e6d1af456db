"""A recording file written by us, not by rerun's own file writer.

rerun-sdk 0.41's ``FileSink`` reports a failed write (disk full) only by logging it, and
afterwards ``RecordingStream.disconnect()`` -- and ``set_sinks`` with a blueprint -- wait
forever for the dead writer thread (measured on a full tmpfs). So the ``FileSink`` here
writes into a pipe (``/dev/fd/N``), and a thread of ours copies the bytes into the file:
a failed write is recorded and reported by :meth:`RrdFile.sync` (the thread keeps
draining the pipe, so rerun never blocks), and the bytes are the same ``.rrd`` stream a
``FileSink`` writes (footer included once the stream is disconnected).

:meth:`RrdFile.sync`, after ``RecordingStream.flush``, waits until every byte rerun wrote
is in the file, and returns the file's size then: a message boundary, which a killed run's
tail guard cuts the file back to. Where ``/dev/fd`` does not exist (Windows), rerun's
``FileSink`` writes the file itself (:func:`file_sink`).
"""

from __future__ import annotations

import contextlib
import os
import select
import struct
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from cosim.limits import unwritten

if TYPE_CHECKING:  # rerun itself is imported where a sink is made: it takes ~0.3 s
    import rerun as rr

try:  # FIONREAD: the bytes waiting in a pipe
    import fcntl
    import termios
except ImportError:  # Windows
    fcntl = termios = None  # type: ignore[assignment]

OVERLAY_FILE = "overlay.rrd"  # a study folder's recording of several runs (cosim.viz.overlay)
STUDY_FILE = "study.json"  # what marks a study folder (cosim.study.folder)
PIPE_FOLDER = Path("/dev/fd")
READ_SIZE = 1 << 20


def pumped() -> bool:
    """Whether recordings go through :class:`RrdFile` here (POSIX with /dev/fd)."""
    return fcntl is not None and hasattr(select, "poll") and PIPE_FOLDER.is_dir()


class RrdFile:
    """``path`` receiving what :meth:`sink` is given. Raises OSError if it cannot be
    created."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._out = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o666)
        self._read, self._write = os.pipe()
        self._lock = threading.Lock()  # held while a piece is read and written
        self._written = 0
        self._synced = 0
        self.error: OSError | None = None
        self._thread = threading.Thread(target=self._pump, name=f"rrd {self.path}", daemon=True)
        self._thread.start()

    def sink(self) -> rr.FileSink:
        """The rerun sink that feeds this file."""
        import rerun as rr

        return rr.FileSink(str(PIPE_FOLDER / str(self._write)))

    def sync(self, timeout: float) -> int:
        """Wait until the bytes rerun wrote so far are in the file; return its size.

        Raises OSError naming the file if a write failed or ``timeout`` s passed.
        """
        deadline = time.monotonic() + timeout
        while True:
            with self._lock:  # the pump is not between a read and its write
                if self.error is not None:
                    raise OSError(
                        f"cannot write the recording {self.path}: {unwritten(self.error)}"
                    )
                if _waiting(self._read) == 0:
                    self._synced = self._written
                    return self._synced
            if time.monotonic() > deadline:
                raise OSError(
                    f"cannot write the recording {self.path}: timed out after {timeout} s"
                )
            time.sleep(0.001)

    def close(self, timeout: float) -> None:
        """After rerun let go of the sink (disconnect): take the rest, close the file.

        Raises OSError if a write failed.
        """
        with contextlib.suppress(OSError):
            os.close(self._write)  # the pump sees the end once rerun closed its copy too
        self._thread.join(timeout)
        if not self._thread.is_alive():
            os.close(self._read)
        os.close(self._out)
        if self.error is not None:
            raise OSError(f"cannot write the recording {self.path}: {unwritten(self.error)}")

    def _pump(self) -> None:
        poller = select.poll()
        poller.register(self._read, select.POLLIN)
        while True:
            poller.poll()
            with self._lock:
                data = os.read(self._read, READ_SIZE)
                if not data:
                    return  # every writer closed the pipe
                if self.error is None:
                    self._copy(data)

    def _copy(self, data: bytes) -> None:
        view = memoryview(data)
        try:
            while view:
                view = view[os.write(self._out, view) :]
            self._written += len(data)
        except OSError as exc:
            self.error = exc
            with contextlib.suppress(OSError):  # back to the last whole flush
                os.ftruncate(self._out, self._synced)


def file_sink(path: Path) -> rr.FileSink:
    """rerun's own file writer (where :func:`pumped` is false)."""
    import rerun as rr

    return rr.FileSink(str(path))


def set_sinks(rec: rr.RecordingStream, application_id: str, sink: Any, blueprint: Any) -> None:
    """``rec.set_sinks(sink, default_blueprint=blueprint)`` (``rec`` made with
    ``application_id``) without keeping a stream behind: rerun-sdk makes a stream for the
    blueprint at each call, which its own memory sink holds, with two threads, for the
    life of the process; this one is disconnected once its bytes are handed over, so that
    :func:`drop_closed_streams` ends it. (Private rerun-sdk calls: the pin keeps 0.41.)"""
    import rerun_bindings
    from rerun.recording_stream import RecordingStream

    stream = RecordingStream._from_native(
        rerun_bindings.new_blueprint(
            application_id=application_id,
            make_default=False,
            make_thread_default=False,
            default_enabled=True,
        )
    )
    try:
        stream.set_time("blueprint", sequence=0)
        blueprint.to_blueprint()._log_to_stream(stream)
        storage = stream.memory_recording().storage
        rerun_bindings.set_sinks([sink], default_blueprint=storage, recording=rec.to_native())
    finally:
        stream.disconnect()


def drop_closed_streams() -> None:
    """End the Rerun streams nothing in Python holds any more (those of a recording
    closed and let go of, and the blueprint stream each ``set_sinks`` makes), with their
    threads. rerun-sdk keeps every stream a Python process made, disconnected, with its
    batcher and forwarding threads running, until asked: a process that writes a
    recording per run (a notebook re-running a cell) kept 4 threads and about 3 MB a run."""
    import rerun_bindings

    rerun_bindings.flush_and_cleanup_orphaned_recordings()


def _waiting(fd: int) -> int:
    return struct.unpack("i", fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"))[0]
