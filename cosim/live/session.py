"""What a live or paced run adds around the master, opened before it steps and closed after.

:meth:`LiveSession.open` makes the :class:`cosim.engine.pacing.Pacer` (``--real-time``),
the :class:`cosim.engine.live.LiveControl` with the control endpoint (``--control``) and
the terminal keys (``--interactive``); :meth:`LiveSession.close` ends them and restores the
terminal, whatever way the run ended (the runner calls it in a ``finally``).
"""

from __future__ import annotations

import dataclasses
import math
import sys
from dataclasses import dataclass

from cosim.engine.live import LiveControl, replay_events
from cosim.engine.master import RunResult
from cosim.engine.pacing import Pacer
from cosim.errors import CosimError
from cosim.live.control import ControlServer
from cosim.live.keys import KeyPad
from cosim.scenario.spec import Scenario

PACED_HAND_OFF_S = 0.1  # a paced run hands rows to the sinks (the viewer) this often


@dataclass
class LiveSession:
    """The pacer, the override queue and what feeds it, for one run (each may be None)."""

    pacer: Pacer | None = None
    live: LiveControl | None = None
    server: ControlServer | None = None
    keys: KeyPad | None = None

    @classmethod
    def open(
        cls,
        scenario: Scenario,
        real_time: float | None,
        control: str | None,
        interactive: bool,
    ) -> LiveSession:
        """Everything the options ask for; :class:`CosimError` (one line) if refused."""
        if real_time is not None and not (math.isfinite(real_time) and real_time > 0):
            raise CosimError(f"--real-time {real_time!r}: expected a finite factor > 0")
        if interactive and real_time is None:
            raise CosimError("--interactive needs --real-time [FACTOR] (keys steer a paced run)")
        session = cls()
        if real_time is not None:
            session.pacer = Pacer(scenario.coupling.step, real_time)
        if control is not None or interactive:
            session.live = LiveControl(scenario)
        try:
            if control is not None:
                session.server = ControlServer.open(session.live, control)  # type: ignore[arg-type]
                print(f"control endpoint: {session.server.address}", file=sys.stderr, flush=True)
            if interactive:
                status = session.pacer.status if session.pacer is not None else None
                session.keys = KeyPad(session.live, scenario, status)  # type: ignore[arg-type]
                session.keys.start()
        except BaseException:
            session.close()
            raise
        return session

    @property
    def hand_off_interval(self) -> float | None:
        """How often the master hands rows to the sinks (None: its default)."""
        return PACED_HAND_OFF_S if self.pacer is not None else None

    def status(self) -> str:
        """The progress line's real-time figures ("" for a run not paced)."""
        return self.pacer.status() if self.pacer is not None else ""

    def close(self) -> None:
        """End the keys (terminal restored) and the endpoint; safe to call twice."""
        if self.keys is not None:
            self.keys.close()
        if self.server is not None:
            self.server.close()


def replay_scenario(scenario: Scenario, result: RunResult) -> Scenario | None:
    """``scenario`` with the run's accepted overrides as ``[[events]]`` at the times they
    were applied (and the time reached as stop time, if stopped early): running it gives
    the same results.csv. None for a run without overrides."""
    if not result.overrides:
        return None
    events = scenario.events + replay_events(result.overrides)
    stop_time = scenario.stop_time
    if result.rows < scenario.n_steps + 1 and result.time_reached > 0:
        stop_time = result.time_reached
    return dataclasses.replace(scenario, events=events, stop_time=stop_time)
