"""The stepping loop's FMI calls (``Slave.put_inputs``/``read_reals``/``advance``): C
functions called without declared argument types, so every argument must already be a
ctypes object of the C type (a Python int would go as a 32-bit int, a float not at all),
and a status worse than fmi2Warning raises what fmpy's wrappers raise."""

from __future__ import annotations

import ctypes
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException

from cosim.engine.slave import _hot_calls

_CTYPES = (ctypes._SimpleCData, ctypes.Array, ctypes._Pointer)  # what ctypes passes as is


class FakeLibrary:
    """Records each call's arguments and answers ``status``."""

    def __init__(self, status: int) -> None:
        self.status = status
        self.calls: list[tuple[str, tuple[Any, ...]]] = []

    def __getitem__(self, name: str) -> Any:
        library = self

        class Function:
            restype: Any = None

            def __call__(self, *args: Any) -> int:
                library.calls.append((name, args))
                return library.status

        return Function()


def _slave(status: int, others: bool = False) -> SimpleNamespace:
    inputs, outputs = np.zeros(2), np.zeros(3)
    double_p = ctypes.POINTER(ctypes.c_double)
    fake = SimpleNamespace(
        handle=ctypes.c_void_p(0x1234),
        fmu=SimpleNamespace(dll=FakeLibrary(status)),
        input_vrs=(ctypes.c_uint * 2)(1, 2),
        n_inputs=2,
        input_ptr=inputs.ctypes.data_as(double_p),
        output_vrs=(ctypes.c_uint * 3)(3, 4, 5),
        n_outputs=3,
        output_ptr=outputs.ctypes.data_as(double_p),
        others=others,
        read_others=[],
    )
    fake.get_others = lambda: fake.read_others.append(True)
    fake.warnings = []  # (function, t) of each fmi2Warning
    fake.note_warning = lambda function, t: fake.warnings.append((function, t))
    return fake


@pytest.mark.parametrize("status", [0, 1])
def test_every_argument_of_every_call_is_a_ctypes_object(status: int) -> None:
    """The component, the counts, the times and the flag go as c_void_p, c_size_t,
    c_double and c_int; a Warning passes as fmpy's wrappers let it."""
    fake = _slave(status)
    put_inputs, read_reals, advance = _hot_calls(fake)  # type: ignore[arg-type]
    put_inputs()
    read_reals()
    advance(0.25, 0.01)
    calls = fake.fmu.dll.calls
    assert [name for name, _ in calls] == [
        "fmi2SetReal",
        "fmi2GetReal",
        "fmi2DoStep",
        "fmi2GetReal",
    ]
    for name, args in calls:
        assert all(isinstance(arg, _CTYPES) for arg in args), (name, args)
        assert args[0].value == 0x1234
    # a doStep's Warning is noted with the step's start time (its message kept)
    assert fake.warnings == ([("fmi2DoStep", 0.25)] if status else [])
    _, (_, t, h, flag) = calls[2]
    assert (type(t), t.value, type(h), h.value) == (ctypes.c_double, 0.25, ctypes.c_double, 0.01)
    assert (type(flag), flag.value) == (ctypes.c_int, 1)
    assert [(type(args[2]), args[2].value) for name, args in calls if name != "fmi2DoStep"] == [
        (ctypes.c_size_t, 2), (ctypes.c_size_t, 3), (ctypes.c_size_t, 3)
    ]  # fmt: skip


@pytest.mark.parametrize("status", [2, 3, 4])
@pytest.mark.parametrize(
    ("call", "function"),
    [("put_inputs", "fmi2SetReal"), ("read_reals", "fmi2GetReal"), ("advance", "fmi2DoStep")],
)
def test_a_refused_call_raises_what_fmpy_raises(status: int, call: str, function: str) -> None:
    """Discard, Error or Fatal raises FMICallException naming the C function, as fmpy's
    wrappers do (the master reports it, or ends the run on a doStep's Discard)."""
    fake = _slave(status)
    put_inputs, read_reals, advance = _hot_calls(fake)  # type: ignore[arg-type]
    calls = {"put_inputs": put_inputs, "read_reals": read_reals, "advance": advance}
    with pytest.raises(FMICallException) as caught:
        calls[call](*((0.0, 0.01) if call == "advance" else ()))
    assert (caught.value.function, caught.value.status) == (function, status)
    assert len(fake.fmu.dll.calls) == 1  # nothing after the refused call


def test_a_step_reads_the_integer_and_boolean_outputs_too() -> None:
    fake = _slave(0, others=True)
    _, _, advance = _hot_calls(fake)  # type: ignore[arg-type]
    advance(0.0, 0.01)
    assert fake.read_others == [True]
