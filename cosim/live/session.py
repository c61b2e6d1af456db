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
from cosim.engine.pacing import MAX_STEP_WALL_S, Pacer
from cosim.errors import CosimError
from cosim.live.control import ControlServer
from cosim.live.keys import KeyPad
from cosim.scenario.spec import Scenario, scenario_from_toml

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
        """Everything the options ask for; :class:`CosimError` (one line) if refused,
        before anything is opened (an adaptive run: its steps are its own)."""
        given = {"--real-time": real_time is not None, "--control": control is not None,
                 "--interactive": interactive}  # fmt: skip
        wanted = [flag for flag, on in given.items() if on]
        if wanted and scenario.coupling.algorithm == "adaptive":
            raise CosimError(
                f"{' and '.join(wanted)}: a paced or live run needs a fixed step; algorithm "
                "'adaptive' chooses its own (--algorithm gauss-seidel or jacobi)"
            )
        if real_time is not None:
            _check_factor(real_time, scenario.coupling.step)
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
                if session.server.reachable_from_network:
                    print(_network_warning(session.server.address), file=sys.stderr, flush=True)
            if interactive:
                status = session.pacer.short_status if session.pacer is not None else None
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
        """End the keys (terminal restored) and the endpoint, after answering every request
        still waiting (not applied: the run has ended); safe to call twice."""
        if self.live is not None:
            self.live.close()
        if self.keys is not None:
            self.keys.close()
        if self.server is not None:
            self.server.close()


def _network_warning(address: str) -> str:
    return (
        f"control endpoint: WARNING: {address} is reachable from the network and has no "
        "authentication: anyone who reaches it can change, pause or stop this run "
        "(docs/live-runs.md, Security)"
    )


def _check_factor(factor: float, step: float) -> None:
    """A real-time factor that is finite, > 0 and gives a step at most
    :data:`cosim.engine.pacing.MAX_STEP_WALL_S` of wall clock; :class:`CosimError` if not."""
    if not (math.isfinite(factor) and factor > 0):
        raise CosimError(f"--real-time {factor!r}: expected a finite factor > 0")
    if step / factor > MAX_STEP_WALL_S:
        raise CosimError(
            f"--real-time {factor!r}: one communication step of {step:g} s would last "
            f"{step / factor:.3g} s of wall clock; expected a factor >= "
            f"{step / MAX_STEP_WALL_S:.3g} (at most a day per step)"
        )


def replay_scenario(scenario: Scenario, result: RunResult, live: bool) -> Scenario | None:
    """``scenario`` with the run's accepted overrides as ``[[events]]`` at the times they
    were applied, and, for a live run that was stopped, the time reached as stop time:
    running it gives the same results.csv. A run that failed keeps its stop time (its
    replay fails at the same step). None when there is nothing to rewrite (no override,
    and not a stopped live run)."""
    stopped = result.stop_signal is not None and result.time_reached > 0
    if not result.overrides and not (live and stopped):
        return None
    events = scenario.events + replay_events(result.overrides)
    stop_time = result.time_reached if stopped else scenario.stop_time
    replay = dataclasses.replace(scenario, events=events, stop_time=stop_time)
    # resolved again from its text, as a file of it would be: a copy made from it (the
    # step checks' runs at h/2, Scenario.with_overrides) starts from its checked spec,
    # which the replace above leaves without the events
    return scenario_from_toml(
        replay.to_toml(), f"{scenario.described} (replayed)", scenario.base_dir, scenario.fmu_dir
    )
