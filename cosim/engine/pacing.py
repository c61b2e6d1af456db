"""Real-time pacing of a run: communication points released on a monotonic clock.

A paced run at real-time factor f (1.0: real time, 10: ten times faster) releases
communication point n (t_n = n h of simulated time) no earlier than its absolute deadline

    d_n = t0 + n h / f         (wall clock, ``time.monotonic``; t0 when point 0 is released)

so the sleeps never add up (no drift): a step that ran late is followed by shorter sleeps,
or none, until the run is back on its deadlines. A run that falls :data:`BEHIND_S` behind
(the FMUs are slower than the target, or the machine was busy) says so once (``say``),
drops that backlog (t0 moves on: the run does not race to make up lost time, which a viewer
or a program in the loop would see as a burst) and goes on, as fast as it can while it
cannot keep up. A pause (:meth:`Pacer.pause` / :meth:`Pacer.resume`) moves t0 by its
length, so a resumed run is not "late".

Figures, all in wall-clock seconds: a point is *late* when it is computed after its
deadline; its lateness is how long after its deadline it was released (the computation's
delay, plus the sleep's own overshoot for a point that slept). The rolling real-time factor
is the simulated time advanced over the last :data:`ROLLING_WINDOW_S` of wall clock divided
by that wall time, the total one the simulated time reached over the wall time since
point 0 (pauses excluded).

Written by hand: no library paces a loop on absolute deadlines with these figures (libcosim's
``real_time_timer`` is C++ inside its execution; ``sched`` or ``asyncio`` schedule callbacks,
not a loop that must stay in the calling thread). The clock and the sleep are injectable, so
tests check the deadlines and the accounting on a fake clock, with no timed assertion.
"""

from __future__ import annotations

import collections
import functools
import gc
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from cosim.scenario.timeline_spec import shown_time

MAX_STEP_WALL_S = 86_400.0  # s of wall clock one communication step may take: a day
SLEEP_SLICE_S = 0.05  # s: a long wait for a deadline checks for a stop this often
ROLLING_WINDOW_S = 1.0  # wall clock over which the rolling real-time factor is taken
BEHIND_S = 0.5  # s of wall clock behind the deadlines at which the run says it cannot keep up
_SAMPLE_S = 0.05  # wall clock between two samples of the rolling window
SWITCH_INTERVAL_S = 0.0005  # the interpreter's thread switch interval in a paced loop


@contextmanager
def interpreter_for_pacing() -> Iterator[None]:
    """The interpreter set for a paced loop, until the end:

    * collect once, then move every object that exists (the imported libraries, the FMUs,
      the outputs: ~1e5 objects) out of the garbage collector's reach (``gc.freeze``). A
      full collection over them took 50-80 ms (rerun, numba, scipy and pandas loaded) at a
      moment the interpreter chooses: a step late by as much. The loop's own objects are
      collected as before.
      Not where the caller froze objects of its own (a program calling ``cli.main`` in its
      process): ``gc.unfreeze`` takes back every freeze, so the loop's could not be taken
      back alone, and the caller's objects are left as they were. Objects the interpreter
      keeps frozen itself (:func:`_interpreters_own_frozen`) are not the caller's.
    * hand the GIL over every :data:`SWITCH_INTERVAL_S` instead of 5 ms
      (``sys.setswitchinterval``): the recording's thread (:mod:`cosim.outputs.background`)
      runs Python for tens of ms per send, and the stepping thread waking from its sleep
      waited up to the interval, several times over, to get the interpreter back.
    """
    interval = sys.getswitchinterval()
    gc.collect()  # before counting: CPython 3.12 moves its immortal objects out as it collects
    freezing = gc.get_freeze_count() <= _interpreters_own_frozen()
    if freezing:
        gc.freeze()
    sys.setswitchinterval(SWITCH_INTERVAL_S)
    try:
        yield
    finally:
        sys.setswitchinterval(interval)
        if freezing:
            gc.unfreeze()


@functools.cache
def _interpreters_own_frozen() -> int:
    """How many objects a fresh interpreter of this executable keeps in the collector's
    permanent generation after a collection, which ``gc.get_freeze_count`` counts beside
    those a program froze: CPython 3.12 moves its immortal objects there as it collects
    (375 tuples of the built-in types in 3.12.1), 3.11 and 3.13 keep none. Measured once a
    process, in a child (~20 ms): the count cannot tell the interpreter's from a caller's,
    and Python lists no object of the permanent generation. 0 where no child answers (an
    embedded interpreter): the loop then freezes only where the count is 0, as before."""
    count = "import gc; gc.collect(); print(gc.get_freeze_count())"
    try:
        done = subprocess.run(
            [sys.executable, "-I", "-S", "-c", count], capture_output=True, text=True, timeout=30
        )
        return int(done.stdout) if done.returncode == 0 else 0
    except (OSError, ValueError, subprocess.SubprocessError):
        return 0


def _stderr_line(text: str) -> None:
    print(text, file=sys.stderr, flush=True)


class Pacer:
    """Releases communication points at ``t0 + n h / factor`` (see the module docstring).

    ``clock`` (s, monotonic) and ``sleep`` are ``time.monotonic`` and ``time.sleep`` unless
    a test gives its own; ``say`` gets the one line printed when the run falls behind.
    """

    def __init__(
        self,
        h: float,
        factor: float = 1.0,
        *,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        say: Callable[[str], None] = _stderr_line,
    ) -> None:
        if not (factor > 0.0 and factor < float("inf")):
            raise ValueError(f"real-time factor {factor!r}: expected a finite number > 0")
        self.h, self.factor = h, factor
        self.clock, self.sleep, self.say = clock, sleep, say
        self.t0: float | None = None
        self._started = 0.0  # clock() at point 0
        self._paused_s = 0.0  # wall clock spent paused
        self.n = 0  # the last point released
        self.late_steps = 0
        self.max_lateness = 0.0  # s
        self.latest_at: float | None = None  # s of simulated time: the latest point's t_n
        self.behind = False  # said once that the machine cannot keep up
        self._paused_at: float | None = None
        self._samples: collections.deque[tuple[float, int]] = collections.deque()

    def deadline(self, n: int) -> float:
        """The wall-clock time (``clock``) at which point n is due."""
        assert self.t0 is not None, "point 0 not released yet"
        return self.t0 + n * self.h / self.factor

    def release(self, n: int, stopping: Callable[[], bool] | None = None) -> None:
        """Wait until point n is due (point 0 starts the clock); account for lateness.

        ``stopping``, if given, is asked every :data:`SLEEP_SLICE_S` of a wait: once it
        says True the point is released at once (a stop does not wait out a long step)."""
        now = self.clock()
        if self.t0 is None or n == 0:
            self.t0 = self._started = now
            self.n = n
            self._samples.append((now, n))
            return
        due = self.deadline(n)
        if now < due:
            while now < due and not (stopping is not None and stopping()):
                self.sleep(min(due - now, SLEEP_SLICE_S))
                now = self.clock()
            if now < due:  # stopped early: not late, and no sample of a rushed point
                self.n = n
                return
        elif now > due:
            self.late_steps += 1
            if now - due >= BEHIND_S:
                self._fall_behind(n, now - due)
        if now - due > self.max_lateness:
            self.max_lateness, self.latest_at = now - due, shown_time(n * self.h, self.h)
        self.n = n
        if now - self._samples[-1][0] >= _SAMPLE_S:
            self._samples.append((now, n))
            while now - self._samples[0][0] > ROLLING_WINDOW_S and len(self._samples) > 2:
                self._samples.popleft()

    def _fall_behind(self, n: int, lag: float) -> None:
        """Say once that the run cannot keep up; drop the backlog of ``lag`` s."""
        if not self.behind:
            self.behind = True
            self.say(
                f"real time: cannot keep up with {self.factor:g}x real time at "
                f"t = {shown_time(n * self.h, self.h):.15g} s ({lag:.2f} s behind); going on "
                "as fast as possible"
            )
        assert self.t0 is not None
        self.t0 += lag

    def pause(self) -> None:
        """Stop the clock (the run waits); :meth:`resume` moves the deadlines on."""
        if self._paused_at is None:
            self._paused_at = self.clock()

    def resume(self) -> None:
        if self._paused_at is not None:
            paused = self.clock() - self._paused_at
            self._paused_at = None
            self._paused_s += paused
            if self.t0 is not None:
                self.t0 += paused
                self._samples = collections.deque((t + paused, n) for t, n in self._samples)

    def rolling_factor(self) -> float | None:
        """Simulated over wall time across the last second (None before there is one)."""
        if len(self._samples) < 2:
            return None
        (t_old, n_old), (t_new, n_new) = self._samples[0], self._samples[-1]
        return (n_new - n_old) * self.h / (t_new - t_old) if t_new > t_old else None

    def total_factor(self) -> float | None:
        """Simulated time reached over the wall time since point 0 (pauses excluded)."""
        if self.t0 is None:
            return None
        wall = (self._paused_at or self.clock()) - self._started - self._paused_s
        return self.n * self.h / wall if wall > 0 else None

    def status(self) -> str:
        """The progress line's text: ``rt 1.00x (total 1.00x)``."""
        rolling, total = self.rolling_factor(), self.total_factor()
        fmt = lambda f: "-" if f is None else f"{f:.2f}x"  # noqa: E731
        return f"rt {fmt(rolling)} (total {fmt(total)}, target {self.factor:g}x)"

    def short_status(self) -> str:
        """The rolling factor alone, for a status line short of room: ``rt 1.00x``."""
        rolling = self.rolling_factor()
        return "rt -" if rolling is None else f"rt {rolling:.2f}x"

    def summary(self) -> dict[str, Any]:
        """What summary.json records under ``real_time``."""
        return {
            "target_factor": self.factor,
            "achieved_factor": self.total_factor(),
            "late_steps": self.late_steps,
            "max_lateness_s": self.max_lateness,
            "max_lateness_at_s": self.latest_at,
            "fell_behind": self.behind,
        }
