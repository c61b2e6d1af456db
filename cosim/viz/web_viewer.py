"""``auv-cosim view RUN --web``: a recording in Rerun's web viewer, on 127.0.0.1 only.

The recording is served as a file: this process serves it over HTTP (port F, only that
file, to the viewer's page only), and the ``rerun`` binary (rerun-sdk 0.41) hosts the web
viewer's page: ``rerun --serve-web --bind 127.0.0.1 --web-viewer-port W
http://127.0.0.1:F/recording.rrd``. Given a URL the viewer can open itself, rerun starts no
gRPC server, and the viewer loads the file as a file. (Loaded into rerun's gRPC proxy, a
file reached the viewer as a live stream, and the viewer showed a "latency" counter of the
seconds since the file's rows were logged, which means nothing for a file.) The page alone
shows Rerun's welcome screen; the viewer opens the recording only when told where it is, by
the ``url`` query parameter naming the file's URL, URL-encoded -- :func:`viewer_url` builds
that one URL (rerun's own log line names ``localhost``, which a browser may resolve to
``::1``, where nothing listens). Both servers bind 127.0.0.1, never every interface
(rerun's default ``--bind`` is 0.0.0.0): to look from another machine, forward the two ports
over ssh.

The server runs in this process's process group, so Ctrl-C in the terminal (and a test
ending the group) ends it too; :func:`serve` also ends it on SIGTERM/SIGHUP or any error,
and on Linux the kernel ends it when this process dies, however it dies (SIGKILL
included: the parent-death signal, :func:`_die_with_parent`).

A recording cut short -- its run was killed, or is still writing it -- has no footer, and
rerun's importer waited for the rest of such a file forever (the viewer never finished
loading): :func:`whole_recording` serves a copy completed by ``rerun rrd migrate``
instead, and says so.
"""

from __future__ import annotations

import contextlib
import ctypes
import ctypes.util
import http.server
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
import webbrowser
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any
from urllib.parse import quote

from cosim.errors import CosimError
from cosim.local_peers import another_user
from cosim.scratch import process_folder
from cosim.viz.ports import FILE_PORT, WEB_PORT

HOST = "127.0.0.1"
START_TIMEOUT = 60.0  # s for the rerun binary to start listening
MIGRATE_TIMEOUT = 120.0  # s for `rerun rrd migrate` to complete a copy of a cut recording
FOOTER = b"FOOT"  # rerun 0.41: a whole .rrd ends with its 4-byte magic, FOOT, a version
SCRATCH_PREFIX = "auv-cosim-view-"  # the temporary folder of a completed copy
PR_SET_PDEATHSIG = 1  # prctl(2): the signal a Linux process gets when its parent dies


def file_url(rrd: Path, file_port: int = FILE_PORT) -> str:
    """Where this process serves the recording ``rrd`` over HTTP."""
    return f"http://{HOST}:{file_port}/{quote(rrd.name)}"


def viewer_url(rrd: Path, web_port: int = WEB_PORT, file_port: int = FILE_PORT) -> str:
    """The web viewer's address with ``?url=`` naming the recording's file URL."""
    return f"http://{HOST}:{web_port}/?url={quote(file_url(rrd, file_port), safe='')}"


def serve_command(executable: str, rrd: Path, web_port: int, file_port: int) -> list[str]:
    """The rerun command line hosting the web viewer's page on :data:`HOST` only, for the
    recording served at :func:`file_url` (a URL: rerun starts no gRPC server)."""
    url = file_url(rrd, file_port)
    return [executable, "--serve-web", "--bind", HOST, "--web-viewer-port", str(web_port), url]


@contextlib.contextmanager
def _file_server(rrd: Path, port: int, web_port: int) -> Iterator[None]:
    """``rrd`` served over HTTP on :data:`HOST` at :func:`file_url` while inside: that one
    path only, readable by the web viewer's page (CORS: its origin only), and on Linux by
    this user's programs only (another user's process of this machine gets 403).

    Written with the standard library's ``http.server``: rerun's binary serves a file only
    through its gRPC proxy (the live stream above)."""
    name, origin = f"/{quote(rrd.name)}", f"http://{HOST}:{web_port}"

    class Recording(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            self._answer(body=True)

        def do_HEAD(self) -> None:  # what a browser or curl -I asks first (was 501)
            self._answer(body=False)

        def _answer(self, body: bool) -> None:
            owner = another_user(self.connection)
            if owner is not None:  # on a shared machine: another user's process
                self.send_error(403, f"served to the programs of its own user, not uid {owner}")
                return
            if self.path != name:
                self.send_error(404)
                return
            with contextlib.suppress(OSError), rrd.open("rb") as file:
                self.send_response(200)
                self.send_header("Content-Type", "application/octet-stream")
                self.send_header("Content-Length", str(rrd.stat().st_size))
                self.send_header("Access-Control-Allow-Origin", origin)
                self.end_headers()
                if body:
                    shutil.copyfileobj(file, self.wfile)

        def log_message(self, *args: Any) -> None:
            """Quiet: the terminal shows the URL, not each request."""

    server = http.server.ThreadingHTTPServer((HOST, port), Recording)
    server.daemon_threads = True
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield
    finally:
        server.shutdown()
        server.server_close()


def serve(executable: str, rrd: Path, web_port: int, file_port: int, open_browser: bool) -> int:
    """Serve ``rrd`` until Ctrl-C (or SIGTERM/SIGHUP); print the one URL that opens it.

    A port of 0 picks a free one. Returns 130 after Ctrl-C, 128 + the signal number
    after SIGTERM/SIGHUP (each saying so in a line on stderr), else 0 (the server ended
    by itself, with status 0).

    Raises:
        CosimError: a port is taken, or the server did not start or failed while serving
            (its status or signal and its last log line).
    """
    executable = _binary(executable)
    web_port, file_port = _free_port(web_port, "--web-port"), _free_port(file_port, "--file-port")
    if web_port == file_port:
        raise CosimError(f"--web-port and --file-port are both {web_port}: give two ports")
    with _stop_signals_raise(), tempfile.TemporaryFile() as log, contextlib.ExitStack() as scratch:
        try:
            served = rrd
            if not _ends_with_footer(rrd):  # a folder only then: a SIGKILL'd view leaves none
                # in this process's scratch folder: a killed view's goes at the next run
                copy = tempfile.TemporaryDirectory(prefix=SCRATCH_PREFIX, dir=process_folder())
                folder = scratch.enter_context(copy)
                served = whole_recording(executable, rrd, Path(folder))
            return _serve_until_stopped(
                executable, rrd, served, (web_port, file_port), log, open_browser
            )
        except _StopSignalError as stop:
            print(f"stopped serving {rrd} ({signal.Signals(stop.signum).name})", file=sys.stderr)
            return 128 + stop.signum
        except KeyboardInterrupt:  # a line of its own: the shell's prompt comes after it
            print(f"stopped serving {rrd} (Ctrl-C)", file=sys.stderr)
            return 130


def _serve_until_stopped(
    executable: str,
    rrd: Path,
    served: Path,
    ports: tuple[int, int],
    log: IO[bytes],
    open_browser: bool,
) -> int:
    """Serve ``served`` (``rrd`` or its completed copy) on ``ports`` (the page's, the
    file's), its log to ``log``, until the server ends; the server is ended on the way
    out, whatever stops it."""
    web_port, file_port = ports
    command = serve_command(executable, served, web_port, file_port)
    with _file_server(served, file_port, web_port):
        server = subprocess.Popen(
            command, stdin=subprocess.DEVNULL, stdout=log, stderr=log,
            preexec_fn=_die_with_parent(),
        )  # fmt: skip
        try:
            _wait_listening(server, (web_port,), log)
            url = viewer_url(served, web_port, file_port)
            print(f"serving {rrd} on {HOST} only; open this URL (Ctrl-C stops):\n  {url}")
            print(_forward_hint(web_port, file_port), flush=True)
            if open_browser:
                _open(url)
            code = server.wait()
            if code != 0:  # a failed command (1): the server's own status means other things
                raise CosimError(f"the rerun server {ended(code)} while serving: {_last(log)}")
            return 0
        finally:
            _end(server)


def ended(code: int) -> str:
    """How a process that returned ``code`` (``subprocess``'s: minus the signal number for
    one killed by a signal) ended: "exited with status 2", "was killed by SIGSEGV"."""
    if code >= 0:
        return f"exited with status {code}"
    try:
        return f"was killed by {signal.Signals(-code).name}"
    except ValueError:
        return f"was killed by signal {-code}"


def _last(log: IO[bytes]) -> str:
    """The last line the server wrote to ``log``, or "no output"."""
    log.seek(0)
    lines = log.read().decode("utf-8", "replace").strip().splitlines()
    return lines[-1] if lines else "no output"


def whole_recording(executable: str, rrd: Path, folder: Path) -> Path:
    """What to serve for ``rrd``: the file itself if it ends with rerun's footer; else a
    copy in ``folder`` completed by ``rerun rrd migrate`` (what the file holds now, with a
    footer), after saying so (the file is served once, so a run still writing it is shown
    as far as it got).

    Raises:
        CosimError: the file holds no recording yet (cut short before any data: the
            viewer would show its welcome page forever), or the copy cannot be made.
    """
    if _ends_with_footer(rrd):
        return rrd
    copy = folder / "recording.rrd"
    try:
        shutil.copyfile(rrd, copy)
        done = subprocess.run(
            [executable, "rrd", "migrate", str(copy)], stdin=subprocess.DEVNULL,
            capture_output=True, text=True, timeout=MIGRATE_TIMEOUT, check=False,
        )  # fmt: skip
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise CosimError(f"cannot complete a copy of {rrd}: {exc}") from None
    if done.returncode != 0 or not _ends_with_footer(copy):
        lines = (done.stderr or done.stdout).strip().splitlines()
        raise CosimError(
            f"{rrd} was cut short and cannot be completed: {lines[-1] if lines else 'no output'}"
        )
    from rerun.chunk import RrdReader

    if not list(RrdReader(copy).recordings()):
        raise CosimError(
            f"{rrd} holds no recording yet: it was cut short after {rrd.stat().st_size} bytes, "
            "before any data (its run was killed as it started)"
        )
    why = "a run is still writing it" if _being_written(rrd) else "its run was killed"
    print(
        f"auv-cosim view: note: {rrd} was cut short ({why}): serving a completed copy of what "
        "it holds",
        file=sys.stderr,
        flush=True,
    )  # a message: stdout holds the URL a script reads
    return copy


def _being_written(rrd: Path) -> bool:
    """Whether a run holds the lock on ``rrd`` (it is writing it)."""
    try:
        import fcntl
    except ImportError:  # Windows: the runs lock it otherwise; take it as finished
        return False
    try:
        fd = os.open(rrd, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        return True
    finally:
        os.close(fd)  # closing releases a lock taken here
    return False


def _ends_with_footer(rrd: Path) -> bool:
    """Whether ``rrd`` ends with rerun's footer: its first 4 bytes (the magic) then FOOT,
    12 bytes before the end (what ``rerun rrd verify`` looks for first). Read by hand:
    verifying the whole file takes seconds for a long run, this takes two reads."""
    try:
        with open(rrd, "rb") as f:
            magic = f.read(4)
            f.seek(0, os.SEEK_END)
            if f.tell() < 24:
                return False
            f.seek(-12, os.SEEK_END)
            return f.read(8) == magic + FOOTER
    except OSError:
        return False


def _die_with_parent() -> Any:
    """The ``preexec_fn`` that makes the kernel send the server SIGKILL when this process
    dies, however it dies (Linux ``prctl(PR_SET_PDEATHSIG)``), or None elsewhere. Written
    with ctypes: the standard library has no binding. The signal follows the thread that
    started the child: :func:`serve` runs on the main thread, which lives as long as the
    process does."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        prctl = ctypes.CDLL(ctypes.util.find_library("c"), use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    parent = os.getpid()

    def in_child() -> None:  # between fork and exec: no allocation-heavy work
        prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
        if os.getppid() != parent:  # the parent died before the call: nothing would come
            os._exit(1)

    return in_child


def _binary(executable: str) -> str:
    """The rerun binary itself where rerun-sdk's package has it: pip's ``rerun`` is a
    Python wrapper that runs the binary as a child and, when sent SIGTERM, exits and
    leaves the server running."""
    try:
        import rerun_cli
    except ImportError:
        return executable
    binary = Path(rerun_cli.__file__).with_name("rerun")
    return str(binary) if binary.is_file() else executable


def _free_port(port: int, flag: str) -> int:
    """``port`` if nothing listens on it on :data:`HOST`, a free one for 0; a refusal
    names the ``flag`` that gave it (the default's, when none was given)."""
    if not 0 <= port <= 65535:
        raise CosimError(f"{flag} {port}: expected a port from 0 (any free port) to 65535")
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((HOST, port))
        except OSError as exc:
            raise CosimError(
                f"{flag} {port}: port {port} on {HOST} is taken ({exc.strerror}): another "
                f"viewer is running; stop it or give another {flag} (0 picks a free port)"
            ) from None
        return probe.getsockname()[1]


def _wait_listening(server: subprocess.Popen, ports: tuple[int, ...], log: Any) -> None:
    """Return once every port accepts connections; raise if the server exits first."""
    deadline = time.monotonic() + START_TIMEOUT
    waiting = list(ports)
    while waiting:
        if server.poll() is not None:
            raise CosimError(f"the rerun server exited ({server.returncode}): {_last(log)}")
        if time.monotonic() > deadline:
            raise CosimError(f"the rerun server did not listen on {waiting} within "
                             f"{START_TIMEOUT:g} s")  # fmt: skip
        with contextlib.suppress(OSError), socket.create_connection((HOST, waiting[0]), 0.5):
            waiting.pop(0)
            continue
        time.sleep(0.1)


def _forward_hint(web_port: int, file_port: int) -> str:
    return (
        f"  (from another machine: ssh -L {web_port}:{HOST}:{web_port} "
        f"-L {file_port}:{HOST}:{file_port} HOST, then open the same URL there)"
    )


def _open(url: str) -> None:
    """Open ``url`` in a browser if this machine has one; else say so."""
    try:
        opened = webbrowser.get().open(url)
    except webbrowser.Error:
        opened = False
    if not opened:
        print(
            "auv-cosim view: no browser found here: open the URL above yourself",
            file=sys.stderr,
            flush=True,
        )


def _end(server: subprocess.Popen) -> None:
    """Stop the server and reap it (SIGTERM, then SIGKILL after 10 s)."""
    if server.poll() is None:
        server.terminate()
        try:
            server.wait(timeout=10)
        except subprocess.TimeoutExpired:
            server.kill()
            server.wait()


class _StopSignalError(Exception):
    def __init__(self, signum: int) -> None:
        super().__init__(signum)
        self.signum = signum


@contextlib.contextmanager
def _stop_signals_raise() -> Iterator[None]:
    """SIGTERM and SIGHUP raise :class:`_StopSignalError` (so the server is ended) while on."""

    def stop(signum: int, _frame: Any) -> None:
        raise _StopSignalError(signum)

    names = [name for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name)]
    previous = {name: signal.signal(getattr(signal, name), stop) for name in names}
    try:
        yield
    finally:
        for name, handler in previous.items():
            signal.signal(getattr(signal, name), handler)
