"""Every way a run ends leaves a consistent folder: SIGKILL, SIGTERM, SIGHUP,
Ctrl-C once or twice, during the stepping or while the outputs are completed, and a second
run into the same folder. The command line runs in a subprocess (``python -m cosim.cli``),
on the built FMUs (bs-3)."""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
from process_group import as_in_a_terminal
from rerun.chunk import RrdReader

from cosim.engine.master import ROWS_PER_CHUNK
from cosim.metrics.manoeuvres import manoeuvre_metrics, metric_names
from cosim.outputs.folder import LOCK_FILE
from cosim.outputs.results import read_csv
from cosim.runner import run_scenario
from cosim.scenario.spec import scenario_path
from cosim.viz.recording import rerun_executable
from plant_fmu.model import compiled

H = 0.01  # s, bs-3's communication step
LONG = "6000"  # s of bs-3: a run still stepping when the test signals it (~30 s of wall clock)


def start(fmu_dir: Path, out: Path, *options: str, scenario: str = "bs-3") -> subprocess.Popen:
    """`auv-cosim run SCENARIO --out OUT ...` in a fresh interpreter."""
    command = [sys.executable, "-m", "cosim.cli", "run", scenario, "--fmu-dir", str(fmu_dir)]
    command += ["--out", str(out), "--quiet", *options]
    return subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=as_in_a_terminal)  # fmt: skip


def rows_in(path: Path) -> int:
    """Whole data rows in a results.csv being written (0 if not there yet)."""
    try:
        return max(path.read_bytes().count(b"\n") - 1, 0)
    except FileNotFoundError:
        return 0


def wait_for_rows(proc: subprocess.Popen, out: Path, rows: int, timeout: float = 120.0) -> None:
    deadline = time.monotonic() + timeout
    while rows_in(out / "results.csv") < rows:
        assert proc.poll() is None, f"the run ended early: {proc.communicate()}"
        assert time.monotonic() < deadline, f"no {rows} rows within {timeout} s"
        time.sleep(0.05)


def finish(proc: subprocess.Popen, timeout: float = 120.0) -> tuple[int, str]:
    """(exit code, stderr); the process is killed if it does not end in time."""
    try:
        _, err = proc.communicate(timeout=timeout)
    finally:
        proc.kill()
        proc.wait()
    return proc.returncode, err


def wait_unlocked(out: Path, timeout: float = 10.0) -> None:
    """Until no process (the run, its tail guard) holds the folder's lock."""
    deadline = time.monotonic() + timeout
    while (out / LOCK_FILE).exists():
        with open(out / LOCK_FILE, "rb") as f, contextlib.suppress(BlockingIOError):
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
            return
        assert time.monotonic() < deadline, "the folder stayed locked"
        time.sleep(0.02)


def summary(out: Path) -> dict:
    return json.loads((out / "summary.json").read_text())


def csv_lines(out: Path) -> list[str]:
    """results.csv as lines; each must be whole (as many fields as the header)."""
    text = (out / "results.csv").read_text()
    assert text.endswith("\n"), "torn last row"
    lines = text.splitlines()
    assert {line.count(",") for line in lines} == {lines[0].count(",")}, "a torn row"
    return lines


def verify(rrd: Path) -> None:
    proc = subprocess.run(
        [rerun_executable(), "rrd", "verify", str(rrd)],
        capture_output=True,
        text=True,
        env={**os.environ, "RERUN_ANALYTICS_ENABLED": "false"},
    )
    assert proc.returncode == 0, proc.stderr


def recorded_yaw(rrd: Path) -> np.ndarray:
    """plant.yaw as the recording holds it (deg, in time order: the first series of the
    yaw panel)."""
    times, values = [], []
    for chunk in RrdReader(rrd).stream():
        batch = chunk.to_record_batch()
        if chunk.entity_path != "/attitude/yaw_deg" or "sim_time" not in batch.schema.names:
            continue
        scalars = batch.column("Scalars:scalars")
        while pa.types.is_list(scalars.type) or pa.types.is_fixed_size_list(scalars.type):
            scalars = scalars.flatten()
        times.append(batch.column("sim_time").cast(pa.int64()).to_numpy())
        values.append(scalars.to_numpy(zero_copy_only=False).reshape(len(batch), -1)[:, 0])
    if not times:
        return np.empty(0)
    order = np.argsort(np.concatenate(times), kind="stable")
    return np.concatenate(values)[order]


def last_note(rrd: Path) -> tuple[int, str] | None:
    """(sim_time in ns, text) of the last entry of the recording's events log, if any."""
    notes = []
    for chunk in RrdReader(rrd).stream():
        if chunk.entity_path == "/events":
            batch = chunk.to_record_batch()
            texts = [row[0] for row in batch.column("TextLog:text").to_pylist()]
            nanos = batch.column("sim_time").cast(pa.int64()).to_pylist()
            notes += list(zip(nanos, texts, strict=True))
    return max(notes) if notes else None


def entities(rrd: Path) -> set[str]:
    return {chunk.entity_path for chunk in RrdReader(rrd).stream()}


@pytest.mark.slow
@pytest.mark.filterwarnings("ignore:RRD file has no footer")  # a killed run has none
def test_sigkill_leaves_whole_rows_of_the_uninterrupted_run(fmu_dir: Path, tmp_path: Path):
    moments = [random.uniform(0.3, 3.0) for _ in range(3)]
    killed = []
    for i, moment in enumerate(moments):
        out = tmp_path / f"kill{i}"
        started = time.monotonic()
        proc = start(fmu_dir, out, "--stop-time", LONG)
        wait_for_rows(proc, out, 1)  # stepping
        time.sleep(moment)
        proc.send_signal(signal.SIGKILL)
        lived = time.monotonic() - started
        assert finish(proc)[0] == -signal.SIGKILL
        wait_unlocked(out)  # the tail guard has finished
        lines = csv_lines(out)
        assert len(lines) - 1 >= lived - 1.0, f"kill {moment:.2f} s into the stepping"
        assert summary(out)["status"] == "running"
        killed.append((out, lines))
    longest = max(len(lines) for _, lines in killed) - 1
    reference = run_scenario(
        "bs-3", tmp_path / "ref", stop_time=(longest - 1) * H, no_rrd=True, fmu_dir=fmu_dir
    )
    assert reference.result.complete
    expected = (tmp_path / "ref" / "results.csv").read_text().splitlines()
    for (out, lines), moment in zip(killed, moments, strict=True):
        assert lines == expected[: len(lines)], f"kill {moment:.2f} s into the stepping"
        assert "/scenario" in entities(out / "recording.rrd")  # readable: what was flushed
        yaw = recorded_yaw(out / "recording.rrd")
        assert len(yaw) <= len(lines) - 1
        _, table = read_csv(out / "results.csv")
        yaw_column = lines[0].split(",").index("plant.yaw")
        np.testing.assert_array_equal(yaw, np.degrees(table[: len(yaw), yaw_column]))


@pytest.mark.slow
@pytest.mark.parametrize(
    ("signum", "code", "reason", "options"),
    [
        (signal.SIGTERM, 143, "terminated (SIGTERM)", ()),
        (signal.SIGTERM, 143, "terminated (SIGTERM)", ("--no-rrd",)),
        (signal.SIGHUP, 129, "hung up (SIGHUP)", ()),
    ],
)
def test_sigterm_and_sighup_end_a_run_like_ctrl_c(
    fmu_dir: Path, tmp_path: Path, signum: int, code: int, reason: str, options: tuple[str, ...]
):
    """Regression: `timeout -s TERM 6 auv-cosim run bs-3 --stop-time 600` left a recording
    without footer (and nothing at all with --no-rrd)."""
    out = tmp_path / "run"
    proc = start(fmu_dir, out, "--stop-time", LONG, *options)
    wait_for_rows(proc, out, 300)
    proc.send_signal(signum)
    returncode, err = finish(proc)
    assert returncode == code
    assert err.count("\n") == 1 and f"auv-cosim run: {reason} at t = " in err
    done = summary(out)
    assert done["status"] == "incomplete" and done["complete"] is False
    assert done["error"].startswith(reason) and done["signal"] == signal.Signals(signum).name
    # where the yaw stays after the rows is not known: no settling time, the peaks so far
    assert done["key_figures"]["yaw_settling_time_s"] is None
    assert done["key_figures"]["peak_abs_mass_position_m"] > 0.0
    lines = csv_lines(out)
    assert len(lines) - 1 == done["rows"] == round(done["time_reached"] / H) + 1
    assert not (out / LOCK_FILE).exists()
    if "--no-rrd" not in options:
        verify(out / "recording.rrd")


@pytest.mark.slow
def test_two_ctrl_c_in_quick_succession_still_complete_the_folder(fmu_dir: Path, tmp_path: Path):
    """Regression: two Ctrl-C 0.02-0.3 s apart left an empty run folder."""
    out = tmp_path / "run"
    proc = start(fmu_dir, out, "--stop-time", LONG)
    wait_for_rows(proc, out, 300)
    proc.send_signal(signal.SIGINT)
    time.sleep(random.uniform(0.02, 0.3))
    proc.send_signal(signal.SIGINT)
    returncode, err = finish(proc)
    assert returncode == 130 and "interrupted (Ctrl-C) at t = " in err
    done = summary(out)
    assert done["status"] == "incomplete" and done["signal"] == "SIGINT"
    assert len(csv_lines(out)) - 1 == done["rows"]
    verify(out / "recording.rrd")
    # the recording ends saying why, where the run ended
    assert last_note(out / "recording.rrd") == (
        round(done["time_reached"] * 1e9),
        f"run incomplete: {done['error']}",
    )


@pytest.mark.slow
def test_ctrl_c_held_down_until_the_process_ends_never_kills_it(fmu_dir: Path, tmp_path: Path):
    """Regression: a Ctrl-C arriving while the interpreter shut down, after the run had
    completed its folder and printed its line, killed the process by SIGINT (exit -2 to
    its parent, no 130): Python's finalization puts the default action back for a signal
    handled by a Python function. Seen under load as a second Ctrl-C 0.02-0.3 s after
    the first came late. Here Ctrl-C comes every 5 ms from the first until the end."""
    out = tmp_path / "run"
    proc = start(fmu_dir, out, "--stop-time", LONG, "--no-rrd")
    wait_for_rows(proc, out, 300)
    deadline = time.monotonic() + 120.0  # a guard against a hang, not a measure
    while proc.poll() is None and time.monotonic() < deadline:
        proc.send_signal(signal.SIGINT)
        time.sleep(0.005)
    returncode, err = finish(proc)
    assert returncode == 130, err
    assert err.count("\n") == 1 and "auv-cosim run: interrupted (Ctrl-C) at t = " in err
    done = summary(out)
    assert done["status"] == "incomplete" and done["signal"] == "SIGINT"
    assert len(csv_lines(out)) - 1 == done["rows"]


CTRL_C_WHILE_WRITING = """
import os, signal, sys, time
from cosim.cli import main
from cosim.outputs import sinks

close = sinks.CsvSink.close


def close_under_fire(self):
    # the stepping is over: Ctrl-C twice while the outputs are being completed
    os.kill(os.getpid(), signal.SIGINT)
    time.sleep(0.05)
    os.kill(os.getpid(), signal.SIGINT)
    close(self)


sinks.CsvSink.close = close_under_fire
sys.exit(main(["run", "bs-3", "--stop-time", "2", "--fmu-dir", sys.argv[1], "--out", sys.argv[2],
               "--quiet"]))
"""


@pytest.mark.slow
def test_ctrl_c_while_the_outputs_are_written_does_not_abort_them(
    fmu_dir: Path, tmp_path: Path, run_python
):
    """Regression: one Ctrl-C after vert-2 finished stepping, while the outputs were written,
    left an empty run folder (rc 130)."""
    out = tmp_path / "run"
    proc = run_python(CTRL_C_WHILE_WRITING, fmu_dir, out)
    assert proc.returncode == 130, proc.stderr
    assert "interrupted (Ctrl-C) while the outputs were completed; the run is complete" in (
        proc.stderr
    )
    done = summary(out)
    assert done["status"] == "complete" and done["complete"] is True
    assert done["signal"] == "SIGINT" and done["rows"] == 201
    assert len(csv_lines(out)) == 1 + 201
    verify(out / "recording.rrd")


@pytest.mark.slow
def test_a_second_run_into_a_running_folder_fails_at_once(fmu_dir: Path, tmp_path: Path):
    """Regression: `run bs-3 --out same & run bs-1 --out same` both exited 0 and the
    recording failed its CRC. The second fails while the first still runs (it does not
    wait for the folder), and the first's files stay whole."""
    out = tmp_path / "same"
    first = start(fmu_dir, out, "--stop-time", "300", "--real-time", "10")  # 30 s, stopped below
    try:
        wait_for_rows(first, out, 1)
        second = start(fmu_dir, out, "--stop-time", "5", scenario="bs-1")
        code, err = finish(second, timeout=30)
        assert first.poll() is None, "the first run ended before the second was refused"
    finally:
        first.send_signal(signal.SIGTERM)
        first_code, _ = finish(first)
    assert code == 1
    assert f"run folder {out} is in use by process {first.pid} (" in err
    assert first_code == 143
    done = summary(out)
    assert done["scenario"] == "bs-3" and done["signal"] == "SIGTERM"
    assert len(csv_lines(out)) == 1 + done["rows"]
    verify(out / "recording.rrd")


@pytest.mark.slow
def test_a_slow_runs_rows_reach_results_csv_before_a_chunk_fills(fmu_dir: Path, tmp_path: Path):
    """A slow run (the full 6-DOF plant sub-steps every 1.2 us, or 0.1 ms on the 50x slower
    reference path: fewer than ROWS_PER_CHUNK rows a second) has its rows on disk as the
    wall-clock interval passes, not only in full chunks of ROWS_PER_CHUNK rows: results.csv
    is seen holding a number of rows that no whole number of chunks makes. (When the
    hand-offs happen is checked without a clock in test_master.py.)"""
    scenario = tmp_path / "slow.toml"
    text = scenario_path("bs-3").read_text().replace('variant = "lateral"', 'variant = "full"')
    substep = "1.2e-6" if compiled.AVAILABLE else "1e-4"
    scenario.write_text(text.replace("v_0 = -0.10", f"v_0 = -0.10\nmax_substep = {substep}"))
    out = tmp_path / "run"
    proc = start(fmu_dir, out, "--no-rrd", scenario=str(scenario))
    seen: set[int] = set()
    try:
        wait_for_rows(proc, out, 2)
        deadline = time.monotonic() + 60.0  # a timeout, not a measure: seen at once as a rule
        while time.monotonic() < deadline and all(n % ROWS_PER_CHUNK == 0 for n in seen):
            seen.add(rows_in(out / "results.csv"))
            time.sleep(0.05)
    finally:
        proc.send_signal(signal.SIGTERM)
        finish(proc)
    assert any(n % ROWS_PER_CHUNK for n in seen), f"only whole chunks of rows seen: {sorted(seen)}"


@pytest.mark.slow
def test_a_huge_stop_time_streams_with_bounded_memory(fmu_dir: Path, tmp_path: Path):
    """Regression: `--stop-time 1e6` took 4.3 GB before the first step."""
    out = tmp_path / "run"
    proc = start(fmu_dir, out, "--stop-time", "1e6", "--no-rrd")
    wait_for_rows(proc, out, 400, timeout=60)
    peak = peak_rss_kb(proc.pid)
    proc.send_signal(signal.SIGTERM)
    while proc.poll() is None:  # the peak of the clean-up too, while the process exists
        peak = max(peak, peak_rss_kb(proc.pid))
        time.sleep(0.01)
    assert proc.returncode == 143
    assert peak < 600 * 1024, f"peak RSS {peak / 1024:.0f} MB"
    proc.communicate()


def peak_rss_kb(pid: int) -> int:
    """The process's peak resident set (kB, VmHWM), 0 once it has exited.

    Not wait4's ru_maxrss: the kernel folds into that the RSS of the address space the
    child left at exec, which is the forking pytest process's (650 MB late in a full run).
    """
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except (FileNotFoundError, ProcessLookupError):
        return 0
    return next((int(line.split()[1]) for line in status.splitlines()
                 if line.startswith("VmHWM:")), 0)  # fmt: skip


@pytest.mark.slow
def test_a_stopped_manoeuvre_gets_the_metrics_of_what_it_ran(fmu_dir: Path, tmp_path: Path):
    """Regression: a turning circle stopped by SIGTERM after 3 s: summary.json names the
    manoeuvre and has every metric, measured over the rows it ran (the 90 deg point is
    not reached by then: None), exactly as from its partial results.csv."""
    out = tmp_path / "run"
    proc = start(fmu_dir, out, "--stop-time", "600", "--no-rrd", scenario="turning-circle")
    wait_for_rows(proc, out, 300)
    proc.send_signal(signal.SIGTERM)
    returncode, err = finish(proc)
    assert returncode == 128 + signal.SIGTERM, err
    done = summary(out)
    assert done["status"] == "incomplete" and done["manoeuvre"] == "turning-circle"
    names, table = read_csv(out / "results.csv")
    expected = manoeuvre_metrics("turning-circle", dict(zip(names, table.T, strict=True)))
    assert tuple(expected) == metric_names("turning-circle")
    assert {name: done[name] for name in expected} == expected
    if done["time_reached"] < 5.0:  # the heading turns 90 deg after about 8 s
        assert done["advance_m"] is None


@pytest.mark.slow
def test_a_run_under_nohup_is_not_ended_by_a_hangup(fmu_dir: Path, tmp_path: Path) -> None:
    """``nohup auv-cosim run ...`` (SIGHUP ignored from the start), then the terminal hangs
    up: the run caught SIGHUP anyway and ended, "hung up (SIGHUP)", exit 129. It goes on;
    the SIGTERM sent after the SIGHUP is the signal that ends it (the first one counts)."""
    out = tmp_path / "run"
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir),
               "--out", str(out), "--quiet", "--no-rrd", "--stop-time", LONG]  # fmt: skip
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN),  # as nohup does
    )
    try:
        wait_for_rows(proc, out, 300)
        proc.send_signal(signal.SIGHUP)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    assert proc.returncode == 143, err
    assert summary(out)["signal"] == "SIGTERM"
