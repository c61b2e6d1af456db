"""The pacer's deadlines and accounting on a fake clock (no timed assertion): absolute
deadlines t0 + n h / f that do not drift with the steps' own time, late steps and the
maximum lateness, the one line said when the run falls behind, pauses, and the factors."""

from __future__ import annotations

import contextlib
import gc
import sys
from decimal import Decimal
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import ROOT

from cosim.engine.pacing import (
    BEHIND_S,
    SLEEP_SLICE_S,
    SWITCH_INTERVAL_S,
    Pacer,
    _interpreters_own_frozen,
    interpreter_for_pacing,
)


class FakeClock:
    """A monotonic clock that moves only when the test or the pacer's sleep moves it."""

    def __init__(self) -> None:
        self.now = 100.0
        self.slept: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.slept.append(seconds)
        self.now += seconds


def pacer(factor: float = 1.0, h: float = 0.01) -> tuple[Pacer, FakeClock, list[str]]:
    clock, said = FakeClock(), []
    return Pacer(h, factor, clock=clock, sleep=clock.sleep, say=said.append), clock, said


def test_points_are_released_on_absolute_deadlines_without_drift() -> None:
    paced, clock, _ = pacer(factor=10.0)  # h / f = 1 ms per point
    paced.release(0)
    for n in range(1, 1001):
        clock.now += 0.0003 if n % 2 else 0.0007  # the steps' own time varies
        paced.release(n)
        assert clock.now == pytest.approx(100.0 + n * 0.001, abs=1e-9)
    assert paced.late_steps == 0
    assert paced.total_factor() == pytest.approx(10.0)


def test_a_late_step_is_counted_and_the_next_ones_catch_up() -> None:
    paced, clock, said = pacer()
    paced.release(0)
    clock.now += 0.015  # step 1 takes 15 ms: 5 ms after its 10 ms deadline
    paced.release(1)
    assert (paced.late_steps, paced.max_lateness) == (1, pytest.approx(0.005))
    clock.now += 0.001  # step 2 is quick: released at its own deadline, 20 ms after t0
    paced.release(2)
    assert clock.now == pytest.approx(100.02)
    assert paced.late_steps == 1 and said == []
    assert paced.summary()["max_lateness_s"] == pytest.approx(0.005)


def test_falling_behind_is_said_once_and_the_backlog_dropped() -> None:
    paced, clock, said = pacer()
    paced.release(0)
    clock.now += BEHIND_S + 0.2  # step 1 far too slow
    paced.release(1)
    clock.now += 0.002
    paced.release(2)  # paced again from where it is: due 10 ms after point 1's release
    assert clock.now == pytest.approx(100.0 + BEHIND_S + 0.2 + 0.01)
    clock.now += 2 * BEHIND_S
    paced.release(3)
    assert len(said) == 1 and "cannot keep up" in said[0] and "1x real time" in said[0]
    summary = paced.summary()
    assert summary["fell_behind"] and summary["late_steps"] == 2
    assert summary["max_lateness_s"] == pytest.approx(2 * BEHIND_S - 0.01)


def test_a_pause_moves_the_deadlines_and_is_not_counted() -> None:
    paced, clock, _ = pacer()
    paced.release(0)
    clock.now += 0.01
    paced.release(1)
    paced.pause()
    clock.now += 5.0
    paced.resume()
    paced.release(2)
    assert clock.now == pytest.approx(100.0 + 5.0 + 0.02)
    assert paced.late_steps == 0
    assert paced.total_factor() == pytest.approx(1.0)


def test_the_rolling_factor_covers_the_last_second_only() -> None:
    paced, clock, _ = pacer(factor=2.0, h=0.1)  # 50 ms a point
    paced.release(0)
    for n in range(1, 41):  # 2 s on target
        paced.release(n)
    assert paced.rolling_factor() == pytest.approx(2.0)
    for n in range(41, 61):  # then 20 points at 100 ms each (1x), each late
        clock.now += 0.1
        paced.release(n)
    assert paced.rolling_factor() == pytest.approx(1.0, rel=0.06)
    assert paced.total_factor() == pytest.approx(6.0 / 4.0)
    assert "rt 1.0" in paced.status() and "target 2x" in paced.status()


@pytest.mark.parametrize("factor", [0.0, -1.0, float("inf"), float("nan")])
def test_a_factor_that_is_not_finite_and_positive_is_refused(factor: float) -> None:
    with pytest.raises(ValueError, match="real-time factor"):
        Pacer(0.01, factor)


def test_a_paced_loop_runs_with_start_up_frozen_and_a_short_switch_interval():
    """Inside, what exists is out of the collector's reach and threads switch every 0.5 ms
    (no 50-80 ms full collection, no 5 ms wait for the recording's thread); afterwards the
    interpreter is as it was, even when the loop raised."""
    gc.collect()  # CPython 3.12 counts its immortal objects as frozen once it collected
    before, frozen = sys.getswitchinterval(), gc.get_freeze_count()
    with pytest.raises(RuntimeError), interpreter_for_pacing():
        assert gc.get_freeze_count() > frozen + 1000
        assert sys.getswitchinterval() == SWITCH_INTERVAL_S < before
        raise RuntimeError("the loop failed")
    gc.collect()
    assert gc.get_freeze_count() == frozen
    assert sys.getswitchinterval() == before


# The paced loop's freeze under a bare CPython: pacing.py loaded from its file, the one name
# it imports from cosim given in its place (the interpreter has none of cosim's libraries).
_FREEZE_IN_ANOTHER_PYTHON = """
import gc, importlib.util, sys, types
shown = types.ModuleType("cosim.scenario.timeline_spec")
shown.shown_time = str
sys.modules["cosim.scenario.timeline_spec"] = shown
spec = importlib.util.spec_from_file_location("pacing", sys.argv[1])
pacing = importlib.util.module_from_spec(spec)
spec.loader.exec_module(pacing)
made = [[n] for n in range(5000)]
gc.collect()
before = gc.get_freeze_count()
with pacing.interpreter_for_pacing():
    inside = gc.get_freeze_count()
gc.collect()
print(before, inside, gc.get_freeze_count())
"""


def _other_cpythons() -> list[Path]:
    """The other CPythons the project supports (3.11 to 3.13, but this one's minor)
    installed beside this one (pyenv)."""
    mine = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    found = Path("/root/.pyenv/versions").glob("3.1[123].*/bin/python3.1[123]")
    return sorted(python for python in found if python.name != mine)


@pytest.mark.parametrize("python", [Path(sys.executable), *_other_cpythons()], ids=str)
def test_the_paced_loop_freezes_in_every_python_though_it_keeps_objects_frozen_itself(
    python: Path,
) -> None:
    """CPython 3.12 keeps objects of its own in the permanent generation (it moves its
    immortal objects there at each collection: 375 tuples in 3.12.1, none in 3.11 or 3.13),
    which ``gc.get_freeze_count`` counts as if a caller had frozen them: the paced loop,
    which freezes only where the caller froze nothing, never froze there. Under each CPython
    found here (this one, and the other supported ones where installed), the loop freezes
    what exists and takes back its freeze alone."""
    done = run_in_group(
        [python, "-I", "-c", _FREEZE_IN_ANOTHER_PYTHON, ROOT / "cosim/engine/pacing.py"],
        timeout=120,
    )
    assert done.returncode == 0, done.stderr.strip().splitlines()[-1:]
    before, inside, after = map(int, done.stdout.split())
    assert inside > before + 5000, f"{python}: nothing frozen in the loop ({before} before)"
    assert after == before


@pytest.mark.parametrize("collecting", [True, False], ids=["collector-on", "collector-off"])
@pytest.mark.parametrize("fails", [False, True], ids=["ends", "raises"])
def test_a_callers_own_freeze_and_collector_are_left_as_they_were(
    collecting: bool, fails: bool
) -> None:
    """A program that froze its own objects (``gc.freeze``) and maybe turned the collector
    off, then calls ``cli.main(["run", "--real-time", ...])`` in its process: afterwards
    the same objects are frozen, no more (the paced loop's freeze is not the caller's to
    keep: gc.unfreeze takes back every freeze, so the loop leaves such a caller's freeze
    alone), and the collector is on or off as it was."""
    gc.collect()  # CPython 3.12 counts its immortal objects as frozen once it collected
    assert gc.get_freeze_count() <= _interpreters_own_frozen(), "this test needs nothing frozen"
    try:
        gc.freeze()
        if not collecting:
            gc.disable()
        frozen = gc.get_freeze_count()
        made_since = [[n] for n in range(5000)]  # objects of the caller's, not frozen
        with contextlib.suppress(RuntimeError), interpreter_for_pacing():
            if fails:
                raise RuntimeError("the loop failed")
        enabled = gc.isenabled()
        gc.collect()
        count = gc.get_freeze_count()  # frozen objects still die by their reference counts:
        assert frozen - 100 <= count <= frozen  # none frozen since (made_since), none thawed
        assert enabled == collecting
        assert made_since
    finally:
        gc.unfreeze()
        gc.enable()


def test_a_stop_ends_a_long_wait_for_a_deadline_at_once() -> None:
    """Ctrl-C, SIGTERM, stop or q while the run waits 1000 s for its next point."""
    paced, clock, _ = pacer(factor=1e-5)  # 1000 s of wall clock per 10 ms step
    paced.release(0)
    asked: list[float] = []
    paced.release(1, lambda: asked.append(clock.now) or len(asked) > 3)
    assert sum(clock.slept) <= 4 * SLEEP_SLICE_S  # not 1000 s
    assert paced.late_steps == 0 and paced.n == 1
    paced.release(2)  # without a stop, the next point waits for its own deadline
    assert clock.now == pytest.approx(100.0 + 2000.0)


def test_the_times_it_shows_read_as_the_step_writes_them() -> None:
    """The line said when the run falls behind and summary.json's ``max_lateness_at_s``
    gave n h as its float (t = 6.52 s at point 163 of a 0.04 s step was
    6.5200000000000005): they give it with the step's decimals."""
    h = 0.04
    n = next(n for n in range(1, 10_000) if len(repr(n * h)) > len(repr(round(n * h, 2))))
    paced, clock, said = pacer(h=h)
    paced.release(0)
    clock.now += n * h + BEHIND_S + 0.5  # point n comes late enough to fall behind
    paced.release(n)
    shown = float(n * Decimal(repr(h)))
    assert paced.summary()["max_lateness_at_s"] == shown
    assert said and f"at t = {shown!r} s (" in said[0], said
