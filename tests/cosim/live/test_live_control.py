"""A paced run steered through the control endpoint, then replayed from its run folder.

The command line runs in a subprocess (its own process group, killed in a ``finally``) on
the built FMUs (bs-3); a client sets the yaw set-point twice and reads the yaw back over
JSON lines; summary.json, results.csv and the recording log both overrides, and the run
folder's scenario.toml, run again, gives a byte-identical results.csv.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar

import numpy as np
import pytest
from process_group import started_in_group
from rerun.chunk import RrdReader

from cosim.engine.live import LiveControl, OverrideError
from cosim.outputs.results import read_csv
from cosim.runner import run_scenario
from cosim.scenario.spec import load_scenario
from cosim.viz.recording import rerun_executable

TIMEOUT_S = 120.0  # generous: the machine may be busy; nothing here is timed


@contextlib.contextmanager
def cli_run(
    fmu_dir: Path, out: Path, *options: str, env: dict[str, str] | None = None
) -> Iterator[subprocess.Popen]:
    """`auv-cosim run bs-3 ...` (in ``env``: this process's unless given) in its own process
    group, killed on the way out."""
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--fmu-dir", str(fmu_dir),
               "--out", str(out), "--quiet", *options]  # fmt: skip
    with started_in_group(command, env=env) as proc:
        yield proc


def endpoint(proc: subprocess.Popen) -> tuple[str, int]:
    """The address the run printed: ``control endpoint: HOST:PORT``."""
    assert proc.stderr is not None
    line = proc.stderr.readline()
    assert line.startswith("control endpoint: "), line
    host, _, port = line.split(": ", 1)[1].strip().rpartition(":")
    return host, int(port)


class Client:
    """One JSON line out, one JSON line back; closed at the end of the test that opened it
    (:func:`_clients_closed`)."""

    opened: ClassVar[list[Client]] = []

    def __init__(self, address: tuple[str, int]) -> None:
        self.sock = socket.create_connection(address, timeout=TIMEOUT_S)
        self.file = self.sock.makefile("rw", encoding="utf-8")
        Client.opened.append(self)

    def close(self) -> None:
        with contextlib.suppress(OSError):  # the write buffer's flush to a closed endpoint
            self.file.close()
        self.sock.close()

    def raw(self, text: str) -> str:
        self.file.write(text + "\n")
        self.file.flush()
        return self.file.readline()

    def ask(self, request: object) -> dict:
        return json.loads(self.raw(json.dumps(request)))

    def time_at_least(self, t: float) -> float:
        """Poll until the run has reached ``t`` (s); the time it has reached."""
        deadline = time.monotonic() + TIMEOUT_S
        while time.monotonic() < deadline:
            reply = self.ask({"get": ["plant.yaw"]})
            if "t" in reply and reply["t"] is not None and reply["t"] >= t:
                return reply["t"]
            time.sleep(0.02)
        raise AssertionError(f"the run did not reach t = {t} s")

    def time_held(self) -> float:
        """Poll until two reads 0.2 s of wall clock apart give the same time; that time."""
        deadline, before = time.monotonic() + TIMEOUT_S, None
        while time.monotonic() < deadline:
            now = self.ask({"get": []})["t"]
            if now == before:
                return now
            before = now
            time.sleep(0.2)
        raise AssertionError("the run did not pause")


@pytest.fixture(autouse=True)
def _clients_closed() -> Iterator[None]:
    """Every client a test opened is closed as it ends, passed or failed: a socket left to
    the garbage collector is a ResourceWarning in whichever test happens to collect it."""
    yield
    while Client.opened:
        Client.opened.pop().close()


@pytest.mark.slow
def test_a_paced_run_steered_over_the_endpoint_replays_byte_identical(
    fmu_dir: Path, tmp_path: Path
) -> None:
    out = tmp_path / "live"
    with cli_run(fmu_dir, out, "--stop-time", "60", "--real-time", "4",
                 "--control", "127.0.0.1:0") as proc:  # fmt: skip
        host, port = endpoint(proc)
        client = Client((host, port))
        t_first = client.time_at_least(0.5)
        first = client.ask({"set": {"controller.yaw_setpoint": 0.3}})
        assert first == {"ok": True, "set": {"controller.yaw_setpoint": 0.3}, "name": "live-1",
                         "t": first["t"]}  # fmt: skip
        t_second = client.time_at_least(t_first + 0.5)
        second = client.ask({"set": {"controller.yaw_setpoint": 0.6}})
        assert second["ok"] and second["name"] == "live-2"
        t_read = client.time_at_least(t_second + 1.0)
        reply = client.ask({"get": ["plant.yaw", "controller.yaw_setpoint"]})
        assert reply["t"] >= t_read and reply["values"]["controller.yaw_setpoint"] == 0.6
        assert 0.0 < reply["values"]["plant.yaw"] < 1.0  # turning towards the set-points
        assert client.ask({"stop": True}) == {"ok": True}
        _, err = proc.communicate(timeout=TIMEOUT_S)
        assert proc.returncode == 130, err  # stopped like Ctrl-C, partial results kept
    assert host == "127.0.0.1"
    summary = json.loads((out / "summary.json").read_text())
    overrides = summary["overrides"]
    assert [o["set"] for o in overrides] == [{"controller.yaw_setpoint": v} for v in (0.3, 0.6)]
    assert all(o["source"].startswith("control 127.0.0.1:") for o in overrides)
    assert t_first < overrides[0]["time"] <= t_second < overrides[1]["time"] <= t_read
    assert [o["time"] for o in overrides] == [first["t"], second["t"]]  # as the replies said
    columns, table = read_csv(out / "results.csv")
    setpoint = table[:, columns.index("controller.yaw_setpoint")]
    times = table[:, 0]
    assert set(setpoint[times < overrides[0]["time"]]) == {0.0}
    assert set(setpoint[times >= overrides[1]["time"]]) == {0.6}
    assert summary["real_time"]["target_factor"] == 4.0
    assert summary["real_time"]["achieved_factor"] > 0.0

    notes = []  # the recording marks each override at its time
    for chunk in RrdReader(out / "recording.rrd").stream():
        if chunk.entity_path == "/events":
            batch = chunk.to_record_batch()
            texts = [t for row in batch.column("TextLog:text").to_pylist() for t in row]
            nanos = batch.column("sim_time").cast("int64").to_pylist()
            notes += list(zip(nanos, texts, strict=True))
    *marked, (t_end, ending) = sorted(notes)  # the last says how the run ended
    assert t_end == round(summary["time_reached"] * 1e9) and ending.startswith("run ")
    assert marked == [
        (round(o["time"] * 1e9), f"override {o['name']} from {o['source']}: "
                                 f"controller.yaw_setpoint = {value} rad ({degrees} deg)")
        for o, value, degrees in zip(overrides, (0.3, 0.6), ("17.1887", "34.3775"), strict=True)
    ]  # fmt: skip

    replay = run_scenario(out / "scenario.toml", tmp_path / "replay", fmu_dir=fmu_dir,
                          no_rrd=True, tail_guard=False)  # fmt: skip
    assert replay.result.complete, replay.result.error
    assert (tmp_path / "replay" / "results.csv").read_bytes() == (out / "results.csv").read_bytes()


@pytest.mark.slow
def test_the_endpoint_refuses_bad_requests_with_one_line_each(
    fmu_dir: Path, tmp_path: Path
) -> None:
    with cli_run(fmu_dir, tmp_path / "run", "--no-rrd", "--stop-time", "60", "--real-time", "1",
                 "--control", "0") as proc:  # fmt: skip
        host, port = endpoint(proc)
        assert host == "127.0.0.1"  # the default interface, port 0: any free port
        client = Client((host, port))
        client.time_at_least(0.0)
        replies = [
            client.raw('{"set": {"controller.no_such_input": 1.0}}'),
            client.raw('{"set": {"controller.yaw_setpoint": 1e999}}'),
            client.raw('{"set": {"plant.mass_position_cmd": 0.01}}'),
            client.raw('{"get": ["plant.no_such_output"]}'),
            client.raw("not json"),
        ]
        assert client.ask({"pause": True}) == {"ok": True, "paused": True}
        held = client.time_held()  # the run waits at a communication point
        assert client.ask({"pause": False}) == {"ok": True, "paused": False}
        assert client.time_at_least(held + 0.05) > held  # and goes on once resumed
        client.ask({"stop": True})
        proc.communicate(timeout=TIMEOUT_S)
        assert proc.returncode == 130  # stopped like Ctrl-C
    errors = [json.loads(reply)["error"] for reply in replies]
    assert all(reply.count("\n") == 1 for reply in replies)
    assert "has no variable 'no_such_input'" in errors[0]
    assert "inf is not a finite number" in errors[1]
    assert "is connected from controller.mass_position_cmd" in errors[2]
    assert "'plant.no_such_output'" in errors[3]
    assert "not a JSON line" in errors[4]
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["overrides"] == []


def test_a_value_outside_the_declared_range_is_refused(fmu_dir: Path) -> None:
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    inst = scenario.instances["controller"]
    var = dataclasses.replace(inst.interface.variables["yaw_setpoint"], min=-math.pi, max=math.pi)
    interface = dataclasses.replace(
        inst.interface, variables={**inst.interface.variables, "yaw_setpoint": var}
    )
    instances = {**scenario.instances, "controller": dataclasses.replace(inst, interface=interface)}
    live = LiveControl(dataclasses.replace(scenario, instances=instances))
    assert live.check("controller.yaw_setpoint", 3.0) == 3.0
    with pytest.raises(OverrideError, match=r"4\.0 is outside \[-3\.14.*, 3\.14.*\]"):
        live.request({"controller.yaw_setpoint": 4.0}, "test")
    with pytest.raises(OverrideError, match="is a fixed parameter"):
        live.request({"controller.yaw_setpoint": 0.1, "controller.k0": 0.3}, "test")
    # a refused request queues nothing, not even its good values
    assert list(live.take(0, 0.0, np.zeros(1))) == []


def test_a_depth_set_point_above_the_surface_is_refused(fmu_dir: Path) -> None:
    """``{"set": {"controller.depth_setpoint": -5}}`` (5 m above the surface, depth down
    positive) was taken: the autopilot declared no minimum for it (only the keys stopped
    at 0 m). It declares 0 m now, and the endpoint refuses it as any value out of range,
    saying which way depths count."""
    live = LiveControl(load_scenario("bs-3", fmu_dir=fmu_dir))
    assert live.check("controller.depth_setpoint", 0.0) == 0.0
    with pytest.raises(
        OverrideError, match=r"-5\.0 is outside \[0(\.0)?, .*down positive, 0 m at the surface"
    ):
        live.request({"controller.depth_setpoint": -5.0}, "test")


def _replayed(out: Path, fmu_dir: Path, tmp_path: Path) -> tuple[bool, bytes]:
    """Run the live run's scenario.toml again: (complete, its results.csv)."""
    replay = run_scenario(out / "scenario.toml", tmp_path / "replay", fmu_dir=fmu_dir,
                          no_rrd=True, tail_guard=False)  # fmt: skip
    return replay.result.complete, (tmp_path / "replay" / "results.csv").read_bytes()


def _pipelined(client: Client, *requests: object) -> list[dict]:
    """Send every request at once, then read one reply each."""
    client.file.write("".join(json.dumps(r) + "\n" for r in requests))
    client.file.flush()
    return [json.loads(client.file.readline()) for _ in requests]


@pytest.mark.slow
@pytest.mark.parametrize("case", ["set then stop before t = 0", "stopped without override",
                                  "broken by an override"])  # fmt: skip
def test_a_live_run_replays_byte_identical(fmu_dir: Path, tmp_path: Path, case: str) -> None:
    out = tmp_path / "live"
    with cli_run(fmu_dir, out, "--no-rrd", "--stop-time", "5", "--real-time", "10",
                 "--control", "0") as proc:  # fmt: skip
        client = Client(endpoint(proc))
        if case == "set then stop before t = 0":  # both sent while the FMUs are set up
            replies = _pipelined(client, {"set": {"controller.yaw_setpoint": 0.2}}, {"stop": True})
            assert replies[0]["ok"] and replies[0]["t"] == 0.0 and replies[1] == {"ok": True}
        elif case == "stopped without override":
            client.time_at_least(0.5)
            assert client.ask({"stop": True}) == {"ok": True}
        else:  # the plant fails in the step after the override, well after t = 0
            client.time_at_least(0.5)
            reply = client.ask({"set": {"plant.roll_torque": 1e300}})
            assert reply["ok"], reply
        proc.communicate(timeout=TIMEOUT_S)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False
    complete, replayed = _replayed(out, fmu_dir, tmp_path)
    assert replayed == (out / "results.csv").read_bytes()
    assert complete == (case != "broken by an override")  # a replay of a failure fails too
    if case == "set then stop before t = 0":
        # the stop is read once the set is applied at t = 0 (its reply waits for that), so
        # the run stops within a few steps, however loaded the machine: far from 5 s
        assert 3 <= replayed.count(b"\n") < 100


@pytest.mark.slow
def test_every_set_around_the_end_of_a_run_is_applied_and_logged_or_answered_not(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A client sets the yaw set-point as fast as it can across the run's end (and after a
    stop): each "ok" names a point where summary.json logs it; every other reply says
    "not applied". The endpoint closes soon after the end (docs/live-runs.md: the client
    then reads end of file), so a request sent late, as a loaded machine sends it, may
    find it closed: that ends the requests too, never an "ok" the run did not log."""
    out = tmp_path / "run"
    with cli_run(fmu_dir, out, "--no-rrd", "--stop-time", "1", "--real-time", "10",
                 "--control", "0") as proc:  # fmt: skip
        client = Client(endpoint(proc))
        replies: list[dict] = []
        k = 0
        while not replies or "ok" in replies[-1]:
            k += 1
            reply = _reply_unless_closed(client, {"set": {"controller.yaw_setpoint": k * 1e-4}})
            if reply is None:
                break
            replies.append(reply)
        after = _reply_unless_closed(client, {"stop": True}) if reply is not None else None
        proc.communicate(timeout=TIMEOUT_S)
        assert proc.returncode == 0  # complete: the stop came after the end
    summary = json.loads((out / "summary.json").read_text())
    logged = {o["name"]: (o["time"], o["set"]) for o in summary["overrides"]}
    acked = {r["name"]: (r["t"], r["set"]) for r in replies if "ok" in r}
    assert acked == logged and acked  # however many the client got in before the end
    refused = [r["error"] for r in replies if "ok" not in r]
    assert all(e == refused[0] and "not applied: the run ended at t = 1 s" in e for e in refused)
    assert after is None or "stop: the run ended at t = 1 s" in after["error"]


def _reply_unless_closed(client: Client, request: object) -> dict | None:
    """The reply to ``request``, or None if the endpoint had closed (end of file)."""
    try:
        line = client.raw(json.dumps(request))
    except OSError:  # the close came first: the request could not even be sent
        return None
    return json.loads(line) if line else None


@pytest.mark.slow
def test_check_step_of_a_steered_run_checks_what_it_ran(fmu_dir: Path, tmp_path: Path) -> None:
    """--check-step of a live run steered to a new set-point ran its h/2 and h/4 runs
    without the override: "yaw_settling_time_s +2.04 (+64 %)", where its replay's check
    said -0.025 %. The check is now the replay's, to the last digit."""
    out = tmp_path / "live"
    with cli_run(fmu_dir, out, "--stop-time", "3", "--real-time", "5", "--check-step",
                 "--no-rrd", "--control", "127.0.0.1:0") as proc:  # fmt: skip
        client = Client(endpoint(proc))
        client.time_at_least(0.5)
        assert client.ask({"set": {"controller.yaw_setpoint": 0.3}})["ok"]
        _, err = proc.communicate(timeout=TIMEOUT_S)
        assert proc.returncode == 0, err
    live = json.loads((out / "summary.json").read_text())["coupling"]["check_step"]
    replay = run_scenario(out / "scenario.toml", tmp_path / "replay", fmu_dir=fmu_dir,
                          no_rrd=True, tail_guard=False, check_step=True)  # fmt: skip
    assert replay.result.coupling["check_step"] == live


@contextlib.contextmanager
def viewer_server(port: int) -> Iterator[subprocess.Popen]:
    """``rerun --serve-grpc`` on 127.0.0.1:``port`` in its own process group (the launcher
    starts the viewer binary as its child), listening when this yields; killed on the way
    out if the test has not stopped it."""
    command = [str(rerun_executable()), "--serve-grpc", "--bind", "127.0.0.1",
               "--port", str(port)]  # fmt: skip
    server = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                              start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + TIMEOUT_S
        while not _listening(port):
            assert server.poll() is None and time.monotonic() < deadline, "no viewer server"
            time.sleep(0.1)
        yield server
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(server.pid, signal.SIGKILL)
        server.wait()


def _listening(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) == 0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.mark.slow
@pytest.mark.skipif(rerun_executable() is None, reason="the rerun CLI is not installed")
def test_a_viewer_that_goes_away_mid_run_costs_one_warning_line(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A viewer closed during a streamed run (``--connect``) is told in one line of ours; the
    SDK's own log lines ("ERROR re_grpc_client::write: Write messages call failed", "Failed
    to flush previous sink", in terminal colours) came out beside it. The run goes on."""
    port = _free_port()
    url = f"rerun+http://127.0.0.1:{port}/proxy"
    env = {key: value for key, value in os.environ.items() if key != "RUST_LOG"}
    with viewer_server(port) as server, cli_run(
        fmu_dir, tmp_path / "run", "--stop-time", "600", "--real-time", "5", "--no-rrd",
        "--connect", url, "--control", "127.0.0.1:0", env=env,
    ) as proc:  # fmt: skip
        client = Client(endpoint(proc))
        t_closed = client.time_at_least(1.0)
        os.killpg(server.pid, signal.SIGKILL)
        client.time_at_least(t_closed + 5.0)  # the run sends a few times to no one
        assert client.ask({"stop": True}) == {"ok": True}
        _, err = proc.communicate(timeout=TIMEOUT_S)
    assert proc.returncode == 130, err
    lines = [line for line in err.splitlines() if "stopped by control" not in line]
    assert len(lines) == 1 and "warning: Rerun viewer: " in lines[0], err


@pytest.mark.slow
def test_sets_sent_in_a_burst_are_applied_at_the_next_points_not_one_per_point(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A client sending set-points faster than the run's points (1000 a second, without
    waiting for each reply) saw them applied one per communication point, each waiting for
    the one before: 3 s of them (3,000) took 30 s of simulated time to come into force at
    1x. Each now goes into force at the next point after it arrived, in order, and the
    replies come back in the order sent; a ``get`` after them reads the last value."""
    count = 300
    with cli_run(fmu_dir, tmp_path / "run", "--stop-time", "600", "--real-time", "1",
                 "--no-rrd", "--control", "127.0.0.1:0") as proc:  # fmt: skip
        client = Client(endpoint(proc))
        client.time_at_least(0.1)
        values = [round(0.001 * i, 3) for i in range(1, count + 1)]
        burst = "".join(json.dumps({"set": {"controller.yaw_setpoint": v}}) + "\n" for v in values)
        client.file.write(burst + json.dumps({"get": ["controller.yaw_setpoint"]}) + "\n")
        client.file.flush()
        replies = [json.loads(client.file.readline()) for _ in range(count + 1)]
        assert client.ask({"stop": True}) == {"ok": True}
        proc.communicate(timeout=TIMEOUT_S)
    sets, read = replies[:-1], replies[-1]
    assert [r.get("set") for r in sets] == [{"controller.yaw_setpoint": v} for v in values]
    assert [r["name"] for r in sets] == [f"live-{i}" for i in range(1, count + 1)]
    times = [r["t"] for r in sets]
    assert times == sorted(times) and len(set(times)) < count // 2, times
    assert read["values"] == {"controller.yaw_setpoint": values[-1]} and read["t"] >= times[-1]
