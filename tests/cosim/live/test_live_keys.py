"""Interactive runs through a pseudo-terminal: keys in, set-points out, terminal restored.

The command line runs in a subprocess (its own process group, killed in a ``finally``) on
the built FMUs (bs-3) with a pty as its terminal; the test types arrows, a heading-mode key
the autopilot refuses while running, and ``q``, and reads the status line and summary.json.
"""

from __future__ import annotations

import contextlib
import fcntl
import io
import json
import math
import os
import pty
import re
import select
import signal
import struct
import subprocess
import sys
import termios
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from cosim.cli import main
from cosim.engine.live import LiveControl
from cosim.engine.signals import StopRequest
from cosim.live.keys import DEPTH_STEP, YAW_STEP, KeyPad, keys_of, split_partial
from cosim.scenario.spec import Scenario, load_scenario

TIMEOUT_S = 120.0  # generous: the machine may be busy; nothing here is timed


def test_arrow_escape_sequences_are_keys() -> None:
    assert keys_of("\x1b[A\x1b[Bq\x1bOC\x1b[D1") == ["up", "down", "q", "right", "left", "1"]


ACTING = {"q", "p", "m", "0", "1", "2", "3", "up", "down", "left", "right"}
REAL_SEQUENCES = {
    "F1": "\x1bOP", "F5": "\x1b[15~", "F9": "\x1b[20~", "F10": "\x1b[21~", "F11": "\x1b[23~",
    "F12": "\x1b[24~", "Shift+F3": "\x1b[1;2R", "Insert": "\x1b[2~", "Page Up": "\x1b[5~",
    "Shift+Up": "\x1b[1;2A", "Alt+Left": "\x1b[1;3D", "Ctrl+Right": "\x1b[1;5C",
    "Alt+1": "\x1b1", "Alt+q": "\x1bq", "Alt+m": "\x1bm", "bracketed paste": "\x1b[200~",
    "mouse": "\x1b[<0;12;30M", "focus in": "\x1b[I",
}  # fmt: skip

csi = st.builds(
    lambda params, inter, final: "\x1b[" + params + inter + final,
    st.text(st.characters(min_codepoint=0x30, max_codepoint=0x3F), max_size=8),
    st.text(st.characters(min_codepoint=0x20, max_codepoint=0x2F), max_size=2),
    st.characters(min_codepoint=0x40, max_codepoint=0x7E),
)
ss3 = st.characters(min_codepoint=0x20, max_codepoint=0x7E).map(lambda c: "\x1bO" + c)
alt = st.characters(min_codepoint=0x20, max_codepoint=0x7E).filter(lambda c: c not in "[O")
sequences = st.one_of(csi, ss3, alt.map(lambda c: "\x1b" + c))


@pytest.mark.parametrize("name", list(REAL_SEQUENCES))
def test_function_and_modified_keys_do_nothing(name: str) -> None:
    assert keys_of(REAL_SEQUENCES[name]) == ["escape"]


@given(sequences, st.text(alphabet="abc", max_size=3))
def test_every_escape_sequence_is_one_key_that_acts_only_if_a_plain_arrow(
    sequence: str, after: str
) -> None:
    keys = keys_of(sequence + after)
    assert keys[1:] == list(after)  # the sequence is read whole: nothing of it is left over
    plain = sequence in ("\x1b[A", "\x1b[B", "\x1b[C", "\x1b[D") or (
        sequence.startswith("\x1bO") and sequence[2:] in "ABCD"
    )
    assert (keys[0] in ACTING) == plain and (plain or keys[0] == "escape")


@given(sequences, st.integers(min_value=1, max_value=12))
def test_an_escape_sequence_split_over_two_reads_is_read_whole(sequence: str, cut: int) -> None:
    cut = min(cut, len(sequence))
    whole, rest = split_partial("x" + sequence[:cut])
    keys = keys_of(whole) + keys_of(rest + sequence[cut:]) if cut < len(sequence) else None
    assert keys is None or keys == ["x", *keys_of(sequence)]


@pytest.fixture
def terminal() -> Iterator[int]:
    parent, child = pty.openpty()
    yield child
    os.close(parent)
    os.close(child)


@pytest.fixture(scope="module")
def bs3(fmu_dir: Path) -> Scenario:
    return load_scenario("bs-3", fmu_dir=fmu_dir)


def test_the_arrow_keys_start_from_the_set_point_a_client_set(bs3: Scenario, terminal: int) -> None:
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    pad = KeyPad(live, bs3, fd=terminal, out=io.StringIO())
    client = live.request({"controller.yaw_setpoint": 0.5}, "control 127.0.0.1:1")
    for ticket in live.take(1, 0.01, np.zeros(1)):
        live.applied(ticket, "live-1", 0.01)
    assert client.done
    pad.press("right")
    pad.press("right")  # builds on the queued value, not on what the run had before
    queued = list(live.take(2, 0.02, np.zeros(1)))
    assert [t.values for t in queued] == [
        {"controller.yaw_setpoint": 0.5 + YAW_STEP},
        {"controller.yaw_setpoint": 0.5 + 2 * YAW_STEP},
    ]


def test_interactive_with_a_closed_standard_input_says_so_in_one_line(
    fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    monkeypatch.setattr(sys, "stdin", None)  # what Python makes of a closed fd 0
    code = main(["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "run"),
                 "--no-rrd", "--real-time", "--interactive"])  # fmt: skip
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    assert "--interactive: standard input is closed" in err


@given(
    yaw=st.floats(-1e3, 1e3),
    depth=st.floats(-1e4, 1e4),
    t=st.one_of(st.none(), st.floats(0.0, 1e7)),
    message=st.text(max_size=300),
    width=st.integers(min_value=20, max_value=300),
)
def test_the_status_line_fits_the_terminal_width(
    bs3: Scenario, yaw: float, depth: float, t: float | None, message: str, width: int
) -> None:
    live = LiveControl(bs3)
    index = {"controller.yaw_setpoint": 0, "controller.depth_setpoint": 1}
    live.bind(index, StopRequest())
    if t is not None:
        live.publish(t, np.array([yaw, depth]))
    with open(os.devnull) as null:
        pad = KeyPad.__new__(KeyPad)  # no terminal needed to compose the line
        pad.live, pad.status, pad.fd, pad.out = live, lambda: "rt 123.45x", null.fileno(), null
        names = ("yaw_setpoint", "depth_setpoint", "heading_mode", "mass_lock_time")
        pad.refs = {n: f"controller.{n}" for n in names}
        pad.initial = dict.fromkeys(pad.refs, 0.0)
        pad.message, pad._last = message.replace("\n", " "), None
        line = pad.status_line(width)
    assert len(line) <= width - 1


@pytest.mark.parametrize("width", [40, 60])
def test_a_narrow_terminal_keeps_the_message_and_the_time(
    bs3: Scenario, terminal: int, width: int
) -> None:
    """At 40 or 60 columns the status line was cut after its set-points, so the message
    saying what a key did (queued, applied, refused) never showed: it comes before the
    set-points the keys change, which the line drops first."""
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    pad = KeyPad(live, bs3, fd=terminal, out=io.StringIO())
    live.publish(12.5, np.zeros(1))
    pad.press("1")
    line = pad.status_line(width)
    assert len(line) <= width - 1, line
    assert line.startswith("t 12.50 s") and "| heading_mode" in line, line
    assert "heading_mode = 1 queued" in pad.status_line(40)  # a short message whole
    assert pad.status_line(200).endswith("| heading_mode = 1 queued")  # all of it, when wide


def test_switching_to_lqr_says_designing_until_the_run_goes_on(
    bs3: Scenario, terminal: int
) -> None:
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    pad = KeyPad(live, bs3, fd=terminal, out=io.StringIO())
    pad.press("1")
    assert "heading_mode = 1 queued" in pad.status_line(200)
    for ticket in live.take(7, 0.07, np.zeros(1)):
        live.applied(ticket, "live-1", 0.07)
    live.publish(0.07, np.zeros(1))  # applied; the FMU designs the law in its next step
    assert "designing" in pad.status_line(200)
    live.publish(0.08, np.zeros(1))
    assert "heading_mode = 1 applied at t = 0.07 s" in pad.status_line(200)


@pytest.mark.parametrize(
    ("step", "t", "shown"), [(0.001, 1.234, "t 1.234 s"), (0.01, 1.2, "t 1.20 s"),
                             (0.5, 1.5, "t 1.5 s"), (1.0, 3.0, "t 3 s")]
)  # fmt: skip
def test_the_status_line_shows_the_clock_with_the_steps_decimals(
    bs3: Scenario, terminal: int, step: float, t: float, shown: str
) -> None:
    """The status line's clock had 2 decimals whatever the step: t = 1.234 s of a 1 ms run
    read 1.23 (every other live time is shown with the step's decimals)."""
    scenario = bs3.with_overrides(step=step)
    live = LiveControl(scenario)
    live.bind({}, StopRequest())
    pad = KeyPad(live, scenario, fd=terminal, out=io.StringIO())
    live.publish(t, np.zeros(1))
    assert pad.status_line(200).startswith(f"{shown} yaw_sp"), pad.status_line(200)


def test_a_set_point_change_is_told_in_the_unit_the_status_line_shows(
    bs3: Scenario, terminal: int
) -> None:
    """The line read "yaw_sp +5.0 deg ... | yaw_setpoint = 0.08727 queued": the same
    set-point in degrees and, unnamed, in radians."""
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    pad = KeyPad(live, bs3, fd=terminal, out=io.StringIO())
    yaw = math.degrees(pad.value("yaw_setpoint") + YAW_STEP)
    pad.press("right")
    assert f"yaw_setpoint = {yaw:+.1f} deg queued" in pad.status_line(200)
    depth = pad.value("depth_setpoint") + DEPTH_STEP
    pad.press("down")
    assert f"depth_setpoint = {depth:.1f} m queued" in pad.status_line(200)


def test_a_yaw_set_point_past_a_whole_turn_is_shown_within_one_turn(
    bs3: Scenario, terminal: int
) -> None:
    """Two right arrows from a client's 355 deg read "+365.0 deg": the status line shows
    the set-point in (-180, 180] deg, as the report and the recording do."""
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    pad = KeyPad(live, bs3, fd=terminal, out=io.StringIO())
    live.request({"controller.yaw_setpoint": math.radians(355.0)}, "control 127.0.0.1:1")
    for ticket in live.take(1, 0.01, np.zeros(1)):
        live.applied(ticket, "live-1", 0.01)
    pad.press("right")
    pad.press("right")
    line = pad.status_line(200)
    assert "yaw_sp +5.0 deg" in line and "yaw_setpoint = +5.0 deg queued" in line, line
    for _ in range(37):  # 185 deg to the left: -180 deg is shown as +180
        pad.press("left")
    assert "yaw_setpoint = +180.0 deg queued" in pad.status_line(200), pad.status_line(200)


def test_the_status_line_to_a_file_is_a_line_per_message_without_escapes(
    bs3: Scenario, terminal: int, tmp_path: Path
) -> None:
    """stderr redirected to a log (``2> log``) while the keys come from the terminal: the
    status line was redrawn there every half second as a carriage return and an erase
    escape, one endless line of ``\\r\\x1b[K...`` in the log. It is the message alone, one line
    each time it changes."""
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    log = tmp_path / "stderr.log"
    with log.open("w", encoding="utf-8") as out:
        pad = KeyPad(live, bs3, fd=terminal, out=out)
        for _ in range(3):
            pad.draw()  # nothing new: the message once
        yaw = math.degrees(pad.value("yaw_setpoint") + YAW_STEP)
        pad.press("right")
        pad.draw()
        pad.close()
    written = log.read_bytes()
    assert b"\x1b" not in written and b"\r" not in written, written
    assert written.decode().splitlines() == [pad.message, f"yaw_setpoint = {yaw:+.1f} deg queued"]


def test_the_status_line_on_a_terminal_is_redrawn_without_escape_sequences(
    bs3: Scenario, terminal: int
) -> None:
    """A terminal that takes no escape sequences (``TERM=dumb``, a ``script`` log) showed the
    erase-to-end-of-line escape before every redraw; a shorter line is padded with spaces
    over the longer one instead, within the terminal's width (100 columns here)."""
    parent, child = pty.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    try:
        with os.fdopen(os.dup(child), "w", encoding="utf-8") as out:
            pad = KeyPad(live, bs3, fd=terminal, out=out)
            pad.message = "a message long enough to reach the last column of a terminal 100 wide"
            pad.draw()
            pad.message = "short"
            pad.draw()
        shown = b""
        while select.select([parent], [], [], 0.5)[0]:
            shown += os.read(parent, 4096)
    finally:
        os.close(parent)
        os.close(child)
    assert b"\x1b" not in shown, shown
    lines = shown.decode().split("\r")[1:]
    assert len(lines) == 2 and all(len(line) == 99 for line in lines), lines
    assert lines[1].rstrip().endswith("| short"), lines


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


def test_the_up_key_stops_the_depth_set_point_at_the_surface(bs3: Scenario, terminal: int) -> None:
    """Up from 0.5 m asks for 0 m, not -0.5 m, and up again keeps 0 m: a depth set-point
    above the surface is one the autopilot's depth loop refuses, which would end the run."""
    live = LiveControl(bs3)
    live.bind({}, StopRequest())
    pad = KeyPad(live, bs3, fd=terminal, out=io.StringIO())
    asked = []
    for start in (0.5, 0.0):
        live.request({"controller.depth_setpoint": start}, "control 127.0.0.1:1")
        pad.press("up")
        asked.append(live.current("controller.depth_setpoint"))
    assert asked == [0.0, 0.0]


BACKGROUND_JOB = """
import fcntl, os, sys, termios
fcntl.ioctl(0, termios.TIOCSCTTY, 0)  # the pty: this session's terminal, this group in front
job = os.fork()
if job == 0:
    os.setpgid(0, 0)  # a group of its own: a job in the background, as `... &` starts it
    os.execv(sys.executable, [sys.executable, "-m", "cosim.cli", *sys.argv[1:]])
print(f"job {job}", flush=True)
_, status = os.waitpid(job, os.WUNTRACED)
if os.WIFSTOPPED(status):
    print("job stopped by the terminal", flush=True)
    os.killpg(job, 9)
    _, status = os.waitpid(job, 0)
print(f"job exit {os.waitstatus_to_exitcode(status)}", flush=True)
"""


def test_interactive_in_the_background_is_refused_in_one_line(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """``auv-cosim run ... --interactive &``: the run put its terminal in cbreak mode from
    the background, and the terminal stopped it ("Stopped (tty output)") for good; it now
    says in one line that keys need it in the foreground, and ends."""
    parent, child = pty.openpty()
    command = [sys.executable, "-c", BACKGROUND_JOB, "run", "bs-3", "--fmu-dir", str(fmu_dir),
               "--out", str(tmp_path / "run"), "--no-rrd", "--quiet", "--stop-time", "1",
               "--real-time", "5", "--interactive"]  # fmt: skip
    proc = subprocess.Popen(command, stdin=child, stdout=child, stderr=child,
                            start_new_session=True, cwd=tmp_path)  # fmt: skip
    terminal, job = Terminal(parent), None
    try:
        job = int(terminal.read_until(r"job (\d+)").group(1))
        ended = terminal.read_until(r"job (stopped by the terminal|exit -?\d+)").group(1)
        assert proc.wait(timeout=TIMEOUT_S) == 0, terminal.text
    finally:
        for group in (proc.pid, job):
            with contextlib.suppress(ProcessLookupError, TypeError):
                os.killpg(group, signal.SIGKILL)  # type: ignore[arg-type]
        proc.wait()
        os.close(parent)
        os.close(child)
    assert ended == "exit 1", terminal.text
    refusals = [line for line in terminal.text.splitlines() if "--interactive" in line]
    assert refusals == [
        "auv-cosim run: --interactive: this run is in the background of its "
        "terminal: keys need it in the foreground (start it without &, or fg)"
    ]
