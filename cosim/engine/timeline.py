"""A run's events and faults as the master applies them (docs/events.md).

The master's stepping loop (``cosim.engine.master._loop``), when a scenario has events or
faults, calls

* :meth:`Timeline.at` once per communication point t_n = n h (n = 0 .. N), after every due
  instance has stepped to t_n and its outputs were read, before row n is recorded and
  before any instance steps from t_n. In this order: time events due at t_n fire (the
  first point with t_n >= time, within 1e-9 of a step, or a few roundings late in a long run:
  ``point_slack``), running ramps and series write
  their values for t_n, ``when`` conditions are evaluated on the values at t_n (including
  what was just written) and fire on a false -> true crossing (never at n = 0), then the
  faults' ``fault.<name>`` columns are set and actuator faults on unconnected inputs hold
  their input. In a live run (:mod:`cosim.engine.live`) the overrides queued since the last
  point fire right after the time events, each as a time event at t_n would;
* :meth:`Timeline.deliver` for an instance right after the master gathered its connected
  inputs (``z.take(input_sources, out=inputs)``) and before ``fmi2SetReal``: each active
  fault on one of those connections replaces the gathered value in its slot. A feedthrough
  given its inputs again at a point is delivered the same again (one draw, one step of a
  delay's history per step of the instance).

Values are written with fmpy's ``setReal``/``setInteger``/``setBoolean`` on the instance; a
recorded unconnected input's column follows the value written. An instance that is not
due at t_n (step multiple k > 1) sees a value written at t_n when it next steps.
"""

from __future__ import annotations

import bisect
import collections
import dataclasses
import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from fmpy.fmi1 import FMICallException

from cosim.engine.slave import STATUS_LABELS, Slave
from cosim.errors import CosimError, seconds
from cosim.scenario.spec import FAULT_COLUMN_PREFIX, Scenario
from cosim.scenario.timeline_spec import (
    Event,
    Fault,
    first_point,
    point_slack,
    shown_time,
)

if TYPE_CHECKING:
    from cosim.engine.live import LiveControl

OVERRIDE_PREFIX = "live-"  # the names of applied overrides as events: live-1, live-2, ...


class _Writer:
    """Reads and writes ``"<instance>.<variable>"`` of the running instances; a written
    recorded input's column (its slot in ``z``) follows."""

    def __init__(self, slaves: Mapping[str, Slave], index: Mapping[str, int], z: np.ndarray):
        self.slaves, self.index, self.z = slaves, index, z
        self.assigned: dict[str, float] = {}  # the last value an event gave each variable

    def _resolve(self, ref: str) -> tuple[Slave, Any]:
        instance, variable = ref.split(".", 1)
        slave = self.slaves[instance]
        return slave, slave.instance.variable(variable)

    def get(self, ref: str) -> float:
        """The present value (of a Real)."""
        if ref in self.index:
            return float(self.z[self.index[ref]])
        slave, var = self._resolve(ref)
        return float(slave.fmu.getReal([var.valueReference])[0])

    def shown(self, ref: str, value: bool | int | float | str) -> str:
        """``value`` of ``ref`` as a note says it: with the variable's unit, and an angle
        in rad also in degrees (the recording's plots show angles in degrees)."""
        _, var = self._resolve(ref)
        unit = var.unit or (var.declaredType.unit if var.declaredType is not None else None)
        if var.type != "Real" or not unit or not isinstance(value, int | float):
            return repr(value)
        if unit in ("rad", "rad/s"):
            degrees = unit.replace("rad", "deg")
            return f"{value!r} {unit} ({math.degrees(value):.6g} {degrees})"
        return f"{value!r} {unit}"

    def set(self, ref: str, value: bool | int | float | str, why: str, assign: bool = True) -> None:
        """Write ``value``; ``assign``: an event's value (restored when a fault ends)."""
        slave, var = self._resolve(ref)
        setter = {
            "Real": slave.fmu.setReal,
            "Boolean": slave.fmu.setBoolean,
            "String": slave.fmu.setString,
        }.get(var.type, slave.fmu.setInteger)
        try:
            setter([var.valueReference], [value])
        except FMICallException as exc:
            slave.failed(exc.status)
            raise CosimError(
                f"{why}: setting {ref} = {value!r} returned {STATUS_LABELS[exc.status]}"
            ) from None
        if isinstance(value, str):
            return  # a String is neither recorded nor restored
        if ref in self.index:
            self.z[self.index[ref]] = value
        if assign:
            self.assigned[ref] = float(value)


class _EventRun:
    """One event's state: when it fires, whether its condition held at the last point."""

    def __init__(self, event: Event, h: float) -> None:
        self.event = event
        self.n_fire = first_point(event.time, h) if event.time is not None else None
        self.was_true: bool | None = None  # the condition at the previous point
        self.fired = False


class _FaultRun:
    """One fault's state; :meth:`deliver` turns the gathered value into the delivered one.

    A feedthrough is given its inputs twice at a point (after its sources stepped, then
    as it steps): the second delivery at one point is the same delivery again, with the
    point's draw and without another step of the delay's history."""

    def __init__(self, fault: Fault, h: float, index: Mapping[str, int]) -> None:
        self.fault = fault
        self.n_start = first_point(fault.start, h)
        self.n_stop = first_point(fault.stop, h) if fault.stop is not None else None
        self.rng = np.random.default_rng(fault.seed) if fault.seed is not None else None
        steps = fault.steps or 0
        self.history: collections.deque[float] = collections.deque(maxlen=steps + 1)
        self.hold_index = index[fault.hold_source] if fault.hold_source else None
        self.n_last: int | None = None  # the point of the latest delivery
        self.last: float | None = None  # the value delivered then
        self.before: float | None = None  # the value delivered at the point before it
        self.draw = 0.0  # noise, dropout: the random number of point n_last
        self.held: float | None = None  # stuck, plane-stuck, mass-jam: the value held

    def active(self, n: int) -> bool:
        return self.n_start <= n and (self.n_stop is None or n < self.n_stop)

    def state(self) -> tuple[Any, ...]:
        """What :meth:`deliver` changes (for an adaptive step's rollback)."""
        rng = None if self.rng is None else self.rng.bit_generator.state
        return list(self.history), self.n_last, self.last, self.before, self.draw, self.held, rng

    def misfit(self, saved: Any) -> str | None:
        """What makes ``saved`` (read from a file anyone may edit) not a :meth:`state` of
        this fault, or None: the delay's history and the values finite doubles, the point
        a whole number from 0, the random generator's state one its kind takes."""
        if not isinstance(saved, tuple) or len(saved) != 7:
            return "not a fault's state (seven entries)"
        history, n_last, last, before, draw, held, rng = saved
        if not isinstance(history, list) or len(history) > (self.history.maxlen or 0):
            return f"its history is not a list of at most {self.history.maxlen} values"
        if not all(_finite(v) for v in history) or not _finite(draw):
            return "its history or draw is not finite doubles"
        if not all(v is None or _finite(v) for v in (last, before, held)):
            return "its last, before or held value is neither null nor a finite double"
        if n_last is not None and not (type(n_last) is int and 0 <= n_last < _COUNT):
            return f"its point {n_last!r} is not a whole number from 0"
        if self.rng is None:
            return None if rng is None else "it holds a random generator the fault has none of"
        try:  # its own kind of generator takes it, or says why not
            type(self.rng.bit_generator)().state = rng
        except (TypeError, ValueError, KeyError, AttributeError, OverflowError):
            return "its random generator's state is not one of its kind"
        return None

    def set_state(self, saved: tuple[Any, ...]) -> None:
        history, self.n_last, self.last, self.before, self.draw, self.held, rng = saved
        self.history.clear()
        self.history.extend(history)
        if self.rng is not None:
            self.rng.bit_generator.state = rng

    def deliver(self, gathered: float, n: int, z: np.ndarray) -> float:
        """The value delivered at point n for ``gathered`` (the connection's own value)."""
        active = self.active(n)
        if n != self.n_last:  # the point's first delivery
            self.n_last, self.before = n, self.last
            if self.fault.kind == "delay":
                self.history.append(gathered)
            if active and self.rng is not None:
                self.draw = self._random()
        elif self.fault.kind == "delay":  # the same delivery again, gathered anew
            self.history[-1] = gathered
        value = self._faulty(gathered, z) if active else gathered
        self.last = value
        return value

    def _random(self) -> float:
        """noise: a draw of N(0, std); dropout: one of U[0, 1)."""
        rng = self.rng
        assert rng is not None
        if self.fault.kind == "noise":
            return float(rng.normal(0.0, self.fault.std))  # type: ignore[arg-type]
        return float(rng.random())

    def _faulty(self, gathered: float, z: np.ndarray) -> float:
        fault = self.fault
        kind = fault.kind
        if kind in ("stuck", "plane-stuck", "mass-jam"):
            if self.held is None:  # the present value when the fault starts
                if self.hold_index is not None:
                    self.held = float(z[self.hold_index])
                else:
                    self.held = self.before if self.before is not None else gathered
            return self.held
        if kind == "thruster-off":
            return 0.0
        if kind == "gain":
            return gathered * fault.value  # type: ignore[operator]
        if kind == "bias":
            return gathered + fault.value  # type: ignore[operator]
        if kind == "noise":
            return gathered + self.draw
        if kind == "delay":
            return self.history[0]  # `steps` deliveries ago (the first one before that)
        lost = self.draw < fault.probability  # type: ignore[operator]
        return self.before if lost and self.before is not None else gathered  # dropout


def replay(
    faults: Sequence[Fault],
    h: float,
    points: Sequence[int],
    gathered: np.ndarray,
    held: np.ndarray | None = None,
) -> np.ndarray:
    """What ``faults`` (all on one target, in file order) deliver to it at the points
    ``points`` (n, increasing, one delivery each) from the ``gathered`` values (the
    connection's own value at each), as :meth:`Timeline.deliver` does in a run, the same
    code: a report draws from a run's rows what its faults made of the recorded sources.
    ``h``: the points' spacing (s); ``held``: the value of a mass-jam's ``hold_source`` at
    each point (else that fault holds the gathered value)."""
    z = np.zeros(1)  # the hold source's present value, as the master's z holds it
    if held is None:
        faults = [dataclasses.replace(f, hold_source=None) for f in faults]
    runs = [_FaultRun(f, h, {f.hold_source: 0} if f.hold_source else {}) for f in faults]
    delivered = np.empty(len(points))
    for i, n in enumerate(points):
        value = float(gathered[i])
        if held is not None:
            z[0] = held[i]
        for run in runs:
            value = run.deliver(value, n, z)
        delivered[i] = value
    return delivered


def _due_by_point(events: list[_EventRun]) -> dict[int, list[_EventRun]]:
    """The time events by the point they fire at, in scenario order at each point."""
    due: dict[int, list[_EventRun]] = {}
    for timed in events:
        if timed.n_fire is not None:
            due.setdefault(timed.n_fire, []).append(timed)
    return due


def _place_faults(
    scenario: Scenario, faults: list[_FaultRun]
) -> tuple[dict[str, list[tuple[int, _FaultRun]]], list[_FaultRun]]:
    """Where each fault acts: a fault on a connection's target, by the target's instance,
    with the target's slot in that instance's Real input buffer
    (:meth:`cosim.engine.slave.Slave.bind`); a fault on an unconnected input, held apart."""
    on_inputs: dict[str, list[tuple[int, _FaultRun]]] = {}
    held: list[_FaultRun] = []
    driven = [c.target for c in scenario.connections]
    for run in faults:
        target = run.fault.target
        if target in driven:
            instance = target.split(".", 1)[0]
            inst = scenario.instances[instance]
            mine = [  # the instance's Real input buffer
                c
                for c in driven
                if c.split(".", 1)[0] == instance
                and inst.variable(c.split(".", 1)[1]).type == "Real"
            ]
            on_inputs.setdefault(instance, []).append((mine.index(target), run))
        else:
            held.append(run)
    return on_inputs, held


class Timeline:
    """The events and faults of one run (see the module docstring)."""

    def __init__(
        self,
        scenario: Scenario,
        slaves: Mapping[str, Slave],
        index: Mapping[str, int],
        z: np.ndarray,
        live: LiveControl | None = None,
        h: float | None = None,
    ) -> None:
        self.h = scenario.coupling.step if h is None else h  # s, point n is at n h
        self.z = z
        self.epoch = 0  # counts the points at which something jumped (extrapolation)
        self.live = live
        self.fired: list[dict[str, Any]] = []  # {"name", "time", "set"} per firing
        self.overrides: list[dict[str, Any]] = []  # {"name", "time", "set", "source"}
        self._taken = {e.name for e in scenario.events}  # names an override cannot have
        self.notes: list[tuple[float, str]] = []  # (t, text) not yet handed to the sinks
        self.handed: list[tuple[float, str]] = []  # (t, text) handed to them: a checkpoint
        # keeps them, so that a resumed run hands its sinks the notes before it again
        self._writer = _Writer(slaves, index, z)
        self._events = [_EventRun(e, self.h) for e in scenario.events]
        # a point looks only at what can act then: the time events due at it (by point),
        # the series and the `when` conditions; a time event's state never changes
        self._due = _due_by_point(self._events)
        self._series = [e for e in self._events if e.event.series is not None]
        self._stateful = [
            e for e in self._events if e.event.series is not None or e.event.when is not None
        ]
        self._ramps: dict[str, tuple[float, float, float, float]] = {}  # ref -> v0, v1, t0, T
        self._faults = [_FaultRun(f, self.h, index) for f in scenario.faults]
        self._sequential = scenario.coupling.algorithm != "jacobi"  # Gauss-Seidel, adaptive
        self._flags = [index[f"{FAULT_COLUMN_PREFIX}{f.name}"] for f in scenario.faults]
        # faults on connections, by target instance: (slot in its input buffer, fault), and
        # actuator faults on unconnected inputs
        self.on_inputs, self._held = _place_faults(scenario, self._faults)
        self._saved: dict[str, float] = {}  # the held faults' inputs before they started
        multiples = scenario.coupling.step_multiples
        self._step = scenario.coupling.step  # s
        self._receivers = _receivers(scenario)
        self._multiples = multiples
        # per instance: the points at which its input history starts again, because a
        # source an event wrote to reaches it there (:meth:`epoch_of`), and how often it did
        self._restart_at: dict[str, set[int]] = {}
        self._restarts: dict[str, int] = {}
        # a `when` on a slow instance's output (step multiple k) is evaluated at that
        # instance's own points only: in between, z holds its value from the end of the
        # step it is in, which lies ahead of t_n
        points = round(scenario.coupling.step / self.h)  # points per communication step
        self._conditions = [
            (e, when, k * points if (k := multiples.get(when.ref.split(".", 1)[0], 1)) > 1 else 1)
            for e in self._events
            if (when := e.event.when) is not None
        ]

    def epoch_of(self, instance: str, n: int) -> int:
        """The epoch of ``instance``'s input history as it takes its inputs at point n: it
        changes at every point where something jumped (:attr:`epoch`), and again at the
        first point at or after n where a jump an event caused in a source instance's
        outputs reaches it (:meth:`_source_jumps`), so that no input is extrapolated
        across that jump."""
        pending = self._restart_at.get(instance)
        if pending:
            passed = {point for point in pending if point <= n}
            if passed:
                pending -= passed
                self._restarts[instance] = self._restarts.get(instance, 0) + 1
        return self.epoch + self._restarts.get(instance, 0)

    def _source_jumps(self, source: str, n: int) -> None:
        """Something was written to ``source`` at point n: its outputs may jump when it
        next steps. An instance that takes them from a later point than that step's start
        (Jacobi, or it steps before ``source`` in the Gauss-Seidel order) restarts its
        input history where they reach it: the point after that step's start."""
        k = self._multiples.get(source, 1)
        period = k * round(self._step / self.h) if k > 1 else 1  # points between its steps
        steps_at = -(-n // period) * period  # its first step from n on
        for receiver, late in self._receivers.get(source, {}).items():
            point = steps_at + 1 if late else steps_at
            if point > n:
                self._restart_at.setdefault(receiver, set()).add(point)

    def points(self) -> list[int]:
        """The points n at which something is due to happen whatever the values: time
        events, the times of a series, faults starting and stopping (an adaptive step
        ends on each)."""
        due = {run.n_fire for run in self._events if run.n_fire is not None}
        for run in self._events:
            if run.event.series is not None:
                due |= {first_point(t, self.h) for t in run.event.series.times}
        for fault in self._faults:
            due |= {n for n in (fault.n_start, fault.n_stop) if n is not None}
        return sorted(due)

    def snapshot(self) -> tuple[Any, ...]:
        """Everything :meth:`at` and :meth:`deliver` change, for :meth:`restore` (the
        adaptive algorithm rolls a rejected step back)."""
        faults = [r.state() for r in self._faults]
        return (
            len(self.fired), len(self.overrides), len(self.notes), self.epoch,
            [(r.was_true, r.fired) for r in self._stateful], dict(self._ramps), faults,
            dict(self._saved), dict(self._writer.assigned),
            {name: set(points) for name, points in self._restart_at.items()},
            dict(self._restarts),
        )  # fmt: skip

    def restore(self, saved: tuple[Any, ...]) -> None:
        """Back to :meth:`snapshot`'s state (the FMUs' own values are restored apart)."""
        fired, overrides, notes, self.epoch, events, ramps, faults, kept, assigned, *rest = saved
        restart_at, restarts = rest
        self._restart_at = {name: set(points) for name, points in restart_at.items()}
        self._restarts = dict(restarts)
        del self.fired[fired:], self.overrides[overrides:], self.notes[notes:]
        for event, (was_true, done) in zip(self._stateful, events, strict=True):
            event.was_true, event.fired = was_true, done
        self._ramps = dict(ramps)
        for fault, state in zip(self._faults, faults, strict=True):
            fault.set_state(state)
        self._saved = dict(kept)
        self._writer.assigned = dict(assigned)

    def misfit(self, saved: Any) -> str | None:
        """What makes ``saved`` (read from a checkpoint anyone may edit) not a
        :meth:`snapshot` of this timeline, or None (one line, naming the entry): its counts
        whole numbers from 0, an event state (was true, fired) per event, ramps on the
        events' ramped variables as four finite doubles, a state per fault that fits it
        (:meth:`_FaultRun.misfit`), the values held and assigned as finite doubles of this
        run's variables, the restarts of this run's instances."""
        own = self.snapshot()
        if not isinstance(saved, tuple) or len(saved) != len(own):
            return "its timeline (events and faults) is not this run's"
        counts, (events, ramps, faults, kept, assigned, restart_at, restarts) = saved[:4], saved[4:]
        if not all(_whole(c) for c in counts):
            return "its timeline's counts (events, overrides, notes, epoch) are not this run's"
        if not isinstance(events, list) or len(events) != len(own[4]) or not all(
            isinstance(e, tuple) and len(e) == 2 and e[0] in (None, True, False)
            and type(e[1]) is bool for e in events
        ):  # fmt: skip
            return f"its timeline's event states are not {len(own[4])} pairs (was true, fired)"
        ramped = {ref for e in self._events if e.event.ramp is not None for ref in e.event.set}
        if not _table(ramps, ramped, lambda v: isinstance(v, tuple) and len(v) == 4
                      and all(_finite(x) for x in v) and v[3] > 0):  # fmt: skip
            return "its timeline's ramps are not (from, to, start, duration) of ramped variables"
        if not isinstance(faults, list) or len(faults) != len(self._faults):
            return f"its timeline's fault states are not {len(self._faults)}"
        for run, state in zip(self._faults, faults, strict=True):
            reason = run.misfit(state)
            if reason is not None:
                return f"the state of fault {run.fault.name!r}: {reason}"
        held = {run.fault.target for run in self._held}
        if not _table(kept, held, _finite):
            return "its timeline's held inputs are not finite doubles of the faults' targets"
        written = {ref for e in self._events for ref in e.event.set}
        written |= {ref for e in self._series for ref in e.event.series.columns}  # type: ignore[union-attr]
        if not _table(assigned, written, _finite):
            return "its timeline's assigned values are not finite doubles of the events' variables"
        instances = set(self._writer.slaves)
        points = lambda v: isinstance(v, set) and all(_whole(p) for p in v)  # noqa: E731
        if not _table(restart_at, instances, points) or not _table(restarts, instances, _whole):
            return "its timeline's restarts are not whole numbers of this run's instances"
        return None

    def deliver(self, slave: Slave, n: int, again: bool = False) -> None:
        """Replace the gathered inputs of ``slave`` at point n by what its faults deliver.

        ``again``: a feedthrough given its inputs again after the instances stepped to
        point n. Under Jacobi that is point n's delivery ahead of its step (which then
        repeats it); under Gauss-Seidel the one it just stepped with, gathered anew."""
        inputs = slave.inputs
        for slot, run in self.on_inputs.get(slave.name, ()):
            point = run.n_last if again and self._sequential and run.n_last is not None else n
            inputs[slot] = run.deliver(float(inputs[slot]), point, self.z)

    def at(self, n: int) -> None:
        """Everything that happens at communication point n (see the module docstring)."""
        t = n * self.h
        for run in self._due.get(n, ()):
            self._fire(run.event, t)
        if self.live is not None:
            self._apply_overrides(n, t)
        self._advance_ramps(t)
        for run in self._series:
            self._apply_series(run, t)
        for run, condition, every in self._conditions:
            if n % every:
                continue
            now = condition.holds(self._writer.get(condition.ref))
            crossed = run.was_true is False and now
            run.was_true = now
            if crossed and (run.event.repeat or not run.fired):
                run.fired = True
                self._fire(run.event, t)
        self._fault_points(n, t)

    def _apply_overrides(self, n: int, t: float) -> None:
        """Fire every override queued since the last point as a time event at ``t`` (and,
        while the run is paused here, each one that arrives); tell each request's ticket."""
        live = self.live
        assert live is not None
        for ticket in live.take(n, t, self.z):
            k = len(self.overrides) + 1
            while f"{OVERRIDE_PREFIX}{k}" in self._taken:
                k += 1
            name = f"{OVERRIDE_PREFIX}{k}"
            self._taken.add(name)
            event = Event(name, time=t, set=ticket.values)
            try:
                self._fire(event, t, "override", f" from {ticket.source}")
            except CosimError as exc:
                live.failed(ticket, str(exc))
                raise
            self.overrides.append({"name": name, "time": shown_time(t, self.h),
                                   "set": ticket.values, "source": ticket.source})  # fmt: skip
            live.applied(ticket, name, t)
        self.notes += [(t, note) for note in live.take_notes()]

    def _fire(self, event: Event, t: float, what: str = "event", origin: str = "") -> None:
        why = f"{what} {event.name!r} at t = {seconds(t)} s"
        for ref, value in event.set.items():
            if event.ramp is not None:
                self._ramps[ref] = (self._writer.get(ref), float(value), t, event.ramp)
            else:  # a value set ends a ramp on it: the ramp would write over it
                self._ramps.pop(ref, None)
                self._writer.set(ref, value, why)
        self.fired.append({"name": event.name, "time": t, "set": dict(event.set)})
        self.epoch += 1
        for instance in {ref.split(".", 1)[0] for ref in event.set}:
            self._source_jumps(instance, round(t / self.h))
        told = ", ".join(
            f"{ref} = {self._writer.shown(ref, value)}" for ref, value in event.set.items()
        )
        ramp = f" (ramp over {event.ramp!r} s)" if event.ramp is not None else ""
        self.notes.append((t, f"{what} {event.name}{origin}: {told}{ramp}"))

    def _advance_ramps(self, t: float) -> None:
        for ref, (v0, v1, t0, duration) in list(self._ramps.items()):
            fraction = (t - t0) / duration
            if fraction <= 0.0:
                continue
            if fraction >= 1.0:
                del self._ramps[ref]
                self._writer.set(ref, v1, f"ramp to {ref} = {v1!r}")
            else:
                self._writer.set(ref, v0 + (v1 - v0) * fraction, f"ramp to {ref} = {v1!r}")

    def _apply_series(self, run: _EventRun, t: float) -> None:
        series = run.event.series
        times = series.times  # type: ignore[union-attr]
        if t < times[0] - point_slack(t, self.h):
            return
        values = {}
        linear = series.interpolation == "linear"  # type: ignore[union-attr]
        jumped: set[str] = set()  # instances a held value (or the first) stepped on
        for ref, column in series.columns.items():  # type: ignore[union-attr]
            if linear:
                value = float(np.interp(t, times, column))
            else:
                value = column[bisect.bisect_right(times, t + point_slack(t, self.h)) - 1]
            values[ref] = value
            if (not linear or not run.fired) and value != self._writer.get(ref):
                jumped.add(ref.split(".", 1)[0])
            self._writer.set(ref, value, f"series {run.event.name!r} at t = {seconds(t)} s")
        if jumped:  # as an event's value: no input is extrapolated across the step
            self.epoch += 1
            for instance in jumped:
                self._source_jumps(instance, round(t / self.h))
        if not run.fired:
            run.fired = True
            self.fired.append({"name": run.event.name, "time": t, "set": values})
            self.notes.append((t, f"event {run.event.name}: series from {series.path.name}"))  # type: ignore[union-attr]

    def _fault_points(self, n: int, t: float) -> None:
        for run, flag in zip(self._faults, self._flags, strict=True):
            self.z[flag] = 1.0 if run.active(n) else 0.0
            fault = run.fault
            if run.n_start == run.n_stop:  # between two points: never acts (a warning said)
                continue
            if n in (run.n_start, run.n_stop):
                self.epoch += 1
            if n == run.n_start:
                self.notes.append((t, f"fault {fault.name} starts: {fault.kind} on {fault.target}"))
            elif n == run.n_stop:
                self.notes.append((t, f"fault {fault.name} stops: {fault.kind} on {fault.target}"))
        for run in self._held:
            target, why = run.fault.target, f"fault {run.fault.name!r} at t = {seconds(t)} s"
            if n == run.n_start:  # what the input goes back to if no event sets it meanwhile
                self._saved.setdefault(target, self._writer.get(target))  # (before any fault)
            if n in (run.n_start, run.n_stop):
                self._source_jumps(target.split(".", 1)[0], n)
            if run.active(n):
                held = run.deliver(self._writer.get(target), n, self.z)
                self._writer.set(target, held, why, assign=False)
            elif n == run.n_stop and target in self._saved and not self._holding(target, n):
                saved = self._saved.pop(target)  # the last fault on it let go
                restored = self._writer.assigned.get(target, saved)
                self._writer.set(target, restored, why, assign=False)

    def _holding(self, target: str, n: int) -> bool:
        """Whether an actuator fault on the unconnected input ``target`` acts at point n."""
        return any(run.active(n) for run in self._held if run.fault.target == target)


_COUNT = 1 << 62  # beyond any count of points, events or restarts a run reaches


def _finite(value: Any) -> bool:
    return isinstance(value, float) and math.isfinite(value)


def _whole(value: Any) -> bool:
    """A count or point: a whole number from 0 (not a bool)."""
    return type(value) is int and 0 <= value < _COUNT


def _table(value: Any, keys: set[str], fits: Any) -> bool:
    """``value`` is a dict of some of ``keys``, each value ``fits``."""
    return isinstance(value, dict) and set(value) <= keys and all(map(fits, value.values()))


def _receivers(scenario: Scenario) -> dict[str, dict[str, bool]]:
    """source instance -> {instance it drives a Real input of: whether that instance takes
    the source's values from a later point than the source steps from (Jacobi, or it is
    before the source in the Gauss-Seidel order)}."""
    coupling = scenario.coupling
    position = {name: i for i, name in enumerate(coupling.order)}
    jacobi = coupling.algorithm == "jacobi"
    receivers: dict[str, dict[str, bool]] = {}
    for c in scenario.connections:
        source, target = c.source_instance, c.target_instance
        variable = scenario.instances[target].interface.variables[c.target_variable]
        if source != target and variable.type == "Real":
            late = jacobi or position[target] < position[source]
            receivers.setdefault(source, {})[target] = late
    return receivers
