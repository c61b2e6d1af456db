"""The error-controlled communication step (``[coupling] algorithm = "adaptive"``).

Step doubling with rollback, as MasterSim's error control does it (docs/coupling.md):
from a communication point t every instance's state is saved (``fmi2GetFMUstate``) with
the master's own (exchanged values, input-derivative histories, the timeline's events and
faults). The instances take one step of H in the Gauss-Seidel order (or Jacobi), the
exchanged values are kept; everything is restored and they take two steps of H / 2 (a
point, and a row, at t + H / 2). The difference estimates the error of the two half
steps (Richardson)::

    err = max_i |y_i(two halves) - y_i(one step)| / ((2^p - 1) tol (Y_i + 1e-3 nominal_i))

over every continuous Real value the master reads, Y_i the largest |y_i| of the run so
far (so a value is held to ``tol`` of its own size, the moving mass's 3 cm as much as the
distance run), nominal_i its FMU's ``nominal`` (1 if none). A discrete output
(``variability="discrete"``, like the autopilot's commands) is left out: a sampled value,
computed from the inputs at the start of its step, differs between one step and two
halves by the sampling itself, not by an error. p is the coupling's order
(:func:`coupling_order`): 2 when every instance with connected Real inputs takes their
derivatives, else 1. err <= 1 accepts the half steps (the instances are already at
t + H); a step that was not shortened and has err below 2^-(p + 1) doubles for the next
one. err > 1 restores the saved states and halves H (or more, by err^(-1 / (p + 1))) and
tries again. Steps are H = step 2^j, from ``step`` / 2^:data:`MIN_LEVEL` (taken without a
check when even that misses the tolerance: counted in the summary) to ``max_step``; every
point is a whole number of the smallest step (``grid_step``), so the events and faults
(``Timeline`` at that grid), the sample points of the instances with a step multiple k
(every k ``step``), and the stop time are points a step ends on. ``tol`` bounds the error
of each step: the run's error is larger where the loop carries errors on (docs/coupling.md
measures it).

Costs: an accepted step takes three doSteps per instance and a state save and restore, a
rejected one as many. The summary's ``coupling`` says how many of each were taken.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
from fmpy.fmi1 import FMICallException

from cosim.engine.points import check_finite, end_of_simulation, refresh
from cosim.engine.signals import StopRequest
from cosim.engine.slave import Slave, describe
from cosim.engine.timeline import Timeline
from cosim.errors import CosimError
from cosim.scenario.spec import Coupling, Scenario

if TYPE_CHECKING:
    from cosim.engine.points import RowBuffer

MIN_LEVEL = 10  # the smallest step is coupling.step / 2**MIN_LEVEL
SAFETY = 0.9  # of the step the error estimate proposes after a rejection
FLOOR = 1e-3  # of a value's nominal: the smallest magnitude its error is relative to


def grid_step(coupling: Coupling) -> float:
    """The smallest step (s): every point of an adaptive run is a multiple of it."""
    return coupling.step / 2**MIN_LEVEL


class _Stepper:
    """The instances of an adaptive run, stepped, saved and restored together."""

    def __init__(
        self,
        scenario: Scenario,
        order: list[Slave],
        z: np.ndarray,
        give: Callable[[Slave, int, float], None],
        timeline: Timeline | None,
    ) -> None:
        self.order, self.z, self.give, self.timeline = order, z, give, timeline
        self.grid = grid_step(scenario.coupling)
        self.jacobi = scenario.coupling.algorithm == "jacobi"
        self.period = {s.name: s.k * 2**MIN_LEVEL for s in order}  # grid points per step
        self.do_steps = dict.fromkeys(self.period, 0)
        self.current = order[0]  # the instance called last (a failure names it)
        self.through = [s for s in order if s.feeds_through]

    def advance(self, n: int, units: int) -> None:
        """Every instance due at point n steps ``units`` grid points (one with step
        multiple k steps k ``step`` when n is one of its sample points, else holds)."""
        t = n * self.grid
        due = [s for s in self.order if s.k == 1 or n % self.period[s.name] == 0]
        if self.jacobi:
            for slave in due:
                self.give(slave, n, t)
        for slave in due:
            self.current = slave
            if not self.jacobi:
                self.give(slave, n, t)
            span = units if slave.k == 1 else self.period[slave.name]
            slave.do_step(slave.c, t, (n + span) * self.grid - t, 1)
            self.do_steps[slave.name] += 1
            slave.read_outputs()
        refresh(self.through, self.give, n + units, (n + units) * self.grid)

    def save(self) -> tuple[Any, ...]:
        fmu_states = [s.fmu.getFMUstate() for s in self.order]
        rates = [s.input_rates.snapshot() if s.input_rates else None for s in self.order]
        timeline = self.timeline.snapshot() if self.timeline is not None else None
        return fmu_states, self.z.copy(), rates, timeline

    def restore(self, saved: tuple[Any, ...]) -> None:
        fmu_states, z, rates, timeline = saved
        for slave, state, rate in zip(self.order, fmu_states, rates, strict=True):
            slave.fmu.setFMUstate(state)
            if slave.input_rates is not None:
                slave.input_rates.restore(rate)
        self.z[:] = z
        if self.timeline is not None:
            self.timeline.restore(timeline)

    def free(self, saved: tuple[Any, ...]) -> None:
        for slave, state in zip(self.order, saved[0], strict=True):
            slave.fmu.freeFMUstate(state)


def coupling_order(scenario: Scenario, order: list[Slave]) -> int:
    """p: the order at which the coupling converges (see the module docstring): 1 with
    held inputs, 2 when every instance with connected Real inputs takes their derivatives
    (quadratic extrapolation included: a sampled controller's first-order hold, as the
    autopilot's, keeps the loop at second order)."""
    receivers = [s for s in order if s.n_inputs]
    extrapolated = all(s.input_rates is not None for s in receivers)
    return 2 if extrapolated and scenario.coupling.extrapolation_order else 1


def run(
    scenario: Scenario,
    order: list[Slave],
    index: Mapping[str, int],
    n_read: int,
    z: np.ndarray,
    rows: RowBuffer,
    stop: StopRequest,
    timeline: Timeline | None,
    give: Callable[[Slave, int, float], None],
) -> tuple[str | None, dict[str, Any]]:
    """Step an initialised run to its stop time (see the module docstring); returns the
    one-line error (None if none) and the figures of the steps taken."""
    stepper = _Stepper(scenario, order, z, give, timeline)
    control = _Control(scenario, order, index, n_read, timeline)
    record = np.asarray([index[c] for c in scenario.columns], dtype=np.intp)
    at = timeline.at if timeline is not None else _no_event
    filled, n, error = 0, 0, None
    try:
        at(0)
        filled = rows.push(filled, z[record], 0.0)
        check_finite(z[:n_read], index, 0.0)
        while n < control.last and stop.signum is None and rows.error is None:
            n, filled = _one_step(stepper, control, n, at, rows, filled, record)
    except FMICallException as exc:
        slave = stepper.current
        ended = end_of_simulation(slave, exc, z, record, rows, filled, n * stepper.grid)
        if ended is None:
            slave.failed(exc.status)
            error = describe(slave, exc.function, exc.status, n * stepper.grid)
        else:
            rows.ended, filled = ended
    except CosimError as exc:
        error = str(exc)
    rows.hand_off(filled)
    return error, control.summary(stepper)


def _one_step(
    stepper: _Stepper,
    control: _Control,
    n: int,
    at: Callable[[int], None],
    rows: RowBuffer,
    filled: int,
    record: np.ndarray,
) -> tuple[int, int]:
    """Take one accepted step from point n, retrying as the error asks; returns the new
    point and the rows filled."""
    z, grid = stepper.z, stepper.grid
    while True:
        units, wanted = control.units(n)
        saved = stepper.save()
        try:
            if units >= 2:
                stepper.advance(n, units)
                big = z[: control.n_read].copy()
                stepper.restore(saved)
                stepper.advance(n, units // 2)
                check_finite(z[: control.n_read], control.index, (n + units // 2) * grid)
                at(n + units // 2)
                middle = z[record].copy()
                stepper.advance(n + units // 2, units // 2)
                err = control.error(big, z[: control.n_read])
            else:
                stepper.advance(n, units)
                middle, err = None, 0.0
            check_finite(z[: control.n_read], control.index, (n + units) * grid)
            if control.judge(err, units, wanted):
                break
            stepper.restore(saved)
        finally:
            stepper.free(saved)
    if middle is not None:
        filled = rows.push(filled, middle, (n + units // 2) * grid)
    at(n + units)
    filled = rows.push(filled, z[record], (n + units) * grid)
    return n + units, filled


class _Control:
    """The step size: the level j of H = step 2^j, the points a step must end on, the
    error estimate and the counts."""

    def __init__(
        self,
        scenario: Scenario,
        order: list[Slave],
        index: Mapping[str, int],
        n_read: int,
        timeline: Timeline | None,
    ) -> None:
        coupling = scenario.coupling
        self.index, self.n_read = index, n_read
        self.tolerance = float(coupling.tolerance or 0.0)
        self.p = coupling_order(scenario, order)
        self.level = MIN_LEVEL  # H = 2^level grid points: coupling.step to start with
        max_step = coupling.max_step or coupling.step
        self.top = MIN_LEVEL + max(0, math.floor(math.log2(max_step / coupling.step) + 1e-9))
        self.last = round(scenario.stop_time / grid_step(coupling))
        self.points = [*(timeline.points() if timeline is not None else []), self.last]
        self.periods = sorted({s.k * 2**MIN_LEVEL for s in order if s.k > 1})
        nominal = np.ones(n_read)
        continuous = np.zeros(n_read, dtype=bool)  # the values the error is measured on
        for i, ref in enumerate(list(index)[:n_read]):
            instance, variable = ref.split(".", 1)
            var = scenario.instances[instance].variable(variable)
            nominal[i] = abs(float(var.nominal)) if var.nominal else 1.0
            continuous[i] = var.type == "Real" and var.variability == "continuous"
        self.nominal, self.continuous = nominal, continuous
        self.peak = np.zeros(n_read)  # the largest |value| of each so far
        self.accepted, self.rejected, self.forced = 0, 0, 0
        self.smallest, self.largest = math.inf, 0.0
        self.grid = grid_step(coupling)

    def units(self, n: int) -> tuple[int, int]:
        """(grid points of the next step from n, those the error asked for)."""
        wanted = 2**self.level
        ahead = bisect.bisect_right(self.points, n)
        limit = (self.points[ahead] if ahead < len(self.points) else self.last) - n
        for period in self.periods:
            limit = min(limit, (n // period + 1) * period - n)
        units = wanted if wanted <= limit else 2 ** int(math.log2(limit))
        return units, wanted

    def error(self, big: np.ndarray, halves: np.ndarray) -> float:
        """The scaled error estimate of the two half steps (module docstring)."""
        if not self.continuous.any():
            return 0.0
        np.maximum(self.peak, np.abs(halves), out=self.peak)
        scale = self.tolerance * (self.peak + FLOOR * self.nominal) * (2**self.p - 1)
        return float(np.max((np.abs(halves - big) / scale)[self.continuous]))

    def judge(self, err: float, units: int, wanted: int) -> bool:
        """Accept the step (and choose the next level) or ask for a retry."""
        if err <= 1.0 or units <= 2:
            self.accepted += 1
            self.forced += err > 1.0
            self.smallest = min(self.smallest, units * self.grid)
            self.largest = max(self.largest, units * self.grid)
            grow = units == wanted and err <= 2.0 ** -(self.p + 1)
            if grow and self.level < self.top:
                self.level += 1
            return True
        self.rejected += 1
        shrink = SAFETY * err ** (-1.0 / (self.p + 1))
        down = max(1, math.ceil(-math.log2(shrink)))
        self.level = max(1, int(math.log2(units)) - down)
        return False

    def summary(self, stepper: _Stepper) -> dict[str, Any]:
        return {
            "algorithm": "adaptive",
            "tolerance": self.tolerance,
            "order": self.p,
            "accepted_steps": self.accepted,
            "rejected_steps": self.rejected,
            "steps_over_tolerance": self.forced,
            "smallest_step_s": self.smallest if self.accepted else None,
            "largest_step_s": self.largest if self.accepted else None,
            "do_steps": dict(stepper.do_steps),
        }


def _no_event(n: int) -> None:
    """The timeline of a scenario without events or faults."""
