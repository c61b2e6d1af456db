"""The co-simulation master: steps the FMU instances of a :class:`Scenario` with fmpy.

For a communication step h and N = stop_time / h steps::

    instantiate all -> setupExperiment + start values -> enter/exitInitializationMode
    read the outputs (row 0, t = 0)
    for n in 0 .. N-1, t = n h:
        jacobi:        every due instance takes its inputs from the outputs at t; then every
                       due instance does doStep(t, k h) and its outputs are read
        gauss-seidel:  in `coupling.order`, each due instance takes its inputs from the
                       latest outputs (including those of instances already stepped at t),
                       does doStep(t, k h), and its outputs are read
        check every exchanged value is finite; record row n + 1 (t = (n+1) h)
    terminate all -> freeInstance all

An instance with step multiple k is *due* when n is a multiple of k; it then steps k h
(shortened at the stop time) and holds its outputs in between (multi-rate). Row n holds
every instance's latest outputs once the due instances have advanced to t = n h; an
instance with an output that feeds a connected input through (ModelStructure) then takes
its inputs at t = n h once more and its outputs are read again, so under Jacobi too a
feedthrough passes on the value of the same point, not the one before.

Initialisation (FMI 2.0, section 4.2.4): every instance enters initialisation mode; then,
in ``coupling.order``, each takes its connected inputs from the latest outputs and its
outputs are read, pass after pass until no value changes (:data:`INIT_PASSES` at most),
so an output that feeds an input through (ModelStructure) starts consistent with its
source; then every instance exits initialisation mode and row 0 is read. Integer,
Enumeration and Boolean connections and recorded values travel as numbers (Booleans 0
and 1) beside the Real ones; with ``[coupling] extrapolation`` the instances that can
interpolate their inputs get their derivatives too (:mod:`cosim.engine.extrapolation`).
``algorithm = "adaptive"`` steps with :mod:`cosim.engine.adaptive` instead of the loop
below.

An instance whose doStep returns Discard with ``fmi2Terminated`` true ended the
simulation (FMI 2.0, section 4.2.3): the run ends there, complete, its last row at the
time that instance reached.

Why a loop of our own: ``fmpy.simulate_fmu`` runs one FMU, and ``fmpy.ssp`` has no
Gauss-Seidel order, multi-rate, per-step NaN check or partial results. The style follows
fmpy's ``simulateCS``. The hot path calls the FMUs' ``fmi2SetReal``/``fmi2DoStep``/
``fmi2GetReal`` C functions with every argument (value reference arrays, numpy buffers)
bound once (``Slave.put_inputs``/``advance``), checking the status as fmpy's wrappers do
(raising ``FMICallException``): a step builds no dict and no list.

The rows stream out as the run advances: they fill a buffer of ``rows_per_chunk`` rows that
is handed to the sinks (:mod:`cosim.engine.rows`) when full, and at least once every
``hand_off_interval`` of wall clock, so memory does not grow with the stop time and a
sink writing a file has it on disk within about a second. ``keep_rows`` also keeps every
row in memory (tests, analyses).

Before any FMU is instantiated, :func:`preflight` refuses what would hang a step: an
instance with a ``max_substep`` parameter (the plant's longest internal RK4 step) that would
take more than :data:`MAX_SUBSTEPS` sub-steps per communication step.

Failures after initialisation -- a non-OK status (fmpy raises on Discard, Error, Fatal), a
non-finite exchanged value, a sink that cannot write, a stop signal -- stop the run;
:func:`run` returns the rows so far with ``complete=False`` and a one-line ``error`` naming
the instance, the time and the FMU's logged reason. A signal (Ctrl-C, SIGTERM, SIGHUP)
only sets a flag checked once per step (:mod:`cosim.engine.signals`), so no
``KeyboardInterrupt`` is raised inside an FMU's Python code (pythonfmu would turn it into
fmi2Fatal and the host would crash).

A paced run (``pacer``, :mod:`cosim.engine.pacing`) releases communication point n at its
wall-clock deadline; a live run (``live``, :mod:`cosim.engine.live`) applies the overrides
queued by other threads at each point, publishes the point's values and waits while paused.
Both hook into the per-point call the loop already makes (``at``), so an unpaced run's loop
is the same as before.
"""

from __future__ import annotations

import functools
import math
import re
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from contextlib import nullcontext
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from fmpy.fmi1 import FMICallException

from cosim.engine import adaptive, checkpoint
from cosim.engine.extrapolation import InputRates
from cosim.engine.live import LiveControl
from cosim.engine.pacing import Pacer
from cosim.engine.points import (
    Give,
    RowBuffer,
    check_finite,
    end_of_simulation,
    failure_reason,
    inputs_giver,
    refresh,
)
from cosim.engine.rows import RUN_COMPLETE, RUN_INCOMPLETE, Note, RowSink, RowTable
from cosim.engine.signals import StopRequest, stop_on_signals
from cosim.engine.slave import Slave, describe, reasons, unzipped
from cosim.engine.timeline import Timeline
from cosim.errors import CosimError, seconds
from cosim.fmus.interface import check_binary, check_own_packages
from cosim.scenario.checks import Source
from cosim.scenario.coupling_graph import feedthrough
from cosim.scenario.spec import Scenario

INIT_PASSES = 50  # exchanges in initialisation mode before the values must have settled
# The stepping loop finds a NaN or an infinite exchanged value as x . 0 = NaN (one dot a
# step); numpy warns "invalid value encountered in dot" of the inf . 0 it is there to find,
# a line the run's user saw before the error naming the value. Ignored for this module's
# own calls only: a filter costs nothing per step, np.vdot (which does not warn) 0.3 us.
warnings.filterwarnings(
    "ignore", "invalid value encountered in dot", RuntimeWarning, re.escape(__name__) + "$"
)
ROWS_PER_CHUNK = 200  # rows handed to the sinks at a time
HAND_OFF_INTERVAL_S = 1.0  # ... and at least this often (wall clock), however slow the steps
MAX_SUBSTEPS = 10_000  # sub-steps per communication step beyond which a run is refused
SUBSTEP_PARAMETER = "max_substep"  # s, an FMU's longest internal step (AuvPlant has one)


@dataclass
class RunResult:
    """How a run ended. ``times``/``values`` hold every row only if the run kept them."""

    scenario: Scenario
    columns: tuple[str, ...]
    rows: int  # rows computed, t = 0 included
    time_reached: float  # s, the time of the last row
    final: np.ndarray  # (len(columns),) the last row, SI
    complete: bool
    error: str | None  # one line, None if complete
    wall_clock_s: float  # the stepping loop alone (including the sinks)
    time_started: float = 0.0  # s, where the loop started (a resumed run: its checkpoint)
    # s, the CPU time this process spent in the stepping loop (every thread: an FMU's own
    # too), which other processes' load inflates far less than the wall clock (benchmarks)
    cpu_clock_s: float = 0.0
    # s before the loop: "load_fmus" (unzip, load, instantiate, start values) and
    # "initialise" (enter/exit initialisation mode, where an FMU may compile its code)
    startup_s: dict[str, float] = field(default_factory=dict)
    stop_signal: int | None = None  # the signal that stopped the stepping, if any
    messages: dict[str, list[str]] = field(default_factory=dict)  # instance -> FMU log lines
    # instance -> FMU log lines logged, those beyond the last LOG_LINES_KEPT kept too
    messages_logged: dict[str, int] = field(default_factory=dict)
    events: list[dict[str, Any]] = field(default_factory=list)  # fired: name, time, set
    overrides: list[dict[str, Any]] = field(default_factory=list)  # + source (live runs)
    real_time: dict[str, Any] | None = None  # a paced run's figures (Pacer.summary)
    ended: str | None = None  # "<instance> ended the simulation at t = ... s", if one did
    coupling: dict[str, Any] = field(default_factory=dict)  # the steps taken (summary.json)
    times: np.ndarray | None = None  # (rows,) s, when kept
    values: np.ndarray | None = None  # (rows, len(columns)) SI, when kept

    def column(self, name: str) -> np.ndarray:
        """The recorded time series ``"<instance>.<variable>"`` (the run kept its rows)."""
        if self.values is None:
            raise CosimError(
                f"the rows of run {self.scenario.id!r} were not kept in memory: run it with "
                "keep_rows=True or read its results.csv"
            )
        return self.values[:, self.columns.index(name)]


def ending_note(result: RunResult) -> Note:
    """How ``result``'s run ended, as a note at the time of its last row (s): complete at
    its stop time or where an FMU ended it, or incomplete and why (the run's one-line
    error)."""
    t = result.time_reached
    if not result.complete:
        return t, f"{RUN_INCOMPLETE}{result.error or f'stopped at t = {seconds(t)} s'}"
    if result.ended is not None:
        return t, f"{RUN_COMPLETE}: {result.ended}"
    return t, f"{RUN_COMPLETE} at t = {seconds(t)} s (its stop time)"


@dataclass(frozen=True)
class _Layout:
    """Where every exchanged or recorded value lives, resolved once before the loop.

    ``z`` = [outputs read after every step, instance by instance | recorded inputs that no
    connection drives, read once after initialisation | the faults' ``fault.<name>``
    columns]; ``index``: "<inst>.<var>" (or the column) -> z.
    """

    read: dict[str, list[str]]  # instance -> variables read after each of its steps
    constants: list[str]  # "<instance>.<input>" recorded but never driven
    index: dict[str, int]

    @classmethod
    def of(cls, scenario: Scenario) -> _Layout:
        wanted = {c.source for c in scenario.connections} | set(scenario.record)
        wanted |= {f.hold_source for f in scenario.faults if f.hold_source is not None}
        read: dict[str, list[str]] = {}
        constants: list[str] = []
        for name, inst in scenario.instances.items():
            unconnected = set(scenario.unconnected_inputs(name))
            read[name] = []
            for var in inst.model_description.modelVariables:
                if f"{name}.{var.name}" not in wanted:
                    continue
                if var.causality == "input" and var.name in unconnected:
                    constants.append(f"{name}.{var.name}")
                else:
                    read[name].append(var.name)
            # the Real outputs first: one fmi2GetReal fills them (Slave.bind)
            read[name].sort(key=functools.partial(_not_real, inst))
        order = [f"{n}.{v}" for n, names in read.items() for v in names] + constants
        order += scenario.columns[len(scenario.record) :]  # the faults' columns, last
        return cls(read, constants, {ref: i for i, ref in enumerate(order)})

    @property
    def n_read(self) -> int:
        return sum(len(names) for names in self.read.values())


def _not_real(instance: Any, variable: str) -> bool:
    return bool(instance.variable(variable).type != "Real")


def preflight(scenario: Scenario, src: Source | None = None) -> None:
    """Refuse, before any FMU is loaded, a scenario whose FMUs lack a binary for this
    platform (:func:`cosim.fmus.interface.check_binary`), were built by an older auv-cosim
    into packages this process runs itself (:func:`~cosim.fmus.interface.check_own_packages`)
    or would hang in a step.

    An instance with a Real parameter ``max_substep`` (s) integrates a communication step
    of k h (an adaptive run's steps up to ``max_step``) in ceil(k h / max_substep)
    sub-steps (``plant_fmu.model.stepping.advance``);
    more than :data:`MAX_SUBSTEPS` is refused with the reason (one sub-step of the plant
    takes tens of microseconds, so 1e-9 s would take hours per step and ignore Ctrl-C),
    and so is a ``max_substep`` of 0 s (its declared min, which FMI 2.0 cannot state open).
    ``src`` is the scenario as loaded with the keys a caller's options set, as it gave
    them (:class:`~cosim.scenario.checks.Source`): a refusal they cause names them.
    """
    for inst in scenario.instances.values():
        check_own_packages(inst.fmu_path)
        check_binary(inst.fmu_path, inst.interface.model_identifier)
    src = src or Source(scenario.described)
    for name, inst in scenario.instances.items():
        var = {v.name: v for v in inst.variables("parameter")}.get(SUBSTEP_PARAMETER)
        if var is None or var.type != "Real":
            continue
        max_substep = scenario.start_value(name, SUBSTEP_PARAMETER)
        coupling = scenario.coupling
        step = coupling.step * coupling.step_multiples.get(name, 1)
        longest = "coupling.step"
        if coupling.max_step is not None and coupling.max_step > step:  # adaptive
            step, longest = coupling.max_step, "coupling.max_step"
        if not isinstance(max_substep, float):
            continue  # not a number: the FMU refuses it itself, with its own reason
        key = f"instances.{name}.start.{SUBSTEP_PARAMETER}"
        if not max_substep > 0.0:  # the FMU's min is 0: FMI 2.0 has no open bound
            raise src.error(
                key,
                f"{max_substep!r} is outside (0.0, inf], the range {SUBSTEP_PARAMETER} takes",
                causes=(key,),
            )
        substeps = step / max_substep  # inf for a subnormal max_substep: no ceil of it
        substeps = math.ceil(substeps - 1e-9) if math.isfinite(substeps) else substeps
        if substeps > MAX_SUBSTEPS:
            raise src.error(
                key if SUBSTEP_PARAMETER in inst.start else longest,
                f"{name}.{SUBSTEP_PARAMETER} = {max_substep!r} s would take {substeps:.3g} "
                f"sub-steps per communication step of {step!r} s; at most {MAX_SUBSTEPS} are "
                f"allowed (max_substep >= {step / MAX_SUBSTEPS:.3g} s)",
                causes=(key, longest, "coupling.algorithm"),  # the step compared, and its source
            )


def run(
    scenario: Scenario,
    sinks: Sequence[RowSink] = (),
    *,
    keep_rows: bool = True,
    stop: StopRequest | None = None,
    rows_per_chunk: int = ROWS_PER_CHUNK,
    hand_off_interval: float = HAND_OFF_INTERVAL_S,
    pacer: Pacer | None = None,
    live: LiveControl | None = None,
    on_phase: Callable[[str], None] | None = None,
    checkpoints: checkpoint.Checkpointing | None = None,
) -> RunResult:
    """Run ``scenario`` to its stop time (or the first failure), streaming its rows.

    ``sinks`` receive every row in order (:mod:`cosim.engine.rows`); the caller closes them.
    ``keep_rows`` also keeps the rows in the result (memory grows with the stop time).
    ``stop`` is the caller's :class:`StopRequest` (its signal handlers installed); without
    one, SIGINT/SIGTERM/SIGHUP are caught for the duration of the call. ``pacer`` paces
    the communication points on the wall clock, ``live`` takes overrides while it runs.
    ``on_phase`` is told what the run does before its loop: "loading FMUs", then
    "initialising" (a progress bar shows it); the result's ``startup_s`` says how long each
    took. ``checkpoints`` saves the run's state every so many steps and where a signal
    stops it, or resumes it from a saved state (:mod:`cosim.engine.checkpoint`).

    Raises :class:`CosimError` if the scenario is refused (:func:`preflight`) or an FMU
    cannot be set up (instantiation, start values, initialisation); every failure after
    that is reported in the returned result.
    """
    preflight(scenario)
    phase = on_phase or _no_phase
    table = RowTable(len(scenario.columns)) if keep_rows else None
    feed = [*sinks, table] if table is not None else list(sinks)
    layout = _Layout.of(scenario)
    z = np.zeros(len(layout.index))
    phase("loading FMUs")
    started = time.perf_counter()
    slaves = [
        Slave(inst, unzipped(inst.fmu_path), scenario.coupling.step_multiples[name])
        for name, inst in scenario.instances.items()
    ]
    by_name = {s.name: s for s in slaves}
    order = [by_name[name] for name in scenario.coupling.order]
    guard = stop_on_signals(StopRequest()) if stop is None else nullcontext(stop)
    with guard as stop_request:
        try:
            for slave in slaves:
                _bind(slave, scenario, layout, z)
                _set_up(slave, functools.partial(slave.load, scenario.stop_time))
            loaded = time.perf_counter()
            phase("initialising")
            _initialise(order, layout, z)
            startup = {"load_fmus": loaded - started, "initialise": time.perf_counter() - loaded}
            result = _step(scenario, order, layout, z, feed, stop_request,
                           rows_per_chunk, hand_off_interval, pacer, live,
                           checkpoints)  # fmt: skip
            result.startup_s = {**startup, **result.startup_s}
        finally:
            if live is not None:  # a request still waiting is answered: not applied
                live.close()
            for slave in slaves:
                slave.finish()
    # what the instances logged as they were terminated too (a failed fmi2Terminate)
    result.messages, result.messages_logged = _logged(order)
    if table is not None:
        result.times, result.values = table.table()
    return result


def _step(
    scenario: Scenario,
    order: list[Slave],
    layout: _Layout,
    z: np.ndarray,
    feed: list[RowSink],
    stop: StopRequest,
    rows_per_chunk: int,
    hand_off_interval: float,
    pacer: Pacer | None,
    live: LiveControl | None,
    checkpoints: checkpoint.Checkpointing | None = None,
) -> RunResult:
    """The stepping of an initialised run: the fixed-step loop or the adaptive one."""
    by_name = {s.name: s for s in order}
    timed = scenario.events or scenario.faults or live is not None
    h = scenario.coupling.step
    grid = adaptive.grid_step(scenario.coupling) if scenario.coupling.algorithm == "adaptive" else h
    timeline = Timeline(scenario, by_name, layout.index, z, live, grid) if timed else None
    rows = RowBuffer(scenario, feed, rows_per_chunk, hand_off_interval, timeline, grid)
    if scenario.coupling.algorithm == "adaptive":
        if live is not None or pacer is not None:
            raise CosimError("a paced or live run needs a fixed step: algorithm 'adaptive' "
                             "chooses its own")  # fmt: skip
        started, cpu_started = time.perf_counter(), time.process_time()
        give = inputs_giver(z, timeline)
        error, figures = adaptive.run(
            scenario, order, layout.index, layout.n_read, z, rows, stop, timeline, give
        )
        result = _result(scenario, order, rows, error, stop, time.perf_counter() - started,
                         time.process_time() - cpu_started)  # fmt: skip
        result.coupling = figures
    else:
        at: Callable[[int], None] = timeline.at if timeline is not None else _no_event
        if live is not None:
            live.bind(layout.index, stop, pacer)
        if live is not None or pacer is not None:
            at = _live_point(at, pacer, live, z, h, stop)
        saver, replay = None, {}
        if checkpoints:
            replaying = time.perf_counter()
            saver = _Saver(order, z, rows, timeline, checkpoints, layout, scenario.columns)
            if saver.resumed:  # its rows up to the checkpoint handed to the sinks again
                replay = {"replay": time.perf_counter() - replaying}
        result = _loop(scenario, order, layout, z, rows, stop, timeline, at, saver)
        result.startup_s = replay
        result.coupling = {
            "algorithm": scenario.coupling.algorithm,
            "step_s": h,
            "extrapolation": scenario.coupling.extrapolation,
            "input_derivatives": [s.name for s in order if s.input_rates is not None],
        }
    result.events = timeline.fired if timeline is not None else []
    result.overrides = timeline.overrides if timeline is not None else []
    result.real_time = pacer.summary() if pacer is not None else None
    return result


def _bind(slave: Slave, scenario: Scenario, layout: _Layout, z: np.ndarray) -> None:
    inst, read = slave.instance, layout.read[slave.name]
    targets = [c for c in scenario.connections if c.target_instance == slave.name]
    start = layout.index[f"{slave.name}.{read[0]}"] if read else 0
    inputs = [(inst.variable(c.target_variable), layout.index[c.source]) for c in targets]
    order = scenario.coupling.extrapolation_order
    real = [v.valueReference for v, _ in inputs if v.type == "Real"]
    multiples = scenario.coupling.step_multiples
    sources = [
        c.source_instance for c in targets if inst.variable(c.target_variable).type == "Real"
    ]
    # a source whose steps do not end at each of this instance's points: stairs, held
    held = [i for i, source in enumerate(sources) if slave.k % multiples[source]]
    wanted = order and slave.interpolates and len(held) < len(real)
    rates = InputRates(slave.fmu, real, order, slave.handle, held) if wanted else None
    slave.bind(inputs, [inst.variable(v) for v in read], z[start : start + len(read)], rates)
    driven = {c.target_variable for c in targets}
    slave.feeds_through = any(
        driven & inputs for inputs in feedthrough(inst.model_description).values()
    )


def _set_up(slave: Slave, call: Callable[[], None]) -> None:
    """Run one set-up ``call`` of ``slave`` (load, initialisation), a failure turned into
    a one-line :class:`CosimError` naming the instance and the FMU's reason."""
    try:
        call()
    except FMICallException as exc:
        slave.failed(exc.status)
        raise CosimError(describe(slave, exc.function, exc.status, 0.0)) from None
    except CosimError:
        raise
    except Exception as exc:  # fmpy raises a plain Exception when instantiation fails
        file = slave.instance.fmu_path.name
        tool = (
            f' ({file} declares needsExecutionTool="true": is the tool it needs installed '
            "and running?)"
            if slave.instance.model_description.coSimulation.needsExecutionTool
            else ""
        )
        raise CosimError(
            f"{slave.name}: cannot set up {file}: {exc}{reasons(slave)}{tool}"
        ) from None


def _initialise(order: list[Slave], layout: _Layout, z: np.ndarray) -> None:
    """Initialisation mode for every instance, the connected values exchanged until they
    settle (see the module docstring), then row 0's values: every output, and the
    recorded inputs no connection drives."""
    for slave in order:
        _set_up(slave, slave.enter_initialisation)
    for _ in range(INIT_PASSES):
        before = z.copy()
        for slave in order:
            _set_up(slave, functools.partial(slave.exchange, z))
        if np.array_equal(before, z, equal_nan=True):
            break
    else:
        moving = [name for name, i in layout.index.items() if before[i] != z[i]]
        raise CosimError(
            f"the connected values did not settle in initialisation mode after {INIT_PASSES} "
            f"exchanges: {', '.join(moving[:5])} still change (an algebraic loop with no "
            "solution, or one the exchanges do not converge on)"
        )
    for slave in order:
        _set_up(slave, slave.exit_initialisation)
        # pythonfmu cannot return a status from exitInitializationMode: an FMU whose
        # initialisation failed logs an Error (and refuses to step), so that counts too
        logged = [m for m in slave.messages if m.startswith(("[Error]", "[Fatal]"))]
        if logged:
            raise CosimError(
                f"{slave.name}: error logged during initialisation: {' | '.join(logged[-3:])}"
            )
    for slave in order:
        _set_up(slave, functools.partial(_read_initial, slave, layout, z))


def _read_initial(slave: Slave, layout: _Layout, z: np.ndarray) -> None:
    """Row 0 of one instance: its inputs set once more from the latest outputs (an FMU
    that computes its outputs only as it leaves initialisation mode feeds them through
    now), its outputs read, and its recorded inputs no connection drives."""
    slave.exchange(z)
    for ref in layout.constants:
        instance, variable = ref.split(".", 1)
        if instance == slave.name:
            var = slave.instance.variable(variable)
            get = {"Real": slave.fmu.getReal, "Boolean": slave.fmu.getBoolean}.get(
                var.type, slave.fmu.getInteger
            )
            z[layout.index[ref]] = float(get([var.valueReference])[0])


def _loop(
    scenario: Scenario,
    order: list[Slave],
    layout: _Layout,
    z: np.ndarray,
    rows: RowBuffer,
    stop: StopRequest,
    timeline: Timeline | None,
    at: Callable[[int], None],
    saver: _Saver | None = None,
) -> RunResult:
    """The stepping loop proper (see the module docstring); ``stop`` ends it early.

    With a ``timeline`` (:mod:`cosim.engine.timeline`: the scenario's events and faults),
    ``timeline.at(n)`` runs at every communication point before its row is recorded and
    before any instance steps from it, and ``timeline.deliver`` after each gather of inputs;
    without one, both are no-ops (about 0.1 us a step: nothing against an FMU's doStep).
    ``at`` is ``timeline.at`` (or the no-op), wrapped by :func:`_live_point` in a paced or
    live run. A ``saver`` starts the loop at a saved point and saves it at its points.
    """
    h, n_steps = scenario.coupling.step, scenario.n_steps
    jacobi = scenario.coupling.algorithm == "jacobi"
    record = np.asarray([layout.index[c] for c in scenario.columns], dtype=np.intp)
    exchanged = z[: layout.n_read]
    multi_rate = any(s.k != 1 for s in order)
    through = [s for s in order if s.feeds_through]  # refreshed at every point

    take = z.take  # z.take(indices, out=buffer): a gather without allocation
    give = inputs_giver(z, timeline)
    probe = np.zeros(layout.n_read)  # x . 0 is NaN iff some x is NaN or infinite
    check_dot = exchanged.dot  # (its warning of the inf . 0 it finds: INF_DOT_WARNING)
    slots, chunk, clock, interval = rows.slots, len(rows.slots), time.perf_counter, rows.interval
    error: str | None = None
    first, save_at = (saver.first, saver.next) if saver is not None else (0, -1)  # -1: none
    filled, slave, n, due = 0, order[0], first, order
    started, cpu_started = clock(), time.process_time()
    hand_off_at = started + interval
    try:
        if saver is None or not saver.resumed:  # row 0 (a resumed run's rows are replayed)
            filled = _row_zero(at, take, record, slots[0], exchanged, layout.index)
        for n in range(first, n_steps):
            if stop.signum is not None:
                break
            t = n * h  # t_n = n h, never accumulated (no drift)
            due = [s for s in order if n % s.k == 0] if multi_rate else order
            if jacobi:  # every due instance takes the values at t before any steps
                for slave in due:
                    give(slave, n, t)
            for slave in due:
                if not jacobi:  # the latest values, including those stepped just now
                    give(slave, n, t)
                # step to t_{n+k} - t_n as fmpy.simulate_fmu does, then read the outputs
                slave.advance(t, (min(n + slave.k, n_steps) if multi_rate else n + 1) * h - t)
            if through:  # feedthroughs follow their inputs
                refresh(through, give, n + 1, (n + 1) * h)
            nan_if_bad = check_dot(probe)
            if nan_if_bad != nan_if_bad:
                check_finite(exchanged, layout.index, (n + 1) * h)
            at(n + 1)
            if record.size:  # (a run recording nothing gathers nothing)
                take(record, out=slots[filled])
            filled += 1
            if filled == chunk or clock() >= hand_off_at or n + 1 == save_at:
                rows.hand_off(filled)  # (a checkpoint's rows first, whether or not it saves)
                filled, hand_off_at = 0, clock() + interval
                if rows.error is not None:
                    break
                if n + 1 == save_at and saver is not None:
                    save_at = saver.save(n + 1)
    except FMICallException as exc:
        ends = [min(n + s.k, n_steps) if multi_rate else n + 1 for s in due]
        finish = _Finish(slave, due, ends, give, jacobi, through, n, h)
        error, filled = _end_or_fail(exc, finish, filled, z, record, rows, exchanged, layout.index)
    except CosimError as exc:
        error = str(exc)
    rows.hand_off(filled)
    if saver is not None and error is None:
        error = saver.stopped(n, stop, h)
    return _result(scenario, order, rows, error, stop, clock() - started,
                   time.process_time() - cpu_started, first * h)  # fmt: skip


def _row_zero(
    at: Callable[[int], None],
    take: Callable[..., Any],
    record: np.ndarray,
    slot: np.ndarray,
    exchanged: np.ndarray,
    index: Mapping[str, int],
) -> int:
    """Row 0 (t = 0) into ``slot``, its timeline applied and its values checked; 1 row."""
    at(0)
    take(record, out=slot)
    check_finite(exchanged, index, 0.0)
    return 1


class _Saver:
    """The checkpoints of the fixed-step loop (:mod:`cosim.engine.checkpoint`): it puts
    the saved state back and hands the rows written before it to the sinks again (``first``
    is then the saved point), and saves at every ``every``-th point (``next``; -1: none)."""

    def __init__(
        self,
        order: list[Slave],
        z: np.ndarray,
        rows: RowBuffer,
        timeline: Timeline | None,
        checkpoints: checkpoint.Checkpointing,
        layout: _Layout,
        columns: Sequence[str],
    ) -> None:
        self.order, self.z, self.rows, self.timeline = order, z, rows, timeline
        self.checkpoints = checkpoints
        self.first = 0  # the point the loop starts at (a resumed run: the saved one, 0 too)
        start = checkpoints.start
        self.resumed = start is not None  # row 0 and the rows up to ``first`` handed off
        if start is not None:
            try:
                checkpoint.restore(start, order, z, timeline)
            except ValueError as exc:
                raise CosimError(f"{checkpoints.source}: does not fit this run: {exc}") from None
            if checkpoints.rows is not None:
                self._check_values(checkpoints.rows.last, layout, columns, checkpoints.source)
            # the earlier run's checkpoint goes with its files as the replay's rows replace
            # them: written again first, so that a failure leaves the earlier run as it was
            checkpoints.save(start)
            if checkpoints.rows is not None:
                self._replay(checkpoints.rows)
                checkpoints.save(start)  # again, recorded with results.csv's rows up to it
            self.first = int(start["step"])
        every = checkpoints.every
        self.next = (self.first // every + 1) * every if every else -1

    def _check_values(
        self, last: np.ndarray | None, layout: _Layout, columns: Sequence[str], source: str
    ) -> None:
        """Refuse a restored ``z`` whose exchanged values are not finite, or whose recorded
        ones are not the last row written before the checkpoint (``last``), to the bit: a
        state edited, or taken from another run, would resume a run never interrupted."""
        if not np.isfinite(self.z[: layout.n_read]).all():
            raise CosimError(f"{source}: does not fit this run: its values z are not all finite")
        record = [layout.index[c] for c in columns]
        if last is not None and not np.array_equal(self.z[record], last, equal_nan=True):
            raise CosimError(
                f"{source}: does not fit this run: its values z are not those of the last "
                "row of results.csv it keeps (one of them edited since?)"
            )

    def _replay(self, saved: checkpoint.SavedRows) -> None:
        """The rows up to the saved point, read a chunk at a time, to every sink as the
        loop handed them off (their times: row n at n h)."""
        chunk = len(self.rows.slots)
        for values in saved.chunks():
            for i in range(0, len(values), chunk):
                part = values[i : i + chunk]
                self.rows.buffer[: len(part)] = part
                self.rows.hand_off(len(part))

    def save(self, n: int) -> int:
        """Save the state at point ``n`` (its rows handed off); the next point to save."""
        state = checkpoint.capture(self.order, self.z, n, self.rows.count, self.timeline)
        self.checkpoints.save(state)
        every = self.checkpoints.every
        self.next = n + every if every else -1
        return self.next

    def stopped(self, n: int, stop: StopRequest, h: float) -> str | None:
        """After the loop: a checkpoint at point ``n`` if a signal stopped the run there
        (its rows so far handed off: ``n + 1``); the run's error if it cannot be saved."""
        if stop.signum is None or self.rows.error is not None or self.rows.count != n + 1:
            return None
        try:
            self.save(n)
        except (CosimError, FMICallException) as exc:
            return f"{stop.reason} at t = {seconds(n * h)} s; no checkpoint there: {exc}"
        return None


@dataclass
class _Finish:
    """The rest of the step from point ``n`` after ``stepped`` ended the simulation in it,
    when it ended where its step ends: the ``due`` instances after it in the order step to
    their ``ends`` (points) as they would have (Gauss-Seidel: with the latest values), and
    the feedthroughs follow (``through``), so the last row holds every instance at the
    point it reached. An FMU that ends inside its step leaves the others where they are."""

    stepped: Slave
    due: Sequence[Slave]
    ends: Sequence[int]
    give: Give
    jacobi: bool
    through: Sequence[Slave]
    n: int
    h: float  # s
    current: Slave | None = None  # the instance stepping now

    def __call__(self, reached: float) -> None:
        t, i = self.n * self.h, list(self.due).index(self.stepped)
        if not math.isclose(reached, self.ends[i] * self.h, rel_tol=1e-9, abs_tol=1e-12):
            return
        for later, end in zip(self.due[i + 1 :], self.ends[i + 1 :], strict=True):
            self.current = later
            if not self.jacobi:
                self.give(later, self.n, t)
            later.advance(t, end * self.h - t)
        refresh(list(self.through), self.give, self.n + 1, (self.n + 1) * self.h)


def _end_or_fail(
    exc: FMICallException,
    finish: _Finish,
    filled: int,
    z: np.ndarray,
    record: np.ndarray,
    rows: RowBuffer,
    exchanged: np.ndarray,
    index: Mapping[str, int],
) -> tuple[str | None, int]:
    """After ``finish.stepped``'s call failed in the step from point ``finish.n``: None and
    the rows filled when it ended the simulation (``rows.ended`` says so), else the reason
    it failed -- or the reason an instance finishing the step failed."""
    slave, t = finish.stepped, finish.n * finish.h
    try:
        ended = end_of_simulation(slave, exc, z, record, rows, filled, t, finish)
    except FMICallException as later:
        failed = finish.current if finish.current is not None else slave
        return failure_reason(failed, later, t, exchanged, index), filled
    if ended is None:
        return failure_reason(slave, exc, t, exchanged, index), filled
    rows.ended, filled = ended
    return None, filled


def _live_point(
    at: Callable[[int], None],
    pacer: Pacer | None,
    live: LiveControl | None,
    z: np.ndarray,
    h: float,
    stop: StopRequest,
) -> Callable[[int], None]:
    """``at`` wrapped for a paced or live run: at each communication point n, wait for n's
    deadline (a stop ends the wait at once), then ``at`` (which applies the overrides and
    holds a paused run, :meth:`LiveControl.take`), then publish the point's values."""
    stopping = (lambda: live.stopping) if live is not None else (lambda: stop.requested)

    def point(n: int) -> None:
        if pacer is not None:
            pacer.release(n, stopping)
        at(n)
        if live is not None:
            live.publish(n * h, z)

    return point


def _no_phase(text: str) -> None:
    """No one to tell what the run is doing."""


def _no_event(n: int) -> None:
    """The timeline of a scenario without events or faults."""


def _result(
    scenario: Scenario,
    order: list[Slave],
    rows: RowBuffer,
    error: str | None,
    stop: StopRequest,
    wall: float,
    cpu: float,
    time_started: float = 0.0,
) -> RunResult:
    """How the loop ended, as a :class:`RunResult` (the sinks' failure or the stop signal
    named as the reason when nothing else failed); ``wall`` and ``cpu``: the loop's wall
    clock and process CPU time, s; ``time_started``: where the loop started, s (a resumed
    run: its checkpoint)."""
    t_end = rows.time_reached
    if error is None and rows.error is not None:
        error = f"{rows.error} (at t = {seconds(t_end)} s)"
    reached = rows.ended is not None or t_end >= scenario.stop_time - 1e-6 * scenario.coupling.step
    stopped = stop.requested and error is None and not reached
    if stopped:
        error = f"{stop.reason} at t = {seconds(t_end)} s"
    messages, logged = _logged(order)
    return RunResult(
        scenario=scenario,
        columns=scenario.columns,
        rows=rows.count,
        time_reached=t_end,
        final=rows.final,
        complete=reached and error is None,
        error=error,
        wall_clock_s=wall,
        time_started=time_started,
        cpu_clock_s=cpu,
        stop_signal=stop.signum if stopped else None,
        messages=messages,
        messages_logged=logged,
        ended=rows.ended,
    )


def _logged(order: list[Slave]) -> tuple[dict[str, list[str]], dict[str, int]]:
    """Each instance's kept messages (warnings and worse), and how many it logged, for
    those that logged any."""
    kept = {s.name: list(s.messages) for s in order}
    return kept, {s.name: max(s.logged, len(s.messages)) for s in order if s.messages}
