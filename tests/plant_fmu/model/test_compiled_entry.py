"""``jit.compiled_entry``: a compiled function called without numba's dispatch (as the
plant FMU's step and the master's input extrapolation call theirs) computes exactly what
the dispatched call computes."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from plant_fmu.model import compiled
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.jit import compiled_entry
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.state_layout import CURRENT
from plant_fmu.model.stepping import stepping_state


@pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)
def test_the_bound_step_steps_bit_for_bit_as_the_dispatched_one() -> None:
    """compiled.step_into with its arrays bound once, as AuvPlant binds its buffers, over
    50 steps with input derivatives (a strided view, as the FMU's derivative buffer)."""
    fast = compiled.CompiledPlant(PlantModel(load_vehicle("remus100"), Variant.FULL))
    x0 = fast.model.project(stepping_state(state_vector({"u": 1.5, "v": 0.1, "r": 0.2})))
    inputs = input_vector({"tunnel_force": 1.0, "fin_angle": 0.05, "mass_position_cmd": 0.03},
                          thrust=9.0)  # fmt: skip

    def arrays() -> tuple[np.ndarray, ...]:
        rates = np.zeros((2, inputs.size + 1))[:, : inputs.size]
        rates[0, 2:5], rates[1, 2:5] = (0.3, -0.01, 0.002), (0.1, 0.0, -0.001)
        scratch = np.empty(compiled.STEP_SCRATCH)
        return (fast.parameters, inputs.copy(), rates, x0.copy(), np.zeros(4),
                inputs[CURRENT].copy(), scratch)  # fmt: skip

    bound = arrays()
    stepper = functools.partial(compiled_entry(compiled.step_into, (*bound, 1, 1.0)), *bound)
    dispatched = arrays()
    for _ in range(50):
        assert stepper(2, 0.005) == 0
        assert compiled.step_into(*dispatched, 2, 0.005) == 0
    np.testing.assert_array_equal(bound[3], dispatched[3])  # the state
    np.testing.assert_array_equal(bound[4], dispatched[4])  # the derived outputs
    assert not np.array_equal(bound[3], x0)  # it moved


def test_without_numba_the_function_itself_is_called() -> None:
    def add(a: float, b: float) -> float:
        return a + b

    assert compiled_entry(add, (1.0, 2.0)) is add
