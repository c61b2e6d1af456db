"""Steering a live run from the terminal: key presses, no Enter (``--interactive``).

=========  =====================================================================
key        what it does (each change is an override, checked and logged)
=========  =====================================================================
<- / ->    yaw set-point -/+ :data:`YAW_STEP` (``<instance>.yaw_setpoint``)
up / down  depth set-point -/+ :data:`DEPTH_STEP` (up: shallower; ``.depth_setpoint``)
0 .. 3     heading mode (``.heading_mode``: 0 off, 1 LQR, 2 sliding mode, 3 backstepping)
m          lock the moving mass at the centre (``.mass_lock_time`` = now); again: release (-1)
p          pause / resume
q          end the run like Ctrl-C (partial results, exit code 130)
=========  =====================================================================

The set-points belong to the first instance with that input unconnected (the autopilot
``controller`` of the built-in scenarios), whose tunable parameters ``heading_mode`` and
``mass_lock_time`` take effect at its next step. A value the FMU does not take while
running is refused like any override; the status line shows the reason. The status line
(stderr) shows the set-points, the heading mode, the mass (free or locked), the simulated
time, the real-time factor and the last message.

The terminal is put in cbreak mode (``tty.setcbreak``: keys arrive one by one, Ctrl-C still
sends SIGINT) and restored by :meth:`KeyPad.close` -- and at interpreter exit if that was
never reached. Standard library ``termios``/``tty``/``select`` only (POSIX).
"""

from __future__ import annotations

import atexit
import contextlib
import math
import os
import select
import sys
import termios
import threading
import tty
from collections.abc import Callable
from typing import IO

from cosim.engine.live import LiveControl, OverrideError
from cosim.errors import CosimError
from cosim.scenario.spec import Scenario

YAW_STEP = math.radians(5.0)  # rad per arrow press
DEPTH_STEP = 1.0  # m per arrow press
_ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}
_REFRESH_S = 0.5  # the status line is redrawn at least this often


def keys_of(data: str) -> list[str]:
    """The keys in what the terminal sent: ``"up"`` for ESC [ A (or ESC O A), else the
    character itself."""
    keys, i = [], 0
    while i < len(data):
        if data[i] == "\x1b" and data[i + 1 : i + 2] in ("[", "O") and i + 2 < len(data):
            keys.append(_ARROWS.get(data[i + 2], "escape"))
            i += 3
        else:
            keys.append(data[i])
            i += 1
    return keys


def _owner(scenario: Scenario, variable: str) -> str:
    """The instance whose input ``variable`` is unconnected (else the first that has it)."""
    having = [n for n, i in scenario.instances.items() if variable in i.interface.variables]
    free = [n for n in having if variable in scenario.unconnected_inputs(n)]
    return (free or having or list(scenario.instances))[0]


def _number(value: object, default: float) -> float:
    return float(value) if isinstance(value, int | float) else default


class KeyPad:
    """Reads keys from ``fd`` in a thread and turns them into overrides on ``live``."""

    def __init__(
        self,
        live: LiveControl,
        scenario: Scenario,
        status: Callable[[], str] | None = None,
        fd: int | None = None,
        out: IO[str] | None = None,
    ) -> None:
        self.live, self.status = live, status
        self.fd = sys.stdin.fileno() if fd is None else fd
        self.out = sys.stderr if out is None else out
        if not os.isatty(self.fd):
            raise CosimError("--interactive: standard input is not a terminal")
        controller = _owner(scenario, "yaw_setpoint")
        names = ("yaw_setpoint", "depth_setpoint", "heading_mode", "mass_lock_time")
        self.refs = {name: f"{controller}.{name}" for name in names}
        unset = dict(zip(names, (0.0, 0.0, 0.0, -1.0), strict=True))  # off, for a missing one
        self.values = {n: _number(scenario.start_value(controller, n), unset[n]) for n in names}
        self.message = "keys: <- -> yaw, up/down depth, 0-3 mode, m mass, p pause, q quit"
        self._saved = termios.tcgetattr(self.fd)
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)

    def start(self) -> None:
        """cbreak mode on, reading keys from now on."""
        atexit.register(self._restore)
        tty.setcbreak(self.fd)
        self._thread.start()

    def close(self) -> None:
        """Stop reading, restore the terminal, end the status line; safe to call twice."""
        self._done.set()
        if self._thread.is_alive():
            self._thread.join(timeout=2.0)
        self._restore()
        atexit.unregister(self._restore)

    def _restore(self) -> None:
        with contextlib.suppress(termios.error, OSError):
            termios.tcsetattr(self.fd, termios.TCSADRAIN, self._saved)
        with contextlib.suppress(OSError, ValueError):
            self.out.write("\n")
            self.out.flush()

    def _read(self) -> None:
        try:
            while not self._done.is_set():
                ready, _, _ = select.select([self.fd], [], [], _REFRESH_S)
                if ready:
                    data = os.read(self.fd, 64).decode("utf-8", "replace")
                    if not data:
                        return  # end of input
                    for key in keys_of(data):
                        self.press(key)
                self.draw()
        except (OSError, ValueError):
            return  # the terminal went away: the run goes on without keys

    def press(self, key: str) -> None:
        """What ``key`` does (see the module docstring)."""
        if key == "q":
            self.message = "stopping"
            self.live.stop()
        elif key == "p":
            self.live.resume() if self.live.paused else self.live.pause()
            self.message = "paused (p resumes)" if self.live.paused else "running"
        elif key in ("left", "right"):
            sign = 1.0 if key == "right" else -1.0
            self._set("yaw_setpoint", self.values["yaw_setpoint"] + sign * YAW_STEP)
        elif key in ("up", "down"):
            sign = -1.0 if key == "up" else 1.0
            self._set("depth_setpoint", self.values["depth_setpoint"] + sign * DEPTH_STEP)
        elif key in "0123" and len(key) == 1:
            self._set("heading_mode", int(key))
        elif key == "m":
            locked = self.values["mass_lock_time"] >= 0.0
            self._set("mass_lock_time", -1.0 if locked else (self.live.time or 0.0))
        self.draw()

    def _set(self, name: str, value: float | int) -> None:
        ref = self.refs[name]
        try:
            self.live.request({ref: value}, "keys")
        except OverrideError as exc:
            self.message = str(exc)
            return
        if name in self.values:
            self.values[name] = float(value)
        self.message = f"{ref} = {value:.6g}"

    def draw(self) -> None:
        """Redraw the status line: set-points, time, real-time factor, last message."""
        t = self.live.time
        yaw, depth = math.degrees(self.values["yaw_setpoint"]), self.values["depth_setpoint"]
        rt = f"  {self.status()}" if self.status is not None else ""
        clock = "-" if t is None else f"{t:.2f}"
        mode = int(self.values["heading_mode"])
        mass = "locked" if self.values["mass_lock_time"] >= 0.0 else "free"
        line = (
            f"yaw_sp {yaw:+.1f} deg  depth_sp {depth:.1f} m  mode {mode}  mass {mass}  "
            f"t {clock} s{rt}  | {self.message}"
        )
        self.out.write(f"\r\x1b[K{line}")
        self.out.flush()
