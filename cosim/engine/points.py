"""What the fixed-step loop (:mod:`cosim.engine.master`) and the adaptive one
(:mod:`cosim.engine.adaptive`) share at a communication point: the row buffer, giving an
instance its inputs, an FMU that ends the simulation, and the check of the exchanged
values."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Protocol

import numpy as np
from fmpy.fmi1 import FMICallException

from cosim.engine.rows import RowSink
from cosim.engine.slave import Slave, describe
from cosim.engine.timeline import Timeline
from cosim.errors import CosimError, seconds
from cosim.scenario.spec import Scenario
from cosim.scenario.timeline_spec import POINT_TOLERANCE


class RowBuffer:
    """The rows of a run, a chunk at a time: the loop fills ``slots`` (one view per row of
    the chunk buffer) and hands them to the sinks with :meth:`hand_off` when the chunk is
    full or ``interval`` s of wall clock have passed since the last hand-off. With a
    ``timeline`` (events or faults), each hand-off first gives the sinks that take them
    (``add_notes(notes)``, notes being (t in s, text)) the timeline's notes so far: events
    fired, faults started and stopped. Row n is at t = n ``grid`` (the communication step)
    unless the loop wrote its time into ``times`` (the adaptive algorithm's points, the
    time an FMU ended the simulation)."""

    def __init__(
        self,
        scenario: Scenario,
        sinks: list[RowSink],
        rows_per_chunk: int,
        interval: float,
        timeline: Timeline | None = None,
        grid: float | None = None,
    ) -> None:
        self.h = scenario.coupling.step if grid is None else grid
        self.stop_time = scenario.stop_time
        self.timeline = timeline
        self.buffer = np.empty((rows_per_chunk, len(scenario.columns)))
        self.slots = list(self.buffer)  # made once: the loop indexes a list, not the array
        self.times = np.full(rows_per_chunk, np.nan)  # NaN: the row's time is count h
        self.count = 0  # rows handed off
        self.sinks = sinks
        self.interval = interval
        self.final = np.full(len(scenario.columns), np.nan)
        self.time_reached = 0.0  # s, of the last row handed off
        self.error: str | None = None  # the first sink failure
        self.ended: str | None = None  # an FMU ended the simulation: who, and when

    def hand_off(self, filled: int) -> None:
        """Give the first ``filled`` rows of the buffer to every sink; a failing sink is
        dropped and its reason kept in ``error``."""
        if self.timeline is not None and self.timeline.notes:
            self._hand_off_notes()
        if not filled:
            return
        # t_n = n h, never accumulated (no drift), as the loop computes it
        times = np.arange(self.count, self.count + filled) * self.h
        given = self.times[:filled]
        if not np.isnan(given).all():
            times = np.where(np.isnan(given), times, given)
            self.times[:] = np.nan
        # the last point, N h, can miss the stop time by a rounding either way (7 x 0.1 s
        # is 0.7000000000000001 s, 3 x 0.3 s 0.8999999999999999 s): the stop time then,
        # as the FMUs were told it
        stop = self.stop_time
        if math.isclose(times[-1], stop, rel_tol=1e-13, abs_tol=POINT_TOLERANCE * self.h):
            times[-1] = stop
        values = self.buffer[:filled]
        for sink in list(self.sinks):
            try:
                sink.add_rows(times, values)
            except (OSError, CosimError) as exc:
                self.sinks.remove(sink)
                self.error = self.error or str(exc)
        self.final = values[-1].copy()
        self.time_reached = float(times[-1])
        self.count += filled

    def push(self, filled: int, row: np.ndarray, t: float) -> int:
        """Put ``row`` (recorded values at ``t``, s) into the chunk after ``filled`` rows,
        handing the chunk off when it is full; the rows now filled."""
        self.buffer[filled] = row
        self.times[filled] = t
        filled += 1
        if filled == len(self.slots):
            self.hand_off(filled)
            filled = 0
        return filled

    def _hand_off_notes(self) -> None:
        assert self.timeline is not None
        notes, self.timeline.notes = self.timeline.notes, []
        self.timeline.handed += notes
        for sink in list(self.sinks):
            try:
                sink.add_notes(notes)
            except (OSError, CosimError) as exc:
                self.sinks.remove(sink)
                self.error = self.error or str(exc)


class Give(Protocol):
    """What :func:`inputs_giver` returns."""

    def __call__(self, slave: Slave, n: int, t: float, again: bool = False) -> None: ...


def inputs_giver(z: np.ndarray, timeline: Timeline | None) -> Give:
    """``give(slave, n, t, again)``: set ``slave``'s connected inputs from z at point n
    (t = n h, s), its faults applied, and their derivatives when it takes them; ``again``:
    a feedthrough given its inputs again after a step (:func:`refresh`)."""
    take = z.take

    def give(slave: Slave, n: int, t: float, again: bool = False) -> None:
        take(slave.input_sources, out=slave.inputs)
        if timeline is not None:
            timeline.deliver(slave, n, again)
        slave.put_inputs()
        if slave.others:
            slave.set_others(z)
        if slave.input_rates is not None:
            epoch = timeline.epoch_of(slave.name, n) if timeline is not None else 0
            slave.input_rates.send(slave.inputs, t, epoch)

    return give


def refresh(slaves: list[Slave], give: Give, n: int, t: float) -> None:
    """Give each of ``slaves`` (instances with an output that feeds a connected input
    through) its inputs at point n (t, s) again and read its outputs: under Jacobi too a
    feedthrough then passes on the value of the same point."""
    for slave in slaves:
        give(slave, n, t, True)
        slave.read_outputs()


def end_of_simulation(
    slave: Slave,
    exc: FMICallException,
    z: np.ndarray,
    record: np.ndarray,
    rows: RowBuffer,
    filled: int,
    t: float,
    finish: Callable[[float], None] | None = None,
) -> tuple[str, int] | None:
    """After a call failed in the step from ``t`` (s): if ``slave`` ended the simulation
    (a doStep's Discard with ``fmi2Terminated``), its outputs at the time it reached become
    the last row if that time is past ``t`` (``finish``, given that time, first steps the
    instances that had not stepped yet in that step), and the line saying so and the rows
    now filled are returned; else None."""
    if exc.function != "fmi2DoStep" or exc.status != 2:
        return None
    reached = slave.ended_simulation()
    if reached is None:
        return None
    line = f"{slave.name} ended the simulation at t = {seconds(reached)} s"
    if reached <= t + 1e-9 * max(1.0, abs(t)):  # nothing after the last row
        return line, filled
    if finish is not None:
        finish(reached)
    if filled == len(rows.slots):  # the chunk is full: hand it off first
        rows.hand_off(filled)
        filled = 0
    slave.read_outputs()
    z.take(record, out=rows.slots[filled])
    rows.times[filled] = reached
    return line, filled + 1


def check_finite(exchanged: np.ndarray, index: Mapping[str, int], t: float) -> None:
    """Raise naming the first non-finite exchanged values (at ``t``, s)."""
    listed = _non_finite(exchanged, index)
    if listed:
        raise CosimError(f"non-finite value at t = {seconds(t)} s: {listed}")


def failure_reason(
    slave: Slave, exc: FMICallException, t: float, exchanged: np.ndarray, index: Mapping[str, int]
) -> str:
    """``slave``'s call failed at ``t`` (s): mark it failed and say why in one line, ending
    with the non-finite values the instances exchanged, if any, whose source an instance's
    refusal of its input (a Gauss-Seidel consumer, before the step's check) does not name."""
    slave.failed(exc.status)
    listed = _non_finite(exchanged, index)
    note = f" (non-finite values exchanged: {listed})" if listed else ""
    return describe(slave, exc.function, exc.status, t) + note


def _non_finite(exchanged: np.ndarray, index: Mapping[str, int]) -> str:
    bad = np.flatnonzero(~np.isfinite(exchanged))
    names = list(index)
    return ", ".join(f"{names[i]} = {exchanged[i]}" for i in bad[:5])
