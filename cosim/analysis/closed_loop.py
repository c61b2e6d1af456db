"""In-process closed loop: the plant model and the autopilot, no FMI in between.

This is the reference the tests check the FMUs and the master against: the controller
tests (``tests/controller_fmu/``) run the dissertation's scenarios through
:func:`simulate_closed_loop`, and the FMU and recording tests compare what the FMUs,
coupled by a master, produce with it. It is also the quickest way to try a controller.
It is analysis code: neither FMU ships it.

At each communication step the autopilot reads the plant's outputs (the same quantities,
and the same arithmetic, the plant FMU publishes), its commands are held over the step,
and :func:`plant_fmu.model.stepping.advance` integrates the plant: a sampled loop without
delay, like a master's Gauss-Seidel order controller -> plant (the built-in scenarios').
With a waypoint guidance (:class:`controller_fmu.los_guidance.LosGuidance`) the set-points
come from it, sampled first at each step (the order guidance -> controller -> plant of the
``survey`` scenario).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from controller_fmu.autopilot import COMMAND_NAMES, Autopilot
from controller_fmu.los_guidance import LosGuidance
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel
from plant_fmu.model.stepping import DEFAULT_MAX_SUBSTEP, advance

_COMMAND_INPUTS = [INPUT_INDEX[name] for name in COMMAND_NAMES]
_MEASURED_STATES = (
    "yaw", "r", "p", "roll", "down", "pitch", "q", "mass_position", "mass_velocity",
)  # fmt: skip


def measurements(
    model: PlantModel,
    x: np.ndarray,
    inputs: np.ndarray,
    yaw_setpoint: float = 0.0,
    depth_setpoint: float = 0.0,
) -> dict[str, float]:
    """The autopilot's inputs from the plant state x and plant inputs (the plant FMU's
    outputs of the same names, plus the current it is given and the set-points)."""
    nu_r = model.relative_velocity(x, inputs)
    values = {name: float(x[STATE_INDEX[name]]) for name in _MEASURED_STATES}
    values.update(
        u_rel=float(nu_r[0]),
        v_rel=float(nu_r[1]),
        w_rel=float(nu_r[2]),
        current_north=float(inputs[INPUT_INDEX["current_north"]]),
        current_east=float(inputs[INPUT_INDEX["current_east"]]),
        yaw_setpoint=yaw_setpoint,
        depth_setpoint=depth_setpoint,
    )
    return values


@dataclass(frozen=True)
class ClosedLoopRun:
    """Times [n+1] (s), plant states [n+1, N_STATES] and the commands held from each time
    [n+1, 4] (:data:`COMMAND_NAMES` order; the last row repeats the final step's)."""

    times: np.ndarray
    states: np.ndarray
    commands: np.ndarray

    def state(self, name: str) -> np.ndarray:
        return self.states[:, STATE_INDEX[name]]

    def command(self, name: str) -> np.ndarray:
        return self.commands[:, COMMAND_NAMES.index(name)]


def simulate_closed_loop(
    autopilot: Autopilot,
    model: PlantModel,
    x0: np.ndarray,
    stop_time: float,
    step: float,
    current: Mapping[str, float] | None = None,
    yaw_setpoint: float = 0.0,
    depth_setpoint: float = 0.0,
    max_substep: float = DEFAULT_MAX_SUBSTEP,
    guidance: LosGuidance | None = None,
    compiled: CompiledPlant | None = None,
) -> ClosedLoopRun:
    """Run plant + autopilot from x0 for stop_time seconds in steps of ``step``.

    Args:
        autopilot: reset before the run.
        model: the plant.
        x0: initial plant state (``STATE_NAMES`` order).
        stop_time, step: s; stop_time must be a whole number of steps.
        current: constant earth-frame current ``{"current_north": ..., ...}``, m/s.
        yaw_setpoint, depth_setpoint: rad, m.
        max_substep: the plant's longest RK4 sub-step, s.
        guidance: if given (it is not reset), its set-points replace ``yaw_setpoint`` and
            ``depth_setpoint``; it measures the plant's position and the current.
        compiled: step the plant with this compiled path of ``model``
            (:class:`plant_fmu.model.compiled.CompiledPlant`) instead of the reference.
    """
    n = round(stop_time / step)
    if n < 1 or not math.isclose(n * step, stop_time, rel_tol=1e-9):
        raise ValueError(f"stop_time {stop_time!r} s is not a whole number of steps {step!r} s")
    inputs = np.zeros(len(INPUT_INDEX))
    for name, value in (current or {}).items():
        if not name.startswith("current_"):
            raise ValueError(f"unknown current component {name!r}")
        inputs[INPUT_INDEX[name]] = value
    autopilot.reset()
    states = np.empty((n + 1, len(STATE_INDEX)))
    commands = np.empty((n + 1, len(COMMAND_NAMES)))
    x = model.project(np.array(x0, dtype=float))
    states[0] = x
    for k in range(n):
        if guidance is not None:
            north, east = x[STATE_INDEX["north"]], x[STATE_INDEX["east"]]
            water = inputs[[INPUT_INDEX["current_north"], INPUT_INDEX["current_east"]]]
            water_north, water_east = water.tolist()
            yaw = x[STATE_INDEX["yaw"]]
            out = guidance.step(north, east, water_north, water_east, step=step, yaw=yaw)
            yaw_setpoint, depth_setpoint = out.yaw_setpoint, out.depth_setpoint
        meas = measurements(model, x, inputs, yaw_setpoint, depth_setpoint)
        held = autopilot.step(k * step, meas).values()
        commands[k] = held
        inputs[_COMMAND_INPUTS] = held
        x = advance(model, x, inputs, step, max_substep, compiled)
        states[k + 1] = x
    commands[n] = commands[n - 1]
    return ClosedLoopRun(np.arange(n + 1) * step, states, commands)
