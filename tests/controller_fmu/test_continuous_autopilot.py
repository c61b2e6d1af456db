"""The autopilot between samples: the backstepping's command filters with a first-order
hold (the importer's input derivatives), the closed loop's order of convergence with the
communication step, and the digital autopilot's own sample period."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.linalg import expm

from controller_fmu.autopilot import COMMAND_NAMES, Autopilot, AutopilotConfig
from controller_fmu.command_filter import CommandFilterBank
from cosim.analysis.closed_loop import measurements
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance, stepping_state

COMMANDS = [INPUT_INDEX[name] for name in COMMAND_NAMES]


def test_the_first_order_hold_is_exact_for_a_ramp() -> None:
    """A filter advanced by advance_ramp over T equals the exact response to its input
    going linearly from a to b (the 4 x 4 augmented exponential, computed here apart)."""
    bank = CommandFilterBank(1, frequency=10.0)
    bank.start([0.3])
    bank.rate[:] = [0.7]
    a, b, interval = 0.3, 1.1, 0.037
    bank.advance_ramp(0, a, b, interval)
    w = 10.0
    system = np.zeros((4, 4))  # [a_c, a_c', input, input's rate]
    system[0, 1] = 1.0
    system[1, :3] = (-(w**2), -2.0 * w, w**2)
    system[2, 3] = 1.0
    exact = expm(system * interval) @ np.array([0.3, 0.7, a, (b - a) / interval])
    np.testing.assert_allclose([bank.value[0], bank.rate[0]], exact[:2], rtol=1e-12)


def closed_loop(h: float, varying: bool, stop_time: float = 8.0) -> np.ndarray:
    """bs-3 in process: the autopilot sampled every h, the plant following its commands
    as the master's quadratic extrapolation gives them (``varying``), or holding them.
    Returns the mass position at every multiple of 0.5 s."""
    model = PlantModel(load_vehicle("remus100"), variant=Variant.LATERAL)
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3))
    fast = compiled.CompiledPlant(model) if compiled.AVAILABLE else None
    x = np.zeros(14)
    x[STATE_INDEX["u"]], x[STATE_INDEX["v"]] = 1.5, -0.1
    z, inputs = stepping_state(model.project(x)), np.zeros(8)
    past: list[np.ndarray] = []
    every = round(0.5 / h)
    samples = []
    for n in range(round(stop_time / h)):
        if n % every == 0:
            samples.append(z[STATE_INDEX["mass_position"]])
        held = np.array(autopilot.step(n * h, measurements(model, z[:14], inputs), varying))
        inputs[COMMANDS] = held.tolist()
        rates = None
        if varying and len(past) >= 2:  # the master's backward differences (quadratic)
            rates = np.zeros((2, 8))
            rates[0, COMMANDS] = (3 * held - 4 * past[-1] + past[-2]) / (2 * h)
            rates[1, COMMANDS] = (held - 2 * past[-1] + past[-2]) / h**2
        past.append(held)
        z = advance(model, z, inputs, h, 0.01, fast, rates)
    return np.array(samples)


@pytest.mark.slow
def test_the_loop_converges_at_second_order_with_input_derivatives_and_first_without() -> None:
    """With derivatives (plant stages following the commands, filters on a first-order
    hold) halving the step divides the error by about 4; held, by about 2."""
    orders = {}
    for varying in (True, False):
        runs = [closed_loop(h, varying) for h in (0.02, 0.01, 0.005)]
        d1 = np.max(np.abs(runs[0] - runs[1]))
        d2 = np.max(np.abs(runs[1] - runs[2]))
        orders[varying] = math.log2(d1 / d2)
    assert orders[True] > 1.7
    assert 0.7 < orders[False] < 1.3


def test_a_digital_autopilot_samples_at_its_own_period() -> None:
    """sample_period = 0.05 s, stepped every 0.01 s: new commands at multiples of 0.05 s
    only, held in between; a snapshot restores when the next sample is due."""
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3, sample_period=0.05))
    meas = dict.fromkeys(("yaw", "r", "p", "roll", "v_rel", "u_rel", "down", "pitch", "q",
                          "w_rel", "mass_position", "mass_velocity", "current_north",
                          "current_east", "yaw_setpoint", "depth_setpoint"), 0.0)  # fmt: skip
    changes = []
    last = None
    for n in range(30):
        meas["yaw"] = 0.001 * n  # the heading error grows every step
        commands = autopilot.step(n * 0.01, meas, varying=True)
        if commands != last:
            changes.append(n)
        last = commands
        if n == 12:
            saved = autopilot.snapshot()
    assert changes == [0, 5, 10, 15, 20, 25]
    autopilot.restore(saved)
    assert autopilot.next_sample == pytest.approx(0.15)


def test_a_digital_autopilot_samples_at_every_point_of_a_host_that_adds_its_step() -> None:
    """sample_period = step = 0.1 s, the host's time t += 0.1 s (as many hosts count it):
    at about 1300 s the sum falls more than 1e-11 s (the old slack, 1e-9 of a period) below
    the multiple it stands for, as the FMU's own time check allows (1e-9 of the time).
    Every call is still a sample: none is skipped, holding the commands two steps."""
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3, sample_period=0.1))
    meas = dict.fromkeys(("yaw", "r", "p", "roll", "v_rel", "u_rel", "down", "pitch", "q",
                          "w_rel", "mass_position", "mass_velocity", "current_north",
                          "current_east", "yaw_setpoint", "depth_setpoint"), 0.0)  # fmt: skip
    t, skipped = 0.0, []
    for n in range(15_000):
        before = autopilot.next_sample
        autopilot.step(t, meas)
        if autopilot.next_sample == before:
            skipped.append((n, t))
        t += 0.1
    assert not skipped, f"no sample at the calls (n, t) {skipped[:3]}"


@pytest.mark.parametrize("period", [5e-324, 1e-300])
def test_a_sample_period_below_the_times_resolution_samples_at_every_call(period) -> None:
    """A sample period so short that time / period overflows (5e-324 s, subnormal) or
    passes 2**53, where a double tells no multiple of it from the next: every call is then
    a sample, as with any period shorter than the step. The subnormal one failed the
    second doStep with "OverflowError: cannot convert float infinity to integer"."""
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3, sample_period=period))
    meas = dict.fromkeys(("yaw", "r", "p", "roll", "v_rel", "u_rel", "down", "pitch", "q",
                          "w_rel", "mass_position", "mass_velocity", "current_north",
                          "current_east", "yaw_setpoint", "depth_setpoint"), 0.0)  # fmt: skip
    sampled = []
    for n in range(4):
        meas["yaw"] = 0.01 * (n + 1)  # the heading error grows every call
        before = autopilot.commands
        sampled.append(autopilot.step(0.05 * n, meas) != before)
    assert sampled == [True] * 4
