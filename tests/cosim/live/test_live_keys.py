"""Interactive runs through a pseudo-terminal: keys in, set-points out, terminal restored.

The command line runs in a subprocess (its own process group, killed in a ``finally``) on
the built FMUs (bs-3) with a pty as its terminal; the test types arrows, a heading-mode key
the autopilot refuses while running, and ``q``, and reads the status line and summary.json.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import pty
import re
import select
import signal
import subprocess
import sys
import termios
import time
from pathlib import Path

import pandas as pd
import pytest

from cosim.live.keys import DEPTH_STEP, YAW_STEP, keys_of

TIMEOUT_S = 120.0  # generous: the machine may be busy; nothing here is timed


@pytest.fixture(scope="module")
def fmu_dir(fmu_paths: dict[str, Path]) -> Path:
    return fmu_paths["AuvAutopilot"].parent


def test_arrow_escape_sequences_are_keys() -> None:
    assert keys_of("\x1b[A\x1b[Bq\x1bOC\x1b[D1") == ["up", "down", "q", "right", "left", "1"]


class Terminal:
    """The parent's side of the pty: what the run wrote so far, and keys to type."""

    def __init__(self, fd: int) -> None:
        self.fd, self.text = fd, ""

    def read_until(self, pattern: str) -> re.Match[str]:
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            found = re.search(pattern, self.text)
            if found:
                return found
            ready, _, _ = select.select([self.fd], [], [], 0.1)
            if ready:
                try:
                    self.text += os.read(self.fd, 4096).decode("utf-8", "replace")
                except OSError:  # the run ended and closed its side
                    break
        raise AssertionError(f"no {pattern!r} in the terminal: {self.text[-2000:]!r}")

    def time_shown(self) -> float:
        """The simulated time (s) the status line shows last."""
        return float(re.findall(r"t (\d+\.\d+) s", self.text)[-1])

    def read_past(self, seconds: float) -> None:
        """Read until the status line shows a time ``seconds`` past the one shown now: the
        overrides requested before have then been applied at a communication point."""
        target = self.time_shown() + seconds
        deadline = time.monotonic() + TIMEOUT_S
        while self.time_shown() < target:
            if time.monotonic() > deadline:
                raise AssertionError(f"the run did not reach t = {target} s: {self.text[-500:]!r}")
            ready, _, _ = select.select([self.fd], [], [], 0.1)
            if ready:
                self.text += os.read(self.fd, 4096).decode("utf-8", "replace")

    def type(self, keys: str) -> None:
        os.write(self.fd, keys.encode())


@pytest.mark.slow
def test_keys_change_the_set_points_and_q_ends_the_run(fmu_dir: Path, tmp_path: Path) -> None:
    parent, child = pty.openpty()
    before = termios.tcgetattr(child)
    out = tmp_path / "run"
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir),
               "--out", str(out), "--no-rrd", "--stop-time", "120", "--real-time", "2",
               "--interactive"]  # fmt: skip
    proc = subprocess.Popen(command, stdin=child, stdout=child, stderr=child,
                            start_new_session=True)  # fmt: skip
    terminal = Terminal(parent)
    try:
        terminal.read_until(r"t \d+\.\d+ s")  # stepping: the status line shows the time
        terminal.type("\x1b[C\x1b[C")  # right twice: yaw +2 steps
        terminal.read_until(r"yaw_sp \+10\.0 deg")
        terminal.type("\x1b[B")  # down: deeper by one step
        terminal.read_until(r"depth_sp 1\.0 m")
        terminal.read_past(0.2)  # the three set-points applied before the run is ended
        terminal.type("2")  # heading mode: sliding mode
        terminal.read_until(r"mode 2 ")
        terminal.type("m")  # lock the moving mass now
        terminal.read_until(r"mass locked")
        terminal.read_past(0.2)
        terminal.type("q")
        assert proc.wait(timeout=TIMEOUT_S) == 130  # ended like Ctrl-C
        after = termios.tcgetattr(child)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        os.close(parent)
        os.close(child)
    assert after == before  # the terminal is back in the mode it was found in
    summary = json.loads((out / "summary.json").read_text())
    applied = [(o["set"], o["source"]) for o in summary["overrides"]]
    locked = summary["overrides"][-1]["set"]["controller.mass_lock_time"]
    assert applied == [
        ({"controller.yaw_setpoint": YAW_STEP}, "keys"),
        ({"controller.yaw_setpoint": 2 * YAW_STEP}, "keys"),
        ({"controller.depth_setpoint": DEPTH_STEP}, "keys"),
        ({"controller.heading_mode": 2}, "keys"),
        ({"controller.mass_lock_time": locked}, "keys"),
    ]
    assert locked > 0.0  # the simulated time the key was pressed
    results = pd.read_csv(out / "results.csv")
    applied_at = summary["overrides"][-1]["time"]  # the communication point it applied at
    held = results[results["time"] >= applied_at + 0.011]
    assert len(held) > 0 and (held["controller.mass_position_cmd"] == 0.0).all()
    assert math.isclose(2 * YAW_STEP, math.radians(10.0))
