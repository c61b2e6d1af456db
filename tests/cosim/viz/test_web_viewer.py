"""``auv-cosim view --web`` without a browser: the URL it prints, the recording a folder
names, the refusals, a recording cut short (served completed, or refused when it holds no
data), and the server's lifetime: it dies with the command, SIGKILL included
(tests/cosim/viz/test_browser.py opens the served page)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import psutil
import pytest
from deadline import deadline
from process_group import close_pipes, run_in_group
from rerun.chunk import RrdReader

from cosim.cli import main
from cosim.errors import CosimError
from cosim.viz.recording import recording_in, rerun_executable
from cosim.viz.web_viewer import (
    HOST,
    SCRATCH_PREFIX,
    serve_command,
    viewer_url,
    whole_recording,
)

# starts like a recording: enough for the checks before serving (the magic, version 0.0:
# none to compare, rerun's encoding options: LZ4, Protobuf)
FAKE_RRD = b"RRF2" + bytes(4) + b"\x01\x02\x00\x00" + bytes(52)


def test_the_url_names_the_recordings_file_url_encoded() -> None:
    """The bare page shows Rerun's welcome screen: the URL must say where the recording is."""
    assert viewer_url(Path("runs/bs-3/recording.rrd"), 9090, 9876) == (
        "http://127.0.0.1:9090/?url=http%3A%2F%2F127.0.0.1%3A9876%2Frecording.rrd"
    )


def test_the_recording_is_served_as_a_file_not_a_stream() -> None:
    """rerun gets the file's HTTP URL, so it starts no gRPC proxy and the viewer loads a
    file (through the proxy it was a live stream, with a "latency" counter that means
    nothing for a file); the page is served on 127.0.0.1 only."""
    command = serve_command("rerun", Path("r.rrd"), 9090, 9876)
    assert command[command.index("--bind") + 1] == HOST == "127.0.0.1"
    assert command[command.index("--web-viewer-port") + 1] == "9090"
    assert command[-1] == "http://127.0.0.1:9876/r.rrd" and "--port" not in command
    assert not any(arg.startswith("rerun+") or arg.endswith("/proxy") for arg in command)


def test_a_study_folder_views_its_overlay(tmp_path: Path) -> None:
    (tmp_path / "overlay.rrd").write_bytes(FAKE_RRD)
    assert recording_in(tmp_path) == tmp_path / "overlay.rrd"
    (tmp_path / "recording.rrd").write_bytes(FAKE_RRD)  # a run folder's own comes first
    assert recording_in(tmp_path) == tmp_path / "recording.rrd"
    with pytest.raises(CosimError, match=r"overlay\.rrd"):
        recording_in(tmp_path / "empty")


def test_a_study_folder_without_its_overlay_says_how_to_draw_one(tmp_path: Path) -> None:
    """`view` of a study folder run without an overlay said "no recording at
    <study>/recording.rrd", a file no study writes."""
    (tmp_path / "study.json").write_text("{}\n")
    with pytest.raises(CosimError) as refused:
        recording_in(tmp_path)
    message = str(refused.value)
    assert message.startswith(f"{tmp_path} is a study folder without overlay.rrd")
    assert "--resume --overlay N" in message and "recording.rrd" not in message


def test_a_taken_port_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    (tmp_path / "recording.rrd").write_bytes(FAKE_RRD)
    with socket.socket() as taken:
        taken.bind((HOST, 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", str(tmp_path), "--web", "--web-port", str(port)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--web-port {port}: port {port} on 127.0.0.1 is taken" in err
    assert main(["view", str(tmp_path), "--web", "--web-port", "0", "--grpc-port", "70000"]) == 1
    # the flag that gave the port is named: "port 70000" did not say which of the two
    assert "--file-port 70000: expected a port from 0 (any free port) to 65535" in (
        capsys.readouterr().err
    )


@pytest.fixture(scope="module")
def recording(test_fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A whole recording of the test FMUs' loop (a few hundred kB)."""
    from scenario_factory import loop_toml

    folder = tmp_path_factory.mktemp("recording")
    scenario = folder / "loop.toml"
    scenario.write_text('id = "loop"\n' + loop_toml(fmu_dir=test_fmu_dir))
    assert main(["run", str(scenario), "--out", str(folder / "run")]) == 0
    return folder / "run" / "recording.rrd"


def _recordings(rrd: Path) -> set[tuple[str, str]]:
    return {(r.application_id, r.recording_id) for r in RrdReader(rrd).recordings()}


def test_a_recording_cut_before_any_data_is_refused_in_one_line(
    recording: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`view --web` of a recording cut short before its data served Rerun's welcome page
    forever: the viewer never showed anything, and the command never said why."""
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(recording.read_bytes()[:1000])
    with deadline(60, "still serving"):
        code = main(["view", str(cut), "--web", "--web-port", "0", "--file-port", "0"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, err
    assert f"{cut} holds no recording yet: it was cut short after 1000 bytes" in err


@pytest.mark.parametrize("kept", [0.5, 0.75, 0.95])
def test_a_recording_cut_short_is_served_as_a_completed_copy(
    recording: Path, tmp_path: Path, kept: float, capsys: pytest.CaptureFixture[str]
) -> None:
    """Rerun's importer waits forever for the rest of a file without its footer: what a
    cut recording holds is served from a copy `rerun rrd migrate` completed, said in a
    note on stderr (on stdout it came before the URL a script reads there)."""
    data = recording.read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: int(len(data) * kept)])
    executable = rerun_executable()
    assert executable is not None
    served = whole_recording(executable, cut, tmp_path)
    assert served != cut and served.read_bytes()[-12:-4] == data[:4] + b"FOOT"
    assert _recordings(served) == _recordings(recording)
    assert cut.read_bytes() == data[: int(len(data) * kept)]  # the user's file untouched
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"auv-cosim view: note: {cut} was cut short"), (out, err)
    assert whole_recording(executable, recording, tmp_path) == recording  # whole: as it is


@pytest.mark.slow
@pytest.mark.viewer
def test_the_rerun_server_dies_with_auv_cosim_when_it_is_killed(
    recording: Path, tmp_path: Path
) -> None:
    """SIGKILL of `auv-cosim view --web` left its rerun server running (and serving), and
    its temporary folder behind (made for every recording, needed only for one cut short)."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    with _web_view(recording, scratch, subprocess.STDOUT) as proc:
        servers = _children_once_one_listens(proc, time.monotonic() + 120)
        os.kill(proc.pid, signal.SIGKILL)  # auv-cosim alone, not its process group
        proc.wait(timeout=30)
        _, alive = psutil.wait_procs(servers, timeout=30)
        assert alive == [], f"the rerun server outlived auv-cosim: {alive}"
        assert list(scratch.glob(f"{SCRATCH_PREFIX}*")) == []


def _ctrl_c_as_in_a_shell() -> None:
    """In the child: SIGINT's default action, as a shell's foreground command has it; a
    pytest-xdist worker ignores SIGINT, and a child of it then ignored Ctrl-C too."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@contextlib.contextmanager
def _web_view(recording: Path, scratch: Path, stderr: int) -> Iterator[subprocess.Popen]:
    """`auv-cosim view RECORDING --web` on free ports, its temporary folder ``scratch``,
    in a process group of its own that is killed at the end, whatever happened."""
    command = [sys.executable, "-m", "cosim.cli", "view", str(recording), "--web"]
    proc = subprocess.Popen(
        [*command, "--web-port", "0", "--file-port", "0"], stdout=subprocess.PIPE,
        stderr=stderr, start_new_session=True, env={**os.environ, "TMPDIR": str(scratch)},
        preexec_fn=_ctrl_c_as_in_a_shell,
    )  # fmt: skip
    try:
        yield proc
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        close_pipes(proc)


@pytest.mark.parametrize(
    ("signum", "said"), [(signal.SIGINT, "Ctrl-C"), (signal.SIGTERM, "SIGTERM")]
)
def test_a_stopped_view_says_so_on_a_line_of_its_own(
    recording: Path, tmp_path: Path, signum: int, said: str
) -> None:
    """Ctrl-C ended `auv-cosim view --web` without a word, so the shell's prompt came
    right after the terminal's ^C; it ends as `run` does, on one line saying what stopped."""
    with _web_view(recording, tmp_path, subprocess.PIPE) as proc:
        _children_once_one_listens(proc, time.monotonic() + 120)
        os.kill(proc.pid, signum)
        _, err = proc.communicate(timeout=60)
        assert proc.returncode == 128 + signum, err
        assert err.decode().splitlines()[-1] == f"stopped serving {recording} ({said})", err


def _children_once_one_listens(proc: subprocess.Popen, deadline: float) -> list[psutil.Process]:
    """``proc``'s children once one of them listens on a port (serving the page); a child
    that ends before (a short-lived helper process) is passed over."""
    while True:
        assert proc.poll() is None and time.monotonic() < deadline, proc.returncode
        children = psutil.Process(proc.pid).children()
        for child in children:
            with contextlib.suppress(psutil.NoSuchProcess, psutil.AccessDenied):
                if any(c.status == psutil.CONN_LISTEN for c in child.net_connections()):
                    return children
        time.sleep(0.2)


@pytest.mark.parametrize("display", [{}, {"DISPLAY": ""}, {"WAYLAND_DISPLAY": ""}])
def test_view_without_a_display_fails_in_one_line_saying_to_use_web(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys, display: dict[str, str]
) -> None:
    (tmp_path / "recording.rrd").write_bytes(FAKE_RRD)
    for name in ("DISPLAY", "WAYLAND_DISPLAY"):
        monkeypatch.delenv(name, raising=False)
    for name, value in display.items():
        monkeypatch.setenv(name, value)
    assert main(["view", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1 and captured.out == "", captured
    assert "no display" in captured.err and f"auv-cosim view {tmp_path} --web" in captured.err


def test_the_file_server_answers_head_as_get_without_the_body(tmp_path: Path) -> None:
    """`curl -I` (a HEAD) of the served recording got "501 Unsupported method"."""
    import http.client

    from cosim.viz.web_viewer import _file_server

    rrd = tmp_path / "recording.rrd"
    rrd.write_bytes(FAKE_RRD)
    with socket.socket() as probe:
        probe.bind((HOST, 0))
        port = probe.getsockname()[1]
    with _file_server(rrd, port, 9090):
        connection = http.client.HTTPConnection(HOST, port, timeout=10)
        connection.request("HEAD", "/recording.rrd")
        head = connection.getresponse()
        assert head.status == 200 and head.read() == b""
        assert head.getheader("Content-Length") == str(len(FAKE_RRD))
        connection.request("GET", "/recording.rrd")
        assert connection.getresponse().read() == FAKE_RRD
        connection.request("HEAD", "/other")
        assert connection.getresponse().status == 404
        connection.close()


@pytest.mark.slow
@pytest.mark.viewer
def test_the_next_run_removes_the_copy_a_killed_view_served(recording: Path, tmp_path: Path):
    """SIGKILL of `auv-cosim view --web` of a recording cut short (a killed run's) left the
    completed copy it served, as large as the recording, in TMPDIR forever; the next run
    removes it."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    env = {**os.environ, "TMPDIR": str(scratch)}
    data = recording.read_bytes()
    cut = tmp_path / "cut.rrd"
    cut.write_bytes(data[: len(data) * 3 // 4])
    command = [sys.executable, "-m", "cosim.cli", "view", str(cut), "--web"]
    proc = subprocess.Popen(
        [*command, "--web-port", "0", "--file-port", "0"], stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT, start_new_session=True, env=env,
    )  # fmt: skip
    try:
        _children_once_one_listens(proc, time.monotonic() + 120)
        assert list(scratch.rglob(f"{SCRATCH_PREFIX}*")), "no copy served: no test"
        os.kill(proc.pid, signal.SIGKILL)  # auv-cosim alone, not its process group
        proc.wait(timeout=30)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
        close_pipes(proc)
    scenario = recording.parent.parent / "loop.toml"
    command = [sys.executable, "-m", "cosim.cli", "run", str(scenario), "--quiet", "--no-rrd",
               "--out", str(tmp_path / "next")]  # fmt: skip
    done = run_in_group(command, timeout=120, env=env)
    assert done.returncode == 0, done.stderr
    assert list(scratch.rglob(f"{SCRATCH_PREFIX}*")) == []


@pytest.mark.skipif(
    not hasattr(os, "geteuid") or os.geteuid() != 0 or not Path("/proc/net/tcp").exists(),
    reason="needs root (to be another user) and Linux's /proc/net/tcp",
)
def test_the_file_server_refuses_another_users_process(tmp_path: Path) -> None:
    """On a shared machine every user's programs reach 127.0.0.1: while a recording was
    served, another user's process could fetch it (200 and the file). It gets 403; the
    user's own requests (the browser's) are served."""
    import http.client

    from process_group import run_in_group

    from cosim.viz.web_viewer import _file_server

    rrd = tmp_path / "recording.rrd"
    rrd.write_bytes(FAKE_RRD)
    with socket.socket() as probe:
        probe.bind((HOST, 0))
        port = probe.getsockname()[1]
    request = "GET /recording.rrd HTTP/1.0\\r\\n\\r\\n"
    fetch = f"exec 3<>/dev/tcp/{HOST}/{port}; printf '{request}' >&3; head -n 1 <&3"
    with _file_server(rrd, port, 9090):
        done = run_in_group(["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups",
                             "bash", "-c", fetch], timeout=60)  # fmt: skip
        assert done.returncode == 0, done.stderr
        assert done.stdout.split()[1:2] == ["403"], done.stdout
        connection = http.client.HTTPConnection(HOST, port, timeout=10)
        connection.request("GET", "/recording.rrd")
        assert connection.getresponse().read() == FAKE_RRD
        connection.close()


FAKE_SERVER = """#!{python}
import os, signal, socket, sys
if sys.argv[1:] == ["--version"]:
    print("rerun-cli {version} (native_viewer) [rustc]")
    sys.exit(0)
port = int(sys.argv[sys.argv.index("--web-viewer-port") + 1])
with socket.create_server(("127.0.0.1", port)) as listening:
    listening.accept()  # the command's check that the page is served
{ending}
"""


@pytest.mark.skipif(sys.platform == "win32", reason="the fake server is a script")
@pytest.mark.parametrize(
    ("ending", "said"),
    [("sys.exit(2)", "exited with status 2"),
     ("os.kill(os.getpid(), signal.SIGSEGV)", "was killed by SIGSEGV")],
)  # fmt: skip
def test_a_server_that_fails_while_serving_is_a_failed_command(
    recording: Path, tmp_path: Path, monkeypatch, capsys, ending: str, said: str
) -> None:
    """``view --web`` exited with the rerun server's own status when it ended by itself:
    2 read as a command line auv-cosim cannot parse, and a server killed by a signal gave
    -11, which the shell saw as 245. It is a failed command: exit 1, one line naming the
    server's status or signal."""
    import rerun as rr

    from cosim.viz import recording as viz_recording
    from cosim.viz import web_viewer

    fake = tmp_path / "rerun"
    version = rr.__version__.split("+")[0]
    fake.write_text(FAKE_SERVER.format(python=sys.executable, version=version, ending=ending))
    fake.chmod(0o755)
    monkeypatch.setattr(viz_recording, "rerun_executable", lambda: str(fake))
    monkeypatch.setattr(web_viewer, "_binary", lambda executable: executable)
    with deadline(60, "still serving"):
        code = main(["view", str(recording), "--web", "--web-port", "0", "--file-port", "0"])
    err = capsys.readouterr().err
    assert code == 1 and err.count("\n") == 1, (code, err)
    assert f"auv-cosim view: the rerun server {said} while serving" in err, err
