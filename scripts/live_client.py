"""Steer a live run over its control endpoint: a zigzag on the yaw set-point.

    auv-cosim run bs-3 --real-time --control 127.0.0.1:5555 --stop-time 120 &
    python scripts/live_client.py 5555

JSON lines over TCP (docs/live-runs.md): one request line, one reply line. The run opens its
endpoint after it has loaded the scenario (a few seconds the first time, while it builds the
FMUs): the client tries to connect until then, for at most ``WAIT_S`` seconds.
"""

import argparse
import json
import socket
import sys
import time

WAIT_S = 120.0  # s to wait for the run's endpoint to open


def tcp_port(text: str) -> int:
    """``text`` as a TCP port, 1 to 65535."""
    if not (text.isdigit() and 0 < int(text) < 65536):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a TCP port, 1 to 65535")
    return int(text)


parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("port", nargs="?", type=tcp_port, default=5555,
                    help="the run's --control port on 127.0.0.1, 1 to 65535 [5555]")  # fmt: skip
port = parser.parse_args().port
deadline = time.monotonic() + WAIT_S
while True:
    try:
        sock = socket.create_connection(("127.0.0.1", port))
        break
    except ConnectionRefusedError:
        if time.monotonic() > deadline:
            sys.exit(f"live_client: nothing listens on 127.0.0.1:{port} after {WAIT_S:g} s")
        time.sleep(0.2)  # the run is still starting

with sock:
    channel = sock.makefile("rw", encoding="utf-8")

    def ask(request: dict) -> dict:
        channel.write(json.dumps(request) + "\n")
        channel.flush()
        reply = channel.readline()
        if not reply:
            sys.exit("live_client: the run has ended")
        return json.loads(reply)

    def yaw() -> tuple[float, float]:  # (t, yaw) once the run has started
        while "values" not in (reply := ask({"get": ["plant.yaw"]})):
            time.sleep(0.1)  # {"error": ...}: the FMUs are still being set up
        return reply["t"], reply["values"]["plant.yaw"]

    heading = 0.35  # rad, about 20 degrees
    for _ in range(6):  # three zigzags: turn, wait until the yaw is 90 % there, turn back
        print(ask({"set": {"controller.yaw_setpoint": heading}}))  # once applied
        while (now := yaw())[1] * heading < 0.9 * heading**2:
            time.sleep(0.1)
        print(f"t = {now[0]:.2f} s, yaw = {now[1]:+.3f} rad")
        heading = -heading
