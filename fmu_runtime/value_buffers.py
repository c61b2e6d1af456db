"""The FMU's variable values in one buffer per type, shared with the FMU's C runtime.

Every Real, Integer and Boolean variable of a :class:`fmu_runtime.safe_slave.SafeSlave` has
a *slot* in its type's buffer: slot ``i`` of a type is its ``i``-th variable in
value-reference order (the order of registration), the same dense index the runtime
computes from ``resources/fmu_variables.txt``. The buffers are ``bytearray`` objects: the
runtime (``fmu_runtime/native/slave.c``) takes a buffer export of each after constructing
the slave and answers ``fmi2Get*``/``fmi2Set*`` from that memory in C, without entering
Python; the slave reads its inputs and writes its outputs through numpy views of the same
memory (:meth:`ValueBuffers.view`). A ``bytearray`` with exports cannot be resized or
freed, so neither side can ever see memory the other has let go. Under the pythonfmu
fallback nobody else takes an export and :class:`SafeSlave` answers the calls from the same
arrays, so the slave's code is the same in both runtimes.

Beside the values (layout shared with ``fmu_runtime/native/loader.h``):

* ``flags``, one byte per value reference: :data:`WATCHED` (set here: the variable's value
  lives in Python storage of its own, a setter to call when it is written),
  :data:`CHANGED` (a watched variable written since Python last took it), :data:`WRITTEN`
  (written, accepted, since instantiation), :data:`DERIVATIVE_1` / :data:`DERIVATIVE_2`
  (an input derivative of that order set for the next step);
* ``control``, :data:`CONTROL_SIZE` bytes: :data:`CHANGES` (some watched variable is
  CHANGED), :data:`STALE` (something was written since the outputs to start from were
  computed), :data:`DERIVATIVES` (some input derivative is set);
* ``derivatives``: two float64 per Real slot, the input derivatives of order 1 (unit/s)
  then order 2 (unit/s^2) for the next step, 0.0 where none is set.

Strings have no slot: their values stay in Python storage (and C keeps copies).

Written by hand because no library shares typed values between C and Python this way
(``multiprocessing.shared_memory`` is for other processes; ctypes arrays would tie the
memory's life to an object the runtime cannot reach without the GIL).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

REAL, INTEGER, BOOLEAN = "R", "I", "B"
KINDS = (REAL, INTEGER, BOOLEAN)
_DTYPES = {REAL: np.float64, INTEGER: np.int32, BOOLEAN: np.int32}  # fmi2Boolean is an int
_ITEM_SIZES = {REAL: 8, INTEGER: 4, BOOLEAN: 4}

# flags, one byte per value reference
WATCHED, CHANGED, WRITTEN, DERIVATIVE_1, DERIVATIVE_2 = 1, 2, 4, 8, 16
# control bytes
CHANGES, STALE, DERIVATIVES = 0, 1, 2
CONTROL_SIZE = 8


class ValueBuffers:
    """The value buffers of one slave instance (see the module docstring).

    Slots are added while the slave registers its variables (:meth:`add`); the buffers are
    allocated, exactly sized, by :meth:`seal`, which the first view or FMI call does.
    Until then the slots' values are kept in lists with the same indexing, so getters made
    before sealing keep working after it.
    """

    def __init__(self) -> None:
        self.sealed = False
        self.shared = False  # True once the FMU's runtime holds the buffers
        self._pending: dict[str, list[Any]] = {kind: [] for kind in KINDS}
        self.kinds: list[str] = []  # per value reference: R I B, or "" (a String)
        self.slots: list[int] = []  # per value reference: the slot, -1 for a String
        self._watched: list[bool] = []
        # before sealing: the pending lists; after: memoryviews of the buffers
        self.values: dict[str, Any] = dict(self._pending)
        self.bytes: dict[str, bytearray] = {}
        self.arrays: dict[str, np.ndarray] = {}
        self.flags = bytearray()
        self.control = bytearray(CONTROL_SIZE)
        self.derivatives = np.zeros((2, 0))
        self._derivative_bytes = bytearray()
        self._flag_array = np.zeros(0, dtype=np.uint8)

    # --- layout ---------------------------------------------------------------------------

    def add(self, kind: str, value: Any, watched: bool) -> int:
        """A new variable of ``kind`` (R, I, B; "" for a String, which gets no slot) with
        the initial ``value``, at the next value reference; returns its slot (-1)."""
        if self.sealed:
            raise RuntimeError(
                "a variable was registered after the slave's values were laid out (register "
                "every variable before taking a view with SafeSlave.values_of)"
            )
        slot = -1
        if kind:
            slot = len(self._pending[kind])
            self._pending[kind].append(value)
        self.kinds.append(kind)
        self.slots.append(slot)
        self._watched.append(watched or not kind)
        return slot

    def count(self, kind: str) -> int:
        """How many variables of ``kind`` have a slot."""
        return len(self._pending[kind])

    def seal(self) -> None:
        """Allocate the buffers (once) and move the slots' values into them."""
        if self.sealed:
            return
        for kind in KINDS:
            pending = self._pending[kind]
            data = bytearray(_ITEM_SIZES[kind] * len(pending))
            array = np.frombuffer(data, dtype=_DTYPES[kind])
            array[:] = pending
            self.bytes[kind], self.arrays[kind] = data, array
            self.values[kind] = memoryview(data).cast("d" if kind == REAL else "i")
        self.flags = bytearray(WATCHED if watched else 0 for watched in self._watched)
        self._flag_array = np.frombuffer(self.flags, dtype=np.uint8)
        self._derivative_bytes = bytearray(16 * self.count(REAL))
        self.derivatives = np.frombuffer(self._derivative_bytes).reshape(2, self.count(REAL))
        # exports of every buffer for as long as this object lives: none can be resized
        self._pinned = [memoryview(buffer) for buffer in (self.flags, self.control)]
        self.sealed = True

    def buffers(self) -> tuple[bytearray, ...]:
        """The six buffers the runtime takes: Real, Integer and Boolean values, flags,
        control, derivatives (seals first)."""
        self.seal()
        return (
            self.bytes[REAL],
            self.bytes[INTEGER],
            self.bytes[BOOLEAN],
            self.flags,
            self.control,
            self._derivative_bytes,
        )

    def view(self, kind: str, first: int, n: int) -> np.ndarray:
        """A numpy view of ``n`` consecutive slots of ``kind`` from slot ``first`` (seals)."""
        self.seal()
        return self.arrays[kind][first : first + n]

    # --- access ---------------------------------------------------------------------------

    def getter(self, kind: str, slot: int) -> Callable[[], Any]:
        """A pythonfmu getter of a slot (a Python float or int)."""
        values = self.values

        def get() -> Any:
            return values[kind][slot]

        return get

    def setter(self, kind: str, slot: int) -> Callable[[Any], None]:
        """A pythonfmu setter of a slot (a Boolean is stored as 0 or 1)."""
        values = self.values
        convert: Callable[[Any], Any] = float if kind == REAL else int

        def set_(value: Any) -> None:
            values[kind][slot] = convert(bool(value)) if kind == BOOLEAN else convert(value)

        return set_

    def watched(self) -> list[int]:
        """The value references whose values live in Python storage of their own."""
        return [vr for vr, watched in enumerate(self._watched) if watched]

    def take_changed(self) -> list[int]:
        """The watched value references written since the last call (cleared)."""
        self.control[CHANGES] = 0
        changed = [vr for vr, f in enumerate(self.flags) if f & CHANGED]
        for vr in changed:
            self.flags[vr] &= ~CHANGED & 0xFF
        return changed

    def mark_written(self, vr: int) -> None:
        """An accepted write of ``vr`` (by Python: the runtime marks its own)."""
        self.flags[vr] |= WRITTEN
        self.control[STALE] = 1

    def set_derivatives(self, slots: Sequence[int], orders: Sequence[int], values: Sequence[float],
                        vrs: Sequence[int]) -> None:  # fmt: skip
        """Input derivatives for the next step (checked by the caller)."""
        for i, slot in enumerate(slots):  # (no zip(strict=): CPython 3.9)
            self.derivatives[orders[i] - 1, slot] = values[i]
            self.flags[vrs[i]] |= DERIVATIVE_1 if orders[i] == 1 else DERIVATIVE_2
        self.control[DERIVATIVES] = 1

    def clear_derivatives(self) -> None:
        """No input derivative set any more (after each step)."""
        self.derivatives.fill(0.0)
        self._flag_array &= ~(DERIVATIVE_1 | DERIVATIVE_2) & 0xFF
        self.control[DERIVATIVES] = 0

    # --- FMU state ------------------------------------------------------------------------

    def dump(self) -> dict[str, str]:
        """Every buffer as hex text (exact, JSON-serialisable)."""
        buffers = self.buffers()
        return {name: bytes(buffers[i]).hex() for i, name in enumerate(_BUFFER_NAMES)}

    def load(self, dumped: dict[str, str]) -> None:
        """Back to what :meth:`dump` returned (same layout, else ValueError)."""
        loaded = [bytes.fromhex(dumped[name]) for name in _BUFFER_NAMES]
        buffers = self.buffers()
        for i, name in enumerate(_BUFFER_NAMES):  # (no zip(strict=): CPython 3.9)
            if len(loaded[i]) != len(buffers[i]):
                raise ValueError(
                    f"the FMU state's {name} hold {len(loaded[i])} bytes, this FMU's "
                    f"{len(buffers[i])}"
                )
        for i, target in enumerate(buffers):
            target[:] = loaded[i]  # the same length: no resize, the views stay valid


_BUFFER_NAMES = ("reals", "integers", "booleans", "flags", "control", "derivatives")
