"""Numbers at the edges of a run, refused before it starts with one line each: a stop time
under one step (a run of zero steps), a real-time factor that makes a step last more than a
day, an event or fault time no run reaches. And the stop that must not wait out a long step:
Ctrl-C, SIGTERM, the endpoint's ``stop`` and the ``q`` key end a paced run at once, at a
factor where one step lasts a day (with the old sleep, hours)."""

from __future__ import annotations

import contextlib
import json
import os
import pty
import re
import select
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.scenario.spec import ScenarioError, load_scenario

TIMEOUT_S = 120.0  # generous: the machine may be busy; nothing here is timed


def _refused(args: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(args) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("stop_time", ["1e-300", "0.004", "5e-324"])
def test_a_run_of_zero_steps_is_refused_in_one_line(
    fmu_dir: Path, tmp_path: Path, stop_time: str, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _refused(["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "r"),
                    "--no-rrd", "--stop-time", stop_time], capsys)  # fmt: skip
    assert "less than one communication step of 0.01 s" in err
    assert not (tmp_path / "r" / "results.csv").exists()


@pytest.mark.parametrize("factor", ["1e-300", "1e-10", "5e-324"])
def test_a_real_time_factor_making_a_step_last_over_a_day_is_refused_in_one_line(
    fmu_dir: Path, tmp_path: Path, factor: str, capsys: pytest.CaptureFixture[str]
) -> None:
    err = _refused(["run", "bs-3", "--fmu-dir", str(fmu_dir), "--out", str(tmp_path / "r"),
                    "--no-rrd", "--real-time", factor], capsys)  # fmt: skip
    assert f"--real-time {float(factor)!r}: one communication step of 0.01 s" in err
    assert "at most a day per step" in err


SCENARIO = """
stop_time = 1.0
[coupling]
step = 0.01
order = ["controller", "plant"]
[instances.plant]
fmu = "AuvPlant"
[instances.plant.start]
variant = "lateral"
[instances.controller]
fmu = "AuvAutopilot"
[instances.controller.start]
heading_mode = "backstepping"
[connections]
remove = ["plant.fin_angle"]
"""
UNREACHABLE = {
    "events[0].time": '[[events]]\ntime = 1e308\nset = { "controller.yaw_setpoint" = 0.5 }',
    "faults[0].start": '[[faults]]\nkind = "mass-jam"\nstart = 1e308',
    "faults[0].stop": '[[faults]]\nkind = "mass-jam"\nstart = 1.0\nstop = 1e300',
}


@pytest.mark.parametrize("key", list(UNREACHABLE))
def test_an_event_or_fault_time_no_run_reaches_is_refused(
    fmu_dir: Path, tmp_path: Path, key: str
) -> None:
    path = tmp_path / "late.toml"
    path.write_text(SCENARIO + UNREACHABLE[key] + "\n")
    with pytest.raises(
        ScenarioError, match=rf"key {re.escape(repr(key))}.*communication steps of 0\.01 s"
    ):
        load_scenario(path, fmu_dir=fmu_dir)
    later = path.read_text().replace("1e308", "1e6").replace("1e300", "1e6")
    path.write_text(later)  # later than the stop time but reachable: fine (never fires)
    load_scenario(path, fmu_dir=fmu_dir)


WAIT_FOR_T0_THEN = """
import json, socket, sys, time
host, port = sys.argv[1].rsplit(":", 1)
sock = socket.create_connection((host, int(port)))
f = sock.makefile("rw")
while True:  # until the run has passed t = 0: it then steps and waits for t = h
    f.write('{"get": []}\\n'); f.flush()
    if json.loads(f.readline()).get("t") is not None: break
    time.sleep(0.1)
if sys.argv[2] == "stop":
    f.write('{"stop": true}\\n'); f.flush(); print(f.readline())
"""


def _paced_run(fmu_dir: Path, out: Path, *options: str, **popen: object) -> subprocess.Popen:
    """bs-3 at 1.2e-7x real time: one step of 10 ms lasts 23 hours of wall clock."""
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir),
               "--out", str(out), "--no-rrd", "--quiet", "--real-time", "1.2e-7"]  # fmt: skip
    command += options
    return subprocess.Popen(command, start_new_session=True, **popen)  # type: ignore[call-overload]


def _keys_then_q(fmu_dir: Path, out: Path) -> int:
    parent, child = pty.openpty()
    proc = _paced_run(fmu_dir, out, "--interactive", stdin=child, stdout=child, stderr=child)
    try:
        text = ""
        while not re.search(r"t \d+\.\d+ s yaw_sp", text):  # past t = 0
            ready, _, _ = select.select([parent], [], [], TIMEOUT_S)
            assert ready, text
            text += os.read(parent, 4096).decode("utf-8", "replace")
        os.write(parent, b"q")
        return proc.wait(timeout=TIMEOUT_S)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        os.close(parent)
        os.close(child)


def _endpoint_then(fmu_dir: Path, out: Path, how: str) -> int:
    proc = _paced_run(fmu_dir, out, "--control", "0", stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stderr.readline()
        assert line.startswith("control endpoint: "), line
        address = line.split(": ", 1)[1].strip()
        subprocess.run([sys.executable, "-c", WAIT_FOR_T0_THEN, address, how],
                       timeout=TIMEOUT_S, check=True)  # fmt: skip
        if how != "stop":
            proc.send_signal(getattr(signal, how))
        return proc.wait(timeout=TIMEOUT_S)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


@pytest.mark.slow
@pytest.mark.parametrize("how", ["SIGINT", "SIGTERM", "stop", "q"])
def test_ctrl_c_sigterm_stop_and_q_end_a_day_long_step_at_once(
    fmu_dir: Path, tmp_path: Path, how: str
) -> None:
    """The run waits 23 hours for its next point; it must end within the test's timeout.
    A stop asked for on the endpoint or with q is said to be one: it was recorded as a
    Ctrl-C ("interrupted (Ctrl-C)", signal SIGINT) though no signal came."""
    out = tmp_path / "r"
    code = _keys_then_q(fmu_dir, out) if how == "q" else _endpoint_then(fmu_dir, out, how)
    assert code == {"SIGTERM": 143}.get(how, 130)
    assert (out / "results.csv").read_text().count("\n") == 3  # header, t = 0 and t = h
    summary = json.loads((out / "summary.json").read_text(encoding="utf-8"))
    by = {"stop": "stopped by control 127.0.0.1:", "q": "stopped by the q key at t = "}
    if how in by:
        assert summary["signal"] is None and summary["error"].startswith(by[how]), summary
    else:
        assert summary["signal"] == how
