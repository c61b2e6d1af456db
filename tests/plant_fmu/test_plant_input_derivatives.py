"""The plant and autopilot slaves take the importer's input derivatives (FMI's
fmi2SetRealInputDerivatives: ``SafeSlave.set_real_input_derivatives`` in Python, the
runtime's buffer in C) into their steps."""

from __future__ import annotations

import numpy as np
import pytest
from pythonfmu.enums import Fmi2Causality

from controller_fmu.auv_autopilot import AuvAutopilot
from controller_fmu.modes import HeadingMode
from plant_fmu.auv_plant import AuvPlant
from plant_fmu.model.state_layout import INPUT_NAMES

RATES = {("mass_position_cmd", 1): 0.5, ("current_east", 1): 3.0, ("yaw", 1): 0.2}


def started(cls: type, **integers: int) -> AuvPlant | AuvAutopilot:
    slave = cls(instance_name=cls.__name__)
    for name, value in integers.items():
        slave.set_integer([slave._vr_of[name]], [value])
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


def set_rates(slave: AuvPlant | AuvAutopilot) -> None:
    """RATES' derivatives of the slave's inputs, as an importer sets them for a step."""
    inputs = {v.name: vr for vr, v in slave.vars.items() if v.causality == Fmi2Causality.input}
    taken = [(inputs[name], order, value) for (name, order), value in RATES.items()
             if name in inputs]  # fmt: skip
    vrs, orders, values = (list(column) for column in zip(*taken, strict=True))
    slave.set_real_input_derivatives(vrs, orders, values)


@pytest.mark.slow  # compiles the varying-input step the first time (numba)
def test_the_plant_uses_its_actuator_inputs_derivatives_and_holds_the_currents() -> None:
    plant = started(AuvPlant)
    set_rates(plant)
    rates = plant._input_rates()
    assert rates is not None
    assert rates[0, INPUT_NAMES.index("mass_position_cmd")] == 0.5
    assert rates[0, INPUT_NAMES.index("current_east")] == 0.0  # held over the step
    held = started(AuvPlant)
    assert held._input_rates() is None
    for slave in (plant, held):
        assert slave.do_step(0.0, 0.5)
    mass = INPUT_NAMES.index("mass_position_cmd")  # the command ramps to 0.25 m, held at 0
    assert plant._inputs[mass] == held._inputs[mass] == 0.0
    assert plant._x[12] > 0.0 == held._x[12]
    assert plant._input_rates() is None  # cleared after the step


def test_the_autopilot_follows_its_inputs_when_they_vary() -> None:
    """The backstepping's command filters take the measurements as ramping from the last
    sample when derivatives are set (a first-order hold): other commands than held."""
    backstepping = {"heading_mode": int(HeadingMode.BACKSTEPPING)}
    varying, held = started(AuvAutopilot, **backstepping), started(AuvAutopilot, **backstepping)
    yaw = varying._vr_of["yaw"]
    for t, value in ((0.0, 0.0), (0.01, 0.002)):
        for slave in (varying, held):
            slave.set_real([yaw], [value])
        if t > 0.0:
            set_rates(varying)
        assert varying.do_step(t, 0.01) and held.do_step(t, 0.01)
    assert not np.array_equal(varying._outputs, held._outputs)
    assert not varying._rates.any()  # cleared after the step


def test_both_declare_that_they_interpolate_their_inputs() -> None:
    assert AuvPlant.interpolates_inputs and AuvAutopilot.interpolates_inputs
    assert np.all([name in INPUT_NAMES for name, _ in RATES if name != "yaw"])


@pytest.mark.slow  # compiles the varying-input step the first time (numba)
def test_a_second_derivative_alone_is_followed_as_when_a_first_one_is_near_zero() -> None:
    """With every first derivative 0, a second derivative (a quadratic extrapolation's
    turning point) was ignored, while with one of 1e-12 beside it it was followed: the
    step was discontinuous in the derivatives the importer set."""

    def stepped(first: float) -> np.ndarray:
        plant = started(AuvPlant)
        mass = plant._vr_of["mass_position_cmd"]
        plant.set_real_input_derivatives([mass, mass], [1, 2], [first, 0.2])
        assert plant.do_step(0.0, 0.5)
        return plant._x.copy()

    alone, beside = stepped(0.0), stepped(1e-12)
    assert alone[12] > 0.0  # the mass moved: the command rose as 0.1 t^2
    np.testing.assert_allclose(alone, beside, rtol=1e-9, atol=1e-15)
