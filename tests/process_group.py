"""A command run to its end in a process group of its own, the group killed as it returns
or times out: whatever the command started (a Dask cluster, a viewer, a forked worker)
ends with it, whatever happens in the test."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
from collections.abc import Sequence
from typing import Any


def run_in_group(
    command: Sequence[Any], *, timeout: float, **popen: Any
) -> subprocess.CompletedProcess:
    """``command`` run with ``popen`` (subprocess.Popen's keywords; stdout and stderr
    captured as text unless given), its result; ``subprocess.TimeoutExpired`` after
    ``timeout`` s, the group killed either way."""
    options = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, "text": True, **popen}
    proc = subprocess.Popen(command, start_new_session=True, **options)
    try:
        out, err = proc.communicate(timeout=timeout)
    finally:
        with contextlib.suppress(ProcessLookupError):  # the group may have ended on its own
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)
