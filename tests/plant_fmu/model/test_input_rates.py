"""The plant step with varying inputs (``stepping.advance`` with ``rates``: the master's
input extrapolation through FMI input derivatives)."""

from __future__ import annotations

import numpy as np
import pytest

from plant_fmu.model import compiled
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance, stepping_state

MASS_CMD = INPUT_INDEX["mass_position_cmd"]


def plant(variant: Variant = Variant.LATERAL) -> tuple[PlantModel, np.ndarray, np.ndarray]:
    model = PlantModel(load_vehicle("remus100"), variant=variant)
    x = np.zeros(14)
    x[STATE_INDEX["u"]], x[STATE_INDEX["v"]] = 1.5, -0.05
    inputs = np.zeros(8)
    inputs[INPUT_INDEX["thrust"]] = 9.0
    return model, stepping_state(model.project(x)), inputs


def test_zero_rates_are_the_held_step_to_the_bit() -> None:
    model, z, inputs = plant()
    held = advance(model, z, inputs, 0.05)
    assert np.array_equal(advance(model, z, inputs, 0.05, rates=np.zeros((2, 8))), held)


@pytest.mark.slow  # compiles the varying-input step the first time (numba)
@pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)
@pytest.mark.parametrize("variant", [Variant.FULL, Variant.LATERAL])
def test_the_compiled_step_with_rates_agrees_with_the_reference(variant: Variant) -> None:
    model, z, inputs = plant(variant)
    inputs[MASS_CMD] = 0.01
    rates = np.zeros((2, 8))
    rates[:, MASS_CMD] = (0.2, -1.5)
    rates[:, INPUT_INDEX["fin_angle"]] = (0.1, 0.3)
    fast = compiled.CompiledPlant(model)
    reference = advance(model, z, inputs, 0.03, 0.01, None, rates)
    np.testing.assert_allclose(advance(model, z, inputs, 0.03, 0.01, fast, rates), reference,
                               rtol=1e-12, atol=1e-13)  # fmt: skip


def test_a_step_following_its_inputs_gains_orders_over_a_held_one() -> None:
    """Driven by y_d(t) = 0.05 sin(2 t), one step from t = 0 with the derivatives at its
    start is compared with the same step taken in fine sub-steps that follow y_d exactly:
    its error in the mass position shrinks two orders faster with h than holding y_d(0)
    does (about h^5 against h^3: the servo integrates y_d twice), and is 10x smaller."""
    model, z, inputs = plant()

    def exact(h: float) -> np.ndarray:
        state, n = z, 64
        for k in range(n):
            u = inputs.copy()
            rates = np.zeros((2, 8))
            t = k * h / n
            u[MASS_CMD] = 0.05 * np.sin(2 * t)
            rates[:, MASS_CMD] = (0.1 * np.cos(2 * t), -0.2 * np.sin(2 * t))
            state = advance(model, state, u, h / n, h / n, None, rates)
        return state

    rates = np.zeros((2, 8))
    rates[:, MASS_CMD] = (0.1, 0.0)  # y_d'(0) = 0.1 m/s, y_d''(0) = 0
    errors_rates, errors_held = [], []
    for h in (0.2, 0.1):
        reference = exact(h)[STATE_INDEX["mass_position"]]
        with_rates = advance(model, z, inputs, h, h, None, rates)[STATE_INDEX["mass_position"]]
        held = advance(model, z, inputs, h, h)[STATE_INDEX["mass_position"]]
        errors_rates.append(abs(with_rates - reference))
        errors_held.append(abs(held - reference))
    order_rates = np.log2(errors_rates[0] / errors_rates[1])
    order_held = np.log2(errors_held[0] / errors_held[1])
    assert order_rates > order_held + 0.8
    assert errors_rates[1] < errors_held[1] / 10


def test_a_non_finite_rate_is_named() -> None:
    model, z, inputs = plant()
    rates = np.zeros((2, 8))
    rates[1, MASS_CMD] = np.nan
    with pytest.raises(ValueError, match=r"input derivative of mass_position_cmd = nan"):
        advance(model, z, inputs, 0.01, rates=rates)
