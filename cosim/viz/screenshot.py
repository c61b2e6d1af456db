"""Render a recording to a PNG with the native Rerun viewer, without a display.

Starts ``rerun --headless`` bound to 127.0.0.1 on a free port (the viewer draws off-screen
through Vulkan; without a GPU, Mesa's lavapipe from Debian's ``mesa-vulkan-drivers`` does
it), drives it with ``rerun.experimental.ViewerClient`` (open, move the time cursor,
``save_screenshot``) and stops it. The viewer writes its settings under HOME and the XDG
folders of the environment given. Used by tests/cosim/viz/test_screenshot.py and
scripts/render_recording.py; browsers' own ``--screenshot`` shoots before the web viewer
has loaded, hence the native viewer.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

from rerun.experimental import ViewerClient

from cosim.viz.recording import rerun_executable

START_TIMEOUT = 60.0  # s for the viewer to answer (software rendering starts slowly)
LOAD_TIMEOUT = 60.0  # s for a recording to load
SETTLE_TIMEOUT = 60.0  # s for the picture to stop changing
SETTLE_INTERVAL = 0.5  # s between two frames compared
# s a frame must stay unchanged to count as settled: longer than the viewer's start-up
# notice ("Headless viewer running at 1920x1080.") stands unchanged in its corner (gone
# 4.6 s after the start here), so that no shot catches it
STILL_S = 6.0


class ScreenshotError(RuntimeError):
    """The headless viewer could not start, load the recording or take the screenshot."""


@dataclass(frozen=True)
class ViewReport:
    """A view of the rendered layout, and what the viewer said failed in it (if anything)."""

    name: str
    problems: tuple[str, ...]


def free_port() -> int:
    """A TCP port on 127.0.0.1 nobody listens on right now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def render_screenshots(
    rrd: Path,
    shots: Sequence[tuple[float, Path]],
    env: Mapping[str, str] | None = None,
    log: Path | None = None,
) -> list[ViewReport]:
    """Screenshot the whole viewer on ``rrd`` at each (sim_time in s, png path) of ``shots``.

    Returns the views the viewer shows with the problems it reports for each. ``env`` is
    the viewer's environment (point HOME/XDG_* at a scratch folder in tests); ``log``
    receives its output. Each shot is taken once the picture has settled (the data
    loaded and the start-up notices gone: unchanged for ``STILL_S``).

    Raises:
        ScreenshotError: no file ``rrd``, no ``rerun`` binary, the viewer exited or did
            not answer in time (e.g. "No graphics adapter was found" without Vulkan), or
            its picture kept changing.
    """
    if not Path(rrd).is_file():  # the viewer would open nothing, then fail obscurely
        raise ScreenshotError(f"{rrd}: no recording: no such file")
    executable = rerun_executable()
    if executable is None:
        raise ScreenshotError("the `rerun` viewer binary was not found (pip install rerun-sdk)")
    port = free_port()
    command = [executable, "--headless", "--bind", "127.0.0.1", "--port", str(port)]
    command += ["--hide-welcome-screen", "--threads", "1"]
    out = open(log, "wb") if log is not None else subprocess.DEVNULL  # noqa: SIM115
    # Its own process group: the `rerun` launcher starts the viewer binary as a child, and
    # ending only the launcher would leave the viewer running (see _stop).
    viewer = subprocess.Popen(
        command,
        stdout=out,
        stderr=subprocess.STDOUT,
        env=None if env is None else dict(env),
        start_new_session=True,
    )
    try:
        client = _connect(viewer, f"rerun+http://127.0.0.1:{port}/proxy")
        client.open(str(Path(rrd).resolve()))
        deadline = time.monotonic() + LOAD_TIMEOUT
        while client.get_state().loading:
            if time.monotonic() > deadline:
                raise ScreenshotError(f"the viewer did not finish loading {rrd} in time")
            time.sleep(0.2)
        for sim_time, png in shots:
            client.set_time("sim_time", duration=sim_time, play_state="paused")
            Path(png).write_bytes(_settled_frame(client))
        return [
            ViewReport(view.name, tuple(str(r) for r in view.reports))
            for view in client.get_state().views
        ]
    finally:
        _stop(viewer)
        if log is not None:
            out.close()  # type: ignore[union-attr]


def _stop(viewer: subprocess.Popen[bytes]) -> None:
    """End the viewer's whole process group (the launcher and the binary it started)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(viewer.pid, signal.SIGTERM)
    try:
        viewer.wait(timeout=10)
    except subprocess.TimeoutExpired:
        viewer.kill()
        viewer.wait()
    with contextlib.suppress(ProcessLookupError):
        os.killpg(viewer.pid, signal.SIGKILL)  # a binary that outlived its launcher


def _settled_frame(client: ViewerClient) -> bytes:
    """The viewer's frame once it has stayed the same for ``STILL_S``.

    The viewer fetches chunks on demand after ``open`` and shows its start-up notices in
    the first seconds, each unchanged until it goes: a single early frame can show empty
    plots, and two equal frames half a second apart the notice over the panels.
    """
    deadline = time.monotonic() + SETTLE_TIMEOUT
    frame = client.take_screenshot()
    since = time.monotonic()
    while True:
        time.sleep(SETTLE_INTERVAL)
        latest = client.take_screenshot()
        now = time.monotonic()
        if latest != frame:
            frame, since = latest, now
        elif now - since >= STILL_S:
            return frame
        if now > deadline:
            raise ScreenshotError(f"the viewer's picture did not settle in {SETTLE_TIMEOUT} s")


def _connect(viewer: subprocess.Popen[bytes], url: str) -> ViewerClient:
    deadline = time.monotonic() + START_TIMEOUT
    while True:
        if viewer.poll() is not None:
            raise ScreenshotError(f"the headless viewer exited with code {viewer.returncode}")
        try:
            client = ViewerClient.connect(url)
            client.get_state()
            return client
        except Exception as exc:  # the bindings raise plain Exception subclasses
            if time.monotonic() > deadline:
                raise ScreenshotError(f"the headless viewer did not answer at {url}") from exc
            time.sleep(0.3)
