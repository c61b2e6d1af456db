"""A run killed once it has written its first checkpoint, for the tests of resuming."""

from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import time
from pathlib import Path

from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.outputs.run_files import MANIFEST_FILE


def kill_after_checkpoint(
    command: list[str],
    out: Path,
    timeout: float = 300.0,
    with_guard: bool = False,
    past: float | None = None,
) -> int:
    """Start ``command`` in a process group of its own, SIGTERM the group once the run's
    first checkpoint is in ``out`` (with ``past``: its first checkpoint of a time past
    ``past`` s, a resumed run's first after the one it resumed from); its exit code.
    ``with_guard``: SIGKILL the group and the run's tail guard (in a session of its own)
    at once, as a batch system killing the job's cgroup or a power cut does, once the
    run's manifest also records the checkpoint (as the run's file, by its SHA-256: the
    run's last act in a checkpoint). The group is killed whatever happens."""
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + timeout
        while not (_saved_past(out, past) and (not with_guard or _recorded(out))):
            assert proc.poll() is None, f"the run ended before a checkpoint: {proc.stderr}"
            assert time.monotonic() < deadline, "no checkpoint in time"
            time.sleep(0.02)
        if not with_guard:
            os.killpg(proc.pid, signal.SIGTERM)
            return proc.wait(timeout=timeout)
        while not _children(proc.pid):  # (the guard may still be starting)
            assert proc.poll() is None, f"the run ended without a tail guard: {proc.stderr}"
            assert time.monotonic() < deadline, "no tail guard in time"
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGSTOP)  # none of them acts between the kills
        guards = _children(proc.pid)
        for pid in guards:
            os.kill(pid, signal.SIGKILL)
        os.killpg(proc.pid, signal.SIGKILL)
        return proc.wait(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        assert proc.stderr is not None
        proc.stderr.close()


def _saved_past(out: Path, past: float | None) -> bool:
    """``out`` holds a checkpoint (with ``past``: of a time past ``past`` s)."""
    if past is None:
        return (out / CHECKPOINT_FILE).exists()
    try:
        return float(json.loads((out / CHECKPOINT_FILE).read_text())["time"]) > past
    except (OSError, ValueError, KeyError):
        return False  # (none yet, or being replaced)


def _recorded(out: Path) -> bool:
    """The run's manifest records the checkpoint in ``out`` (by its SHA-256)."""
    try:
        checkpoint = hashlib.sha256((out / CHECKPOINT_FILE).read_bytes()).hexdigest()
        files = json.loads((out / MANIFEST_FILE).read_text())["files"]
    except (OSError, ValueError, KeyError):
        return False  # (being replaced)
    return any(e.get("path") == CHECKPOINT_FILE and e.get("sha256") == checkpoint for e in files)


def _children(pid: int) -> list[int]:
    """The processes ``pid`` started that run still (Linux: /proc)."""
    text = Path(f"/proc/{pid}/task/{pid}/children").read_text()
    return [int(child) for child in text.split()]
