"""The slave's value buffers (fmu_runtime/value_buffers.py), in-process: the layout the C
runtime relies on (one slot per variable of a type, dense, in value-reference order, and
buffers of exactly that size), views and FMI calls seeing the same memory, memory that
cannot move while viewed, and FMU states that keep every byte."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real, String

from fmu_runtime.safe_slave import SafeSlave
from fmu_runtime.value_buffers import CHANGED, STALE, WATCHED, WRITTEN


class Mixed(SafeSlave):
    """Real, Integer, Boolean and String variables interleaved, some in the buffers (no
    getter, setter or attribute), some in attributes of their own."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.gain = 2.0  # attributes: watched
        self.label = "toy"
        self.count = 0
        io = {"variability": Fmi2Variability.continuous}
        out = {"causality": Fmi2Causality.output, "initial": Fmi2Initial.calculated, **io}
        discrete = {"variability": Fmi2Variability.discrete}
        self.register(Real("u0", causality=Fmi2Causality.input, description="u0", **io), "m")
        self.register(Real("u1", causality=Fmi2Causality.input, description="u1", **io), "m")
        self.register(Integer("count", causality=Fmi2Causality.output, description="n",
                              initial=Fmi2Initial.calculated, **discrete))  # fmt: skip
        self.register(Real("gain", causality=Fmi2Causality.parameter, description="k",
                           variability=Fmi2Variability.tunable), "1")  # fmt: skip
        self.register(Real("y0", description="y0", **out), "m")
        self.register(Real("y1", description="y1", **out), "m")
        self.register(Boolean("on", causality=Fmi2Causality.input, description="on",
                              start=True, **discrete))  # fmt: skip
        self.register(String("label", causality=Fmi2Causality.parameter, description="s",
                             variability=Fmi2Variability.fixed))  # fmt: skip
        self.inputs = self.values_of(["u0", "u1"])
        self.outputs = self.values_of(["y0", "y1"])

    def _initialize(self):
        self._step(0.0, 0.0)

    def _step(self, current_time, step_size):
        self.outputs[:] = self.gain * self.inputs
        self.count += 1


def _initialised() -> Mixed:
    slave = Mixed(instance_name="mixed")
    slave.setup_experiment(0.0, None, None)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


def test_each_type_has_dense_slots_in_value_reference_order_and_buffers_of_that_size():
    slave = _initialised()
    values = slave._values
    assert values.kinds == ["R", "R", "I", "R", "R", "R", "B", ""]
    assert values.slots == [0, 1, 0, 2, 3, 4, 0, -1]  # what the runtime computes
    reals, integers, booleans, flags, control, derivatives = slave._buffers()
    assert (len(reals), len(integers), len(booleans)) == (5 * 8, 1 * 4, 1 * 4)
    assert (len(flags), len(control), len(derivatives)) == (8, 8, 2 * 5 * 8)
    watched = [vr for vr in range(8) if flags[vr] & WATCHED]
    assert watched == [2, 3, 7]  # count (an attribute the step sets), gain, label


def test_a_view_and_the_fmi_calls_see_the_same_memory():
    slave = _initialised()
    u0, y1, on = (slave._vr_of[n] for n in ("u0", "y1", "on"))
    slave.set_real([u0], [1.5])
    assert slave.inputs[0] == 1.5  # the write is in the view
    assert slave.do_step(0.0, 0.1)
    assert slave.get_real([y1]) == [0.0] and slave.outputs[0] == 3.0
    slave.outputs[1] = -4.25  # what the slave writes is what a read gets
    assert slave.get_real([y1]) == [-4.25]
    assert slave.get_boolean([on]) == [True]
    assert np.frombuffer(slave._buffers()[0])[slave._values.slots[u0]] == 1.5


def test_watched_variables_written_by_the_runtime_reach_their_setter_at_the_next_call():
    """The runtime writes a watched variable's slot and flags it CHANGED; the slave
    hands the value to the variable's own setter when it is next called."""
    slave = _initialised()
    gain = slave._vr_of["gain"]
    values = slave._values
    values.values["R"][values.slots[gain]] = 5.0  # as values.c writes it
    values.flags[gain] |= CHANGED | WRITTEN
    values.control[0] = 1
    assert slave.gain == 2.0
    assert slave.do_step(0.0, 0.1)
    assert slave.gain == 5.0 and not values.flags[gain] & CHANGED and values.control[0] == 0
    assert slave.was_written("gain") and not slave.was_written("u0")


def test_views_take_only_runs_of_one_type_kept_in_the_buffers():
    slave = Mixed(instance_name="mixed")
    for names in (["u0", "y0"], ["u1", "count"], ["gain"], ["label"], [], ["y1", "y0"]):
        with pytest.raises(ValueError, match="expected a run of variables"):
            slave.values_of(names)


def test_a_variable_registered_after_the_layout_is_refused():
    slave = Mixed(instance_name="mixed")  # its views laid the buffers out
    with pytest.raises(RuntimeError, match="registered after the slave's values were laid out"):
        slave.register(Real("late", causality=Fmi2Causality.input, description="late",
                            variability=Fmi2Variability.continuous), "m")  # fmt: skip


def test_the_buffers_cannot_move_or_shrink_while_the_slave_views_them():
    """The runtime reads and writes their memory without the GIL: it must stay put."""
    slave = _initialised()
    for buffer in slave._buffers():
        with pytest.raises(BufferError):
            buffer.extend(b"\0" * 8)
        with pytest.raises(BufferError):
            buffer.clear()


def test_a_write_marks_the_outputs_to_start_from_stale_until_they_are_read():
    slave = Mixed(instance_name="mixed")
    slave.setup_experiment(0.0, None, None)
    slave.enter_initialization_mode()
    slave.set_real([slave._vr_of["u0"]], [2.0])
    assert slave._values.control[STALE]
    assert slave.get_real([slave._vr_of["y0"]]) == [4.0]
    assert not slave._values.control[STALE]


finite_or_not = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)


@settings(max_examples=50, deadline=None)
@given(
    reals=st.lists(finite_or_not, min_size=5, max_size=5), count=st.integers(-(2**31), 2**31 - 1)
)
def test_an_fmu_state_keeps_every_byte_of_the_buffers(reals, count):
    slave = _initialised()
    arrays = slave._values.arrays
    arrays["R"][:] = reals
    arrays["I"][0] = count
    slave._values.derivatives[1, 3] = -0.0
    blob = Mixed._fmu_state_to_bytes(slave._get_fmu_state())
    before = [bytes(b) for b in slave._buffers()]  # (the state saved gain's value too)
    arrays["R"][:] = 0.0
    arrays["I"][0] = 0
    slave._values.derivatives.fill(1.0)
    slave._set_fmu_state(Mixed._fmu_state_from_bytes(blob))
    assert [bytes(b) for b in slave._buffers()] == before
    gain = slave._values.slots[slave._vr_of["gain"]]
    restored = [x for i, x in enumerate(arrays["R"].tolist()) if i != gain]
    expected = [x for i, x in enumerate(reals) if i != gain]
    pairs = zip(restored, expected, strict=True)
    assert all(a == b or (math.isnan(a) and math.isnan(b)) for a, b in pairs)
    assert slave.gain == 2.0


def test_a_state_of_another_layout_is_refused():
    slave = _initialised()
    state = slave._get_fmu_state()
    state["values"]["reals"] = state["values"]["reals"][:-16]  # one Real short
    slave._set_fmu_state(state)
    errors = "\n".join(m.msg for m in slave.log_queue)
    assert "the FMU state's reals hold 32 bytes, this FMU's 40" in errors
    assert slave.do_step(0.0, 0.1) is False
