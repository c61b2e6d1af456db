"""The control endpoint of a live run: JSON lines over a local TCP socket.

One JSON object per line each way (the JSON Lines convention, https://jsonlines.org: UTF-8,
one value per ``\\n``-terminated line), so any language's JSON library and a socket are a
client (scripts/live_client.py is one in about 20 lines). Requests, one reply line each::

    {"set": {"controller.yaw_setpoint": 0.5}}  -> {"ok": true, "set": {...}}
    {"get": ["plant.yaw", "plant.down"]}       -> {"t": 12.3, "values": {"plant.yaw": ...}}
    {"pause": true} / {"pause": false}         -> {"ok": true, "paused": true}
    {"stop": true}                             -> {"ok": true} (ends the run like Ctrl-C)

A refused request gets ``{"error": "<one line: the value and the reason>"}``. A ``set`` is
checked whole (:meth:`cosim.engine.live.LiveControl.request`) and applied at the next
communication point; ``get`` answers with the values of the last one.

The socket is bound to 127.0.0.1 unless the address names another interface: there is no
authentication, so anyone who can reach the port can steer the run.

Built on the standard library's ``socketserver`` (a thread per client, line reads from the
socket's file): no dependency for a few requests a second.
"""

from __future__ import annotations

import contextlib
import json
import socket
import socketserver
import threading
from typing import Any

from cosim.engine.live import LiveControl, OverrideError
from cosim.errors import CosimError

DEFAULT_HOST = "127.0.0.1"
MAX_LINE = 65536  # bytes: a longer request line is refused


def parse_address(text: str) -> tuple[str, int]:
    """``"HOST:PORT"`` or ``"PORT"`` (host 127.0.0.1) -> (host, port); port 0 picks a free one."""
    host, _, port = text.rpartition(":")
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise CosimError(f"--control {text!r}: expected HOST:PORT or PORT with PORT in 0..65535")
    return host or DEFAULT_HOST, number


class _Server(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True
    live: LiveControl
    clients: set[socket.socket]


class _Client(socketserver.StreamRequestHandler):
    server: _Server

    def handle(self) -> None:
        self.server.clients.add(self.request)
        peer = "%s:%s" % self.client_address[:2]  # noqa: UP031
        try:
            while True:
                line = self.rfile.readline(MAX_LINE + 1)
                if not line:
                    return
                reply = answer(self.server.live, line, f"control {peer}")
                self.wfile.write((json.dumps(reply) + "\n").encode())
        except OSError:
            return  # the client went away, or the endpoint is closing
        finally:
            self.server.clients.discard(self.request)


def answer(live: LiveControl, line: bytes, source: str) -> dict[str, Any]:
    """The reply to one request line (never raises)."""
    try:
        if len(line) > MAX_LINE:
            raise OverrideError(f"request longer than {MAX_LINE} bytes")
        try:
            request = json.loads(line)
        except (ValueError, UnicodeDecodeError) as exc:
            raise OverrideError(f"not a JSON line: {exc}") from None
        if not isinstance(request, dict) or len(request) != 1:
            raise OverrideError(
                f'{line.strip()[:80]!r}: expected one of {{"set": {{...}}}}, '
                '{"get": [...]}, {"pause": true|false}, {"stop": true}'
            )
        return _do(live, *next(iter(request.items())), source)
    except OverrideError as exc:
        return {"error": str(exc)}


def _do(live: LiveControl, verb: str, arg: Any, source: str) -> dict[str, Any]:
    if verb == "set" and isinstance(arg, dict):
        return {"ok": True, "set": live.request(arg, source)}
    if verb == "get" and isinstance(arg, list) and all(isinstance(r, str) for r in arg):
        t, values = live.latest(arg)
        return {"t": t, "values": values}
    if verb == "pause" and isinstance(arg, bool):
        live.pause() if arg else live.resume()
        return {"ok": True, "paused": arg}
    if verb == "stop" and arg is True:
        live.stop()
        return {"ok": True}
    raise OverrideError(f"{verb!r} with {arg!r}: expected set {{name: value}}, get [names], "
                        "pause true|false or stop true")  # fmt: skip


class ControlServer:
    """The endpoint, serving in a thread from :meth:`open` until :meth:`close`."""

    def __init__(self, server: _Server) -> None:
        self._server = server
        host, port = server.server_address[:2]
        host = host.decode() if isinstance(host, bytes) else host
        self.address = f"{host}:{port}"  # as bound (the port chosen for port 0)
        self._thread = threading.Thread(
            target=server.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True
        )
        self._thread.start()

    @classmethod
    def open(cls, live: LiveControl, address: str) -> ControlServer:
        """Bind ``address`` (:func:`parse_address`); :class:`CosimError` if it cannot."""
        host, port = parse_address(address)
        try:
            server = _Server((host, port), _Client)
        except OSError as exc:
            raise CosimError(f"--control {address}: cannot listen: {exc.strerror or exc}") from None
        server.live, server.clients = live, set()
        return cls(server)

    def close(self) -> None:
        """Stop serving and drop every client; safe to call twice."""
        self._server.shutdown()
        for client in list(self._server.clients):
            with contextlib.suppress(OSError):
                client.shutdown(socket.SHUT_RDWR)
        self._server.server_close()
        self._thread.join(timeout=2.0)
