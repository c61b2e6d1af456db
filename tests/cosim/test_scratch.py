"""Each process's scratch folder: removed as the process ends, and by a later process's
purge once the process is gone however it ended (SIGKILL included), with the paths it
claimed; never while its process lives."""

from __future__ import annotations

import contextlib
import os
import signal
import stat
import subprocess
import sys
import tempfile
import threading
from collections.abc import Iterator
from pathlib import Path

import locket
import pytest
from process_group import started_in_group

from cosim import scratch

# a process that makes its scratch folder and a claimed folder beside it, says where, then
# either waits for its standard input to close or kills itself
MAKER = """
import os, signal, sys, tempfile
from pathlib import Path
import locket

from cosim import scratch
folder = scratch.process_folder()
claimed = Path(tempfile.mkdtemp(prefix="claimed-"))
scratch.claim(claimed)
print(folder, claimed, flush=True)
if sys.argv[1] == "kill":
    os.kill(os.getpid(), signal.SIGKILL)
sys.stdin.read()
"""


@contextlib.contextmanager
def maker(tmpdir: Path, how: str) -> Iterator[subprocess.Popen]:
    """MAKER run with ``how`` in a process group of its own, killed on the way out."""
    env = {**os.environ, "TMPDIR": str(tmpdir), "PYTHONPATH": os.pathsep.join(sys.path)}
    command = [sys.executable, "-c", MAKER, how]
    with started_in_group(command, stdin=subprocess.PIPE, stderr=None, env=env) as proc:
        yield proc


def test_a_killed_process_folder_and_claims_go_at_the_next_purge(tmp_path: Path) -> None:
    with maker(tmp_path, "kill") as proc:
        out, _ = proc.communicate(timeout=60)
    assert proc.returncode == -signal.SIGKILL
    folder, claimed = map(Path, out.split())
    assert folder.is_dir() and claimed.is_dir()
    assert scratch.purge(tmp_path / scratch.SCRATCH_DIR) == [folder]
    assert not folder.exists() and not claimed.exists()
    assert not Path(f"{folder}{scratch.LOCK_SUFFIX}").exists()


def test_a_live_process_folder_stays_and_goes_as_it_ends(tmp_path: Path) -> None:
    with maker(tmp_path, "wait") as proc:
        assert proc.stdout is not None
        folder, claimed = map(Path, proc.stdout.readline().split())
        assert scratch.purge(tmp_path / scratch.SCRATCH_DIR) == []
        assert folder.is_dir() and claimed.is_dir()
        proc.communicate(timeout=60)  # its standard input closes: it ends normally
    assert proc.returncode == 0
    assert not folder.exists() and not Path(f"{folder}{scratch.LOCK_SUFFIX}").exists()


def test_a_purge_waits_for_a_folder_being_made(tmp_path: Path) -> None:
    """A purge that found the global lock taken (another process making its folder: a
    study's workers start together) gave up, and as each process purges once, a killed
    study's folders stayed after the next study; it waits for the lock now."""
    with maker(tmp_path, "kill") as proc:
        out, _ = proc.communicate(timeout=60)
    folder = Path(out.split()[0])
    base = tmp_path / scratch.SCRATCH_DIR
    making = locket.lock_file(str(base / "global.lock"))
    making.acquire()
    threading.Timer(0.3, making.release).start()  # the folder made
    assert scratch.purge(base) == [folder]


POSIX_USERS = pytest.mark.skipif(not hasattr(os, "getuid"), reason="no users' ids here")


@POSIX_USERS
def test_the_scratch_folders_base_is_the_users_own_and_private(tmp_path: Path, monkeypatch):
    """One base for every user of a shared /tmp: another user's runs listed this user's
    folders and lock files, and their purge could be handed paths to remove."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(scratch, "_own", {})  # this process's own folder is elsewhere
    base = tmp_path / f"auv-cosim-scratch-{os.getuid()}"
    base.mkdir(mode=0o755)  # as an older version, or a umask of 022, made it
    base.chmod(0o755)
    folder = scratch.process_folder()
    try:
        assert folder.parent == base
        assert stat.S_IMODE(base.stat().st_mode) == 0o700
    finally:
        scratch.remove(folder)


@POSIX_USERS
@pytest.mark.parametrize("squatted", ["symlink", "other user"])
def test_a_base_that_is_not_the_users_own_is_refused_naming_it(
    tmp_path: Path, monkeypatch, squatted: str
) -> None:
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(scratch, "_own", {})
    base = tmp_path / f"auv-cosim-scratch-{os.getuid()}"
    if squatted == "symlink":
        (tmp_path / "elsewhere").mkdir()
        base.symlink_to(tmp_path / "elsewhere")
    else:
        if os.getuid() != 0:
            pytest.skip("making a folder another user's takes root")
        base.mkdir()
        os.chown(base, 65534, 65534)  # nobody's
    with pytest.raises(PermissionError, match=rf"temporary folder {base} is .*not this user"):
        scratch.process_folder()
    assert scratch._own == {}
