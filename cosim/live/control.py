"""The control endpoint of a live run: JSON lines over a TCP socket.

One JSON object per line each way (the JSON Lines convention, https://jsonlines.org: UTF-8,
one value per ``\\n``-terminated line; a ``\\r\\n`` or a lone ``\\r`` ends a line too), so
any language's JSON library and a socket are a client (scripts/live_client.py is one).
Requests, exactly one reply line each::

    {"set": {"controller.yaw_setpoint": 0.5}}  -> {"ok": true, "set": {...}, "name": "live-1",
                                                   "t": 12.34} once applied
    {"get": ["plant.yaw", "plant.down"]}       -> {"t": 12.3, "values": {"plant.yaw": ...}}
    {"pause": true} / {"pause": false}         -> {"ok": true, "paused": true}
    {"stop": true}                             -> {"ok": true} (ends the run like Ctrl-C)

A ``set`` is checked whole (:meth:`cosim.engine.live.LiveControl.request`) and its reply
waits until the master has applied it at a communication point: ``ok`` means applied and
logged; an angle in rad of more than a full turn (degrees typed by habit) is applied all
the same, and the reply says so in ``"warnings": ["<one line>"]``. A refused request, or a
``set`` the run ended before applying, gets ``{"error": "<one line: the value and the
reason>"}``. ``get`` answers with the values of the last communication point.

A client need not wait for a reply before its next request: a ``set`` is queued as it is
read, so sets sent faster than the run's points (a joystick at 1000 a second) all come into
force at the next point after they arrive, in order; any other request waits until the sets
before it on its connection are applied. The replies come back in the order of the requests.

What the reader refuses, with one reply each and the connection kept: a line over
:data:`MAX_LINE` bytes (discarded whole, up to its end: its tail is never read as a
request), bytes that are not UTF-8 JSON, JSON nested deeper than the decoder takes, an
integer of more than :data:`MAX_DIGITS` digits. At most :data:`MAX_CLIENTS` connections
are served at once; one more is told so in one line and closed. A client that paused the
run and disconnects lets go of its pause (the run resumes when no one else holds it, and
says so on stderr and in the recording).

The socket is bound to 127.0.0.1 unless the address names another interface (``HOST:PORT``,
``[IPv6]:PORT``): there is no authentication, so an address other than the loopback prints a
warning: anyone who can reach the port can steer the run. On Linux a connection from a
process of another user of this machine is refused with one line
(:func:`cosim.local_peers.another_user`).

Built on the standard library's ``socketserver`` (a thread per client) with a line reader of
our own (``socket.makefile().readline(limit)`` returns the first ``limit`` bytes of a long line
and leaves its tail to be read as the next line): no dependency for a few requests a second.
"""

from __future__ import annotations

import contextlib
import ipaddress
import json
import os
import queue
import re
import socket
import socketserver
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

from cosim.engine.live import LiveControl, OverrideError, Ticket
from cosim.errors import CosimError
from cosim.local_peers import another_user

DEFAULT_HOST = "127.0.0.1"
MAX_LINE = 65536  # bytes: a longer request line is refused whole
MAX_DIGITS = 20  # digits of a JSON integer: a longer one is refused
MAX_CLIENTS = 16  # connections served at once: one more is refused with a line
MAX_PENDING = 1024  # requests of a connection waiting for their replies: reading pauses
_CHUNK = 65536  # bytes read from a socket at a time
_END_OF_LINE = re.compile(rb"[\r\n]")
_USAGE = 'expected one of {"set": {...}}, {"get": [...]}, {"pause": true|false}, {"stop": true}'
TOO_LONG = None  # what :func:`lines` yields for a line over MAX_LINE bytes


def parse_address(text: str) -> tuple[str, int]:
    """``"HOST:PORT"``, ``"[IPv6]:PORT"`` or ``"PORT"`` (host 127.0.0.1) -> (host, port);
    port 0 picks a free one. :class:`CosimError` names what is wrong."""
    expected = "expected PORT, HOST:PORT or [IPv6]:PORT with PORT in 0..65535"
    if text.startswith("["):
        host, bracket, rest = text[1:].partition("]")
        if not bracket or not rest.startswith(":"):
            raise CosimError(f"--control {text!r}: {expected}")
        try:
            ipaddress.IPv6Address(host)
        except ValueError:
            raise CosimError(f"--control {text!r}: {host!r} is not an IPv6 address") from None
        port = rest[1:]
    else:
        host, _, port = text.rpartition(":")
        if ":" in host:
            raise CosimError(
                f"--control {text!r}: an IPv6 address goes in brackets, as in [::1]:5555"
            )
    if not (port.isascii() and port.isdigit() and int(port) <= 65535):
        raise CosimError(f"--control {text!r}: port {port!r}: {expected} (ASCII digits)")
    return host or DEFAULT_HOST, int(port)


def lines(recv: Callable[[int], bytes]) -> Iterator[bytes | None]:
    """The request lines read with ``recv`` (a socket's), without their ends (``\\n``,
    ``\\r\\n`` or ``\\r``); :data:`TOO_LONG` (None) once for a line over :data:`MAX_LINE`
    bytes, whose bytes are then skipped up to its end. A last line without an end counts."""
    line, discarding, after_cr = bytearray(), False, False
    while data := recv(_CHUNK):
        i = 1 if after_cr and data[:1] == b"\n" else 0  # the \n of a \r\n split over reads
        after_cr = False
        while i < len(data):
            end = _END_OF_LINE.search(data, i)
            j = len(data) if end is None else end.start()
            if not discarding:
                line += data[i:j]
                if len(line) > MAX_LINE:
                    discarding = True
                    line.clear()
                    yield TOO_LONG
            if end is None:
                break
            if not discarding:
                yield bytes(line)
            line.clear()
            discarding = False
            if data[j : j + 1] == b"\r":
                if j + 1 == len(data):
                    after_cr = True
                elif data[j + 1 : j + 2] == b"\n":
                    j += 1
            i = j + 1
    if line and not discarding:
        yield bytes(line)


def submit(
    live: LiveControl,
    line: bytes | None,
    source: str,
    settle: Callable[[], None] = lambda: None,
) -> Callable[[], dict[str, Any]]:
    """Act on one request line, a ``set`` by queueing it for the next point, anything else
    after ``settle()`` (a connection's: until the sets before it are applied); returns
    what gives the reply (never raises), waiting until a ``set`` is applied."""
    try:
        verb, arg = _request(line)
        if verb == "set" and isinstance(arg, dict):
            ticket = live.request(arg, source)
            return lambda: _set_reply(ticket)
        settle()
        reply = _do(live, (verb, arg), source)
    except OverrideError as exc:
        reply = {"error": str(exc)}
    return lambda: reply


def _set_reply(ticket: Ticket) -> dict[str, Any]:
    ticket.wait()
    if ticket.refused is not None:
        return {"error": f"set {ticket.values}: {ticket.refused}"}
    reply = {"ok": True, "set": ticket.values, "name": ticket.name, "t": ticket.time}
    return reply | ({"warnings": ticket.doubts} if ticket.doubts else {})


def _request(line: bytes | None) -> tuple[str, Any]:
    """The (verb, argument) of one request line; :class:`OverrideError` if malformed."""
    if line is TOO_LONG:
        raise OverrideError(f"request line longer than {MAX_LINE} bytes: refused whole")
    try:
        request = json.loads(bytes(line or b"").decode("utf-8"), parse_int=_integer)
    except OverrideError:
        raise
    except RecursionError:
        raise OverrideError("not a JSON line: nested too deeply") from None
    except ValueError as exc:  # also UnicodeDecodeError: not UTF-8
        raise OverrideError(f"not a JSON line: {exc}") from None
    if not isinstance(request, dict) or len(request) != 1:
        raise OverrideError(f"{bytes(line or b'').strip()[:80]!r}: {_USAGE}")
    verb, arg = next(iter(request.items()))
    return verb, arg


def _integer(text: str) -> int:
    if len(text.lstrip("-")) > MAX_DIGITS:
        raise OverrideError(
            f"not a JSON line: an integer of {len(text)} digits (at most {MAX_DIGITS})"
        )
    return int(text)


def _do(live: LiveControl, request: tuple[str, Any], source: str) -> dict[str, Any]:
    verb, arg = request
    if verb == "get" and isinstance(arg, list) and all(isinstance(r, str) for r in arg):
        t, values = live.latest(arg)
        return {"t": t, "values": values}
    if verb == "pause" and isinstance(arg, bool):
        live.pause(source) if arg else live.resume()
        return {"ok": True, "paused": arg}
    if verb == "stop" and arg is True:
        live.stop(source)
        return {"ok": True}
    shown = repr(arg) if len(repr(arg)) <= 80 else f"{repr(arg)[:77]}..."
    raise OverrideError(f"{verb[:40]!r} with {shown}: expected set {{name: value}}, get "
                        "[names], pause true|false or stop true")  # fmt: skip


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
    live: LiveControl
    clients: set[socket.socket]
    busy: set[threading.Thread]  # handlers writing a reply
    guard: threading.Lock

    def process_request(self, request: Any, client_address: Any) -> None:
        """Serve the client in a thread of its own, unless it is a process of another user
        of this machine (:func:`cosim.local_peers.another_user`) or :data:`MAX_CLIENTS` are
        served."""
        owner = another_user(request)
        if owner is not None:
            mine = os.geteuid()
            self._refuse(request, f"connection from a process of uid {owner} refused: the "
                         f"endpoint serves the programs of its own user (uid {mine})")  # fmt: skip
            return
        with self.guard:
            full = len(self.clients) >= MAX_CLIENTS
            if not full:
                self.clients.add(request)
        if full:
            self._refuse(request, f"too many connections: at most {MAX_CLIENTS} at once; "
                         "closing this one")  # fmt: skip
            return
        super().process_request(request, client_address)

    def _refuse(self, request: Any, refusal: str) -> None:
        """Send ``refusal`` as the one error line, and close the connection."""
        with contextlib.suppress(OSError):
            request.sendall((json.dumps({"error": refusal}) + "\n").encode())
        self.shutdown_request(request)


class _Client(socketserver.BaseRequestHandler):
    """One connection: this thread reads and acts on the requests as they arrive (a run of
    ``set`` lines is queued at once, for the next point), a writer thread of its own sends
    the replies in the order of the requests, each once it is known."""

    server: _Server

    def handle(self) -> None:
        host, port = self.client_address[:2]
        source = f"control {_shown(host, port)}"
        live = self.server.live
        replies: queue.Queue[Callable[[], dict[str, Any]] | None] = queue.Queue(MAX_PENDING)
        writer = threading.Thread(target=self._write, args=(replies,), daemon=True)
        writer.start()
        try:
            for line in lines(self.request.recv):
                replies.put(submit(live, line, source, settle=replies.join))
        except OSError:
            pass  # the client went away, or the endpoint is closing
        finally:
            if live.release(source):
                print(f"{source} disconnected while holding the run paused: resumed",
                      file=sys.stderr, flush=True)  # fmt: skip
            replies.put(None)
            writer.join()  # the sets sent are answered (applied, or the run ended) first
            with self.server.guard:
                self.server.clients.discard(self.request)

    def _write(self, replies: queue.Queue[Callable[[], dict[str, Any]] | None]) -> None:
        """Send each reply as it is known, in order, until the None after the last; a
        client gone keeps the rest from being sent, not from being waited for."""
        gone, me = False, threading.current_thread()
        while (reply := replies.get()) is not None:
            self.server.busy.add(me)
            try:
                text = json.dumps(reply()) + "\n"
                if not gone:
                    self.request.sendall(text.encode())
            except OSError:
                gone = True  # the client went away, or the endpoint is closing
            finally:
                self.server.busy.discard(me)
                replies.task_done()
        replies.task_done()


def _shown(host: str, port: int) -> str:
    return f"[{host}]:{port}" if ":" in host else f"{host}:{port}"


def _server_class(host: str) -> type[_Server]:
    if ":" not in host:
        return _Server
    return type("_Server6", (_Server,), {"address_family": socket.AF_INET6})


class ControlServer:
    """The endpoint, serving in a thread from :meth:`open` until :meth:`close`."""

    def __init__(self, server: _Server) -> None:
        self._server = server
        host, port = server.server_address[:2]
        self.host: str = host.decode() if isinstance(host, bytes | bytearray) else host
        self.address = _shown(self.host, port)  # as bound (the port chosen for port 0)
        self._thread = threading.Thread(
            target=server.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True
        )
        self._thread.start()

    @classmethod
    def open(cls, live: LiveControl, address: str) -> ControlServer:
        """Bind ``address`` (:func:`parse_address`); :class:`CosimError` if it cannot."""
        host, port = parse_address(address)
        try:
            server = _server_class(host)((host, port), _Client)
        except (OSError, OverflowError) as exc:
            reason = getattr(exc, "strerror", None) or exc
            raise CosimError(f"--control {address}: cannot listen: {reason}") from None
        server.live, server.clients, server.busy = live, set(), set()
        server.guard = threading.Lock()
        return cls(server)

    @property
    def reachable_from_network(self) -> bool:
        """Bound to an address other than the loopback (no authentication: warn); an
        IPv4 loopback written as IPv6 (``::ffff:127.0.0.1``) is the loopback too."""
        try:
            address = ipaddress.ip_address(self.host.split("%")[0])
        except ValueError:
            return True
        mapped = getattr(address, "ipv4_mapped", None)
        return not (address.is_loopback or (mapped is not None and mapped.is_loopback))

    def close(self) -> None:
        """Stop serving and drop every client (after the replies being written); safe to
        call twice."""
        self._server.shutdown()
        deadline = time.monotonic() + 2.0
        while self._server.busy and time.monotonic() < deadline:
            time.sleep(0.01)
        for client in list(self._server.clients):
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
        self._server.server_close()
        self._thread.join(timeout=2.0)
