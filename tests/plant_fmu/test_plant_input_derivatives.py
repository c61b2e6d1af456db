"""The plant and autopilot slaves take the importer's input derivatives (the runtime's
``input_derivative``, FMI's fmi2SetRealInputDerivatives) into their steps."""

from __future__ import annotations

import numpy as np
import pytest

from controller_fmu.auv_autopilot import AuvAutopilot
from plant_fmu.auv_plant import AuvPlant
from plant_fmu.model.state_layout import INPUT_NAMES

RATES = {("mass_position_cmd", 1): 0.5, ("current_east", 1): 3.0, ("yaw", 1): 0.2}


class Interpolating:
    """input_derivative as the native runtime gives it: the values set for this step."""

    def input_derivative(self, name: str, order: int) -> float:
        return RATES.get((name, order), 0.0)


class InterpolatingPlant(Interpolating, AuvPlant):
    pass


class InterpolatingAutopilot(Interpolating, AuvAutopilot):
    pass


def started(cls: type) -> AuvPlant | AuvAutopilot:
    slave = cls(instance_name=cls.__name__)
    slave.enter_initialization_mode()
    slave.exit_initialization_mode()
    return slave


@pytest.mark.slow  # compiles the varying-input step the first time (numba)
def test_the_plant_uses_its_actuator_inputs_derivatives_and_holds_the_currents() -> None:
    plant = started(InterpolatingPlant)
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


def test_the_autopilot_knows_when_its_inputs_vary() -> None:
    assert started(InterpolatingAutopilot)._inputs_vary()
    assert not started(AuvAutopilot)._inputs_vary()


def test_both_declare_that_they_interpolate_their_inputs() -> None:
    assert AuvPlant.interpolates_inputs and AuvAutopilot.interpolates_inputs
    assert np.all([name in INPUT_NAMES for name, _ in RATES if name != "yaw"])
