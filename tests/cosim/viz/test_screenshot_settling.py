"""When cosim.viz.screenshot takes its shot: once the viewer's picture has settled, with
the start-up notices gone (a fake viewer on a fake clock: no Vulkan needed)."""

from __future__ import annotations

import pytest

from cosim.viz import screenshot

NOTICE_S = 4.6  # s the headless viewer's "Headless viewer running at ..." notice stayed up


class FakeClock:
    """``time.monotonic`` and ``time.sleep`` of the module, advanced by sleeps and shots."""

    def __init__(self) -> None:
        self.now = 0.0

    def monotonic(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


class NoticeThenPlot:
    """A viewer whose picture shows its start-up notice, unchanged, for ``NOTICE_S`` after
    it started, then the plots alone; a screenshot takes 1.3 s (software rendering)."""

    def __init__(self, clock: FakeClock) -> None:
        self.clock = clock

    def take_screenshot(self) -> bytes:
        self.clock.now += 1.3
        return b"plots and notice" if self.clock.now < NOTICE_S else b"plots"


def test_a_notice_unchanged_over_two_frames_is_waited_out(monkeypatch) -> None:
    """scripts/screenshots.py drew docs/figures/user-recording-layout.png with the viewer's
    "Headless viewer running at 1920x1080." notice over the panels on one run and without
    it on the next: two frames half a second apart were equal while the notice stood, and
    the first of them was taken. The shot waits out the notices' time on screen."""
    clock = FakeClock()
    monkeypatch.setattr(screenshot.time, "monotonic", clock.monotonic)
    monkeypatch.setattr(screenshot.time, "sleep", clock.sleep)
    assert screenshot._settled_frame(NoticeThenPlot(clock)) == b"plots"  # type: ignore[arg-type]


def test_a_picture_that_keeps_changing_is_refused_in_one_line(monkeypatch) -> None:
    clock = FakeClock()
    monkeypatch.setattr(screenshot.time, "monotonic", clock.monotonic)
    monkeypatch.setattr(screenshot.time, "sleep", clock.sleep)

    class Flicker:
        def take_screenshot(self) -> bytes:
            clock.now += 1.0
            return str(clock.now).encode()

    with pytest.raises(screenshot.ScreenshotError, match=r"did not settle in 60(\.0)? s$"):
        screenshot._settled_frame(Flicker())  # type: ignore[arg-type]
