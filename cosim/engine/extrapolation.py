"""Input extrapolation across a communication step, through FMI input derivatives.

A connected Real input is set at the start of each step of its instance to the value its
source has then; without more, the FMU holds it over the step (FMI 2.0's default), and a
closed loop converges at first order in the step. With ``[coupling] extrapolation`` set
to ``"linear"`` or ``"quadratic"``, the master also hands an instance that declares
``canInterpolateInputs="true"`` the first (and second) time derivative of each such
input with ``fmi2SetRealInputDerivatives`` (FMI 2.0, section 4.2.2): the derivatives at
t_n of the polynomial through the values the instance took at its last two (three)
steps, by divided differences (steps of any length: the adaptive algorithm's too).
The FMU then uses u(t_n + s) = u_n + s u' + s^2 / 2 u'' inside its step, and the loop
converges at the polynomial's order plus one.

Extrapolation across a jump is wrong for a step or two, so the history starts again at
every event, override or fault boundary the master applies (``epoch``), and where the
jump an event causes in a source's outputs reaches an instance that takes them a point
later (``Timeline.epoch_of``); a jump inside an FMU (a saturation, a switch) costs one
step's worth of accuracy. Instances that cannot
interpolate hold their inputs as before: nothing is sent to them.

Why by hand: fmpy's ``Input`` class interpolates a given table of input signals; no
library extrapolates the exchanged values of a running co-simulation.

Cost: the divided differences and the history's move are one compiled call (numba, no
fastmath: the same IEEE operations as numpy's, value for value) and the FMI call goes to
the C function directly, with arguments made once, its status checked here as fmpy's
wrapper does; a send costs ~1 us instead of ~8 us of numpy calls and fmpy's wrapper
(``scripts/bench_loader.py`` times the FMU's side).
"""

from __future__ import annotations

import ctypes
import functools
from collections.abc import Callable
from typing import Any

import numpy as np
from fmpy.fmi1 import FMICallException

from plant_fmu.model.jit import compiled_entry, load_numba, njit

_DOUBLE_P = ctypes.POINTER(ctypes.c_double)


@functools.cache
def _compiled_extrapolate() -> Callable[..., int]:
    """numba's compiled :func:`_extrapolate` (:func:`njit`: cached where it can be) when
    numba is usable, else the Python function unchanged; made at the first extrapolation
    in a process, not as the engine is imported: a local study's client imports the
    engine's modules but steps no FMU, and numba's import (~0.15 s of CPU) delayed its
    first run (on a 2-core machine the client's start-up is the last thing the workers
    wait for)."""
    numba, _ = load_numba()
    if numba is None:
        return _extrapolate
    return njit(numba, _extrapolate)


def _extrapolate(
    inputs: np.ndarray,
    past: np.ndarray,
    times: np.ndarray,
    slope: np.ndarray,
    values: np.ndarray,
    order: int,
    t: float,
    count: int,
) -> int:
    """One step of an input history: with ``count`` points in it (``past[0]`` at
    ``times[0]``, ``past[1]`` at ``times[1]``, s) and ``inputs`` now at ``t``, ``values``
    = the first derivatives at t of the polynomial through inputs and past[0] (linear),
    and past[1] too (``order`` 2 and count >= 2), then (when ``values`` has room) the
    second derivatives (0 for linear); ``slope`` is scratch. Then inputs at t join the
    history. Returns 1 when ``values`` were computed (count >= 1 and t after times[0]),
    plus 2 when the history moved on (count 0 or t after times[0])."""
    n = inputs.size
    later = t > times[0]
    code = 0
    if count >= 1 and later:
        scale = 1.0 / (t - times[0])
        for i in range(n):  # [u_n, u_n-1]
            slope[i] = (inputs[i] - past[0, i]) * scale
        if order == 2 and count >= 2:
            t0, t1 = times[0], times[1]
            scale_past, scale_both, span = 1.0 / (t0 - t1), 1.0 / (t - t1), t - t0
            for i in range(n):
                second = (past[0, i] - past[1, i]) * scale_past  # [u_n-1, u_n-2] ...
                second = (slope[i] - second) * scale_both  # ... then [u_n, u_n-1, u_n-2]
                values[i] = second * span + slope[i]
                values[n + i] = second * 2.0
        else:
            for i in range(n):
                values[i] = slope[i]
            for i in range(n, values.size):
                values[i] = 0.0
        code = 1
    if count == 0 or later:
        for i in range(n):
            past[1, i] = past[0, i]
            past[0, i] = inputs[i]
        times[1] = times[0]
        times[0] = t
        code += 2
    return code


class InputRates:
    """The input derivatives of one instance: :meth:`send` after its inputs were set.

    Args:
        fmu: the instance's fmpy ``FMU2Slave`` (its ``fmi2SetRealInputDerivatives``).
        input_vrs: value references of its connected Real inputs (the master's order).
        order: 1 (linear) or 2 (quadratic).
        handle: the instance's fmi2Component as a ``ctypes.c_void_p`` whose value may be
            set later (``Slave.handle``: the loop binds this object before the FMU is
            instantiated); by default the fmu's ``component`` now.
        held: the positions (in ``input_vrs``) of inputs sent derivatives of 0: held over
            the step. An input whose source steps less often than its instance (a larger
            step multiple) is one: its values at the instance's points are stairs, which
            a polynomial through them turns into a zigzag of twice their height.
    """

    def __init__(
        self,
        fmu: Any,
        input_vrs: list[int],
        order: int,
        handle: ctypes.c_void_p | None = None,
        held: list[int] | tuple[int, ...] = (),
    ) -> None:
        n = len(input_vrs)
        # the slots of self._values of the held inputs: first and (quadratic) second
        self._held = np.asarray([i + j * n for j in range(order) for i in held], dtype=np.intp)
        self.order = order
        self.n = n
        # a function object of the C function without declared argument types, called
        # with ctypes objects made once (as cosim.engine.slave's hot calls)
        self._set = fmu.dll["fmi2SetRealInputDerivatives"]
        self._set.restype = ctypes.c_int
        self._handle = ctypes.c_void_p(fmu.component) if handle is None else handle
        self._size = ctypes.c_size_t(order * n)
        # one call per step: every input's first derivative, then (quadratic) its second
        self._vrs = (ctypes.c_uint * (order * n))(*(list(input_vrs) * order))
        self._orders = (ctypes.c_int * (order * n))(*([1] * n + [2] * n)[: order * n])
        self._values = np.zeros(order * n)
        self._ptr = self._values.ctypes.data_as(_DOUBLE_P)
        self._past = np.zeros((2, n))  # the values at the previous two steps
        self._slope = np.zeros(n)
        self._times = np.zeros(2)  # s, of past[0] and past[1]
        self.count = 0  # steps in the history (since the last epoch)
        self.epoch = 0
        # _extrapolate with every array bound, for the inputs array it was bound to
        self._bound: tuple[np.ndarray | None, Callable[..., int]] = (None, _extrapolate)
        self.sent_at: float | None = None  # s, the point of the derivatives last sent

    def send(self, inputs: np.ndarray, t: float, epoch: int) -> None:
        """The derivatives at ``t`` (s) for the values ``inputs`` just set, handed to the
        FMU; the history then moves on by one step. A new ``epoch`` (something jumped)
        starts the history again: nothing is sent at its first step."""
        if epoch != self.epoch:
            self.epoch, self.count = epoch, 0
        bound, extrapolate = self._bound
        if inputs is not bound:  # (the master passes the same array at every step)
            extrapolate = self._bind(inputs)
        code = extrapolate(t, self.count)
        if code & 1:
            if self._held.size:
                self._values[self._held] = 0.0
            status = self._set(self._handle, self._vrs, self._size, self._orders, self._ptr)
            if status and status != 1:  # worse than fmi2Warning, or out of the enum
                raise FMICallException(function="fmi2SetRealInputDerivatives", status=status)
            self.sent_at = t
        if code & 2:
            self.count += 1

    def _bind(self, inputs: np.ndarray) -> Callable[..., int]:
        """:func:`_extrapolate` on ``inputs`` and this history's arrays, called without
        numba's typing of the five arrays at every step (:func:`compiled_entry`)."""
        arrays = (inputs, self._past, self._times, self._slope, self._values, self.order)
        entry = compiled_entry(_compiled_extrapolate(), (*arrays, 0.0, 0))
        extrapolate = functools.partial(entry, *arrays)
        self._bound = (inputs, extrapolate)
        return extrapolate

    def derivatives(self, t: float) -> tuple[np.ndarray, np.ndarray] | None:
        """(first, second) derivatives the FMU was handed at ``t`` (s), if it was: the
        polynomial it follows over its step is u + s first + s^2 / 2 second."""
        if self.sent_at != t:
            return None
        first, second = self._values[: self.n], self._values[self.n :]
        return first.copy(), second.copy() if self.order == 2 else np.zeros(self.n)

    def snapshot(self) -> tuple[Any, ...]:
        """The history, for :meth:`restore` (a rolled-back step)."""
        return self._past.copy(), self._times.tolist(), self.count, self.epoch, self.sent_at

    def restore(self, saved: tuple[Any, ...]) -> None:
        past, times, self.count, self.epoch, self.sent_at = saved
        self._past[:] = past
        self._times[:] = times
