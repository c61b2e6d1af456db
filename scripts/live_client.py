"""Steer a live run over its control endpoint: a zigzag on the yaw set-point.

    auv-cosim run bs-3 --real-time --control 127.0.0.1:5555 --stop-time 120 &
    python scripts/live_client.py 5555

JSON lines over TCP (docs/live-runs.md): one request line, one reply line.
"""

import json
import socket
import sys
import time

port = int(sys.argv[1]) if len(sys.argv) > 1 else 5555
with socket.create_connection(("127.0.0.1", port)) as sock:
    channel = sock.makefile("rw", encoding="utf-8")

    def ask(request: dict) -> dict:
        channel.write(json.dumps(request) + "\n")
        channel.flush()
        return json.loads(channel.readline())

    def yaw() -> tuple[float, float]:  # (t, yaw) once the run has started
        while "values" not in (reply := ask({"get": ["plant.yaw"]})):
            time.sleep(0.1)  # {"error": ...}: the FMUs are still being set up
        return reply["t"], reply["values"]["plant.yaw"]

    heading = 0.35  # rad, about 20 degrees
    for _ in range(6):  # three zigzags: turn, wait until the yaw is 90 % there, turn back
        print(ask({"set": {"controller.yaw_setpoint": heading}}))
        while (now := yaw())[1] * heading < 0.9 * heading**2:
            time.sleep(0.1)
        print(f"t = {now[0]:.2f} s, yaw = {now[1]:+.3f} rad")
        heading = -heading
