"""An exception-proof base class over pythonfmu's ``Fmi2Slave``, shared by both FMUs.

Why it exists (``docs/fmi-notes.md``): with pythonfmu 0.7 an exception escaping a Python
callback becomes fmi2Fatal and the C wrapper then releases the Python objects twice, so the
host process crashes soon after. pythonfmu also accepts NaN inputs, lets a fixed parameter
be written after initialisation, follows no FMI call sequence, and saves only the
registered variables as FMU state. This class closes those holes once, for the plant and
the controller FMU alike, and installs :mod:`fmu_runtime.exit_guard` against pythonfmu's
crash at process exit. The FMU's native runtime (``fmu_runtime/native/``) constructs the
class and calls these methods itself; pythonfmu's own binary, the fallback, calls the same
ones.

What a subclass writes (the whole API)::

    class MySlave(SafeSlave):
        default_experiment = DefaultExperiment(0.0, 60.0, 0.01)   # pythonfmu's own
        direct_feedthrough = {"y": ("u",)}  # outputs that depend directly on inputs

        def __init__(self, **kwargs):
            super().__init__(**kwargs)      # then only assign defaults and register:
            self.mode = 0                   # kept in an attribute of its own (watched)
            self.register(Real("u", causality=Fmi2Causality.input, start=0.0,
                               variability=Fmi2Variability.continuous,
                               description="..."), unit="N")  # kept in the buffers
            self.register(Integer("mode", ...), minimum=0, maximum=2)
            ...
            self._u = self.values_of(["u"])  # last: numpy views of the buffers

        def _initialize(self) -> None: ...            # exit_initialization_mode
        def _step(self, t: float, h: float) -> None: ...  # do_step
            # a debug message, formatted only when the host asked for its category
            # (declared in the class's log_categories, beside pythonfmu's five):
            # if "logMine" in self.debug_categories: self.log(f"...", category="logMine")
        def _state_snapshot(self) -> dict: ...        # the internal state, JSON-serialisable
        def _restore_snapshot(self, snapshot: dict) -> None: ...

Where values live: every Real, Integer and Boolean variable has a slot in its type's value
buffer (:mod:`fmu_runtime.value_buffers`), which the FMU's runtime reads and writes in C:
``fmi2Get*`` and ``fmi2Set*`` never enter Python there, and ``fmi2DoStep`` is the one call
into Python of a step. A variable registered with no getter, no setter and no attribute
of its name lives in its slot: the slave reads and writes it through numpy views of the
buffers (:meth:`SafeSlave.values_of`, contiguous runs of variables registered one after
the other), in place, in ``_step``. Any other variable keeps its own storage (an
attribute, a container through its getter and setter: *watched*): a value written to it
is handed to its setter at the slave's next call, and its getter's value is copied to its
slot after every call but a step (after a step too for an output). Strings keep their own
storage; the runtime keeps copies. Parameters and Strings must not change in ``_step``.
Under pythonfmu's binary (the fallback) nothing else shares the buffers and this class
answers the calls from them itself: a subclass's code is the same in both runtimes.

``_initialize`` computes the outputs the FMU starts from, from the parameters and inputs:
it also runs when an output is read in initialisation mode after a write (so that read
gives the value the FMU will start from, as FMI 2.0 asks of ``initial="calculated"``
outputs), and must therefore be repeatable. A class that takes input derivatives sets
``interpolates_inputs = True`` (the build then declares ``canInterpolateInputs``) and reads
them in ``_step`` with :meth:`SafeSlave.input_derivative`, or through a view
(:meth:`SafeSlave.derivatives_of`); both runtimes hand them over.

``_initialize`` and ``_step`` report a problem by raising (any exception): the base class
catches it, logs the message with ``Fmi2Status.error`` and turns it into a failed
initialisation or a Discard from ``fmi2DoStep``. ``_step`` must leave the state unchanged
when it raises (compute, then commit), so a master can retry or roll back. Files an
instance reads come from ``self.resources`` (the extraction it was instantiated from),
never from a location bound when its modules were imported: pythonfmu keeps those
modules for the life of the process, across extractions a host may delete.

The rules it enforces, how it logs, ``fmi2Reset`` and what the build reads from
``to_xml``: docs/fmi-notes.md#what-safeslave-enforces.
"""

from __future__ import annotations

import copy
import json
import math
import threading
import weakref
import zlib
from collections.abc import Callable, Iterable
from enum import IntEnum
from typing import Any, ClassVar
from xml.etree.ElementTree import Element, SubElement

import numpy as np
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Boolean, Integer, Real, ScalarVariable, String

from fmu_runtime import entry, exit_guard
from fmu_runtime.log_text import shortened
from fmu_runtime.value_buffers import (
    BOOLEAN,
    CHANGES,
    DERIVATIVES,
    INTEGER,
    REAL,
    STALE,
    WRITTEN,
    ValueBuffers,
)
from fmu_runtime.variables import attribute_getter, attribute_setter

_WRITE_ANY_TIME = "any time"
_WRITE_BEFORE_INIT = "before initialisation"
_READ_ONLY = "never"
_STATE_VERSION = 4
# FMI 2.0 co-simulation states this class tracks (the names are used in messages)
_INSTANTIATED = "instantiated"
_INITIALIZATION = "in initialisation mode"
_STEPPING = "initialised"
_TERMINATED = "terminated"
_TIME_TOLERANCE = 1e-9  # relative; see the module docstring (communication points)
_CRC_MARK = b"\ncrc32="  # between a serialised state's JSON and its CRC-32
_MAX_PLANS = 64  # cached get_real / set_real plans per instance
TOOL = "auv-cosim"  # the <Tool name> of our annotations in modelDescription.xml


def _annotate_names(node: Element, names: type[IntEnum]) -> None:
    """``<Annotations><Tool name="auv-cosim"><NamedValues><Item name="lqr" value="1"/>...``
    on the ScalarVariable ``node`` (FMI 2.0 allows one element of any XML in a Tool)."""
    tool = SubElement(SubElement(node, "Annotations"), "Tool", name=TOOL)
    values = SubElement(tool, "NamedValues")
    for member in names:
        SubElement(values, "Item", name=member.name.lower(), value=str(int(member)))


def _readable(var: Any) -> bool:
    return var.getter is not None


# the last SafeSlave constructed on each thread (weakly): claim_constructed
_constructed = threading.local()


def claim_constructed() -> SafeSlave | None:
    """The last SafeSlave constructed on this thread, if it still lives (then forgotten).

    The FMU's runtime calls this right after pythonfmu's binary, its fallback backend,
    constructed a slave in fmi2Instantiate on this thread, to hand that slave the calls
    pythonfmu's binary does not pass on (fmi2SetRealInputDerivatives, and the categories of
    fmi2SetDebugLogging: see
    fmu_runtime/native/forward.c)."""
    ref = getattr(_constructed, "slave", None)
    _constructed.slave = None
    slave: SafeSlave | None = ref() if ref is not None else None
    return slave


class SafeSlave(Fmi2Slave):
    """``Fmi2Slave`` whose callbacks never raise; see the module docstring for the API."""

    direct_feedthrough: ClassVar[dict[str, tuple[str, ...]]] = {}
    # True: the slave uses input derivatives (fmi2SetRealInputDerivatives, orders 1 and 2)
    interpolates_inputs: ClassVar[bool] = False
    # the inputs an output ``_initialize`` computes depends on (besides the parameters, on
    # which every such output may depend); declared in ModelStructure/InitialUnknowns
    initial_dependencies: ClassVar[dict[str, tuple[str, ...]]] = {}
    # why a tolerance given to setupExperiment changes nothing, and what sets the accuracy
    # instead (logged as a Warning when a host gives one)
    tolerance_note: ClassVar[str] = (
        "this FMU has no error-controlled integrator; its results depend on the "
        "communication step only"
    )

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        _constructed.slave = weakref.ref(self)  # (claim_constructed)
        exit_guard.install(self.resources)  # pythonfmu 0.7's crash at process exit
        if self.resources is not None:  # pythonfmu's binary put it on sys.path: not needed
            entry.release_search_path(self.resources)
        self._phase = _INSTANTIATED
        self._time = 0.0  # s: the start time, then the end of the last step
        self._stop_time = math.inf  # s: setupExperiment's stopTime, when it defines one
        self._initialized = False
        self._problems: dict[str, str] = {}
        # every variable's value (docs: fmu_runtime/value_buffers.py); shared with the
        # FMU's runtime, which answers fmi2Get*/fmi2Set* from it in C
        self._values = ValueBuffers()
        self._values.control[STALE] = 1  # the outputs to start from are not computed yet
        self._vr_of: dict[str, int] = {}  # variable name -> value reference
        self._watched_outputs: list[int] = []  # outputs kept in Python storage of their own
        self._access: dict[int, str] = {}
        self._units: dict[str, str] = {}
        self._quantities: dict[str, str] = {}  # Real's name -> its declared quantity
        self._bounds: dict[int, tuple[float | None, float | None]] = {}
        self._names: dict[str, type[IntEnum]] = {}  # Integer variable -> its named values
        # hot-path plans of get_real / set_real, per list of value references
        self._get_plans: dict[tuple[int, ...], Any] = {}
        self._set_plans: dict[tuple[int, ...], Any] = {}
        self._failure: str | None = None
        # the categories whose debug (fmi2OK) messages the host takes: set by the runtime
        # (set_debug_logging); a slave formats a debug message only for one in here
        self.debug_categories: frozenset[str] = frozenset()
        for said in entry.take_import_warnings():  # what the FMU's imports warned of
            self.log(said, Fmi2Status.warning)

    # --- what subclasses call / override ---------------------------------------------------

    def register(
        self,
        var: ScalarVariable,
        unit: str | None = None,
        minimum: float | None = None,
        maximum: float | None = None,
        names: type[IntEnum] | None = None,
        quantity: str | None = None,
    ) -> None:
        """Register an FMU variable; a Real needs its ``unit``, every variable a description.
        A Real may declare its ``quantity`` (FMI 2.0, 2.2.7), what the number is where its
        unit leaves it open: ``"AngularFrequency"``, a natural frequency in rad/s, not a
        turn rate.
        A Real or Integer may declare an inclusive range: writes outside it are refused,
        and modelDescription.xml declares it as ``min``/``max``. An Integer that chooses
        among ``names`` (an IntEnum) takes their range, and modelDescription.xml lists each
        value's name (lower case) in an annotation, so that scenario files can say
        ``heading_mode = "backstepping"`` (an FMI Enumeration would say the same, but
        libcosim and ecos read no Enumeration variables).

        Raises (at build time, where pythonfmu constructs the class): ValueError for a
        missing unit, description or variability, or a range on a Boolean/String, so a
        runtime instance never has to.
        """
        if not var.description:
            raise ValueError(f"variable {var.name!r}: a description is required")
        if isinstance(var, Real) and not unit:
            raise ValueError(f"Real variable {var.name!r}: a unit is required")
        if not isinstance(var, Real) and var.variability is None:
            raise ValueError(f"variable {var.name!r}: Integer/Boolean/String need a variability")
        if (minimum, maximum) != (None, None) and not isinstance(var, (Real, Integer)):
            raise ValueError(f"variable {var.name!r}: only Real and Integer take a range")
        if names is not None:
            if not isinstance(var, Integer):
                raise ValueError(f"variable {var.name!r}: only an Integer takes named values")
            self._names[var.name] = names
            minimum, maximum = int(min(names)), int(max(names))
        self._bind_storage(var)
        self.register_variable(var)
        self._vr_of[var.name] = var.value_reference
        if unit:
            self._units[var.name] = unit
        if quantity:
            self._quantities[var.name] = quantity
        if (minimum, maximum) != (None, None):
            self._bounds[var.value_reference] = (minimum, maximum)
        if var.causality == Fmi2Causality.input or (
            var.causality == Fmi2Causality.parameter and var.variability == Fmi2Variability.tunable
        ):
            access = _WRITE_ANY_TIME
        elif var.causality == Fmi2Causality.parameter:
            access = _WRITE_BEFORE_INIT
        else:
            access = _READ_ONLY
        self._access[var.value_reference] = access

    def _bind_storage(self, var: ScalarVariable) -> None:
        """Give ``var`` its slot in the value buffers and its getter and setter: the slot
        itself when it comes with no getter, no setter and no attribute of its name (the
        value lives in the buffers: see :meth:`values_of`), else its own storage (watched:
        written values are handed to its setter, its getter's values copied to the slot)."""
        kind = {Real: REAL, Integer: INTEGER, Boolean: BOOLEAN}.get(type(var), "")
        in_buffers = (
            kind != ""
            and var.getter is None
            and var.setter is None
            and not hasattr(self, var.local_name)
        )
        start = var.start if var.start is not None else 0
        slot = self._values.add(kind, start if in_buffers else 0, watched=not in_buffers)
        if in_buffers:
            var.getter = self._values.getter(kind, slot)
            if var.variability != Fmi2Variability.constant:
                var.setter = self._values.setter(kind, slot)
            return
        # pythonfmu's defaults, bound weakly: its own close over self (a reference cycle)
        if var.getter is None:
            var.getter = attribute_getter(self, var.local_name)
        if (
            var.setter is None
            and hasattr(self, var.local_name)
            and var.variability != Fmi2Variability.constant
        ):
            var.setter = attribute_setter(self, var.local_name)

    def values_of(self, names: Iterable[str]) -> np.ndarray:
        """A numpy view (float64 for Reals, int32 for Integers and Booleans) of the
        buffer slots of the variables ``names``, registered one after the other, all of
        one type and kept in the buffers (registered without getter, setter or attribute).
        The slave reads its inputs and writes its outputs through such views; the FMU's
        runtime reads and writes the same memory. The first call lays out the buffers:
        register every variable before it.

        Raises ValueError (at build time, where pythonfmu constructs the class) when the
        variables are not such a run."""
        vrs = [self._vr_of[name] for name in names]
        values = self._values
        kinds = {values.kinds[vr] for vr in vrs}
        slots = [values.slots[vr] for vr in vrs]
        watched = set(values.watched())
        if (
            not vrs
            or len(kinds) != 1
            or "" in kinds
            or slots != list(range(slots[0], slots[0] + len(slots)))
            or watched.intersection(vrs)
        ):
            raise ValueError(
                f"variables {[self.vars[vr].name for vr in vrs]}: expected a run of variables "
                "of one type registered one after the other without getter or setter"
            )
        self._seal()
        return values.view(kinds.pop(), slots[0], len(slots))

    def derivatives_of(self, names: Iterable[str]) -> np.ndarray:
        """A numpy view (2 x len(names), float64) of the input derivatives of orders 1
        (unit/s) and 2 (unit/s^2) set for the next step of the Real inputs ``names``, a run
        as :meth:`values_of` takes: 0.0 where none was set. The FMU's runtime writes them
        in C (``fmi2SetRealInputDerivatives``); with pythonfmu's binary (the fallback) the
        runtime hands them to :meth:`set_real_input_derivatives`; they are cleared after
        each step. A step may
        change the view (it is cleared after it anyway).

        Raises ValueError (at build time) when the variables are not such a run of
        Real inputs."""
        names = list(names)
        view = self.values_of(names)
        if view.dtype != np.float64 or any(
            self.vars[self._vr_of[name]].causality != Fmi2Causality.input for name in names
        ):
            raise ValueError(f"variables {names}: expected a run of Real inputs")
        first = self._values.slots[self._vr_of[names[0]]]
        return self._values.derivatives[:, first : first + len(names)]

    def was_written(self, name: str) -> bool:
        """True if the importer wrote variable ``name`` (accepted) since instantiation."""
        return bool(self._values.flags[self._vr_of[name]] & WRITTEN)

    @property
    def initialized(self) -> bool:
        """True after a successful ``exit_initialization_mode``."""
        return self._initialized

    def _initialize(self) -> None:
        """Apply parameters and the initial state (called by exit_initialization_mode)."""

    def _step(self, current_time: float, step_size: float) -> None:
        """Advance over [current_time, current_time + step_size]; raise to discard."""
        raise NotImplementedError(f"{type(self).__name__} does not implement _step")

    def _state_snapshot(self) -> dict[str, Any]:
        """The internal state not held in registered variables (JSON-serialisable)."""
        return {}

    def _restore_snapshot(self, snapshot: dict[str, Any]) -> None:
        """Restore what ``_state_snapshot`` returned (receives a private copy). Of a state
        taken before initialisation (``self.initialized`` is False here) what ``_initialize``
        builds need not be restored, and must not be kept from before: its parameters may
        be unusable yet, and ``_initialize`` runs again at the next read in initialisation
        mode or at ``exit_initialization_mode``."""

    # --- FMI callbacks -----------------------------------------------------------------------

    def setup_experiment(
        self,
        start_time: float = 0.0,
        stop_time: float | None = None,
        tolerance: float | None = None,
        *args: Any,
        **kwargs: Any,
    ) -> None:
        """Record the start time (the first communication point) and the stop time (None:
        not defined), past which no step may end; only right after instantiation, and only
        finite times, the stop time not before the start time. A ``tolerance`` (None: not
        defined) is ignored with a Warning saying so (``tolerance_note``)."""
        try:
            self._enter()
            if self._phase != _INSTANTIATED:
                self._error(
                    f"setupExperiment refused: the FMU is {self._phase} (FMI 2.0 "
                    "allows it only between instantiation and initialisation)"
                )
            elif not math.isfinite(start_time):
                self._error(
                    f"setupExperiment refused: startTime = {start_time!r} s, "
                    "expected a finite number"
                )
            elif stop_time is not None and not start_time <= stop_time < math.inf:
                self._error(
                    f"setupExperiment refused: stopTime = {stop_time!r} s, expected a "
                    f"finite number >= startTime ({start_time!r} s)"
                )
            else:
                self._time = float(start_time)
                self._stop_time = math.inf if stop_time is None else float(stop_time)
                if tolerance is not None:
                    self.log(
                        f"setupExperiment: tolerance = {tolerance!r} ignored: "
                        f"{self.tolerance_note}",
                        Fmi2Status.warning,
                    )
        except Exception as exc:
            self._error(f"setupExperiment failed: {_reason(exc)}")

    def enter_initialization_mode(self) -> None:
        """Enter initialisation mode, once, right after instantiation (parameters are
        applied in exit_initialization_mode)."""
        self._enter()
        if self._phase != _INSTANTIATED:
            self._error(
                f"enterInitializationMode refused: the FMU is {self._phase} "
                "(FMI 2.0 allows it once, right after instantiation)"
            )
            return
        self._phase = _INITIALIZATION
        self._values.control[STALE] = 1

    def exit_initialization_mode(self) -> None:
        self._enter()
        if self._phase != _INITIALIZATION:
            self._error(
                f"exitInitializationMode refused: the FMU is {self._phase}, not in "
                "initialisation mode (call enterInitializationMode first)"
            )
            return
        self._phase = _STEPPING
        try:
            if self._failure is not None:
                raise ValueError(self._failure)
            if self._problems:
                raise ValueError("; ".join(self._problems.values()))
            if self._values.control[STALE]:  # else computed when read, nothing written since
                self._initialize()
            self._values.control[STALE] = 0
            self._initialized = True
        except Exception as exc:
            self._failure = f"initialisation failed: {_reason(exc)}"
            self._error(self._failure)
        self._publish(self._values.watched())

    def do_step(self, current_time: float, step_size: float) -> bool:
        control = self._values.control
        try:
            if control[CHANGES] or not self._values.sealed:
                self._enter()
            refusal = self._step_refusal(current_time, step_size)
            if refusal is not None:
                self._error(f"doStep at t = {current_time!r} s refused: {refusal}")
                return False
            self._step(current_time, step_size)
            if self._watched_outputs:
                self._publish(self._watched_outputs)
            self._time = current_time + step_size
            return True
        except Exception as exc:
            self._error(
                f"doStep at t = {current_time!r} s, h = {step_size!r} s failed: {_reason(exc)}"
            )
            return False
        finally:  # they belong to the communication point this step started from
            if control[DERIVATIVES] and not self._values.shared:  # (else the runtime does)
                self._values.clear_derivatives()

    def set_real_input_derivatives(
        self, vrs: list[int], orders: list[int], values: list[float]
    ) -> None:
        """Take the derivatives of Real inputs (order 1: unit/s, 2: unit/s^2) at the
        current communication point, for the next doStep only (``fmi2SetRealInputDerivatives``;
        refused, with nothing stored, unless the class sets ``interpolates_inputs``). The
        FMU's runtime stores them itself, in the same buffer; with pythonfmu's binary (the
        fallback, which does not pass the call on) the runtime calls this."""
        try:
            self._enter()
            slots = []
            for i, vr in enumerate(vrs):  # (no zip(strict=): CPython 3.9)
                var, order, value = self.vars.get(vr), orders[i], values[i]
                if not self.interpolates_inputs:
                    raise ValueError("this FMU takes no input derivatives")
                if not isinstance(var, Real) or var.causality != Fmi2Causality.input:
                    raise ValueError(f"valueReference {vr!r} is not a Real input")
                if order not in (1, 2) or not math.isfinite(value):
                    raise ValueError(
                        f"{var.name}: derivative of order {order!r} = {value!r}: expected "
                        "order 1 or 2 and a finite number"
                    )
                slots.append(self._values.slots[vr])
            self._values.set_derivatives(slots, orders, [float(v) for v in values], vrs)
        except Exception as exc:
            self._error(f"fmi2SetRealInputDerivatives refused: {_reason(exc)}")

    def input_derivative(self, name: str, order: int) -> float:
        """The derivative of order ``order`` (1: unit/s, 2: unit/s^2) of Real input
        ``name`` set for the current step, 0.0 when none was set."""
        slot = self._values.slots[self._vr_of[name]]
        return float(self._values.derivatives[order - 1, slot])

    def terminate(self) -> None:
        self._enter()
        self._phase = _TERMINATED

    def get_real(self, vrs: list[int]) -> list[float]:
        self._before_reading()
        try:  # the hot path: one lookup per call, finite values
            plan = self._real_plan(vrs, self._get_plans, _readable)
            if plan is not None:
                values = [float(var.getter()) for var in plan[0]]
                if all(map(math.isfinite, values)):
                    return values
        except Exception:  # anything unusual: the checked path below names and reports it
            pass
        return [self._get(vr, Real, float, 0.0) for vr in vrs]

    def get_integer(self, vrs: list[int]) -> list[int]:
        self._before_reading()
        return [self._get(vr, Integer, int, 0) for vr in vrs]

    def get_boolean(self, vrs: list[int]) -> list[bool]:
        self._before_reading()
        return [self._get(vr, Boolean, bool, False) for vr in vrs]

    def get_string(self, vrs: list[int]) -> list[str]:
        self._before_reading()
        return [self._get(vr, String, str, "") for vr in vrs]

    def set_real(self, vrs: list[int], values: list[float]) -> None:
        self._enter()
        try:
            if self._set_planned(vrs, values):
                return
        except Exception:  # anything unusual: the checked path below names and reports it
            pass
        self._set_all(vrs, values, Real)

    def _set_planned(self, vrs: list[int], values: list[float]) -> bool:
        """The hot path of :meth:`set_real` (inputs without a range, finite values); False
        if the call is not one it takes."""
        plan = self._real_plan(vrs, self._set_plans, self._writable_any_time)
        if plan is None or len(values) != len(plan[0]) or not all(map(math.isfinite, values)):
            return False
        variables, names = plan
        for var, value in zip(variables, values):
            var.setter(value)
            self._values.mark_written(var.value_reference)
        if self._problems:
            for name in names:
                self._problems.pop(name, None)
        return True

    def set_integer(self, vrs: list[int], values: list[int]) -> None:
        self._enter()
        self._set_all(vrs, values, Integer)

    def set_boolean(self, vrs: list[int], values: list[bool]) -> None:
        self._enter()
        self._set_all(vrs, values, Boolean)

    def set_string(self, vrs: list[int], values: list[str]) -> None:
        self._enter()
        self._set_all(vrs, values, String)

    # --- what the FMU's runtime calls (fmu_runtime/native/slave.c) ---------------------------

    def _buffers(self) -> tuple[bytearray, ...]:
        """The value buffers the runtime answers fmi2Get*/fmi2Set* from (lays them out)."""
        self._seal()
        self._values.shared = True  # the runtime clears the input derivatives after a step
        return self._values.buffers()

    def _initial_outputs(self) -> None:
        """Before a read in initialisation mode after a write: the outputs the FMU will
        start from, computed from the values written so far, in the buffers."""
        self._before_reading()
        self._publish(self._values.watched())

    def _string_values(self) -> list[str]:
        """Every String variable's value, in value-reference order (the runtime's copies)."""
        return [str(var.getter()) for var in self.vars.values() if isinstance(var, String)]

    def _take_strings(self, values: dict[int, str]) -> None:
        """String values the runtime took since it last called (checked there)."""
        self._enter()
        for vr, value in values.items():
            self._set(vr, value, String)

    # --- FMU state -----------------------------------------------------------------------------

    def _get_fmu_state(self, with_values: bool = True) -> dict[str, Any]:
        """The state: the value buffers (as hex text; the runtime, which asks without
        them, saves the buffers itself), the String values, this class's bookkeeping and
        the subclass's snapshot."""
        try:
            self._enter()
            self._publish(self._values.watched())
            state = {
                "version": _STATE_VERSION,
                "class": type(self).__name__,
                "strings": {
                    v.name: v.getter() for v in self.vars.values() if isinstance(v, String)
                },
                "base": {
                    "phase": self._phase,
                    "time": self._time,
                    "initialized": self._initialized,
                    "failure": self._failure,
                    "problems": dict(self._problems),
                },
                "internal": copy.deepcopy(self._state_snapshot()),
            }
            if with_values:
                state["values"] = self._values.dump()
            return state
        except Exception as exc:
            message = f"fmi2GetFMUstate failed: {_reason(exc)}"
            self._error(message)
            return {"error": message}

    def _set_fmu_state(self, state: dict[str, Any]) -> None:
        """Back to :meth:`_get_fmu_state`'s state (the runtime has put the buffers back
        before it calls this, with a state saved without them)."""
        try:
            if not isinstance(state, dict) or "error" in state:
                raise ValueError(
                    f"the FMU state is unusable: {state.get('error', state)!r}"
                    if isinstance(state, dict)
                    else f"not an FMU state: {state!r}"
                )
            if state.get("version") != _STATE_VERSION or state.get("class") != type(self).__name__:
                raise ValueError(
                    f"the FMU state is from {state.get('class')!r} version "
                    f"{state.get('version')!r}, expected {type(self).__name__!r} version "
                    f"{_STATE_VERSION}"
                )
            self._seal()
            if "values" in state:
                self._values.load(state["values"])
            self._values.take_changed()  # every watched variable is set below
            self._hand_over(self._values.watched())
            for name, value in state["strings"].items():
                self.vars[self._vr_of[name]].setter(value)
            base = state["base"]
            self._phase = base["phase"]
            self._time = base["time"]
            self._initialized = base["initialized"]
            self._failure = base["failure"]
            self._problems = dict(base["problems"])
            if not self._initialized:  # what _initialize built is this instance's, not the
                self._values.control[STALE] = 1  # state's: computed again when needed
            self._restore_snapshot(copy.deepcopy(state["internal"]))
        except Exception as exc:
            message = f"fmi2SetFMUstate failed: {_reason(exc)}"
            self._problems["FMU state"] = message
            self._error(message)

    @staticmethod
    def _fmu_state_to_bytes(state: dict[str, Any]) -> bytes:
        """The state as JSON, then its CRC-32 (``_CRC_MARK`` and 8 hex digits), so that bytes
        changed, cut or extended in a host's storage are refused, not restored."""
        try:
            text = json.dumps(state, allow_nan=False).encode("utf-8")
        except Exception as exc:
            text = json.dumps({"error": f"cannot serialise the FMU state: {exc}"}).encode()
        return text + _CRC_MARK + b"%08x" % zlib.crc32(text)

    @staticmethod
    def _fmu_state_from_bytes(state: bytes) -> dict[str, Any]:
        try:
            text, mark, crc = bytes(state).rpartition(_CRC_MARK)
            if not mark or crc != b"%08x" % zlib.crc32(text):
                raise ValueError(
                    f"these {len(state)} bytes are not a state as this FMU serialised it "
                    "(their CRC-32 differs: changed, cut or extended since)"
                )
            decoded: dict[str, Any] = json.loads(text.decode("utf-8"))
            return decoded
        except Exception as exc:
            return {"error": f"cannot deserialise the FMU state: {exc}"}

    # --- the value buffers ---------------------------------------------------------------------

    def _seal(self) -> None:
        """Lay out the value buffers (once): every variable is registered by now."""
        if self._values.sealed:
            return
        self._values.seal()
        self._watched_outputs = [
            vr for vr in self._values.watched() if self.vars[vr].causality == Fmi2Causality.output
        ]
        self._publish(self._values.watched())

    def _enter(self) -> None:
        """At every call: the buffers laid out, watched variables written since the last
        call handed to their setters."""
        if not self._values.sealed:
            self._seal()
        if self._values.control[CHANGES]:
            self._hand_over(self._values.take_changed())

    def _before_reading(self) -> None:
        """A read in initialisation mode after a write computes the outputs first."""
        self._enter()
        if self._values.control[STALE] and self._phase == _INITIALIZATION:
            self._compute_initial_outputs()

    def _hand_over(self, vrs: Iterable[int]) -> None:
        """The buffers' values of the watched variables ``vrs`` to their setters."""
        values = self._values
        for vr in vrs:
            var, kind = self.vars[vr], values.kinds[vr]
            if not kind or var.setter is None:
                continue
            value = values.values[kind][values.slots[vr]]
            try:
                var.setter(bool(value) if kind == BOOLEAN else value)
                self._problems.pop(var.name, None)
            except Exception as exc:
                message = f"set of {var.name} = {value!r} failed: {_reason(exc)}"
                self._problems[var.name] = message
                self._error(message)

    def _publish(self, vrs: Iterable[int]) -> None:
        """The getters' values of the watched variables ``vrs`` into their slots (a Real
        whose getter fails becomes NaN there, which a read then reports)."""
        values = self._values
        for vr in vrs:
            var, kind = self.vars[vr], values.kinds[vr]
            if not kind:
                continue
            slot = values.slots[vr]
            try:
                value = var.getter()
                values.values[kind][slot] = (
                    float(value) if kind == REAL else int(bool(value) if kind == BOOLEAN else value)
                )
            except Exception:
                if kind == REAL:
                    values.values[kind][slot] = math.nan

    # --- build time ----------------------------------------------------------------------

    def to_xml(self, model_options: dict[str, str] | None = None) -> Element:
        """pythonfmu's description plus a ``unit`` (and any declared ``quantity``) on every
        Real and the declared ``direct_feedthrough`` as ModelStructure dependencies (used by
        the build only)."""
        root: Element = super().to_xml(model_options or {})
        if self.interpolates_inputs:
            cosimulation = root.find("CoSimulation")
            if cosimulation is not None:
                cosimulation.set("canInterpolateInputs", "true")
                cosimulation.set("maxOutputDerivativeOrder", "0")
        index = {var.name: i + 1 for i, var in enumerate(self.vars.values())}
        for node in root.findall("ModelVariables/*"):
            variable = node.attrib["name"]
            unit = self._units.get(variable)
            real = node.find("Real")
            if unit and real is not None:
                real.set("unit", unit)
            if variable in self._quantities and real is not None:
                real.set("quantity", self._quantities[variable])
            bounds = self._bounds.get(int(node.attrib["valueReference"]), (None, None))
            for attribute, value in zip(("min", "max"), bounds):
                if value is not None:  # node[0]: the <Real>/<Integer> element
                    node[0].set(attribute, repr(value))
            if variable in self._names:
                _annotate_names(node, self._names[variable])
        outputs = root.find("ModelStructure/Outputs")
        inputs = {v.name for v in self.vars.values() if v.causality == Fmi2Causality.input}
        names = {i: name for name, i in index.items()}
        for unknown in outputs if outputs is not None else []:
            name = names[int(unknown.attrib["index"])]
            depends_on = self.direct_feedthrough.get(name, ())
            unknown_inputs = set(depends_on) - inputs
            if unknown_inputs:
                raise ValueError(
                    f"direct_feedthrough of {name!r} names non-inputs {sorted(unknown_inputs)}"
                )
            unknown.set("dependencies", " ".join(str(index[d]) for d in depends_on))
            if depends_on:
                unknown.set("dependenciesKind", " ".join("dependent" for _ in depends_on))
        self._declare_initial_unknowns(root, index)
        return root

    def _declare_initial_unknowns(self, root: Element, index: dict[str, int]) -> None:
        """ModelStructure/InitialUnknowns for the calculated outputs, with what they depend
        on: the parameters, and the inputs ``initial_dependencies`` names. Without a
        dependencies list an importer must assume every input, which OMSimulator takes for
        an algebraic loop between our FMUs at initialisation."""
        structure = root.find("ModelStructure")
        parameters = [v.name for v in self.vars.values() if v.causality == Fmi2Causality.parameter]
        calculated = [
            v.name
            for v in self.vars.values()
            if v.causality == Fmi2Causality.output and v.initial == Fmi2Initial.calculated
        ]
        if structure is None or not calculated:
            return
        node = SubElement(structure, "InitialUnknowns")
        for name in calculated:
            inputs = self.initial_dependencies.get(name, ())
            depends_on = sorted(index[n] for n in (*parameters, *inputs))
            SubElement(node, "Unknown", index=str(index[name]),
                       dependencies=" ".join(map(str, depends_on)))  # fmt: skip

    # --- internals ---------------------------------------------------------------------------

    def _step_refusal(self, current_time: float, step_size: float) -> str | None:
        if self._failure is not None:
            return self._failure
        if self._phase == _TERMINATED:
            return "the FMU is terminated"
        if not self._initialized:
            return "the FMU is not initialised (call exitInitializationMode first)"
        if self._problems:
            return "; ".join(self._problems.values())
        # (comparisons only, at every step: NaN and infinities fail them)
        if not 0.0 < step_size < math.inf:
            return f"communication step {step_size!r} s: expected a finite number > 0"
        last = self._time  # finite: the start time or the end of a step
        scale = last if last > 1.0 else -last if last < -1.0 else 1.0
        if not abs(current_time - last) <= _TIME_TOLERANCE * scale:
            return (
                f"currentCommunicationPoint = {current_time!r} s is not the FMU's current "
                f"time {self._time!r} s (the start time or the end of the last step)"
            )
        end = current_time + step_size
        if not current_time < end < math.inf:  # the time would become inf, or not move
            return (
                f"communication step {step_size!r} s: the step would end at t + h = "
                f"{end!r} s, not a finite time after t"
            )
        stop = self._stop_time
        if end > stop + _TIME_TOLERANCE * max(abs(stop), 1.0):
            return (
                f"the step of {step_size!r} s ends past the stop time {stop!r} s "
                "given to setupExperiment (FMI 2.0: the FMU has to refuse it)"
            )
        return None

    def _real_plan(
        self,
        vrs: list[int],
        plans: dict[tuple[int, ...], tuple[tuple[Any, ...], tuple[str, ...]] | None],
        eligible: Callable[[Any], bool],
    ) -> tuple[tuple[Any, ...], tuple[str, ...]] | None:
        """(variables, names) of ``vrs`` when every one is a Real ``eligible`` accepts,
        else None; cached per list of value references, as a host asks for the same list
        at every step. The cached plan spares each value the checked path's lookups and
        checks (~1 us per value), which is most of what an FMU step costs."""
        key = tuple(vrs)
        try:
            return plans[key]
        except KeyError:
            pass
        variables = [self.vars.get(vr) for vr in key]
        plan = None
        if all(isinstance(var, Real) and eligible(var) for var in variables):
            plan = (tuple(variables), tuple(v.name for v in variables))
        if len(plans) >= _MAX_PLANS:
            plans.clear()
        plans[key] = plan
        return plan

    def _writable_any_time(self, var: Any) -> bool:
        vr = var.value_reference
        any_time = self._access.get(vr) == _WRITE_ANY_TIME
        return any_time and vr not in self._bounds and var.setter is not None

    def _get(self, vr: int, kind: type[ScalarVariable], convert: type, fallback: Any) -> Any:
        try:
            var = self.vars[vr]
            if not isinstance(var, kind):
                kinds = f"{_a(type(var).__name__)}, not {_a(kind.__name__)}"
                raise TypeError(f"{var.name!r} is {kinds}")
            value = convert(var.getter())
            if kind is Real and not math.isfinite(value):
                self._error(f"{var.name} = {value!r} is not finite")
            return value
        except Exception as exc:
            self._error(f"get{kind.__name__} of valueReference {vr!r} failed: {_reason(exc)}")
            return fallback

    def _set_all(self, vrs: list[int], values: list[Any], kind: type[ScalarVariable]) -> None:
        for vr, value in zip(vrs, values):
            try:
                self._set(vr, value, kind)
            except Exception as exc:
                message = f"set{kind.__name__} of valueReference {vr!r} failed: {_reason(exc)}"
                self._problems[f"vr {vr}"] = message
                self._error(message)

    def _set(self, vr: int, value: Any, kind: type[ScalarVariable]) -> None:
        var = self.vars.get(vr)
        if var is None:
            self._error(f"set{kind.__name__} refused: no variable has valueReference {vr!r}")
            return  # refused, changes nothing: no later step is discarded for it
        name = var.name
        if not isinstance(var, kind):
            self._error(f"{name} is {_a(type(var).__name__)}, not {_a(kind.__name__)}")
            return
        access = self._access[vr]
        if access != _WRITE_ANY_TIME and (access != _WRITE_BEFORE_INIT or self._initialized):
            if access == _WRITE_BEFORE_INIT and var.getter() == value:
                self._problems.pop(name, None)  # the value in use: a no-op
                return
            self._error(
                f"{name} = {value!r} refused: a fixed parameter can only be set before "
                "initialisation"
                if access == _WRITE_BEFORE_INIT
                else f"{name} = {value!r} refused: {_a(var.causality.name)} cannot be set"
            )
            return
        if kind is Real and not math.isfinite(value):
            refusal = f"{name} = {value!r} refused: expected a finite number"
        elif not _within(value, self._bounds.get(vr, (None, None))):
            refusal = f"{name} = {value!r} refused: expected {_range(name, self._bounds[vr])}"
        else:
            var.setter(value)
            self._values.mark_written(vr)
            self._problems.pop(name, None)
            return
        self._problems[name] = refusal  # the step would use the old value: Discard it
        self._error(refusal)

    def _compute_initial_outputs(self) -> None:
        """The outputs the FMU will start from, read in initialisation mode after a write
        (``_initialize`` on the values written so far). Not while a refused value or a
        failure stands: exitInitializationMode reports those."""
        if self._failure is not None or self._problems:
            return
        try:
            self._initialize()
            self._values.control[STALE] = 0
        except Exception as exc:
            self._error(f"the outputs to start from cannot be computed yet: {_reason(exc)}")

    def set_debug_logging(self, categories: str) -> None:
        """The runtime's call after fmi2SetDebugLogging (and after a reset, to the new
        slave): ``categories``, comma-separated, are those whose debug (fmi2OK) messages
        the host takes now ("" for none; FMI 2.0, 2.1.5). Warnings and worse are passed
        whatever it says (fmu_runtime/native/loader.c)."""
        self.debug_categories = frozenset(name for name in categories.split(",") if name)

    def log(
        self,
        msg: str,
        status: Fmi2Status = Fmi2Status.ok,
        category: str | None = None,
        debug: bool | None = None,
    ) -> None:
        """pythonfmu's log with ``%`` escaped: FMI 2.0 hosts treat the message as a printf
        format string (fmpy's logger proxy does), so a path like ``50%.toml`` would not
        print as written; and shortened (:func:`fmu_runtime.log_text.shortened`): a value
        the host wrote may be megabytes long."""
        super().log(shortened(msg).replace("%", "%%"), status, category)

    def _error(self, message: str) -> None:
        self.log(message, Fmi2Status.error)


def _within(value: float, bounds: tuple[float | None, float | None]) -> bool:
    minimum, maximum = bounds
    return (minimum is None or value >= minimum) and (maximum is None or value <= maximum)


def _range(name: str, bounds: tuple[float | None, float | None]) -> str:
    minimum, maximum = bounds
    parts = [f"{minimum!r} <=" if minimum is not None else "", name]
    parts.append(f"<= {maximum!r}" if maximum is not None else "")
    return " ".join(part for part in parts if part)


def _a(word: str) -> str:
    """``word`` with its indefinite article: "an Integer", "an output", "a Real"."""
    return f"{'an' if word[:1].lower() in 'aeiou' else 'a'} {word}"


def _reason(exc: BaseException) -> str:
    """``Type: message`` for unexpected exceptions, the bare message for ValueError."""
    text = str(exc) or repr(exc)
    return text if isinstance(exc, ValueError) else f"{type(exc).__name__}: {text}"
