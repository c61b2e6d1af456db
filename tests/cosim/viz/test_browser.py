"""The pages and recordings as a user sees them: in a real, headless Chromium.

``auv-cosim view --web`` serves a run's recording and a study's overlay.rrd to Rerun's
web viewer; the browser opens the one URL it prints, waits until the viewer holds the
recording (its page's ``_handle.save_recording()``, which fails while the welcome
screen shows), and the screenshot it takes is not blank. The same browser opens
``auv-cosim report``'s and a study's index.html: every image loads, no console error.
``view --web`` listens on 127.0.0.1 only, and Ctrl-C ends it with its server. The
notebook's inline viewer (docs/notebooks/quickstart.ipynb's last cell) loads with every
request off the machine refused, and opens the run's recording.

Chromium is Debian's (``apt-get install chromium``, done by .ci/run), started by the test
in its own process group with a DevTools port that Playwright's Python package connects
to (no browser download). Every process is ended as a process group, even on failure.
WebGL runs on SwiftShader (no GPU).
"""

from __future__ import annotations

import base64
import contextlib
import http.server
import json
import os
import re
import select
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import psutil
import pytest
from chromium import CHROMIUM, START_TIMEOUT_S, end_group, headless_chromium
from PIL import Image
from repo_paths import ROOT
from rerun.chunk import RrdReader

import cosim
from cosim.viz.recording import recording_in
from cosim.viz.report import write_report

playwright = pytest.importorskip("playwright.sync_api", reason="needs playwright (test extra)")
pytestmark = [
    pytest.mark.slow,
    pytest.mark.viewer,  # starts a browser
    pytest.mark.cluster,  # the study its pages show is swept on Dask
    pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt, .ci/run)"),
]
LOAD_TIMEOUT_S = 240.0
URL_LINE = re.compile(r"^\s+(http://127\.0\.0\.1:\d+/\?url=\S+)$", re.MULTILINE)
VIEWER_STATE = """() => {
    if (!window._handle) return -1;
    try { return window._handle.save_recording().length; } catch (e) { return 0; }
}"""
SAVED_RECORDING = """() => {
    const data = window._handle.save_recording();
    let text = "";
    for (let i = 0; i < data.length; i += 32768) {
        text += String.fromCharCode.apply(null, data.subarray(i, i + 32768));
    }
    return btoa(text);
}"""
IMAGES = "() => Array.from(document.images).map(i => [i.src, i.complete, i.naturalWidth])"


@pytest.fixture(scope="module")
def folders(fmu_paths: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """A run folder with its report, and a study folder with its overlay.rrd."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    base = tmp_path_factory.mktemp("browser")
    run = cosim.run("bs-3", stop_time=3.0, out=base / "run", fmu_dir=fmu_dir)
    report = write_report(run.out_dir)
    study = {"scenario": "bs-3", "stop_time": 1.0, "grid": {"plant.v_0": [-0.1, 0.05]}}
    done = cosim.sweep(study, workers=1, out=base / "study", overlay=2, fmu_dir=fmu_dir)
    assert (done.out_dir / "overlay.rrd").is_file()
    pages = {"run": report, "study": done.out_dir / "index.html"}
    return {"run": run.out_dir, "study": done.out_dir, "pages": pages}


def _read_until(proc: subprocess.Popen, pattern: re.Pattern[str], timeout: float) -> str:
    """What the process wrote to its standard output (a binary pipe) up to the first
    match of ``pattern``, read from the file descriptor (a buffered reader would hide
    lines from ``select``)."""
    stream = proc.stdout
    data, deadline = b"", time.monotonic() + timeout
    while pattern.search(data.decode("utf-8", "replace")) is None:
        assert proc.poll() is None, f"exited {proc.returncode}: {data.decode()}"
        assert time.monotonic() < deadline, f"no match for {pattern.pattern} in {data!r}"
        if select.select([stream], [], [], 0.5)[0]:
            data += os.read(stream.fileno(), 65536)
    return data.decode("utf-8", "replace")


@contextlib.contextmanager
def _served(path: Path) -> Iterator[tuple[subprocess.Popen, str]]:
    """``auv-cosim view PATH --web`` on free ports: (its process, the URL it printed)."""
    command = [sys.executable, "-m", "cosim.cli", "view", str(path), "--web"]
    command += ["--web-port", "0", "--file-port", "0"]
    proc = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        start_new_session=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),  # as in a terminal
    )
    try:
        printed = _read_until(proc, URL_LINE, START_TIMEOUT_S)
        urls = URL_LINE.findall(printed)
        assert len(urls) == 1, printed
        yield proc, urls[0]
    finally:
        end_group(proc)


@pytest.fixture(scope="module")
def browser(tmp_path_factory: pytest.TempPathFactory) -> Iterator:
    """Chromium, headless, in its own process group, driven through its DevTools port."""
    with headless_chromium(tmp_path_factory.mktemp("chromium-profile")) as connected:
        yield connected


def _group(proc: subprocess.Popen) -> list[psutil.Process]:
    """The processes of ``proc``'s process group (it leads it)."""
    members = []
    for process in psutil.process_iter():
        with contextlib.suppress(psutil.Error, ProcessLookupError):
            if os.getpgid(process.pid) == proc.pid:
                members.append(process)
    return members


def _listening(proc: subprocess.Popen) -> list[tuple[str, int]]:
    """(address, port) of every socket listening in ``proc``'s process group."""
    return [
        (c.laddr.ip, c.laddr.port)
        for process in _group(proc)
        for c in process.net_connections(kind="inet")
        if c.status == psutil.CONN_LISTEN
    ]


def _wait_for_recording(page, rrd: Path, saved: Path) -> None:
    """Until the viewer holds the recording of ``rrd`` (the welcome screen has none) and
    has stopped receiving it; what it holds is saved to ``saved``."""
    deadline, sizes = time.monotonic() + LOAD_TIMEOUT_S, [0]
    while not (sizes[-1] > 0 and sizes[-1] == sizes[-2]):
        assert time.monotonic() < deadline, f"the viewer never showed the recording: {sizes}"
        time.sleep(2.0)
        sizes.append(page.evaluate(VIEWER_STATE))
    saved.write_bytes(base64.b64decode(page.evaluate(SAVED_RECORDING)))
    held = {(r.application_id, r.recording_id) for r in RrdReader(saved).recordings()}
    served = {(r.application_id, r.recording_id) for r in RrdReader(rrd).recordings()}
    assert held == served, f"the viewer holds {held}, not the served {served}"


def _not_blank(png: Path) -> None:
    pixels = np.asarray(Image.open(png).convert("RGB")).reshape(-1, 3)
    colours = len(np.unique(pixels, axis=0))
    background = np.mean(np.all(pixels == np.median(pixels, axis=0), axis=1))
    assert colours > 500 and background < 0.9, f"{png}: {colours} colours, {background:.0%} bg"


@pytest.mark.parametrize("kind", ["run", "study"])
def test_view_web_opens_the_recording_in_the_browser(
    folders: dict, browser, kind: str, tmp_path: Path
) -> None:
    with _served(folders[kind]) as (proc, url):
        listening = _listening(proc)
        assert len(listening) >= 2 and {ip for ip, _ in listening} == {"127.0.0.1"}, listening
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        try:
            page.goto(url)
            _wait_for_recording(page, recording_in(folders[kind]), tmp_path / "held.rrd")
            time.sleep(3.0)  # let the last frame be drawn
            page.screenshot(path=tmp_path / f"{kind}.png")
        finally:
            page.close()
    _not_blank(tmp_path / f"{kind}.png")


def test_view_web_listens_on_localhost_only_and_ctrl_c_ends_it(folders: dict) -> None:
    with _served(folders["run"]) as (proc, url):
        listening = _listening(proc)
        ports = {port for _, port in listening}
        assert {ip for ip, _ in listening} == {"127.0.0.1"}, listening
        assert {int(p) for p in re.findall(r"(?:%3A|:)(\d+)", url)} == ports
        members = _group(proc)
        assert len(members) >= 2  # the command and the rerun server
        os.killpg(proc.pid, signal.SIGINT)
        assert proc.wait(timeout=60) == 130
        _, alive = psutil.wait_procs(members, timeout=30)
        assert alive == [], alive


@pytest.mark.parametrize("kind", ["run", "study"])
def test_report_pages_load_every_image_without_console_errors(
    folders: dict, browser, kind: str
) -> None:
    page = browser.new_page()
    errors: list[str] = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("requestfailed", lambda r: errors.append(f"{r.url}: {r.failure}"))
    try:
        page.goto(folders["pages"][kind].as_uri(), wait_until="load")
        images = page.evaluate(IMAGES)
    finally:
        page.close()
    assert images, f"{kind} index.html shows no image"
    broken = [src for src, complete, width in images if not complete or width == 0]
    assert broken == [] and errors == [], (broken, errors)


NOTEBOOK = ROOT / "docs" / "notebooks" / "quickstart.ipynb"
# The Python side of the notebook's viewer cell, in a fresh interpreter (rerun-notebook reads
# its asset source once, at import): the widget's state, the recording's bytes queued for
# it and the address of its viewer code, as one JSON line; then it serves the viewer's
# assets until its standard input closes.
KERNEL_SIDE = """
import base64, json, sys, types
from pathlib import Path
import nbformat
cells = nbformat.read(sys.argv[1], as_version=4).cells
cell = [c for c in cells if c.cell_type == "code" and "viewer" in c.source][-1]
names = {"base": types.SimpleNamespace(out_dir=Path(sys.argv[2]))}
exec(cell.source, names)
import rerun_notebook
widget = names["viewer"]._viewer
state = {k: getattr(widget, k) for k in
         ("_width", "_height", "_panel_states", "_url", "_theme", "_fallback_token")}
events = [[e, [base64.b64encode(bytes(b)).decode() for b in bufs or []]]
          for e, bufs in widget._event_queue]
print(json.dumps({"esm": str(rerun_notebook.ESM_MOD), "state": state, "events": events}))
sys.stdout.flush()
sys.stdin.read()
"""
# A page holding the widget as JupyterLab does (anywidget's render({model, el})), with a
# model that hands it the kernel side's state and messages.
NOTEBOOK_PAGE = """<!doctype html><html><body style="margin:0"><div id="cell" style="width:%dpx">
</div><script type="module">
const state = %s, handlers = {};
window.sent = [];
const model = {get: (k) => state[k], on: (e, f) => (handlers[e] ??= []).push(f),
               send: (m) => window.sent.push(m)};
window.deliver = (messages) => {
  for (const [msg, encoded] of messages) {
    const buffers = encoded.map((b) => new DataView(Uint8Array.from(atob(b), (c) =>
      c.charCodeAt(0)).buffer));
    for (const f of handlers["msg:custom"] ?? []) f(msg, buffers);
  }
};
(await import(%s)).default.render({model, el: document.getElementById("cell")});
</script></body></html>"""
CELL_WIDTH = 900  # px: a notebook cell in JupyterLab on a laptop
VERSION_CHECK = "https://api.github.com/repos/rerun-io/rerun/releases/latest"


@contextlib.contextmanager
def _page_server(html: str) -> Iterator[str]:
    """``html`` served on 127.0.0.1 (a secure context, as JupyterLab's localhost is)."""

    class Page(http.server.BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body = html.encode()
            self.send_response(200)
            self.send_header("Content-Type", "text/html")
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, *args: object) -> None:
            """Quiet."""

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Page)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


@contextlib.contextmanager
def _kernel_side(run_dir: Path) -> Iterator[dict]:
    proc = subprocess.Popen(
        [sys.executable, "-c", KERNEL_SIDE, str(NOTEBOOK), str(run_dir)],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    try:
        line = " "
        while line and not line.startswith("{"):  # rerun-notebook says what it serves first
            line = proc.stdout.readline()  # type: ignore[union-attr]
        assert line, f"the notebook's viewer cell failed (exit {proc.poll()})"
        yield json.loads(line)
    finally:
        end_group(proc)


def test_the_notebooks_inline_viewer_shows_the_run_offline(
    folders: dict, browser, tmp_path: Path
) -> None:
    """The viewer's code and WebAssembly come from this machine; every request that would
    leave it is refused, and the viewer still opens the run's recording, in a widget of the
    cell's width and its set height."""
    with _kernel_side(folders["run"]) as kernel:
        assert re.match(r"http://(localhost|127\.0\.0\.1):\d+/widget\.js$", kernel["esm"])
        html = NOTEBOOK_PAGE % (CELL_WIDTH, json.dumps(kernel["state"]), json.dumps(kernel["esm"]))
        with _page_server(html) as url:
            page = browser.new_page(viewport={"width": 1000, "height": 900})
            left: list[str] = []
            local = re.compile(r"^(?!http://(127\.0\.0\.1|localhost)[:/]|data:|blob:)")
            page.route(local, lambda route: (left.append(route.request.url), route.abort()))
            try:
                page.goto(url)
                page.wait_for_function(
                    "window.sent.includes('ready')", timeout=LOAD_TIMEOUT_S * 1e3
                )
                page.evaluate("(m) => window.deliver(m)", kernel["events"])
                page.wait_for_function(  # the run's own timeline shown: its data is in
                    'window.sent.some((e) => e.includes(\'"timeline":"sim_time"\'))',
                    timeout=LOAD_TIMEOUT_S * 1e3,
                )
                opened = [json.loads(e) for e in page.evaluate("window.sent") if "{" in e]
                box = page.evaluate(
                    "(() => { const r = document.querySelector('.rerun_notebook')"
                    ".getBoundingClientRect(); return [r.width, r.height]; })()"
                )
                time.sleep(5.0)  # let the frames be drawn
                page.locator(".rerun_notebook").screenshot(path=tmp_path / "notebook.png")
            finally:
                page.close()
    stored = RrdReader(recording_in(folders["run"])).recordings()[0]
    assert {e["recording_id"] for e in opened if e["type"] == "recording_open"} == {
        stored.recording_id
    }
    assert set(left) <= {VERSION_CHECK}, left  # only rerun's check for a newer version
    assert box == [CELL_WIDTH, kernel["state"]["_height"]]
    assert kernel["state"]["_panel_states"] == {
        "blueprint": "collapsed", "selection": "collapsed", "time": "collapsed"}  # fmt: skip
    _not_blank(tmp_path / "notebook.png")
