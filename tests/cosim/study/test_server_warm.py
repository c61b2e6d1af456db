"""The workers' fork server of ``auv-cosim sweep`` warms up once on the study the client
hands it (cosim/study/server_warm.py), so that each worker it forks starts with the FMUs'
package imported, their compiled plant code loaded and their libraries loaded, and
nothing of the warm-up live; it gives up, warming nothing, once the client has ended or
has not handed the study over in time."""

from __future__ import annotations

import contextlib
import gc
import hashlib
import os
import pickle
import re
import weakref
import zipfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from cosim.fmus import interface
from cosim.study import fork_server, server_warm
from cosim.study.execution import Job, read_interfaces
from cosim.study.server_warm import handed_over
from cosim.study.task import Base


def test_a_handed_over_study_is_read_once_and_its_file_removed(tmp_path: Path) -> None:
    path = tmp_path / fork_server.HAND_OVER_FILE
    path.write_bytes(b"study")
    assert handed_over(path, os.getppid(), wait_s=60.0) == b"study"
    assert not path.exists()


def test_the_server_gives_up_once_its_client_has_ended(tmp_path: Path) -> None:
    """Its parent is no longer the client that started it: nothing to wait for (the file
    never comes), whatever time is left."""
    gone = os.getppid() + 1  # not this process's parent
    assert handed_over(tmp_path / fork_server.HAND_OVER_FILE, gone, wait_s=3600.0) is None


def test_the_server_gives_up_when_no_study_comes_in_time(tmp_path: Path) -> None:
    assert handed_over(tmp_path / fork_server.HAND_OVER_FILE, os.getppid(), 0.05) is None


class _Checks:
    """``time`` for :mod:`cosim.study.server_warm` while its client checks a study for
    ``checks_s`` seconds and then hands it over: each look for the file is 1 s later."""

    def __init__(self, path: Path, checks_s: float) -> None:
        self.path, self.checks_s, self.now = path, checks_s, 0.0

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += 1.0
        if self.now >= self.checks_s:
            self.path.write_bytes(b"study")


def test_the_server_waits_for_the_study_as_long_as_its_checks_take(tmp_path, monkeypatch):
    """A study whose checks took longer than 5 s (an FMU build, a large plan) found the
    server given up: its workers started up to 0.5 s later, each warming up itself. The
    server waits while the client lives and has not said that no study is coming."""
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(server_warm, "time", _Checks(path, checks_s=30.0))
    assert handed_over(path, os.getppid()) == b"study"


def test_the_study_is_handed_over_once_and_none_ends_the_wait(tmp_path, monkeypatch) -> None:
    """The client hands its study over whole, once; a study that ends without one (its
    cluster closing) tells the server to wait no longer, with nothing to warm up on."""
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over({"study": 1}) is True
    assert pickle.loads(handed_over(path, os.getppid(), 0.0) or b"") == ({"study": 1}, {})
    assert fork_server.hand_over({"study": 2}) is False  # handed over already: no file
    assert not path.exists()
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over(None) is False
    assert handed_over(path, os.getppid(), 0.0) == b""


def test_a_study_handed_over_after_the_server_gave_up_is_not_taken(tmp_path, monkeypatch) -> None:
    """A server that stopped waiting (its wait over) warms nothing: the client is told
    its study was not taken, so it does not count on the time the warm-up would have
    left it (the page's matplotlib loaded then, beside runs already running)."""
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert handed_over(path, os.getppid(), 0.0) is None  # the server gave up
    assert fork_server.hand_over({"study": 1}) is False


def test_a_study_handed_over_just_before_the_server_gives_up_is_taken(
    tmp_path, monkeypatch
) -> None:
    """Handed over as the server's wait ends, the study is still warmed up on: the
    client was told it was taken, and it was."""
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over({"study": 1}) is True
    assert pickle.loads(handed_over(path, os.getppid(), -1.0) or b"") == ({"study": 1}, {})


def test_without_hard_links_the_study_is_handed_over_but_not_over_the_servers_mark(
    tmp_path, monkeypatch
) -> None:
    """A file system without hard links (the hand-over's way of never replacing a file):
    the study is still handed over whole, and still not taken once the server gave up."""

    def no_links(source: object, target: object) -> None:
        raise PermissionError(1, "Operation not permitted")

    monkeypatch.setattr(fork_server.os, "link", no_links)
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over({"study": 1}) is True
    assert pickle.loads(handed_over(path, os.getppid(), 0.0) or b"") == ({"study": 1}, {})
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert handed_over(path, os.getppid(), 0.0) is None  # the server gave up
    assert fork_server.hand_over({"study": 2}) is False
    assert path.read_bytes() == b""  # its mark, not replaced
    assert list(tmp_path.iterdir()) == [path]  # no part file left


def test_a_study_that_cannot_be_handed_over_ends_the_wait(tmp_path, monkeypatch) -> None:
    """A job pickle cannot write (a local function in it, say) is not handed over, and the
    server is told so at once: it does not keep the workers waiting for its whole wait."""
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over({"study": lambda: None}) is False
    assert handed_over(path, os.getppid(), 0.0) == b""  # told: nothing to warm up on
    assert not (tmp_path / f"{fork_server.HAND_OVER_FILE}.part").exists()


def test_a_server_whose_client_has_ended_takes_no_study(tmp_path, monkeypatch) -> None:
    """The server waits for the client that named the hand-over file, not for whatever
    process is its parent once its imports are done: a client that ended before then
    (a sweep refused at once) leaves the server nothing to wait for, the file unread."""
    from multiprocessing import forkserver

    monkeypatch.setattr(forkserver._forkserver, "_forkserver_pid", None)
    monkeypatch.setattr(fork_server, "_hand_over", None)  # (set by the next line)
    with fork_server._warm_up_named(True):  # this process is the client
        named = os.environ[fork_server.WARM_VARIABLE]
    path = Path(fork_server._hand_over or "")
    path.write_bytes(b"study")  # handed over, but by a client this process's parent is not
    warmed: list[bytes] = []
    monkeypatch.setattr(server_warm, "warm", warmed.append)
    monkeypatch.setattr(server_warm.gc, "freeze", lambda: None)
    monkeypatch.setenv(fork_server.WARM_VARIABLE, named)
    try:
        server_warm._warm_from_client()  # as a server whose parent is not the client
        assert (warmed, path.exists()) == ([], True)
    finally:
        path.unlink(missing_ok=True)


def test_what_the_warm_up_left_in_cycles_is_freed_before_it_is_frozen(
    tmp_path, monkeypatch
) -> None:
    """The warm-up's run leaves objects in reference cycles (its FMU slaves, its run
    folder): collected in the server before it freezes what it holds, not frozen into
    every worker it forks for the worker's lifetime."""

    class Left:
        cycle: object

    left: list[weakref.ref[Left]] = []

    def warm(content: bytes) -> None:
        run = Left()
        run.cycle = run
        left.append(weakref.ref(run))

    freed_when_frozen: list[bool] = []
    path = tmp_path / fork_server.HAND_OVER_FILE
    path.write_bytes(b"study")
    monkeypatch.setenv(fork_server.WARM_VARIABLE, f"{os.getppid()}:{path}")
    monkeypatch.setattr(server_warm, "warm", warm)
    monkeypatch.setattr(gc, "freeze", lambda: freed_when_frozen.append(left[0]() is None))
    enabled = gc.isenabled()
    gc.disable()  # no collection of its own between the warm-up and the freeze
    try:
        server_warm._warm_from_client()
    finally:
        if enabled:
            gc.enable()
    assert freed_when_frozen == [True]


WARMED = """
import os, sys, threading
from pathlib import Path
import psutil
from cosim.scratch import base_folder
from cosim.study import fork_server
from cosim.study.execution import make_job, open_client
from cosim.study.task import prepare
from cosim.study.unpacked import unpack

def probe(plugin):
    server = psutil.Process().parent()
    compiled = [m for n, m in sys.modules.items() if n.endswith("plant_fmu.model.compiled")]
    left = [p.name for p in base_folder().iterdir() if p.name.startswith(f"{server.pid}-")]
    return (bool(compiled) and all(bool(m.advance_into.signatures) for m in compiled),
            len(server.threads()), left, fork_server.warmed(plugin))

if __name__ == "__main__":
    fork_server.start(warm=True)
    base, _ = prepare("bs-3", 20.0, Path(sys.argv[1]))
    job, _ = make_job(base, {}, "none", unpacked=unpack(base.fmu_paths, Path(sys.argv[2])))
    fork_server.hand_over(job)
    with open_client(2) as client:
        print(sorted(client.run(probe, job.plugin).values()))
"""


@pytest.mark.slow
@pytest.mark.cluster
@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_workers_are_forked_warm_from_the_server(fmu_paths, run_python, tmp_path) -> None:
    """Before any task, each worker has the plant's compiled code loaded (the server's
    warm-up) and knows it was warmed up on this study, the server that forked it has one
    thread and no scratch folder left."""
    script = tmp_path / "warmed.py"
    script.write_text(WARMED, encoding="utf-8")
    (tmp_path / "fmus").mkdir()
    done = run_python(
        "import runpy, sys; sys.argv[1:] = sys.argv[1:3]; "
        f"runpy.run_path({str(script)!r}, run_name='__main__')",
        fmu_paths["AuvPlant"].parent,
        tmp_path / "fmus",
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == str([(True, 1, [], True)] * 2)


def test_a_study_refused_while_its_cluster_starts_ends_the_servers_wait(
    tmp_path, monkeypatch
) -> None:
    """A study refused after its cluster began to start (a locked or foreign output folder,
    a scenario refused) waits for the cluster to close; the cluster's workers wait for the
    fork server, which waits for the study: the refusal came only after the server's whole
    wait (10 min). Closing tells the server at once that no study is coming."""
    from cosim.study import execution

    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    told = []

    @contextlib.contextmanager
    def workers_forked_once_the_server_is_done(*args: object, **kw: object) -> Iterator[None]:
        told.append(handed_over(path, os.getppid(), 5.0))  # as the server's wait
        yield None

    monkeypatch.setattr(execution, "open_client", workers_forked_once_the_server_is_done)
    with execution.early_client(1):
        pass  # the study refused before its hand-over
    assert told == [b""]  # told that none is coming, not given up waiting


@pytest.mark.parametrize(("server_warmed_on", "warmed_again"), [("this", False), ("other", True)])
def test_a_worker_warms_up_again_only_if_the_server_did_not_on_its_study(
    tmp_path, monkeypatch, server_warmed_on: str, warmed_again: bool
) -> None:
    """A worker forked after the server's warm-up on its study skips its own (another run
    of one step, ~0.015 s of CPU on the way to its first run, which no later run needs);
    one forked from a server that warmed up on another study, or none, warms up."""
    from types import SimpleNamespace

    from cosim.study import execution

    job = SimpleNamespace(plugin="this", unpacked={}, fmu_files={}, data_files={}, base=None)
    plugin = execution.StudyPlugin(job, {})  # type: ignore[arg-type]
    plugin.setup(SimpleNamespace(local_directory=str(tmp_path)))
    monkeypatch.setattr(fork_server, "_warmed_on", server_warmed_on, raising=False)
    warm_ups: list[object] = []
    monkeypatch.setattr(execution, "warm_up", lambda *args: warm_ups.append(args))
    plugin.warm()
    plugin.warm()  # once at most
    assert len(warm_ups) == int(warmed_again)


def test_the_server_reads_no_model_description_the_client_has_read(
    fmu_paths, tmp_path, monkeypatch
) -> None:
    """The client's interfaces of the FMUs it copied for its local workers go with the
    study to the fork server, which warms up on the copies without reading their model
    descriptions again (~0.02 s of its CPU for bs-3, on the way to the first run); not
    for a copy of another content than its original's now, and a copy changed since is
    read again."""
    plant = fmu_paths["AuvPlant"]
    content = plant.read_bytes()
    copy = tmp_path / f"{hashlib.sha256(content).hexdigest()}.fmu"  # as unpacked names it
    copy.write_bytes(content)
    other = tmp_path / f"{'0' * 64}.fmu"  # named by another content: the original changed
    other.write_bytes(content)
    base = Base("bs-3", {}, {"plant": plant, "autopilot": plant})
    files = {"plant": str(copy), "autopilot": str(other)}
    job = Job(base, {}, "none", False, files, "plugin", "session")
    given = read_interfaces(job)  # in the client
    assert list(given) == [str(copy)]

    def read(path: Path, mtime_ns: int, size: int) -> None:
        raise AssertionError(f"{path} read again")

    monkeypatch.setattr(interface, "_given", {})  # in the server
    monkeypatch.setattr(interface, "_read", read)
    interface.given_interface(copy, given[str(copy)])
    found = interface.read_interface(copy)
    assert found.path == copy.resolve()
    assert (found.guid, found.variables) == (given[str(copy)].guid, given[str(copy)].variables)
    stat = copy.stat()
    os.utime(copy, ns=(stat.st_atime_ns, stat.st_mtime_ns + 10**9))
    with pytest.raises(AssertionError, match="read again"):
        interface.read_interface(copy)


def test_the_interfaces_are_read_for_a_waiting_server_only(tmp_path, monkeypatch) -> None:
    """The client reads the interfaces it hands over (hashing each FMU) only when a server
    waits for the study, not for a remote cluster or a study run from Python; reading them
    failing hands the study over without them, for the server to read as before."""
    calls: list[int] = []

    def interfaces() -> dict[str, str]:
        calls.append(1)
        return {"copy.fmu": "its interface"}

    def broken() -> dict[str, str]:
        raise RuntimeError("unreadable")

    monkeypatch.setattr(fork_server, "_hand_over", None)  # no server waits
    assert fork_server.hand_over({"study": 1}, interfaces) is False
    assert calls == []
    path = tmp_path / fork_server.HAND_OVER_FILE
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over({"study": 1}, broken) is True
    assert pickle.loads(handed_over(path, os.getppid(), 0.0) or b"") == ({"study": 1}, {})
    monkeypatch.setattr(fork_server, "_hand_over", str(path))
    assert fork_server.hand_over({"study": 1}, interfaces) is True
    handed = pickle.loads(handed_over(path, os.getppid(), 0.0) or b"")
    assert handed == ({"study": 1}, {"copy.fmu": "its interface"})
    assert calls == [1]


def _stored(source: Path, target: Path, guid: str | None = None) -> str:
    """``source``'s FMU at ``target``, every entry stored (its size the same whatever the
    content), its GUID replaced by ``guid`` (as long); the GUID it has."""
    with zipfile.ZipFile(source) as zin, zipfile.ZipFile(target, "w", zipfile.ZIP_STORED) as zout:
        for info in zin.infolist():
            data = zin.read(info)
            if info.filename == "modelDescription.xml":
                found = re.search(rb'guid="([^"]*)"', data)
                assert found is not None
                old = found[1].decode()
                data = data.replace(found[1], (guid or old).encode())
            info.compress_type = zipfile.ZIP_STORED
            zout.writestr(info, data)
    return guid or old


def test_a_changed_fmu_of_the_same_size_and_time_is_not_given_the_old_interface(
    fmu_paths, tmp_path
) -> None:
    """An FMU replaced by another of the same size and modification time (copied with its
    time kept, say) after the client read it: the client's copy is of the new content, and
    the interface handed over with it is not the old one's."""
    original = tmp_path / "plant.fmu"
    old_guid = _stored(fmu_paths["AuvPlant"], original)
    stat = original.stat()
    assert interface.read_interface(original).guid == old_guid  # the client read it
    new_guid = old_guid.translate(str.maketrans("0123456789abcdef", "fedcba9876543210"))
    _stored(fmu_paths["AuvPlant"], original, new_guid)
    os.utime(original, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    assert original.stat().st_size == stat.st_size
    content = original.read_bytes()
    copy = tmp_path / f"{hashlib.sha256(content).hexdigest()}.fmu"
    copy.write_bytes(content)
    base = Base("bs-3", {}, {"plant": original})
    job = Job(base, {}, "none", False, {"plant": str(copy)}, "plugin", "session")
    given = read_interfaces(job).get(str(copy))
    guid = None if given is None else given.guid
    assert guid in (None, new_guid), f"the copy of GUID {new_guid} given the interface of {guid}"
