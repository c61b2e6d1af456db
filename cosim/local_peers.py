"""Who is at the other end of a TCP connection from this machine: the servers that bind
127.0.0.1 (the live control endpoint, the web viewer's file server) serve the programs of
their own user only, since on a shared machine every user's programs reach the loopback.

Linux lists every TCP socket of the machine, with the uid that owns it, in /proc/net/tcp
and /proc/net/tcp6; elsewhere there is no such list and no check (None). Standard library
only.
"""

from __future__ import annotations

import ipaddress
import os
import socket
import sys
from typing import Any

PROC_NET_TCP = ("/proc/net/tcp", "/proc/net/tcp6")  # Linux: every TCP socket, with its uid


def another_user(connection: socket.socket) -> int | None:
    """The uid of the process at the other end of the accepted ``connection`` if it is a
    process of this machine of another user than this process's (effective) one; None
    for this user's, for a client on another machine, a client gone already, or where
    the owner cannot be known (not Linux)."""
    try:
        owner = peer_owner(connection.getpeername(), connection.getsockname())
    except OSError:
        return None  # the client is gone: its reads end at once
    return owner if owner is not None and owner != os.geteuid() else None


def peer_owner(peer: tuple[Any, ...], own: tuple[Any, ...]) -> int | None:
    """The uid owning the TCP socket of this machine at ``peer`` that is connected to
    ``own`` (an accepted connection's two addresses, ``(host, port, ...)``), as Linux lists
    it in /proc/net/tcp and tcp6; None for a client on another machine, or without /proc
    (not Linux: no check there)."""
    pairs = {(a, b) for a in _proc_forms(peer) for b in _proc_forms(own)}
    for table in PROC_NET_TCP:
        try:
            with open(table, encoding="ascii") as file:
                rows = [line.split() for line in file.readlines()[1:]]
        except OSError:
            continue
        for row in rows:
            if len(row) > 7 and (row[1], row[2]) in pairs:
                return int(row[7])
    return None  # listed in neither table: not of this machine, or closed since


def _proc_forms(address: tuple[Any, ...]) -> list[str]:
    """``address`` as /proc/net/tcp* write it (``0100007F:1F90``: the address in 32-bit
    words of the host's byte order, the port in hex), IPv4 and IPv4-mapped IPv6 both."""
    ip = ipaddress.ip_address(str(address[0]).split("%")[0])
    forms = [ip.packed]
    if isinstance(ip, ipaddress.IPv4Address):
        forms.append(ipaddress.IPv6Address(f"::ffff:{ip}").packed)
    elif ip.ipv4_mapped is not None:
        forms.append(ip.ipv4_mapped.packed)
    words = [
        "".join(f"{int.from_bytes(b[i : i + 4], sys.byteorder):08X}" for i in range(0, len(b), 4))
        for b in forms
    ]
    return [f"{word}:{int(address[1]):04X}" for word in words]
