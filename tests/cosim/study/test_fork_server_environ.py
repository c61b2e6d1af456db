"""The command asks for the fork server twice (early, then as its cluster starts): Dask's
pre-spawn environment, read by parsing Dask's defaults file, is read and set once."""

from __future__ import annotations

from multiprocessing import forkserver

import pytest

from cosim.study import fork_server


@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_the_pre_spawn_environment_is_read_once_per_process(monkeypatch) -> None:
    reads: list[int] = []
    monkeypatch.setattr(forkserver, "ensure_running", lambda: None)  # no server started
    monkeypatch.setattr(fork_server, "_environ_set", False)
    monkeypatch.setattr(fork_server, "pre_spawn_environ", lambda: reads.append(1) or {})
    assert fork_server.start() and fork_server.start()
    assert reads == [1]
