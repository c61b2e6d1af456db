"""The command asks for the fork server twice (early, then as its cluster starts): Dask's
pre-spawn environment, read by parsing Dask's defaults file, is read and set once."""

from __future__ import annotations

from multiprocessing import forkserver
from pathlib import Path

import pytest

from cosim.study import fork_server


@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_the_pre_spawn_environment_is_read_once_per_process(monkeypatch) -> None:
    reads: list[int] = []
    monkeypatch.setattr(forkserver, "ensure_running", lambda: None)  # no server started
    monkeypatch.setattr(fork_server, "_pre_spawn", None)
    monkeypatch.setattr(fork_server, "pre_spawn_environ", lambda: reads.append(1) or {})
    assert fork_server.start() and fork_server.start()
    assert reads == [1]


# the command: a fork server importing server_environ, a probe that waits for a "go" file,
# then server_exit; SIGINT sent to the server while it waits (a Ctrl-C to the terminal's
# process group while the study starts), then the SIGINT and SIGTERM handlers of a worker
# it forks. The pool is closed and joined, not terminated (``with Pool``): its worker
# ignores SIGTERM, as a study's workers forked from the server do, and Pool.terminate ends
# with SIGTERM a worker that waits for the task queue's lock, which terminate takes and
# keeps: that pool's exit hung (1 run in 6 here).
INTERRUPTED_WHILE_IMPORTING = """
import os, pathlib, signal, tempfile, time
from multiprocessing import forkserver, get_context
os.chdir(tempfile.mkdtemp(dir="."))  # the server imports from here: a folder of this run
pathlib.Path("waiting_probe.py").write_text(
    "import pathlib, time\\n"
    "pathlib.Path('ready').touch()\\n"
    "while not pathlib.Path('go').exists():\\n"
    "    time.sleep(0.01)\\n"
)
context = get_context("forkserver")
context.set_forkserver_preload(
    ["cosim.study.server_environ", "waiting_probe", "cosim.study.server_exit"]
)
forkserver.ensure_running()
while not pathlib.Path("ready").exists():
    time.sleep(0.01)
os.kill(forkserver._forkserver._forkserver_pid, signal.SIGINT)
time.sleep(0.5)  # the signal is handled (or raises) while the probe still waits
pathlib.Path("go").touch()
pool = context.Pool(1)
handlers = pool.map(signal.getsignal, [signal.SIGINT, signal.SIGTERM])
pool.close()
pool.join()
print(handlers == [signal.default_int_handler, signal.SIG_IGN], flush=True)
"""


@pytest.mark.slow
@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_ctrl_c_while_the_fork_server_imports_prints_no_traceback(run_python) -> None:
    """A Ctrl-C while a sweep starts reaches the fork server still importing its preloads
    (multiprocessing ignores SIGINT there only once they are imported): it printed a
    KeyboardInterrupt traceback of dozens of lines under "interrupted". The server ignores
    it while it imports, and the workers it forks still take SIGINT as Python does."""
    assert fork_server.PRELOAD[0] == "cosim.study.server_environ"
    assert fork_server.PRELOAD[-1] == "cosim.study.server_exit"
    done = run_python(INTERRUPTED_WHILE_IMPORTING, timeout=120)
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, done.stderr
    assert done.returncode == 0 and done.stdout.split() == ["True"], done.stdout


# the command's own start of the server; SIGINT sent to it as soon as its interpreter
# catches SIGINT (its handler of KeyboardInterrupt set, its first preload not yet imported: a
# Ctrl-C to the terminal's process group as the sweep starts its server); then the SIGINT
# handler of a worker it forks
INTERRUPTED_WHILE_STARTING = """
import os, pathlib, signal, time
from multiprocessing import forkserver, get_context
from cosim.study import fork_server
spawn = forkserver.ensure_running


def catches_sigint(pid):
    status = pathlib.Path(f"/proc/{pid}/status").read_text()
    caught = [line.split()[1] for line in status.splitlines() if line.startswith("SigCgt:")]
    return int(caught[0], 16) >> (signal.SIGINT - 1) & 1


def spawn_then_ctrl_c():
    spawn()
    pid = forkserver._forkserver._forkserver_pid
    deadline = time.monotonic() + 30
    while not catches_sigint(pid) and time.monotonic() < deadline:
        time.sleep(0.001)
    os.kill(pid, signal.SIGINT)


forkserver.ensure_running = spawn_then_ctrl_c
assert fork_server.start()
pool = get_context("forkserver").Pool(1)
handler = pool.apply(signal.getsignal, (signal.SIGINT,))
pool.close()
pool.join()
print(handler is signal.default_int_handler, flush=True)
"""


@pytest.mark.slow
@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="no /proc to watch")
def test_ctrl_c_while_the_fork_server_starts_prints_no_traceback(run_python) -> None:
    """A Ctrl-C 0.4-0.7 s into ``auv-cosim sweep`` reached the fork server before its first
    preload ignored SIGINT (its interpreter starting, importing multiprocessing, then
    cosim): it printed a KeyboardInterrupt traceback (or "Fatal Python error:
    init_import_site") of 9 to 24 lines under "interrupted", and died. The server starts
    with the stop signals blocked, its first preload ignores them, then unblocks them."""
    done = run_python(INTERRUPTED_WHILE_STARTING, timeout=120)
    assert "Traceback" not in done.stderr and "KeyboardInterrupt" not in done.stderr, done.stderr
    assert done.returncode == 0 and done.stdout.split() == ["True"], done.stdout
