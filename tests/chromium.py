"""Debian's Chromium, headless, for the tests that look at pages as a user's browser does.

Chromium is started in its own process group with a DevTools port that Playwright's Python
package connects to (no browser download), and the group is ended as the ``with`` block
ends, even on failure (:func:`end_group`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from process_group import close_pipes

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
START_TIMEOUT_S = 180.0  # the machine may be busy: generous, never a measurement


def end_group(proc: subprocess.Popen, sig: int = signal.SIGTERM) -> None:
    """End the process group the test started (its leader is ``proc``), reap it and close
    the pipes to and from it."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, sig)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    finally:
        close_pipes(proc)


@contextlib.contextmanager
def headless_chromium(profile: Path) -> Iterator[Any]:
    """Chromium with its profile in ``profile`` (an empty folder), as Playwright's Browser
    connected over the DevTools protocol. WebGL runs on SwiftShader (no GPU)."""
    from playwright.sync_api import sync_playwright

    assert CHROMIUM is not None, "needs Debian's chromium (apt, .ci/run)"
    command = [CHROMIUM, "--headless", "--no-sandbox", "--remote-debugging-port=0"]
    command += [f"--user-data-dir={profile}", "--no-first-run", "--disable-gpu-sandbox"]
    command += ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]
    command += ["about:blank"]
    proc = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    try:  # chromium writes its DevTools port (0: it chose one) into the profile
        active = profile / "DevToolsActivePort"
        deadline = time.monotonic() + START_TIMEOUT_S
        while not (active.is_file() and active.read_text().count("\n") >= 1):
            assert proc.poll() is None, f"chromium exited {proc.returncode}"
            assert time.monotonic() < deadline, "chromium wrote no DevToolsActivePort"
            time.sleep(0.2)
        endpoint = f"http://127.0.0.1:{active.read_text().split()[0]}"
        with sync_playwright() as driver:
            connected = driver.chromium.connect_over_cdp(endpoint)
            yield connected
            connected.close()
    finally:
        end_group(proc)


def overflow(page_file: Path, profile: Path, width: int = 375) -> list[str]:
    """What of the page ``page_file`` sticks out past a window ``width`` CSS pixels wide
    (a phone's, by default), outside a box that scrolls on its own: "TAG: right edge"
    each, none when nothing makes the window scroll sideways."""
    script = """() => {
        const edge = document.documentElement.clientWidth;
        const boxed = (e) => { for (let p = e.parentElement; p; p = p.parentElement) {
            if (['auto', 'scroll'].includes(getComputedStyle(p).overflowX)) return true; }
            return false; };
        const wide = (e) => Math.max(e.getBoundingClientRect().right,
            e.getBoundingClientRect().left + e.scrollWidth);  // text past its own box too
        return [...document.body.querySelectorAll('*')]
            .filter((e) => wide(e) > edge + 1 && !boxed(e))
            .map((e) => `${e.tagName}: ${Math.round(wide(e))}`);
    }"""
    with headless_chromium(profile) as browser:
        page = browser.new_page(viewport={"width": width, "height": 800})
        page.goto(page_file.as_uri(), wait_until="load")
        found = page.evaluate(script)
        page.close()
    return found
