"""The error-controlled communication step (``[coupling] algorithm = "adaptive"``).

Two estimates of a step's error (``[coupling] error_estimate``):

* ``"extrapolation"`` (the default): the instances take one step of H from t (states
  saved first) and the error is that of their extrapolated inputs at t + H against what
  the sources' outputs say they were (:mod:`cosim.engine.input_error`; Schierz, Arnold &
  Clauss 2012), err = max_i du_i / (tol (Y_i + 1e-3 nominal_i)) H / ``step`` over the
  inputs, Y_i the largest |value| of the input's source so far. The factor H / ``step``
  (1 at the scenario's step) makes err the error a step leaves in the states the inputs
  drive (an input off by du over a step of H moves them by about du H), so each step is
  held to the same local error, not to the same error per unit time: for a given
  number of steps that makes the sum of the local errors the smallest (local errors
  C_i H_i^k: equal ones give the least sum over a run of a given number of steps), and
  that sum is what an error never undone (an oscillation's phase) accumulates. On
  vert-1 and bs-3 it took fewer doSteps for a trajectory error than the input's error
  alone (docs/coupling.md). One doStep per instance and attempt; err > 1
  restores the states and retries. k below is q + 2, q the lowest degree of the inputs'
  extrapolation (0 held, 2 quadratic: du is O(H^(q + 1))); steps are from one grid point
  up.
  Evenly spaced points: an accepted step's successor is RATIO_MIN to RATIO_MAX (0.8 to
  1.1) times it (never more than twice the step taken last, after a step shortened to
  reach a point). The extrapolation's derivatives are divided differences of the values
  the sources computed at the last points, and those carry errors that depend on the
  steps that led to them; through unevenly spaced points they are amplified, through
  slowly varying ones they stay smooth (docs/coupling.md, vert-1). Kinks: a step whose
  err (for the step asked for) is over 1 and over KINK times the last smooth step's is
  taken to cross a slope discontinuity of an input (a saturation, a boundary layer;
  Gear & Osterby, ACM TOMS 10 (1984) 23-44: there du falls only like H, err like H^2, so a
  shorter step buys little and the steps collapse); it is accepted as it is (counted in
  ``steps_over_tolerance`` and ``kinks`` where its own err is over 1: a step shortened to
  reach a point may meet the tolerance), the next step is as long and the error level
  the PI controller sees stays the smooth steps'.
* ``"doubling"``, the rest of this docstring:

Step doubling with rollback, as MasterSim's error control does it (docs/coupling.md):
from a communication point t every instance's state is saved (``fmi2GetFMUstate``) with
the master's own (exchanged values, input-derivative histories, the timeline's events and
faults). The instances take one step of H in the Gauss-Seidel order (or Jacobi), the
exchanged values are kept; everything is restored and they take two steps of H / 2 (a
point, and a row, at t + H / 2). Their difference estimates the local error of the two
half steps (Richardson; Hairer, Norsett & Wanner, *Solving Ordinary Differential
Equations I*, 2nd ed., Section II.4, "extrapolation")::

    le_i = |y_i(two halves) - y_i(one step)| / (2^p - 1)

over every continuous Real value the master reads. p is the coupling's order
(:func:`coupling_order`): 2 when every instance with connected Real inputs takes their
derivatives, else 1; a step's local error is then O(H^(p + 1)). Measured on vert-1
against steps of H / 32 from the same state: the one step's error is 4 times the halves'
(median) at steps up to 40 ms, and true / estimated is 0.7 to 1.3 (median) at steps of
10 to 80 ms, but 3.2 at 160 ms, where the asymptotic order no longer holds. A discrete
output (``variability="discrete"``, like the autopilot's commands) is left out: a sampled
value, computed from the inputs at the start of its step, differs between one step and
two halves by the sampling itself, not by an error.

The error is per step, relative to each value's size::

    err = max_i le_i / (tol (Y_i + 1e-3 nominal_i))

Y_i the largest |y_i| of the run so far (a value is held to ``tol`` of its own size, the
moving mass's 3 cm as much as the distance run), nominal_i its FMU's ``nominal`` (1 if
none; the floor keeps a value that has been 0 so far from asking for an exact 0). Not
per unit step (le_i <= tol Y_i H / T): the plant has kinks (the mass reaching its speed
limit or its stop, the thruster saturating) where a step's error is O(H^2) whatever the
coupling, and per unit step shrinks every step across one to the grid (on vert-1 it
took about 2.5 times the doSteps of error per step for the same trajectory error).

err <= 1 accepts the half steps (the instances are already at t + H); the next step is
Gustafsson's PI controller (ACM TOMS 17 (1991) 533-554; the form of Hairer & Wanner,
*Solving ODEs II*, Section IV.2, as in their DOPRI5)::

    H_next = H * clip(SAFETY * err^(-0.7 / k) * err_prev^(0.4 / k), FAC_MIN, FAC_MAX)

with k = p + 1 the order of err in H. err > 1 restores the saved states and retries with
H * max(FAC_MIN, SAFETY err^(-1/k)) (and the step after a rejection does not grow).
Local extrapolation (continuing from the Richardson-improved values) is not done: an
FMU's state cannot be set to them.

Steps are whole numbers of the smallest step (``grid_step``: ``step`` / 2^:data:`MIN_LEVEL`),
from two of them (taken without a check when even that misses the tolerance: counted in
the summary) to ``max_step``; the events and faults (``Timeline`` at that grid), the sample
points of the instances with a step multiple k (every k ``step``), the sample times of an
autopilot with a ``sample_period`` (our digital autopilot: the first grid point at or after
each multiple of it) and the stop time are points a step ends on (a step shortened to
reach one is judged as if it had been the step asked for, its err scaled by
(asked / taken)^k, so the next step does not start small). A sample time less than two
steps ahead is reached in two even steps, not a whole step and a sliver: the sliver (down
to one grid point) and the steps regrowing from it cost steps at every sample, of every
instance (a second vehicle's too, which steps with the sampling one).
The first step is ``step``.

Discard: an instance that answers a doStep with fmi2Discard without ending the simulation
(FMI 2.0, 4.2.3: "the master should retry the simulation with a shorter communication
step size") has the attempt rolled back and retried at FAC_MIN of its length (counted in
``rejected_steps`` and ``discarded_steps``); at the shortest step the Discard fails the
run, as it does at a fixed step.

Costs: an attempted step takes three doSteps per instance and a state save and restore,
a rejected one as many: the summary's ``coupling`` counts them. Step doubling pays 1.5
doSteps per half step; it beats a fixed step where the step the error allows varies
through the run by more than that (docs/coupling.md measures vert-1 and bs-3, with both
estimates).
"""

from __future__ import annotations

import bisect
import contextlib
import math
from collections.abc import Callable, Iterator, Mapping
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import fmi2Discard

from cosim.engine.input_error import InputError
from cosim.engine.points import (
    Give,
    check_finite,
    end_of_simulation,
    failure_reason,
    refresh,
)
from cosim.engine.signals import StopRequest
from cosim.engine.slave import Slave
from cosim.engine.timeline import Timeline
from cosim.errors import CosimError
from cosim.scenario.spec import Coupling, Scenario, sample_period
from cosim.scenario.timeline_spec import first_point

if TYPE_CHECKING:
    from cosim.engine.points import RowBuffer

_Kept = TypeVar("_Kept")  # what a caller of _until_accepted keeps of an accepted step

MIN_LEVEL = 10  # the smallest step is coupling.step / 2**MIN_LEVEL
SAFETY = 0.9  # of the step the error estimate proposes
FAC_MIN, FAC_MAX = 0.2, 2.0  # the most a step shrinks or grows at once (Hairer I, II.4)
# extrapolation estimate (module docstring): the most an accepted step's successor shrinks
# and grows (the extrapolation's points stay evenly spaced), and how far above the error
# level of the smooth steps before it a step's err marks a kink
RATIO_MIN, RATIO_MAX, KINK = 0.8, 1.1, 10.0
PI_GAINS = (0.7, 0.4)  # Gustafsson's exponents, times 1 / k (module docstring)
FLOOR = 1e-3  # of a value's nominal: the smallest magnitude its error is relative to


def grid_step(coupling: Coupling) -> float:
    """The smallest step (s): every point of an adaptive run is a multiple of it."""
    return coupling.step / 2**MIN_LEVEL


SAMPLE_SLACK = 1e-9  # of a sample period: a time this close before a multiple is at it


def sample_periods(scenario: Scenario) -> list[float]:
    """The periods (s) of the instances that sample at times of their own: our autopilot
    with a ``sample_period`` > 0 (its digital laws) samples at the first doStep at or after
    each multiple of it (:func:`cosim.scenario.spec.sample_period`: another FMU's value of
    that name is not taken for one)."""
    periods = (sample_period(inst) for inst in scenario.instances.values())
    return sorted({period for period in periods if period > 0.0})


def next_sample_point(n: int, period: float, grid: float) -> int:
    """The first grid point (``grid`` s apart) after point n at or after a multiple of
    ``period`` (s) that point n is before: where a step must end for the sample due
    after t_n to be taken at its time."""
    multiple = math.floor(n * grid / period + SAMPLE_SLACK) + 1
    return max(n + 1, first_point(multiple * period, grid))


def points_step(coupling: Coupling) -> float:
    """How far apart (s) the points are at which a run applies events and faults: an
    adaptive run's :func:`grid_step`, else the communication step."""
    return grid_step(coupling) if coupling.algorithm == "adaptive" else coupling.step


class _Stepper:
    """The instances of an adaptive run, stepped, saved and restored together."""

    def __init__(
        self,
        scenario: Scenario,
        order: list[Slave],
        z: np.ndarray,
        give: Give,
        timeline: Timeline | None,
    ) -> None:
        self.order, self.z, self.give, self.timeline = order, z, give, timeline
        self.grid = grid_step(scenario.coupling)
        self.jacobi = scenario.coupling.algorithm == "jacobi"
        self.period = {s.name: s.k * 2**MIN_LEVEL for s in order}  # grid points per step
        self.last = round(scenario.stop_time / self.grid)  # the stop time's grid point
        self.do_steps = dict.fromkeys(self.period, 0)
        self.current = order[0]  # the instance called last (a failure names it)
        self.through = [s for s in order if s.feeds_through]
        self.inputs: InputError | None = None  # the extrapolation estimator's bookkeeping

    def advance(self, n: int, units: int) -> None:
        """Every instance due at point n steps ``units`` grid points (one with step
        multiple k steps k ``step`` when n is one of its sample points, else holds; its
        last step ends at the stop time, as a fixed-step run's does)."""
        t = n * self.grid
        due = [s for s in self.order if s.k == 1 or n % self.period[s.name] == 0]
        if self.jacobi:
            for slave in due:
                self._give(slave, n, units)
        for slave in due:
            self.current = slave
            if not self.jacobi:
                self._give(slave, n, units)
            span = self._span(slave, n, units)
            slave.do_step(slave.c, t, (n + span) * self.grid - t, 1)
            self.do_steps[slave.name] += 1
            slave.read_outputs()
        refresh(self.through, self.give, n + units, (n + units) * self.grid)

    def _span(self, slave: Slave, n: int, units: int) -> int:
        """The grid points ``slave``, due at point n, steps: ``units``, or its own step
        (multiple k) cut at the stop time."""
        return units if slave.k == 1 else min(self.period[slave.name], self.last - n)

    def _give(self, slave: Slave, n: int, units: int) -> None:
        self.give(slave, n, n * self.grid)
        if self.inputs is not None:
            self.inputs.took(slave, n, self._span(slave, n, units))

    def save(self) -> tuple[Any, ...]:
        """Every instance's state (fmi2GetFMUstate) and the master's; when an instance
        cannot save its state, those already taken are freed and its failure raised (it
        is then :attr:`current`, which the run's error names)."""
        fmu_states: list[Any] = []
        try:
            for slave in self.order:
                self.current = slave
                fmu_states.append(slave.fmu.getFMUstate())
        except FMICallException:  # (its state was not taken: nothing of it to free)
            self.free((fmu_states,), failed=self.current)
            raise
        rates = [s.input_rates.snapshot() if s.input_rates else None for s in self.order]
        timeline = self.timeline.snapshot() if self.timeline is not None else None
        inputs = self.inputs.snapshot() if self.inputs is not None else None
        return fmu_states, self.z.copy(), rates, timeline, inputs

    def restore(self, saved: tuple[Any, ...]) -> None:
        fmu_states, z, rates, timeline, inputs = saved
        if self.inputs is not None:
            self.inputs.restore(inputs)
        for slave, state, rate in zip(self.order, fmu_states, rates, strict=True):
            self.current = slave
            slave.fmu.setFMUstate(state)
            if slave.input_rates is not None:
                slave.input_rates.restore(rate)
        self.z[:] = z
        if self.timeline is not None:
            self.timeline.restore(timeline)

    def free(
        self, saved: tuple[Any, ...], failed: Slave | None = None, touch_failed: bool = False
    ) -> None:
        """Free the FMU states of ``saved`` (:meth:`save`'s, or its first states taken).
        After instance ``failed`` failed a call (:meth:`freeing`), the others' failures to
        free are ignored (the first failure is the one told), and its own state is left
        alone unless ``touch_failed`` (its status allows it: not after fmi2Fatal, or a
        number that is no status, after which nothing of it may be called, FMI 2.0, 4.2.4,
        nor after fmi2Pending, its step still running)."""
        for slave, state in zip(self.order, saved[0], strict=False):
            if failed is None:
                slave.fmu.freeFMUstate(state)
            elif slave is not failed or touch_failed:
                with contextlib.suppress(FMICallException):
                    slave.fmu.freeFMUstate(state)

    @contextlib.contextmanager
    def freeing(self, saved: tuple[Any, ...]) -> Iterator[None]:
        """Free ``saved`` as the block ends: after a call that failed in it, the state of
        the instance that made it (:attr:`current`) is freed only where its status allows
        (:meth:`free`)."""
        try:
            yield
        except FMICallException as exc:
            allowed = exc.status in (0, 1, fmi2Discard, 3)  # (OK, Warning, ..., Error)
            self.free(saved, failed=self.current, touch_failed=allowed)
            raise
        except BaseException:
            self.free(saved)
            raise
        self.free(saved)


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
    give: Give,
) -> tuple[str | None, dict[str, Any]]:
    """Step an initialised run to its stop time (see the module docstring); returns the
    one-line error (None if none) and the figures of the steps taken."""
    stepper = _Stepper(scenario, order, z, give, timeline)
    control = _Control(scenario, order, index, n_read, timeline)
    one_step = _one_step
    if not control.doubling:
        jacobi = scenario.coupling.algorithm == "jacobi"
        stepper.inputs = InputError(order, index, jacobi, timeline, stepper.grid)
        one_step = _extrapolated_step
    record = np.asarray([index[c] for c in scenario.columns], dtype=np.intp)
    at = timeline.at if timeline is not None else _no_event
    filled, n, error = 0, 0, None
    try:
        at(0)
        filled = rows.push(filled, z[record], 0.0)
        check_finite(z[:n_read], index, 0.0)
        while n < control.last and stop.signum is None and rows.error is None:
            n, filled = one_step(stepper, control, n, at, rows, filled, record)
    except FMICallException as exc:
        slave = stepper.current
        ended = end_of_simulation(slave, exc, z, record, rows, filled, n * stepper.grid)
        if ended is None:
            error = failure_reason(slave, exc, n * stepper.grid, z[:n_read], index)
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

    def attempt(units: int, saved: tuple[Any, ...]) -> tuple[float, np.ndarray | None]:
        """The step of ``units`` and, where it has a middle point, the same in two halves
        from ``saved``: their difference and the row at the middle (else 0 and None)."""
        half = units // 2
        if half >= 1:
            stepper.advance(n, units)
            big = z[: control.n_read].copy()
            stepper.restore(saved)
            stepper.advance(n, half)
            check_finite(z[: control.n_read], control.index, (n + half) * grid)
            at(n + half)
            middle = z[record].copy()
            stepper.advance(n + half, units - half)
            err = control.error(big, z[: control.n_read])
        else:
            stepper.advance(n, units)
            middle, err = None, 0.0
        check_finite(z[: control.n_read], control.index, (n + units) * grid)
        return err, middle

    units, middle = _until_accepted(stepper, control, n, attempt)
    if middle is not None:
        filled = rows.push(filled, middle, (n + units // 2) * grid)
    at(n + units)
    filled = rows.push(filled, z[record], (n + units) * grid)
    return n + units, filled


def _extrapolated_step(
    stepper: _Stepper,
    control: _Control,
    n: int,
    at: Callable[[int], None],
    rows: RowBuffer,
    filled: int,
    record: np.ndarray,
) -> tuple[int, int]:
    """:func:`_one_step` judged by the inputs' extrapolation error
    (:mod:`cosim.engine.input_error`): one step of H, redone only when rejected."""
    z, inputs = stepper.z, stepper.inputs
    assert inputs is not None

    def attempt(units: int, saved: tuple[Any, ...]) -> tuple[float, None]:
        """The step of ``units`` and its inputs' extrapolation error, scaled."""
        stepper.advance(n, units)
        check_finite(z[: control.n_read], control.index, (n + units) * stepper.grid)
        sources, du = inputs.errors(stepper.order, z, n + units, control.k - 1)
        return control.scaled(z[: control.n_read], sources, du) * units / 2**MIN_LEVEL, None

    units, _ = _until_accepted(stepper, control, n, attempt)
    at(n + units)
    filled = rows.push(filled, z[record], (n + units) * stepper.grid)
    return n + units, filled


def _until_accepted(
    stepper: _Stepper,
    control: _Control,
    n: int,
    attempt: Callable[[int, tuple[Any, ...]], tuple[float, _Kept]],
) -> tuple[int, _Kept]:
    """The step from point n that ``control`` accepts: ``attempt(units, saved)`` takes a
    step of ``units`` grid points from the instances' state ``saved`` and returns its
    error estimate and what the caller keeps of it; a step the error rejects, or that an
    instance discards while a shorter one is possible, is undone and taken again as long
    as ``control`` now asks. Returns the accepted step's units and what was kept."""
    while True:
        units, wanted = control.units(n)
        saved = stepper.save()
        with stepper.freeing(saved):
            try:
                err, kept = attempt(units, saved)
                if control.judge(err, units, wanted):
                    return units, kept
                stepper.restore(saved)
            except FMICallException as exc:
                if not _shorter_after_discard(stepper, control, exc, units):
                    raise
                stepper.restore(saved)


def _shorter_after_discard(
    stepper: _Stepper, control: _Control, exc: FMICallException, units: int
) -> bool:
    """True if the step of ``units`` grid points that raised ``exc`` is to be retried
    shorter: a Discard from an instance that did not end the simulation, and a step longer
    than the shortest (module docstring)."""
    slave = stepper.current
    if exc.status != fmi2Discard or slave.ended_simulation() is not None:
        return False
    if not control.discarded(units):
        return False
    slave.messages.clear()  # the retry answers them; a later Discard is judged by its own
    return True


class _Control:
    """The step size (in grid points), the points a step must end on, the error estimate
    and the counts (module docstring)."""

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
        self.doubling = coupling.error_estimate == "doubling"
        if self.doubling:  # err is O(H^k): the local error's order
            self.k, self.min_units, self.fac_min = self.p + 1, 2, FAC_MIN
        else:  # the extrapolation's error (q + 1, q its lowest degree, held 0) times H
            q = min((s.input_rates.order if s.input_rates else 0 for s in order if s.n_inputs),
                    default=0)  # fmt: skip
            self.k, self.min_units, self.fac_min = q + 2, 1, RATIO_MIN
        self.fac_max = FAC_MAX if self.doubling else RATIO_MAX
        self.level: float | None = None  # err of the last smooth step (extrapolation)
        self.kinks = 0
        self.last_units = 2**MIN_LEVEL  # the last step accepted, grid points
        self.grid = grid_step(coupling)
        self.last = round(scenario.stop_time / self.grid)
        self.next = float(2**MIN_LEVEL)  # the step asked for, grid points: coupling.step
        self.top = max(2, round((coupling.max_step or coupling.step) / self.grid))
        self.err_prev, self.after_rejection = 1.0, False
        # the points a step ends on, sorted: those of events and faults after the stop time
        # (valid: a shorter --stop-time keeps the file) left out, the stop time's last
        due = timeline.points() if timeline is not None else []
        self.points = [*(point for point in due if point < self.last), self.last]
        self.periods = sorted({s.k * 2**MIN_LEVEL for s in order if s.k > 1})
        self.samples = sample_periods(scenario)  # s: a digital autopilot's
        nominal = np.ones(n_read)
        continuous = np.zeros(n_read, dtype=bool)  # the values the error is measured on
        for i, ref in enumerate(list(index)[:n_read]):
            instance, variable = ref.split(".", 1)
            var = scenario.instances[instance].variable(variable)
            nominal[i] = abs(float(var.nominal)) if var.nominal else 1.0
            continuous[i] = var.type == "Real" and var.variability == "continuous"
        self.nominal, self.continuous = nominal, continuous
        self.peak = np.zeros(n_read)  # the largest |value| of each so far
        self.accepted, self.rejected, self.forced, self.discards = 0, 0, 0, 0
        self.smallest, self.largest = math.inf, 0.0

    def units(self, n: int) -> tuple[int, int]:
        """(grid points of the next step from n, those the controller asked for)."""
        wanted = min(self.top, max(self.min_units, int(self.next)))
        if not self.doubling:  # the extrapolation's points stay evenly enough spaced
            wanted = min(wanted, int(FAC_MAX * self.last_units))
        ahead = bisect.bisect_right(self.points, n)
        limit = (self.points[ahead] if ahead < len(self.points) else self.last) - n
        for period in self.periods:
            limit = min(limit, (n // period + 1) * period - n)
        for sample in self.samples:
            to_sample = next_sample_point(n, sample, self.grid) - n
            if wanted < to_sample < 2 * wanted:  # two even steps, not a full one and a sliver
                to_sample = -(-to_sample // 2)
            limit = min(limit, to_sample)
        return min(wanted, limit), wanted

    def estimate(self, big: np.ndarray, halves: np.ndarray) -> np.ndarray:
        """The local error of the two half steps, each value in its unit (Richardson)."""
        return np.abs(halves - big) / (2**self.p - 1)

    def error(self, big: np.ndarray, halves: np.ndarray) -> float:
        """The scaled error of the two half steps (module docstring)."""
        if not self.continuous.any():
            return 0.0
        np.maximum(self.peak, np.abs(halves), out=self.peak)
        scale = self.tolerance * (self.peak + FLOOR * self.nominal)
        return float(np.max((self.estimate(big, halves) / scale)[self.continuous]))

    def scaled(self, values: np.ndarray, sources: np.ndarray, du: np.ndarray) -> float:
        """The scaled error of the extrapolated inputs ``du`` (each in its source's
        unit, ``sources`` the sources' indices in ``values``), as :meth:`error` scales."""
        np.maximum(self.peak, np.abs(values), out=self.peak)
        if not du.size:
            return 0.0
        scale = self.tolerance * (self.peak[sources] + FLOOR * self.nominal[sources])
        return float(np.max(du / scale))

    def judge(self, err: float, units: int, wanted: int) -> bool:
        """Accept the step (and choose the next) or ask for a retry with a shorter one."""
        k = self.k
        # a step shortened to reach a point: as if the step asked for had been taken
        asked = err * (wanted / units) ** k
        if err > 1.0 and units > self.min_units and not self._kink(asked):
            self.rejected += 1
            self.next = units * max(FAC_MIN, SAFETY * err ** (-1.0 / k))
            self.after_rejection = True
            return False
        self.accepted += 1
        self.forced += err > 1.0
        self.smallest = min(self.smallest, units * self.grid)
        self.largest = max(self.largest, units * self.grid)
        self.last_units, after_rejection = units, self.after_rejection
        self.after_rejection = False
        if self._kink(asked):  # the step goes on as it was: a shorter one gains little
            # counted where it missed the tolerance (among the forced steps): one shortened
            # to reach a point may meet it, though the step asked for would not
            self.kinks += err > 1.0
            self.next = float(wanted)
            return True
        err = max(asked, 1e-4)
        factor = SAFETY * err ** (-PI_GAINS[0] / k) * self.err_prev ** (PI_GAINS[1] / k)
        factor = min(self.fac_max, max(self.fac_min, factor))
        if after_rejection:
            factor = min(factor, 1.0)
        # (extrapolation: the fraction of a grid point carried on, so that steps of a few
        # points grow at RATIO_MAX too)
        carried = not self.doubling and int(self.next) == wanted
        self.next = (self.next if carried else wanted) * factor
        self.err_prev, self.level = err, asked
        return True

    def discarded(self, units: int) -> bool:
        """A step an instance discarded: retry at FAC_MIN of it (True), unless it is as
        short as a step may be (False)."""
        if units <= self.min_units:
            return False
        self.rejected += 1
        self.discards += 1
        self.next = max(float(self.min_units), units * FAC_MIN)
        self.after_rejection = True
        return True

    def _kink(self, asked: float) -> bool:
        """A step of the extrapolation estimate across a slope discontinuity: its err (for
        the step asked for) is over 1 and KINK times the last smooth step's."""
        if self.doubling or self.level is None:
            return False
        return asked > 1.0 and asked > KINK * max(self.level, 1e-3)

    def summary(self, stepper: _Stepper) -> dict[str, Any]:
        return {
            "algorithm": "adaptive",
            "error_estimate": "doubling" if self.doubling else "extrapolation",
            "tolerance": self.tolerance,
            "order": self.p,
            "accepted_steps": self.accepted,
            "rejected_steps": self.rejected,
            "discarded_steps": self.discards,
            "steps_over_tolerance": self.forced,
            "kinks": self.kinks,
            "smallest_step_s": self.smallest if self.accepted else None,
            "largest_step_s": self.largest if self.accepted else None,
            "do_steps": dict(stepper.do_steps),
        }


def _no_event(n: int) -> None:
    """The timeline of a scenario without events or faults."""
