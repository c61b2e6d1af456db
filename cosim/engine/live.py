"""Live control of a running master: overrides, pause, stop, and the latest outputs.

A :class:`LiveControl` is shared between the master's thread and the threads that steer the
run (the control endpoint, the terminal keys: :mod:`cosim.live`). They call

* :meth:`LiveControl.request` with ``{"<instance>.<variable>": value}``: every value is
  checked like an ``[[events]]`` value of the scenario (the variable exists, is an
  unconnected input or a tunable parameter, of type Real, Integer or Boolean; the value has
  that type, is finite and within the variable's declared ``min``/``max``), all or none
  queued; a refusal raises :class:`OverrideError` with one line. The :class:`Ticket` it
  returns says, once the master has decided, where the values were applied (name and time)
  or why they were not: the run ended first (at its stop time, after a ``stop``, on a
  failure), or setting them failed. Nothing queued is ever dropped silently;
* :meth:`pause` / :meth:`resume` (a pause is held by the sources that asked for it:
  :meth:`release` lets go of one that went away, and the run resumes when none is left),
  :meth:`stop` (ends the run at the next communication point after t = 0: a stopped live
  run has taken at least one step, so it replays), :meth:`latest` (the values of the last
  communication point).

The master (``cosim.engine.master``) takes the queue at each communication point n through
its :class:`cosim.engine.timeline.Timeline` (:meth:`LiveControl.take`), which applies each
override exactly as a time event at t_n (after the scenario's own events due at t_n, before
ramps, series and conditions): so writing the accepted overrides back as ``[[events]]`` at
those times (:func:`replay_events`) replays the run exactly. A paused run waits inside that
call, at t_n, and applies what arrives meanwhile at t_n too (in order, as the replay does);
the pacer's clock stops while it waits. When the run ends, :meth:`LiveControl.close`
answers every request still waiting ("not applied: the run ended at t = ...") and refuses
later ones.
"""

from __future__ import annotations

import collections
import signal
import threading
from collections.abc import Collection, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cosim.engine.pacing import Pacer
from cosim.engine.signals import StopRequest
from cosim.errors import CosimError
from cosim.scenario.checks import ScenarioError, Source, sign_note
from cosim.scenario.spec import Scenario
from cosim.scenario.timeline_spec import Event, settable, shown_time
from cosim.scenario.unit_doubts import variable_doubt

PAUSE_POLL_S = 0.1  # s: a paused run checks for a signal this often


class OverrideError(CosimError):
    """An override or a read that is refused: one line naming the value and the reason."""


class _Live(Source):
    def error(self, key: str, problem: str, causes: Collection[str] | None = None) -> ScenarioError:
        return ScenarioError(f"override {key}: {problem}")


@dataclass
class Ticket:
    """One accepted override request and its fate: ``name`` and ``time`` (s) once applied,
    ``refused`` (one line) if it never will be; :meth:`wait` until one of them is known."""

    values: dict[str, bool | int | float]
    source: str
    doubts: list[str] = field(default_factory=list)  # values that look like another unit
    name: str | None = None
    time: float | None = None
    refused: str | None = None
    _done: threading.Event = field(default_factory=threading.Event, repr=False)

    @property
    def done(self) -> bool:
        return self._done.is_set()

    def wait(self, timeout: float | None = None) -> bool:
        """Block until the master applied or refused it (True), or ``timeout`` s passed."""
        return self._done.wait(timeout)

    def _resolve(self, name: str | None, time: float | None, refused: str | None) -> None:
        self.name, self.time, self.refused = name, time, refused
        self._done.set()


class LiveControl:
    """Thread-safe override queue and run controls (see the module docstring)."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self._cond = threading.Condition()
        self._queue: collections.deque[Ticket] = collections.deque()
        self._inflight: list[Ticket] = []  # taken by the master, not yet applied
        self._holders: set[str] = set()  # the sources holding the run paused
        self._stop_wanted: str | bool = False  # who asked for a stop (False: none)
        self._closed: str | None = None  # why requests are refused now: the run ended
        self._applied: dict[str, bool | int | float] = {}  # ref -> the last value applied
        self._notes: list[str] = []  # what the recording should say at the next point
        self.stop_request: StopRequest | None = None  # set by the master for its run
        self.pacer: Pacer | None = None
        self._index: Mapping[str, int] = {}
        self._latest: tuple[float, np.ndarray] | None = None

    # --- the steering threads -----------------------------------------------------------

    def check(self, ref: str, value: Any) -> bool | int | float:
        """``value`` as ``ref`` takes it; :class:`OverrideError` (one line) if it cannot."""
        try:
            checked = settable(ref, value, self.scenario, ref, False, _Live("live"))
        except ScenarioError as exc:
            raise OverrideError(str(exc)) from None
        except OverflowError:  # an integer beyond any float, for a Real
            raise OverrideError(
                f"override {ref}: an integer of {int(value).bit_length()} bits is beyond any "
                "finite number"
            ) from None
        _, variable = ref.split(".", 1)
        var = self.scenario.instances[ref.split(".", 1)[0]].interface.variables[variable]
        if var.type == "Real" and not _within(float(checked), var.min, var.max):
            raise OverrideError(
                f"override {ref}: {checked!r} is outside [{_bound(var.min, -1)}, "
                f"{_bound(var.max, 1)}], the range {variable} takes{sign_note(var)}"
            )
        return checked

    def request(self, values: Mapping[str, Any], source: str) -> Ticket:
        """Check every value, then queue them all for the next communication point;
        raises :class:`OverrideError` (nothing queued) if one is refused or the run has
        ended. The ticket tells when they were applied (or why not)."""
        if not values:
            raise OverrideError("override: no value given")
        checked = {ref: self.check(ref, value) for ref, value in values.items()}
        ticket = Ticket(checked, source, self._doubts(checked))
        with self._cond:
            if self._closed is not None:
                raise OverrideError(f"set not applied: {self._closed}")
            self._queue.append(ticket)
            self._cond.notify_all()
        return ticket

    def _doubts(self, values: Mapping[str, bool | int | float]) -> list[str]:
        """A warning line for each value that looks like degrees given to an angle in rad
        (:func:`cosim.scenario.unit_doubts.variable_doubt`): taken all the same."""
        found = []
        for ref, value in values.items():
            instance, variable = ref.split(".", 1)
            var = self.scenario.instances[instance].interface.variables[variable]
            line = variable_doubt(ref, var, value)
            if line is not None:
                found.append(line)
        return found

    def pause(self, source: str) -> None:
        """Hold the run at its next communication point until :meth:`resume` (or until
        ``source`` and every other holder is :meth:`release`\\ d)."""
        with self._cond:
            self._refuse_if_closed("pause")
            self._holders.add(source)

    def resume(self) -> None:
        """Let the run go on, whoever paused it."""
        with self._cond:
            self._refuse_if_closed("resume")
            self._holders.clear()
            self._cond.notify_all()

    def release(self, source: str) -> bool:
        """``source`` went away: its pause no longer holds the run. True if that resumed
        the run (the recording gets a note saying so)."""
        with self._cond:
            if source not in self._holders:
                return False
            self._holders.discard(source)
            if self._holders or self._closed is not None:
                return False
            self._notes.append(f"{source} went away while holding the run paused: resumed")
            self._cond.notify_all()
            return True

    @property
    def paused(self) -> bool:
        return bool(self._holders)

    def stop(self, source: str) -> None:
        """End the run at the next communication point after t = 0, like Ctrl-C (exit
        code 130), the reason naming ``source`` ("control 127.0.0.1:5000", "the q key");
        :class:`OverrideError` if it has already ended."""
        with self._cond:
            self._refuse_if_closed("stop")
            self._stop_wanted = self._stop_wanted or source
            self._cond.notify_all()

    @property
    def stopping(self) -> bool:
        """A stop was asked for (here, or by a signal): waits end at once."""
        stop = self.stop_request
        signalled = stop is not None and stop.requested
        return bool(self._stop_wanted) or self._closed is not None or signalled

    def current(self, ref: str) -> bool | int | float | None:
        """The value ``ref`` has now, as far as this run knows: the last one queued for it,
        else its value at the last communication point (a recorded variable), else the
        last override applied to it; None if none of these is known."""
        with self._cond:
            for ticket in reversed([*self._inflight, *self._queue]):
                if ref in ticket.values:
                    return ticket.values[ref]
            snapshot = self._latest
            if snapshot is not None and ref in self._index:
                return float(snapshot[1][self._index[ref]])
            return self._applied.get(ref)

    def latest(self, refs: Sequence[str]) -> tuple[float | None, dict[str, float]]:
        """(t in s, the values at the last communication point) of recorded or exchanged
        variables; :class:`OverrideError` names one that is neither."""
        if not self._index:
            raise OverrideError("get: the run has not reached t = 0 yet (its FMUs are set up)")
        unknown = [ref for ref in refs if ref not in self._index]
        if unknown:
            raise OverrideError(
                f"get {unknown[0]!r}: not a recorded or exchanged variable of this run"
            )
        snapshot = self._latest
        if snapshot is None:
            return None, {}
        t, z = snapshot
        return t, {ref: float(z[self._index[ref]]) for ref in refs}

    @property
    def time(self) -> float | None:
        """t (s) of the last communication point (None before t = 0)."""
        snapshot = self._latest
        return None if snapshot is None else snapshot[0]

    @property
    def ended(self) -> str | None:
        """Why the run takes no more requests (None while it does)."""
        return self._closed

    def _refuse_if_closed(self, verb: str) -> None:
        if self._closed is not None:
            raise OverrideError(f"{verb}: {self._closed}")

    # --- the master's thread --------------------------------------------------------------

    def bind(self, index: Mapping[str, int], stop: StopRequest, pacer: Pacer | None = None) -> None:
        """The run's value layout (``"<inst>.<var>"`` -> slot of z), stop request and pacer
        (its clock stops while the run is paused)."""
        self._index, self.stop_request, self.pacer = dict(index), stop, pacer

    def publish(self, t: float, z: np.ndarray) -> None:
        """The values at communication point t (a copy; read by :meth:`latest`), with t as
        a user reads it (:func:`shown_time`)."""
        self._latest = (shown_time(t, self.scenario.coupling.step), z.copy())

    def take(self, n: int, t: float, z: np.ndarray) -> Iterator[Ticket]:
        """The requests to apply at communication point n (t_n = ``t`` s), oldest first;
        while the run is paused, waits here and yields what arrives meanwhile. A stop asked
        for is recorded here, at n >= 1, after the requests taken with it."""
        while True:
            with self._cond:
                batch = list(self._queue)
                self._queue.clear()
                self._inflight.extend(batch)
                if n >= 1 and self._stop_wanted and self.stop_request is not None:
                    self.stop_request.record(signal.SIGINT, by=str(self._stop_wanted))
            yield from batch
            if not self._holders or self.stopping:
                return
            self.publish(t, z)
            self._hold()

    def _hold(self) -> None:
        """Wait while paused, until a request, a resume or a stop (the pacer's clock stops)."""
        if self.pacer is not None:
            self.pacer.pause()
        with self._cond:
            while self._holders and not self._queue and not self.stopping:
                self._cond.wait(PAUSE_POLL_S)  # also polls for a signal's stop request
        if self.pacer is not None:
            self.pacer.resume()

    def applied(self, ticket: Ticket, name: str, t: float) -> None:
        """``ticket``'s values were applied as override ``name`` at t (s)."""
        with self._cond:
            self._inflight.remove(ticket)
            self._applied.update(ticket.values)
        ticket._resolve(name, shown_time(t, self.scenario.coupling.step), None)

    def failed(self, ticket: Ticket, reason: str) -> None:
        """Applying ``ticket`` failed (the run ends): ``reason``, one line."""
        with self._cond:
            if ticket in self._inflight:
                self._inflight.remove(ticket)
        ticket._resolve(None, None, f"not applied: {reason}")

    def take_notes(self) -> list[str]:
        """What happened to the run's controls since the last call (for the recording)."""
        with self._cond:
            notes, self._notes = self._notes, []
        return notes

    def close(self, reason: str | None = None) -> None:
        """The run has ended: refuse every request still waiting, and any later one, with
        ``reason`` (default: the time it ended at); safe to call twice."""
        if reason is None:
            t = self.time
            reason = f"the run ended at t = {t:.15g} s" if t is not None else "the run ended"
        with self._cond:
            if self._closed is None:
                self._closed = reason
            waiting = [*self._inflight, *self._queue]
            self._inflight.clear()
            self._queue.clear()
            self._holders.clear()
            self._cond.notify_all()
        for ticket in waiting:
            ticket._resolve(None, None, f"not applied: {self._closed}")


def replay_events(overrides: Sequence[Mapping[str, Any]]) -> tuple[Event, ...]:
    """The accepted overrides (``RunResult.overrides``) as time events that replay them."""
    return tuple(Event(o["name"], time=o["time"], set=dict(o["set"])) for o in overrides)


def _within(value: float, low: float | None, high: float | None) -> bool:
    return (low is None or value >= low) and (high is None or value <= high)


def _bound(value: float | None, sign: int) -> str:
    return str(value) if value is not None else ("inf" if sign > 0 else "-inf")
