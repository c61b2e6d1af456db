"""A run killed once it has written its first checkpoint, for the tests of resuming."""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

from cosim.outputs.checkpoint_file import CHECKPOINT_FILE


def kill_after_checkpoint(command: list[str], out: Path, timeout: float = 300.0) -> int:
    """Start ``command`` in a process group of its own, SIGTERM the group once the run's
    first checkpoint is in ``out``; its exit code. The group is killed whatever happens."""
    proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + timeout
        while not (out / CHECKPOINT_FILE).exists():
            assert proc.poll() is None, f"the run ended before a checkpoint: {proc.stderr}"
            assert time.monotonic() < deadline, "no checkpoint in time"
            time.sleep(0.02)
        os.killpg(proc.pid, signal.SIGTERM)
        return proc.wait(timeout=timeout)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        assert proc.stderr is not None
        proc.stderr.close()
