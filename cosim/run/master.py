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
every instance's latest outputs once the due instances have advanced to t = n h. Connected
inputs are first set at t = 0, just before an instance's first doStep: there is no
exchange in initialisation mode (our FMUs' initial outputs depend on parameters only), so
under Jacobi the first step of the plant sees the controller's initial outputs.

Why a loop of our own: ``fmpy.simulate_fmu`` runs one FMU, and ``fmpy.ssp`` has no
Gauss-Seidel order, multi-rate, per-step NaN check or partial results. The style follows
fmpy's ``simulateCS``. The hot path calls fmpy's thin ``fmi2SetReal``/``fmi2DoStep``/
``fmi2GetReal`` wrappers (they check the status and raise ``FMICallException``) with value
reference arrays and numpy buffers resolved once: a step allocates nothing, builds no dict.

Failures after initialisation -- a non-OK status (fmpy raises on Discard, Error, Fatal), a
non-finite exchanged value, Ctrl-C -- stop the run; :func:`run` returns the rows so far with
``complete=False`` and a one-line ``error`` naming the instance, the time and the FMU's
logged reason. Ctrl-C only sets a flag checked once per step, so no ``KeyboardInterrupt``
is raised inside an FMU's Python code (pythonfmu would turn it into fmi2Fatal and the host
would crash).
"""

from __future__ import annotations

import atexit
import collections
import ctypes
import shutil
import signal
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from fmpy import calloc, extract, free
from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import (
    FMU2Slave,
    fmi2CallbackAllocateMemoryTYPE,
    fmi2CallbackFreeMemoryTYPE,
    fmi2CallbackFunctions,
    fmi2CallbackLoggerTYPE,
)

from cosim.errors import CosimError
from cosim.run.scenario import Instance, Scenario
from fmu_runtime import exit_guard

STATUS_LABELS = ("OK", "Warning", "Discard", "Error", "Fatal", "Pending")
LOG_LINES_KEPT = 20  # logged messages (warning or worse) kept per instance
ROWS_PER_CHUNK = 200  # rows handed to `on_rows` at a time (recording, progress)
RowsCallback = Callable[[np.ndarray, np.ndarray], None]
_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


@dataclass
class RunResult:
    """What a run produced; ``times``/``values`` hold the rows computed (all if complete)."""

    scenario: Scenario
    columns: tuple[str, ...]
    times: np.ndarray  # (rows,) s
    values: np.ndarray  # (rows, len(columns)) SI
    complete: bool
    error: str | None  # one line, None if complete
    wall_clock_s: float  # the stepping loop alone (including the on_rows callbacks)
    interrupted: bool = False
    messages: dict[str, list[str]] = field(default_factory=dict)  # instance -> FMU log lines

    def column(self, name: str) -> np.ndarray:
        """The recorded time series ``"<instance>.<variable>"``."""
        return self.values[:, self.columns.index(name)]


class _Slave:
    """One FMU instance as the master drives it: the fmpy slave, pre-resolved value
    references, its input buffer and output view, its logged messages and FMI state.

    The FMI 2.0 call order is enforced by ``_expect``: new -> instantiated ->
    initialization -> stepping -> terminated -> freed. After an Error status the instance
    is only freed, after Fatal it is not touched again, as the standard requires.
    """

    def __init__(self, instance: Instance, unzip_dir: Path, k: int) -> None:
        md = instance.model_description
        self.name = instance.name
        self.instance = instance
        self.k = k
        self.state = "new"
        self.messages: collections.deque[str] = collections.deque(maxlen=LOG_LINES_KEPT)
        self.fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=str(unzip_dir),
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=instance.name,
        )

    def bind(
        self, input_vrs: list[int], sources: list[int], output_vrs: list[int], out: np.ndarray
    ) -> None:
        """Resolve the buffers once: inputs come from ``z[sources]``, outputs go to ``out``."""
        self.n_inputs, self.n_outputs = len(input_vrs), len(output_vrs)
        self.input_vrs = (ctypes.c_uint * self.n_inputs)(*input_vrs)
        self.inputs = np.zeros(self.n_inputs)
        self.input_ptr = self.inputs.ctypes.data_as(_DOUBLE_P)
        self.input_sources = np.asarray(sources, dtype=np.intp)
        self.output_vrs = (ctypes.c_uint * self.n_outputs)(*output_vrs)
        self.output_ptr = out.ctypes.data_as(_DOUBLE_P)
        # fmpy's status-checking wrappers of the C functions, looked up once
        self.set_real = self.fmu.fmi2SetReal
        self.do_step = self.fmu.fmi2DoStep
        self.get_real = self.fmu.fmi2GetReal

    def _expect(self, *states: str) -> None:
        if self.state not in states:
            raise CosimError(f"{self.name}: FMI call out of order (in state {self.state!r})")

    def set_up(self, stop_time: float) -> None:
        """instantiate (logging on), setupExperiment, start values, initialise."""
        from fmpy.logging import addLoggerProxy

        self._expect("new")
        self.callbacks = fmi2CallbackFunctions()  # kept on self: the FMU holds pointers into it
        self.callbacks.logger = _LOGGER
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        self.callbacks.componentEnvironment = id(self)
        # fmpy's native proxy formats the FMU's printf-style messages; it keeps ONE target
        # function per process, so every instance shares _LOGGER, which dispatches on the
        # componentEnvironment the FMU passes back.
        addLoggerProxy(ctypes.byref(self.callbacks))
        _log_sinks[id(self)] = self.messages
        self.fmu.instantiate(callbacks=self.callbacks, loggingOn=True)
        self.state = "instantiated"
        # any pythonfmu FMU, ours or not, can abort this process at exit: see exit_guard
        exit_guard.install(Path(self.fmu.unzipDirectory) / "resources")
        self.fmu.setupExperiment(startTime=0.0, stopTime=stop_time)
        grouped: dict[str, tuple[list[int], list[Any]]] = {}
        for name, value in self.instance.start.items():
            var = self.instance.variable(name)
            kind = "Integer" if var.type == "Enumeration" else var.type
            vrs, values = grouped.setdefault(kind, ([], []))
            vrs.append(var.valueReference)
            values.append(value)
        setters = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger,
                   "Boolean": self.fmu.setBoolean, "String": self.fmu.setString}  # fmt: skip
        for kind, (vrs, values) in grouped.items():
            setters[kind](vrs, values)
        self.fmu.enterInitializationMode()
        self.state = "initialization"
        self.fmu.exitInitializationMode()
        self.state = "stepping"
        self.c = self.fmu.component

    def read_outputs(self) -> None:
        self._expect("stepping")
        self.get_real(self.c, self.output_vrs, self.n_outputs, self.output_ptr)

    def failed(self, status: int) -> None:
        """Record a non-OK status: after Discard the instance may still be terminated,
        after Error only freed, after Fatal not touched at all (FMI 2.0, 4.2.4)."""
        if status >= 3:
            self.state = "fatal" if status >= 4 else "error"

    def finish(self) -> None:
        """terminate + freeInstance as far as the state allows; never raises."""
        try:
            if self.state in ("initialization", "stepping"):
                self.fmu.terminate()
                self.state = "terminated"
            if self.state in ("instantiated", "terminated", "error"):
                self.state = "freed"
                self.fmu.freeInstance()
        except Exception as exc:  # a failing clean-up must not hide the run's own result
            self.messages.append(f"[clean-up] {exc}")
            self.state = "freed"
        finally:
            if self.state in ("freed", "new"):
                _log_sinks.pop(id(self), None)


_log_sinks: dict[int, collections.deque[str]] = {}  # componentEnvironment -> messages


def _log(env: int | None, _name: bytes, status: int, _category: bytes, message: bytes) -> None:
    """The FMUs' logger: keeps warnings and worse per instance. A C callback: never raises."""
    sink = _log_sinks.get(env or 0)
    if sink is not None and status >= 1:
        label = STATUS_LABELS[status] if status < len(STATUS_LABELS) else str(status)
        sink.append(f"[{label}] {(message or b'').decode('utf-8', 'replace')}")


_LOGGER = fmi2CallbackLoggerTYPE(_log)


@dataclass(frozen=True)
class _Layout:
    """Where every exchanged or recorded value lives, resolved once before the loop.

    ``z`` = [outputs read after every step, instance by instance | recorded inputs that no
    connection drives, read once after initialisation]; ``index``: "<inst>.<var>" -> z.
    """

    read: dict[str, list[str]]  # instance -> variables read after each of its steps
    constants: list[str]  # "<instance>.<input>" recorded but never driven
    index: dict[str, int]

    @classmethod
    def of(cls, scenario: Scenario) -> _Layout:
        wanted = {c.source for c in scenario.connections} | set(scenario.record)
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
        order = [f"{n}.{v}" for n, names in read.items() for v in names] + constants
        return cls(read, constants, {ref: i for i, ref in enumerate(order)})

    @property
    def n_read(self) -> int:
        return len(self.index) - len(self.constants)


def run(
    scenario: Scenario,
    on_rows: RowsCallback | None = None,
    rows_per_chunk: int = ROWS_PER_CHUNK,
) -> RunResult:
    """Run ``scenario`` to its stop time (or the first failure) and return the results.

    ``on_rows(times, values)`` receives the rows in order, ``rows_per_chunk`` at a time
    (views into the result arrays: copy what you keep), also after a failure. Raises
    :class:`CosimError` if an FMU cannot be set up (instantiation, start values,
    initialisation); every failure after that is reported in the returned result.
    """
    layout = _Layout.of(scenario)
    z = np.zeros(len(layout.index))
    slaves = [
        _Slave(inst, _unzipped(inst.fmu_path), scenario.coupling.step_multiples[name])
        for name, inst in scenario.instances.items()
    ]
    stop = [False]  # set by Ctrl-C, also while the FMUs are set up or freed
    with _ctrl_c_sets(stop):
        try:
            for slave in slaves:
                _bind(slave, scenario, layout, z)
            for slave in slaves:
                _set_up(slave, scenario, layout, z)
            if stop[0]:
                raise KeyboardInterrupt  # raised here, never inside an FMU's code
            by_name = {s.name: s for s in slaves}
            order = [by_name[name] for name in scenario.coupling.order]
            return _loop(scenario, order, layout, z, on_rows, rows_per_chunk, stop)
        finally:
            for slave in slaves:
                slave.finish()


def _bind(slave: _Slave, scenario: Scenario, layout: _Layout, z: np.ndarray) -> None:
    inst, read = slave.instance, layout.read[slave.name]
    targets = [c for c in scenario.connections if c.target_instance == slave.name]
    start = layout.index[f"{slave.name}.{read[0]}"] if read else 0
    slave.bind(
        input_vrs=[inst.variable(c.target_variable).valueReference for c in targets],
        sources=[layout.index[c.source] for c in targets],
        output_vrs=[inst.variable(v).valueReference for v in read],
        out=z[start : start + len(read)],
    )


def _set_up(slave: _Slave, scenario: Scenario, layout: _Layout, z: np.ndarray) -> None:
    """Set up one instance and read its t = 0 outputs and recorded constant inputs."""
    try:
        slave.set_up(scenario.stop_time)
        # pythonfmu cannot return a status from exitInitializationMode: an FMU whose
        # initialisation failed logs an Error (and refuses to step), so that counts too
        logged = [m for m in slave.messages if m.startswith(("[Error]", "[Fatal]"))]
        if logged:
            raise CosimError(
                f"{slave.name}: error logged during initialisation: {' | '.join(logged[-3:])}"
            )
        slave.read_outputs()
        for ref in layout.constants:
            instance, variable = ref.split(".", 1)
            if instance == slave.name:
                vr = slave.instance.variable(variable).valueReference
                z[layout.index[ref]] = slave.fmu.getReal([vr])[0]
    except FMICallException as exc:
        slave.failed(exc.status)
        raise CosimError(_describe(slave, exc.function, exc.status, 0.0)) from None
    except CosimError:
        raise
    except Exception as exc:  # fmpy raises a plain Exception when instantiation fails
        raise CosimError(f"{slave.name}: cannot set up {slave.instance.fmu_path.name}: {exc}"
                         f"{_reasons(slave)}") from None  # fmt: skip


def _loop(
    scenario: Scenario,
    order: list[_Slave],
    layout: _Layout,
    z: np.ndarray,
    on_rows: RowsCallback | None,
    rows_per_chunk: int,
    stop: list[bool],
) -> RunResult:
    """The stepping loop proper (see the module docstring); ``stop[0]`` ends it early."""
    h, n_steps = scenario.coupling.step, scenario.n_steps
    jacobi = scenario.coupling.algorithm == "jacobi"
    columns = scenario.record
    record = np.asarray([layout.index[c] for c in columns], dtype=np.intp)
    times = np.arange(n_steps + 1) * h  # t_n = n h, never accumulated (no drift)
    t_list = times.tolist()
    values = np.empty((n_steps + 1, len(columns)))
    exchanged = z[: layout.n_read]
    multi_rate = any(s.k != 1 for s in order)

    take = z.take  # z.take(indices, out=buffer): a gather without allocation
    probe = np.zeros(layout.n_read)  # x . 0 is NaN iff some x is NaN or infinite
    check_dot = exchanged.dot
    error: str | None = None
    rows = 1  # rows of `values` filled; row 0 is t = 0
    sent = 0  # rows handed to on_rows
    take(record, out=values[0])
    slave, n = order[0], 0
    started = time.perf_counter()
    try:
        _check_finite(exchanged, layout, 0.0)
        for n in range(n_steps):
            t = t_list[n]
            due = [s for s in order if n % s.k == 0] if multi_rate else order
            if jacobi:  # every due instance takes the values at t before any steps
                for slave in due:
                    take(slave.input_sources, out=slave.inputs)
                    slave.set_real(slave.c, slave.input_vrs, slave.n_inputs, slave.input_ptr)
            for slave in due:
                if not jacobi:  # the latest values, including those stepped just now
                    take(slave.input_sources, out=slave.inputs)
                    slave.set_real(slave.c, slave.input_vrs, slave.n_inputs, slave.input_ptr)
                # step to t_{n+k} - t_n, as fmpy.simulate_fmu does (bit-identical runs)
                slave.do_step(slave.c, t, t_list[min(n + slave.k, n_steps)] - t, 1)
                slave.get_real(slave.c, slave.output_vrs, slave.n_outputs, slave.output_ptr)
            nan_if_bad = check_dot(probe)
            if nan_if_bad != nan_if_bad:
                _check_finite(exchanged, layout, t_list[n + 1])
            take(record, out=values[rows])
            rows += 1
            if on_rows is not None and rows - sent >= rows_per_chunk:
                on_rows(times[sent:rows], values[sent:rows])
                sent = rows
            if stop[0]:
                error = f"interrupted (Ctrl-C) at t = {t_list[n + 1]:.6g} s"
                break
    except FMICallException as exc:
        slave.failed(exc.status)
        error = _describe(slave, exc.function, exc.status, t_list[n])
    except CosimError as exc:
        error = str(exc)
    if on_rows is not None and rows > sent:
        on_rows(times[sent:rows], values[sent:rows])
    wall = time.perf_counter() - started
    return RunResult(
        scenario=scenario,
        columns=columns,
        times=times[:rows],
        values=values[:rows],
        complete=rows == n_steps + 1 and error is None,
        error=error,
        wall_clock_s=wall,
        interrupted=stop[0],
        messages={s.name: list(s.messages) for s in order},
    )


def _check_finite(exchanged: np.ndarray, layout: _Layout, t: float) -> None:
    bad = np.flatnonzero(~np.isfinite(exchanged))
    if bad.size:
        names = list(layout.index)
        listed = ", ".join(f"{names[i]} = {exchanged[i]}" for i in bad[:5])
        raise CosimError(f"non-finite value at t = {t:.6g} s: {listed}")


def _describe(slave: _Slave, function: str, status: int, t: float) -> str:
    label = STATUS_LABELS[status] if 0 <= status < len(STATUS_LABELS) else str(status)
    return f"{slave.name}: {function} returned {label} at t = {t:.6g} s{_reasons(slave)}"


def _reasons(slave: _Slave) -> str:
    """The FMU's last logged reason(s), one line."""
    lines = [m for m in slave.messages if not m.startswith("[Warning]")][-3:]
    return (": " + " | ".join(lines)) if lines else " (the FMU logged no reason)"


@contextmanager
def _ctrl_c_sets(flag: list[bool]) -> Iterator[None]:
    """While active, Ctrl-C sets ``flag[0]`` instead of raising KeyboardInterrupt."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(_signum: int, _frame: Any) -> None:
        flag[0] = True

    previous = signal.signal(signal.SIGINT, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


# --- unzipped FMUs, one folder per FMU file per process -----------------------------------

_unzipped_dirs: dict[tuple[Path, float], Path] = {}


def _unzipped(fmu_path: Path) -> Path:
    """Extract an FMU once per process (pythonfmu keeps its modules imported anyway)."""
    key = (fmu_path, fmu_path.stat().st_mtime)
    if key not in _unzipped_dirs:
        _unzipped_dirs[key] = Path(extract(str(fmu_path)))
    return _unzipped_dirs[key]


@atexit.register
def _remove_unzipped() -> None:
    for folder in _unzipped_dirs.values():
        shutil.rmtree(folder, ignore_errors=True)
