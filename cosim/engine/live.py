"""Live control of a running master: overrides, pause, stop, and the latest outputs.

A :class:`LiveControl` is shared between the master's thread and the threads that steer the
run (the control endpoint, the terminal keys: :mod:`cosim.live`). They call

* :meth:`LiveControl.request` with ``{"<instance>.<variable>": value}``: every value is
  checked like an ``[[events]]`` value of the scenario (the variable exists, is an
  unconnected input or a tunable parameter, of type Real, Integer or Boolean; the value has
  that type, is finite and within the variable's declared ``min``/``max``), all or none
  queued; a refusal raises :class:`OverrideError` with one line;
* :meth:`pause` / :meth:`resume`, :meth:`stop` (ends the run like Ctrl-C), :meth:`latest`
  (the values of the last communication point).

The master (``cosim.engine.master``) drains the queue at each communication point n through
its :class:`cosim.engine.timeline.Timeline`, which applies each override exactly as a time
event at t_n (after the scenario's own events due at t_n, before ramps, series and
conditions): so writing the accepted overrides back as ``[[events]]`` at those times
(:func:`replay_events`) replays the run exactly.
"""

from __future__ import annotations

import collections
import signal
import threading
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from cosim.engine.signals import StopRequest
from cosim.errors import CosimError
from cosim.scenario.checks import ScenarioError, Source
from cosim.scenario.spec import Scenario
from cosim.scenario.timeline_spec import Event, settable


class OverrideError(CosimError):
    """An override or a read that is refused: one line naming the value and the reason."""


class _Live(Source):
    def error(self, key: str, problem: str) -> ScenarioError:
        return ScenarioError(f"override {key}: {problem}")


class LiveControl:
    """Thread-safe override queue and run controls (see the module docstring)."""

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self._lock = threading.Lock()
        self._queue: collections.deque[tuple[dict[str, bool | int | float], str]] = (
            collections.deque()
        )
        self._resume = threading.Event()
        self._resume.set()
        self.stop_request: StopRequest | None = None  # set by the master for its run
        self._index: Mapping[str, int] = {}
        self._latest: tuple[float, np.ndarray] | None = None

    # --- the steering threads -----------------------------------------------------------

    def check(self, ref: str, value: Any) -> bool | int | float:
        """``value`` as ``ref`` takes it; :class:`OverrideError` (one line) if it cannot."""
        try:
            checked = settable(ref, value, self.scenario, ref, False, _Live("live"))
        except ScenarioError as exc:
            raise OverrideError(str(exc)) from None
        _, variable = ref.split(".", 1)
        var = self.scenario.instances[ref.split(".", 1)[0]].interface.variables[variable]
        if var.type == "Real" and not _within(float(checked), var.min, var.max):
            raise OverrideError(
                f"override {ref}: {checked!r} is outside [{_bound(var.min, -1)}, "
                f"{_bound(var.max, 1)}], the range {variable} takes"
            )
        return checked

    def request(self, values: Mapping[str, Any], source: str) -> dict[str, bool | int | float]:
        """Check every value, then queue them all for the next communication point;
        raises :class:`OverrideError` (nothing queued) if one is refused."""
        if not values:
            raise OverrideError("override: no value given")
        checked = {ref: self.check(ref, value) for ref, value in values.items()}
        with self._lock:
            self._queue.append((checked, source))
        return checked

    def pause(self) -> None:
        self._resume.clear()

    def resume(self) -> None:
        self._resume.set()

    @property
    def paused(self) -> bool:
        return not self._resume.is_set()

    def stop(self) -> None:
        """End the run at the next communication point, like Ctrl-C (exit code 130)."""
        if self.stop_request is not None:
            self.stop_request.record(signal.SIGINT)
        self._resume.set()

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

    # --- the master's thread --------------------------------------------------------------

    def bind(self, index: Mapping[str, int], stop: StopRequest) -> None:
        """The run's value layout (``"<inst>.<var>"`` -> slot of z) and stop request."""
        self._index, self.stop_request = dict(index), stop

    def publish(self, t: float, z: np.ndarray) -> None:
        """The values at communication point t (a copy; read by :meth:`latest`)."""
        self._latest = (t, z.copy())

    def drain(self) -> list[tuple[dict[str, bool | int | float], str]]:
        """Every queued override, oldest first, taken off the queue."""
        with self._lock:
            taken = list(self._queue)
            self._queue.clear()
        return taken

    def wait_while_paused(self, timeout: float) -> bool:
        """Block up to ``timeout`` s while paused; True once running again."""
        return self._resume.wait(timeout)


def replay_events(overrides: Sequence[Mapping[str, Any]]) -> tuple[Event, ...]:
    """The accepted overrides (``RunResult.overrides``) as time events that replay them."""
    return tuple(Event(o["name"], time=o["time"], set=dict(o["set"])) for o in overrides)


def _within(value: float, low: float | None, high: float | None) -> bool:
    return (low is None or value >= low) and (high is None or value <= high)


def _bound(value: float | None, sign: int) -> str:
    return str(value) if value is not None else ("inf" if sign > 0 else "-inf")
