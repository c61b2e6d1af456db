"""The control endpoint against careless and hostile clients, without a run: a
:class:`LiveControl` of bs-3 behind a real socket, and a stand-in for the master's thread
where a test needs one (it takes the queue at points as the master's timeline does).

Every malformed request line gets exactly one error reply and the connection stays open; an
over-long line is refused whole (its tail never runs); every line end ends a line; a pause
is let go when its client goes away; the connections are capped; the ``--control``
address forms are parsed or refused with the true reason; an ``ok`` to a ``set`` means it
was applied, and a ``set`` the run ends before applying is answered "not applied".
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import threading
from collections.abc import Iterator
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from process_group import run_in_group

from cosim.engine.live import LiveControl, OverrideError
from cosim.engine.signals import StopRequest
from cosim.errors import CosimError
from cosim.live.control import (
    MAX_CLIENTS,
    MAX_LINE,
    TOO_LONG,
    ControlServer,
    lines,
    parse_address,
    submit,
)
from cosim.live.session import LiveSession
from cosim.scenario.spec import Scenario, load_scenario

TIMEOUT_S = 60.0  # generous: the machine may be busy; nothing here is timed
GOOD = b'{"pause": false}\n'  # a request answered without a run: {"ok": true, ...}


@pytest.fixture(scope="module")
def scenario(fmu_paths: dict[str, Path]) -> Scenario:
    return load_scenario("bs-3", fmu_dir=fmu_paths["AuvAutopilot"].parent)


@contextlib.contextmanager
def endpoint(live: LiveControl, address: str = "127.0.0.1:0") -> Iterator[ControlServer]:
    server = ControlServer.open(live, address)
    try:
        yield server
    finally:
        live.close()
        server.close()


class Client:
    def __init__(self, server: ControlServer) -> None:
        host, _, port = server.address.rpartition(":")
        self.sock = socket.create_connection((host.strip("[]"), int(port)), timeout=TIMEOUT_S)
        self.file = self.sock.makefile("rb")

    def send(self, data: bytes) -> None:
        self.sock.sendall(data)

    def reply(self) -> dict:
        line = self.file.readline()
        assert line.endswith(b"\n"), line
        return json.loads(line)

    def close(self) -> None:
        self.file.close()
        self.sock.close()


def _nested(depth: int) -> bytes:
    return b"[" * depth + b"]" * depth


MALFORMED = {
    "not JSON": b"not json",
    "not UTF-8": b'{"get": ["\xff\xfe"]}',
    "an empty line": b"",
    "a JSON array": b"[1, 2]",
    "two verbs": b'{"pause": true, "stop": true}',
    "an unknown verb": b'{"launch": true}',
    "set of a list": b'{"set": [1, 2]}',
    "get of a string": b'{"get": "plant.yaw"}',
    "pause of a number": b'{"pause": 1}',
    "stop false": b'{"stop": false}',
    "a NaN value": b'{"set": {"controller.yaw_setpoint": NaN}}',
    "an infinite value": b'{"set": {"controller.yaw_setpoint": 1e999}}',
    "an integer of 5000 digits": b'{"set": {"controller.yaw_setpoint": ' + b"9" * 5000 + b"}}",
    "an integer beyond any float": b'{"set": {"controller.heading_mode": 1' + b"0" * 400 + b"}}",
    "deep nesting": _nested(MAX_LINE // 2 - 8),
    "deep nesting in a set": b'{"set": ' + _nested(50_000) + b"}",
    "a line over the limit": b'{"get": ["' + b"x" * MAX_LINE + b'"]}',
    "a 10 MB line": b"y" * 10_000_000,
}


@pytest.mark.parametrize("kind", list(MALFORMED))
def test_every_malformed_request_line_gets_one_error_reply_and_the_connection_stays(
    scenario: Scenario, kind: str, capfd: pytest.CaptureFixture[str]
) -> None:
    live = LiveControl(scenario)
    with endpoint(live) as server:
        client = Client(server)
        client.send(MALFORMED[kind] + b"\n" + GOOD)
        error = client.reply()
        assert list(error) == ["error"] and "\n" not in error["error"], error
        assert len(error["error"]) < 300, error  # one line, not the request echoed back
        assert client.reply() == {"ok": True, "paused": False}  # the same connection, next line
        client.close()
    assert list(live.take(0, 0.0, np.zeros(1))) == []  # nothing was queued
    assert "Traceback" not in capfd.readouterr().err


def test_an_over_long_line_is_refused_whole_and_its_tail_never_runs(scenario: Scenario) -> None:
    live = LiveControl(scenario)
    with endpoint(live) as server:
        client = Client(server)
        tail = b'{"stop": true}'
        client.send(b" " * (MAX_LINE + 100) + tail + b"\n" + GOOD)
        assert "longer than" in client.reply()["error"]
        assert client.reply() == {"ok": True, "paused": False}
        client.close()
        assert not live.stopping  # the tail of the long line was not read as a request


@pytest.mark.parametrize("end", [b"\n", b"\r\n", b"\r"], ids=["LF", "CRLF", "CR"])
def test_each_line_end_ends_one_request(scenario: Scenario, end: bytes) -> None:
    live = LiveControl(scenario)
    with endpoint(live) as server:
        client = Client(server)
        client.send(b'{"pause": true}' + end)
        assert client.reply() == {"ok": True, "paused": True}  # answered before a next line
        client.send(GOOD.rstrip(b"\n") + end + GOOD)
        assert [client.reply(), client.reply()] == [{"ok": True, "paused": False}] * 2
        client.close()


@given(
    st.lists(st.binary(max_size=40).map(lambda b: b.replace(b"\r", b"").replace(b"\n", b""))),
    st.lists(st.sampled_from([b"\n", b"\r\n", b"\r"])),
    st.lists(st.integers(min_value=1, max_value=30)),
)
def test_lines_split_over_any_reads_are_the_lines_sent(
    texts: list[bytes], ends: list[bytes], cuts: list[int]
) -> None:
    """However the stream is cut into reads (a \\r\\n split in two included)."""
    ends = (ends or [b"\n"]) * (len(texts) + 1)
    stream, before = b"", b""
    for text, end in zip(texts, ends, strict=False):
        if before == b"\r" and text == b"" and end == b"\n":
            end = b"\r\n"  # \r then an empty line ended by \n would read as one \r\n
        stream += text + end
        before = end
    chunks, i = [], 0
    for cut in cuts * 10:
        if i >= len(stream):
            break
        chunks.append(stream[i : i + cut])
        i += cut
    chunks.append(stream[i:])
    reads = iter([c for c in chunks if c] + [b""])
    assert list(lines(lambda _size: next(reads))) == texts


def test_a_line_over_the_limit_is_one_refusal_however_long() -> None:
    reads = iter([b"z" * 70_000] * 200 + [b"z\n{}\n", b""])  # 14 MB in one line, then {}
    assert list(lines(lambda _size: next(reads))) == [TOO_LONG, b"{}"]


def test_a_client_that_paused_and_went_away_lets_the_run_go_on(
    scenario: Scenario, capfd: pytest.CaptureFixture[str]
) -> None:
    live = LiveControl(scenario)
    with endpoint(live) as server:
        pausing, staying = Client(server), Client(server)
        for client in (pausing, staying):
            client.send(b'{"pause": true}\n')
            assert client.reply() == {"ok": True, "paused": True}
        pausing.close()
        staying.send(GOOD.replace(b"false", b"true"))  # a round trip: the first one is gone
        staying.reply()
        assert live.paused  # the other client still holds it
        staying.close()
        deadline = threading.Event()
        for _ in range(int(TIMEOUT_S / 0.05)):
            if not live.paused:
                break
            deadline.wait(0.05)
        assert not live.paused
        notes = live.take_notes()
    assert len(notes) == 1 and "went away while holding the run paused: resumed" in notes[0]
    assert "disconnected while holding the run paused: resumed" in capfd.readouterr().err


def test_connections_beyond_the_cap_are_refused_in_one_line(scenario: Scenario) -> None:
    live = LiveControl(scenario)
    with endpoint(live) as server:
        idle = [Client(server) for _ in range(MAX_CLIENTS)]
        for client in idle:  # each one served (so counted) before the next test
            client.send(GOOD)
            client.reply()
        extra = Client(server)
        refusal = extra.reply()["error"]
        assert f"at most {MAX_CLIENTS}" in refusal and extra.file.readline() == b""  # closed
        idle.pop().close()
        for _ in range(int(TIMEOUT_S / 0.05)):  # the closed one's place is free again
            again = Client(server)
            again.send(GOOD)
            reply = again.reply()
            again.close()
            if "error" not in reply:
                break
            threading.Event().wait(0.05)
        assert reply == {"ok": True, "paused": False}
        for client in [*idle, extra]:
            client.close()


BAD_ADDRESSES = {
    "١٢": "ASCII digits",  # Arabic-Indic digits: int() takes them
    "5_0": "ASCII digits",  # int() takes underscores
    "+50": "ASCII digits",
    " 50": "ASCII digits",
    "-1": "ASCII digits",
    "65536": "0..65535",
    "localhost:": "ASCII digits",
    "::1": "in brackets",
    "::1:5555": "in brackets",
    "[::1]": "[IPv6]:PORT",
    "[::1]5555": "[IPv6]:PORT",
    "[127.0.0.1]:5555": "not an IPv6 address",
    "[::1:5555": "[IPv6]:PORT",
}


@pytest.mark.parametrize("text", list(BAD_ADDRESSES))
def test_a_control_address_that_is_not_port_host_port_or_bracketed_ipv6_is_refused(
    text: str,
) -> None:
    with pytest.raises(CosimError, match=BAD_ADDRESSES[text].replace("[", r"\[")):
        parse_address(text)


@pytest.mark.parametrize(
    ("text", "parsed"),
    [("5555", ("127.0.0.1", 5555)), ("0", ("127.0.0.1", 0)), (":7", ("127.0.0.1", 7)),
     ("localhost:80", ("localhost", 80)), ("[::1]:0", ("::1", 0)),
     ("[fe80::1%lo]:9", ("fe80::1%lo", 9))],
)  # fmt: skip
def test_control_addresses_are_parsed(text: str, parsed: tuple[str, int]) -> None:
    assert parse_address(text) == parsed


def test_an_ipv6_address_in_brackets_is_served(scenario: Scenario) -> None:
    if not socket.has_ipv6:
        pytest.skip("no IPv6 on this machine")
    try:
        with socket.socket(socket.AF_INET6) as probe:
            probe.bind(("::1", 0))
    except OSError:
        pytest.skip("no IPv6 loopback on this machine")
    live = LiveControl(scenario)
    with endpoint(live, "[::1]:0") as server:
        assert server.address.startswith("[::1]:") and not server.reachable_from_network
        client = Client(server)
        client.send(GOOD)
        assert client.reply() == {"ok": True, "paused": False}
        client.close()


@pytest.mark.parametrize("host", ["0.0.0.0", "127.0.0.1", "localhost"])
def test_an_endpoint_reachable_from_the_network_says_so(
    scenario: Scenario, host: str, capfd: pytest.CaptureFixture[str]
) -> None:
    session = LiveSession.open(scenario, None, f"{host}:0", False)
    session.close()
    err = capfd.readouterr().err
    warned = "WARNING" in err and "reachable from the network" in err and "no authentication" in err
    assert warned == (host == "0.0.0.0"), err


def test_an_ipv4_loopback_written_as_ipv6_is_not_warned_about(
    scenario: Scenario, capfd: pytest.CaptureFixture[str]
) -> None:
    """--control [::ffff:127.0.0.1]:0 was warned about as reachable from the network."""
    try:
        with socket.socket(socket.AF_INET6) as probe:
            probe.bind(("::ffff:127.0.0.1", 0))
    except OSError:
        pytest.skip("no IPv4-mapped IPv6 addresses on this machine")
    session = LiveSession.open(scenario, None, "[::ffff:127.0.0.1]:0", False)
    session.close()
    err = capfd.readouterr().err
    assert "control endpoint: [::ffff:127.0.0.1]:" in err and "WARNING" not in err, err


def test_an_adaptive_run_is_refused_before_the_endpoint_opens(
    scenario: Scenario, capfd: pytest.CaptureFixture[str]
) -> None:
    """--control with algorithm = "adaptive" announced its endpoint and loaded the FMUs
    before the master refused the run."""
    adaptive = scenario.with_overrides(algorithm="adaptive")
    with pytest.raises(CosimError, match=r"^--control: a paced or live run needs a fixed"):
        LiveSession.open(adaptive, None, "127.0.0.1:0", False)
    assert "control endpoint" not in capfd.readouterr().err


class Master:
    """The master's side of a run, by hand: communication points on the test's word."""

    def __init__(self, live: LiveControl) -> None:
        self.live, self.stop = live, StopRequest()
        self.z = np.zeros(1)
        live.bind({}, self.stop)
        self.applied: list[tuple[int, dict]] = []

    def point(self, n: int) -> None:
        for ticket in self.live.take(n, n * 0.01, self.z):
            self.applied.append((n, ticket.values))
            self.live.applied(ticket, f"live-{len(self.applied)}", n * 0.01)
        self.live.publish(n * 0.01, self.z)


def test_a_set_is_answered_ok_only_once_applied(scenario: Scenario) -> None:
    live = LiveControl(scenario)
    master = Master(live)
    ticket = live.request({"controller.yaw_setpoint": 0.2}, "test")
    assert not ticket.wait(0.05)  # not applied yet: no answer
    master.point(3)
    assert ticket.wait(0) and (ticket.name, ticket.time, ticket.refused) == ("live-1", 0.03, None)
    assert master.applied == [(3, {"controller.yaw_setpoint": 0.2})]


def _decimals(h: float) -> int:
    return -int(Decimal(repr(h)).as_tuple().exponent)


def test_the_times_in_replies_read_as_the_step_writes_them(scenario: Scenario) -> None:
    """At a point whose n h is no float of the step's decimals (163 x 0.04 s is
    6.5200000000000005 s), a set's and a get's replies said "t": 6.5200000000000005: the
    float's repr where a user reads a time. They say the point's time n h, written with
    the step's decimals."""
    h = scenario.coupling.step
    n = next(n for n in range(1, 10_000) if len(repr(n * h).partition(".")[2]) > _decimals(h))
    live = LiveControl(scenario)
    live.bind({"plant.yaw": 0}, StopRequest())
    with endpoint(live) as server:
        client = Client(server)
        try:
            client.send(b'{"set": {"controller.yaw_setpoint": 0.2}}\n')
            applied = threading.Event()
            while not applied.wait(0.01):  # point n, again until the set has arrived
                for ticket in live.take(n, n * h, np.zeros(1)):
                    live.applied(ticket, "live-1", n * h)
                    applied.set()
            live.publish(n * h, np.zeros(1))
            client.send(b'{"get": ["plant.yaw"]}\n')
            replies = [client.reply(), client.reply()]
        finally:
            client.close()
    assert [reply.get("t") for reply in replies] == [float(n * Decimal(repr(h)))] * 2, replies


def test_a_set_of_degrees_to_an_angle_in_rad_is_applied_with_a_warning(scenario: Scenario) -> None:
    """A yaw set-point of 30 (degrees typed by habit: 4.8 turns in rad) was applied with a
    plain "ok", as a scenario file's warns; it is still applied, and the reply says what
    it is in degrees and what 30 deg would be. A set-point within a turn has no warning."""
    live = LiveControl(scenario)
    master = Master(live)

    def reply_to(value: float) -> dict:
        line = json.dumps({"set": {"controller.yaw_setpoint": value}}).encode()
        replies: list[dict] = []
        waiting = threading.Thread(target=lambda: replies.append(submit(live, line, "test")()))
        waiting.start()
        for n in range(1, 1000):  # communication points until it is applied
            master.point(n)
            waiting.join(0.01)
            if not waiting.is_alive():
                break
        return replies[0]

    degrees, radians = reply_to(30), reply_to(0.5)
    assert degrees["ok"] and radians["ok"] and "warnings" not in radians
    (warning,) = degrees["warnings"]
    assert "controller.yaw_setpoint = 30 rad is more than a full turn (1719 deg)" in warning
    assert "give 0.523599" in warning
    assert [values for _, values in master.applied] == [
        {"controller.yaw_setpoint": 30},
        {"controller.yaw_setpoint": 0.5},
    ]


def test_a_set_the_run_ends_before_applying_is_answered_not_applied(scenario: Scenario) -> None:
    live = LiveControl(scenario)
    with endpoint(live) as server:
        master = Master(live)
        master.point(0)
        client = Client(server)
        client.send(b'{"set": {"controller.yaw_setpoint": 0.1}}\n')
        replied: list[dict] = []
        waiting = threading.Thread(target=lambda: replied.append(client.reply()))
        waiting.start()
        waiting.join(0.2)
        assert replied == []  # queued: no "ok" before it is applied
        live.close()  # the run ends at its stop time before the next point
        waiting.join(TIMEOUT_S)
        assert "not applied: the run ended at t = 0 s" in replied[0]["error"]
        client.send(b'{"set": {"controller.yaw_setpoint": 0.2}}\n{"stop": true}\n')
        assert "set not applied: the run ended" in client.reply()["error"]
        assert "stop: the run ended" in client.reply()["error"]
        client.close()
    assert master.applied == []


def test_a_stop_before_t_0_ends_the_run_after_its_first_step(scenario: Scenario) -> None:
    """So a stopped live run always has a step to replay."""
    live = LiveControl(scenario)
    live.stop("a test")  # while the FMUs are set up
    master = Master(live)
    assert live.stopping  # a wait for a deadline ends at once
    master.point(0)
    assert not master.stop.requested
    master.point(1)
    assert master.stop.requested


def test_requests_while_paused_are_applied_at_the_paused_point_in_order(
    scenario: Scenario,
) -> None:
    live = LiveControl(scenario)
    master = Master(live)
    live.pause("test")
    holding = threading.Thread(target=master.point, args=(5,))
    holding.start()
    first = live.request({"controller.yaw_setpoint": 0.1}, "test")
    assert first.wait(TIMEOUT_S) and first.time == 0.05  # applied while the run waits
    second = live.request({"controller.yaw_setpoint": 0.2}, "test")
    assert second.wait(TIMEOUT_S) and second.time == 0.05
    assert holding.is_alive()  # still paused
    live.resume()
    holding.join(TIMEOUT_S)
    assert [values for _, values in master.applied] == [
        {"controller.yaw_setpoint": 0.1}, {"controller.yaw_setpoint": 0.2}]  # fmt: skip


def test_a_set_refused_by_the_run_ending_raises_for_keys(scenario: Scenario) -> None:
    live = LiveControl(scenario)
    live.close("the run ended at t = 2 s")
    with pytest.raises(OverrideError, match="set not applied: the run ended at t = 2 s"):
        live.request({"controller.yaw_setpoint": 0.1}, "keys")


NOBODY = 65534  # the uid of another user: nobody


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() != 0 or not Path("/proc/net/tcp").exists(),
    reason="needs root (to be another user) and Linux's /proc/net/tcp",
)
def test_a_connection_from_another_users_process_is_refused(scenario: Scenario) -> None:
    """On a shared machine every user's programs reach 127.0.0.1: another student's
    process could pause, steer or stop the run ({"ok": true} to its requests). A
    connection from a process of another user is now refused with one line and closed."""
    live = LiveControl(scenario)
    with endpoint(live) as server:
        host, _, port = server.address.rpartition(":")
        client = (f"exec 3<>/dev/tcp/{host}/{port}; printf '%s\\n' '{GOOD.decode().strip()}' >&3;"
                  " head -n 1 <&3")  # fmt: skip
        command = ["setpriv", f"--reuid={NOBODY}", f"--regid={NOBODY}", "--clear-groups",
                   "bash", "-c", client]  # fmt: skip
        done = run_in_group(command, timeout=TIMEOUT_S)
        assert done.returncode == 0, done.stderr
        reply = json.loads(done.stdout)
        assert str(reply.get("error")).startswith(f"connection from a process of uid {NOBODY}"), (
            reply
        )
        mine = Client(server)  # this user's own client is served
        mine.send(GOOD)
        assert mine.reply() == {"ok": True, "paused": False}
        mine.close()
