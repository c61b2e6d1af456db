"""``auv-cosim view --web`` without a browser: the URL it prints, the recording a folder
names, and the refusals (tests/cosim/viz/test_browser.py opens the served page)."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.errors import CosimError
from cosim.viz.recording import recording_in
from cosim.viz.web_viewer import HOST, serve_command, viewer_url

FAKE_RRD = b"RRF2" + bytes(60)  # starts like a recording: enough for the checks before serving


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


def test_a_taken_port_is_refused_in_one_line(tmp_path: Path, capsys) -> None:
    (tmp_path / "recording.rrd").write_bytes(FAKE_RRD)
    with socket.socket() as taken:
        taken.bind((HOST, 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", str(tmp_path), "--web", "--web-port", str(port)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"port {port} on 127.0.0.1 is taken" in err
    assert main(["view", str(tmp_path), "--web", "--web-port", "0", "--grpc-port", "70000"]) == 1
    assert "port 70000: expected 0 (any free port) to 65535" in capsys.readouterr().err


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
