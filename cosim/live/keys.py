"""Steering a live run from the terminal: key presses, no Enter (``--interactive``).

=========  =====================================================================
key        what it does (each change is an override, checked and logged)
=========  =====================================================================
<- / ->    yaw set-point -/+ :data:`YAW_STEP` (``<instance>.yaw_setpoint``)
up / down  depth set-point -/+ :data:`DEPTH_STEP` (up: shallower, to 0 m; ``.depth_setpoint``)
0 .. 3     heading mode (``.heading_mode``: 0 off, 1 LQR, 2 sliding mode, 3 backstepping)
m          lock the moving mass at the centre (``.mass_lock_time`` = now); again: release (-1)
p          pause / resume
q          end the run like Ctrl-C (partial results, exit code 130)
=========  =====================================================================

The set-points belong to the first instance with that input unconnected (the autopilot
``controller`` of the built-in scenarios), whose tunable parameters ``heading_mode`` and
``mass_lock_time`` take effect at its next step. An arrow starts from the set-point the run
has now (:meth:`cosim.engine.live.LiveControl.current`: one a program set over the control
endpoint, or an event, counts). A value the FMU does not take while running is refused like
any override; the status line shows the reason. The status line (stderr) shows the
set-points, the heading mode, the mass (free or locked), the simulated time, the real-time
factor and the last message (queued, applied at t, not applied and why; "designing" while a
new heading law is designed, which holds the run for a moment), cut to the terminal's width;
to a file or a pipe, the message alone, one line each time it changes.

A terminal sends a key that is not a character as an escape sequence: ESC [ parameters
final byte (CSI: F5-F12, Insert, Page Up, modified arrows such as Shift+Up ``ESC [ 1 ; 2
A``), ESC O final byte (SS3: F1-F4, arrows in application mode) or ESC and a character (Alt
and a key). Each is read whole (:func:`keys_of`, ECMA-48's grammar), also when split over
two reads, so no part of one is taken for a key of its own: only the plain arrows act.

The terminal is put in cbreak mode (``tty.setcbreak``: keys arrive one by one, Ctrl-C still
sends SIGINT) and restored by :meth:`KeyPad.close` -- and at interpreter exit if that was
never reached. Standard library ``termios``/``tty``/``select`` only (POSIX).
"""

from __future__ import annotations

import atexit
import contextlib
import math
import os
import re
import select
import shutil
import sys
import termios
import threading
import tty
from collections.abc import Callable
from typing import IO

from cosim.engine.live import LiveControl, OverrideError, Ticket
from cosim.errors import CosimError
from cosim.scenario.spec import Scenario
from cosim.scenario.timeline_spec import step_decimals

YAW_STEP = math.radians(5.0)  # rad per arrow press
DEPTH_STEP = 1.0  # m per arrow press
_ARROWS = {"A": "up", "B": "down", "C": "right", "D": "left"}
_REFRESH_S = 0.5  # the status line is redrawn at least this often
_ESCAPE_WAIT_S = 0.05  # s for the rest of an escape sequence split over two reads
# ECMA-48: CSI = ESC [ parameter bytes (0x30-0x3F)* intermediate bytes (0x20-0x2F)* final
# byte (0x40-0x7E); SS3 = ESC O and one byte; ESC and any other character (Alt+key)
_SEQUENCE = re.compile(r"\x1b(?:\[([\x30-\x3f]*[\x20-\x2f]*)([\x40-\x7e])|O(.)|(.))", re.DOTALL)
_PARTIAL = re.compile(r"\x1b(?:\[[\x20-\x3f]*|O)?\Z")
DESIGNED_MODES = (1, 2)  # heading modes designed when switched to (LQR, sliding mode)
MESSAGE_KEPT = 12  # characters of the status line's message a narrow terminal still shows
STATUS_WIDTH = 80  # columns of the status line when the terminal's width is unknown


def keys_of(data: str) -> list[str]:
    """The keys in what the terminal sent: ``"up"``/``"down"``/``"left"``/``"right"`` for a
    plain arrow (``ESC [ A``, ``ESC O A``), ``"escape"`` for any other escape sequence
    (read whole), else the character itself. An escape sequence cut off at the end of
    ``data`` is one ``"escape"`` too (:func:`split_partial` keeps it for the next read)."""
    keys, i = [], 0
    while i < len(data):
        if data[i] != "\x1b":
            keys.append(data[i])
            i += 1
            continue
        found = _SEQUENCE.match(data, i)
        if found is None:  # a lone ESC at the end
            keys.append("escape")
            break
        params, final, ss3, _ = found.groups()
        arrow = (final if params == "" else None) if final is not None else ss3
        keys.append(_ARROWS.get(arrow or "", "escape"))
        i = found.end()
    return keys


def split_partial(data: str) -> tuple[str, str]:
    """``data`` cut before an escape sequence it ends in the middle of: (whole, rest)."""
    partial = _PARTIAL.search(data)
    return (data, "") if partial is None else (data[: partial.start()], data[partial.start() :])


def _owner(scenario: Scenario, variable: str) -> str:
    """The instance whose input ``variable`` is unconnected (else the first that has it)."""
    having = [n for n, i in scenario.instances.items() if variable in i.interface.variables]
    free = [n for n in having if variable in scenario.unconnected_inputs(n)]
    return (free or having or list(scenario.instances))[0]


def _number(value: object, default: float) -> float:
    return float(value) if isinstance(value, int | float) else default


def _heading_degrees(angle: float) -> float:
    """``angle`` (rad) in degrees within (-180, 180], rounded to the 0.1 deg the status line
    shows (a set-point the arrows took past a whole turn is the same heading; the autopilot
    turns by the wrapped error)."""
    degrees = round(math.degrees(angle), 1)
    return 180.0 - (180.0 - degrees) % 360.0


def _told(name: str, value: float) -> str:
    """A value the keys set, in the unit the status line shows it in (the yaw in deg)."""
    if name == "yaw_setpoint":
        return f"{_heading_degrees(value):+.1f} deg"
    if name == "depth_setpoint":
        return f"{value:.1f} m"
    if name == "mass_lock_time":
        return "-1 (released)" if value < 0.0 else f"{value:.2f} s"
    return f"{value:.4g}"


def _terminal_fd() -> int:
    """Standard input's file descriptor, a terminal; :class:`CosimError` if it is not."""
    try:
        fd = sys.stdin.fileno()
        terminal = os.isatty(fd)
    except (AttributeError, OSError, ValueError):  # closed: sys.stdin None, or fd 0 closed
        raise CosimError("--interactive: standard input is closed (keys need a terminal)") from None
    if not terminal:
        raise CosimError("--interactive: standard input is not a terminal")
    if _in_background(fd):
        raise CosimError(
            "--interactive: this run is in the background of its terminal: keys need it in "
            "the foreground (start it without &, or fg)"
        )
    return fd


def _in_background(fd: int) -> bool:
    """Whether the terminal ``fd`` is this process's controlling terminal with another
    process group in front (a job started with ``&``): setting its mode, or reading it,
    would have the terminal stop this run until it is brought to the foreground."""
    try:
        return os.tcgetpgrp(fd) != os.getpgrp()
    except OSError:  # not the controlling terminal: it stops no one
        return False


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
        self.fd = _terminal_fd() if fd is None else fd
        self.out = sys.stderr if out is None else out
        self._on_terminal = _is_terminal(self.out)
        self._drawn = False  # whether a status line is on the terminal, to be ended
        self._logged: str | None = None  # the last message written to a file or a pipe
        if not os.isatty(self.fd):
            raise CosimError("--interactive: standard input is not a terminal")
        controller = _owner(scenario, "yaw_setpoint")
        names = ("yaw_setpoint", "depth_setpoint", "heading_mode", "mass_lock_time")
        self.refs = {name: f"{controller}.{name}" for name in names}
        unset = dict(zip(names, (0.0, 0.0, 0.0, -1.0), strict=True))  # off, for a missing one
        self.initial = {n: _number(scenario.start_value(controller, n), unset[n]) for n in names}
        self.message = "<- -> yaw, up/down depth, 0-3 mode, m mass, p pause, q quit"
        self._last: tuple[str, Ticket] | None = None  # the last override asked for
        self._saved = termios.tcgetattr(self.fd)
        self._done = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)

    def value(self, name: str) -> float:
        """The value ``name`` (``"yaw_setpoint"``, ...) has in the run now (or will have at
        the next point, if a change is queued); its start value if none is known."""
        return _number(self.live.current(self.refs[name]), self.initial[name])

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
        if not self._drawn:
            return
        with contextlib.suppress(OSError, ValueError):
            self.out.write("\n")
            self.out.flush()
        self._drawn = False

    def _read(self) -> None:
        pending = ""
        try:
            while not self._done.is_set():
                wait = _ESCAPE_WAIT_S if pending else _REFRESH_S
                ready, _, _ = select.select([self.fd], [], [], wait)
                if ready:
                    data = os.read(self.fd, 64).decode("utf-8", "replace")
                    if not data:
                        return  # end of input
                    whole, pending = split_partial(pending + data)
                else:  # nothing more came: what is pending was all there is (a lone ESC)
                    whole, pending = pending, ""
                for key in keys_of(whole):
                    self.press(key)
                self.draw()
        except (OSError, ValueError):
            return  # the terminal went away: the run goes on without keys

    def press(self, key: str) -> None:
        """What ``key`` does (see the module docstring)."""
        try:
            if key == "q":
                self.live.stop("the q key")
                self._last, self.message = None, "stopping"
            elif key == "p":
                self.live.resume() if self.live.paused else self.live.pause("keys")
                self._last = None
                self.message = "paused (p resumes)" if self.live.paused else "running"
            elif key in ("left", "right"):
                sign = 1.0 if key == "right" else -1.0
                self._set("yaw_setpoint", self.value("yaw_setpoint") + sign * YAW_STEP)
            elif key in ("up", "down"):
                sign = -1.0 if key == "up" else 1.0
                depth = self.value("depth_setpoint") + sign * DEPTH_STEP
                self._set("depth_setpoint", max(depth, 0.0))  # m: not above the surface
            elif key in "0123" and len(key) == 1:
                self._set("heading_mode", int(key))
            elif key == "m":
                locked = self.value("mass_lock_time") >= 0.0
                self._set("mass_lock_time", -1.0 if locked else (self.live.time or 0.0))
        except OverrideError as exc:  # refused, or the run has ended
            self._last, self.message = None, str(exc)
        self.draw()

    def _set(self, name: str, value: float | int) -> None:
        self._last = (name, self.live.request({self.refs[name]: value}, "keys"))

    def _feedback(self) -> str:
        """The message about the last override asked for: queued, designing (a new heading
        law holds the run while it is designed), applied, or not applied and why."""
        if self._last is None:
            return self.message
        name, ticket = self._last
        value = next(iter(ticket.values.values()))
        if ticket.refused is not None:
            return f"{name}: {ticket.refused}"
        if not ticket.done:
            return f"{name} = {_told(name, value)} queued"
        t = self.live.time
        if name == "heading_mode" and value in DESIGNED_MODES and t == ticket.time:
            return f"mode {value}: designing the heading law (the run waits)"
        return f"{name} = {_told(name, value)} applied at t = {ticket.time:.15g} s"

    def status_line(self, width: int) -> str:
        """The status line, at most ``width - 1`` characters (no wrap at the last column).
        Where all of it does not fit, the pacing goes first, then the mass lock, the mode
        and the set-points, so that the time and MESSAGE_KEPT characters of the message saying
        what a key did stay in view; then the message is cut."""
        t = self.live.time
        decimals = step_decimals(self.live.scenario.coupling.step)  # as the step is written
        clock = "-" if t is None else f"{t:.{decimals}f}"
        yaw, depth = _heading_degrees(self.value("yaw_setpoint")), self.value("depth_setpoint")
        mode = int(self.value("heading_mode"))
        mass = "locked" if self.value("mass_lock_time") >= 0.0 else "free"
        paced = f" {self.status()}" if self.status is not None else ""
        message = self._feedback() if self._last is not None else self.message
        set_points = f"t {clock} s yaw_sp {yaw:+.1f} deg depth_sp {depth:.1f} m"
        heads = (f"{set_points} mode {mode} mass {mass}{paced} | ",
                 f"{set_points} mode {mode} mass {mass} | ", f"{set_points} mode {mode} | ",
                 f"{set_points} | ", f"t {clock} s | ")  # fmt: skip
        limit = max(width - 1, 1)
        kept = min(len(message), MESSAGE_KEPT)
        head = next((head for head in heads if len(head) + kept <= limit), heads[-1])
        line = head + message
        return line if len(line) <= limit else line[: limit - 3] + "..."

    def draw(self) -> None:
        """Redraw the status line on a terminal, cut to its width and padded with spaces
        over the line before (no escape sequence, which a ``TERM=dumb`` terminal or a
        ``script`` log shows as text). To a file or a pipe (stderr redirected: ``2> log``),
        the message alone, a line each time it changes: carriage returns there piled every
        redraw into one endless line."""
        if not self._on_terminal:
            message = self._feedback()
            if message != self._logged:
                self._logged = message
                self.out.write(f"{message}\n")
                self.out.flush()
            return
        limit = max(self._width() - 1, 1)  # no character in the last column: no wrap
        self.out.write(f"\r{self.status_line(limit + 1).ljust(limit)}")
        self.out.flush()
        self._drawn = True

    def _width(self) -> int:
        """The columns of the terminal the status line is drawn on (:data:`STATUS_WIDTH`
        when neither it nor ``COLUMNS`` says)."""
        width = shutil.get_terminal_size((STATUS_WIDTH, 24)).columns
        with contextlib.suppress(AttributeError, OSError, ValueError):
            width = os.get_terminal_size(self.out.fileno()).columns or width
        return width


def _is_terminal(out: IO[str]) -> bool:
    """Whether ``out`` is a terminal (not a file, a pipe, a closed stream or a StringIO)."""
    try:
        return out.isatty()
    except (AttributeError, OSError, ValueError):
        return False
