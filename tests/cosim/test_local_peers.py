"""cosim.local_peers: the owner of the other end of a TCP connection from this machine,
read from Linux's /proc/net/tcp and tcp6."""

from __future__ import annotations

import contextlib
import os
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest

from cosim.local_peers import another_user, peer_owner

pytestmark = pytest.mark.skipif(not Path("/proc/net/tcp").exists(), reason="Linux's /proc/net/tcp")


@contextlib.contextmanager
def connected(family: socket.AddressFamily, host: str) -> Iterator[socket.socket]:
    """The server's side of a connection this process makes to itself on ``host``."""
    with socket.socket(family) as server:
        server.bind((host, 0))
        server.listen(1)
        with socket.create_connection(server.getsockname()[:2], timeout=10):
            accepted, _ = server.accept()
            with accepted:
                yield accepted


@pytest.mark.parametrize(("family", "host"), [(socket.AF_INET, "127.0.0.1"),
                                              (socket.AF_INET6, "::1")])  # fmt: skip
def test_the_owner_of_a_connection_from_this_process_is_this_user(
    family: socket.AddressFamily, host: str
) -> None:
    """IPv4 and IPv6: the client's socket is found, owned by this process's user, who is
    no other user."""
    if family == socket.AF_INET6 and not socket.has_ipv6:
        pytest.skip("no IPv6")
    with connected(family, host) as accepted:
        assert peer_owner(accepted.getpeername(), accepted.getsockname()) == os.geteuid()
        assert another_user(accepted) is None


def test_a_peer_no_socket_of_this_machine_has_no_owner() -> None:
    """An address pair no socket of this machine holds (a client elsewhere): unknown."""
    assert peer_owner(("192.0.2.7", 1), ("192.0.2.8", 2)) is None  # TEST-NET-1
