"""Advance the plant over one communication step with its inputs held constant.

Why a fixed-step classical Runge-Kutta (RK4) with internal sub-steps, not scipy's
adaptive ``solve_ivp``:

* The plant is not stiff. Its fastest modes are the roll oscillation (about 5 rad/s,
  Example 5.3), sway (-2.5 1/s) and the moving-mass servo (omega_n = 2.4 rad/s,
  zeta = 0.9: poles at -2.16 +- 1.05i). RK4 is stable for |lambda h| < 2.8, so a 10 ms
  sub-step has a margin of about 50, and its local error (lambda h)^5 / 120 is ~1e-10.
  The -5760 1/s pole the continuous LQR creates belongs to the *closed* loop; a sampled
  controller holds its output over the step, so it never enters the plant's integrator.
* The moving mass hits hard stops. A fixed step lets us project the state onto the
  constraints after every sub-step (:meth:`PlantModel.project`, which also hands the
  mass's momentum to the hull when it arrives at a stop), which an adaptive solver's
  step-size control would fight.
* Determinism: the same state, inputs and h give bit-identical results, which FMU state
  save/restore and rollback rely on; ``solve_ivp`` is deterministic too, but its cost per
  10 ms step (about 1 ms of Python overhead) is 5-10x ours.

The number of sub-steps is ceil(h / max_substep); the default 10 ms makes a 10 ms
communication step one RK4 step, and users who want more accuracy lower ``max_substep``.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from plant_fmu.model.dynamics import INPUT_NAMES, N_INPUTS, N_STATES, STATE_NAMES, PlantModel

if TYPE_CHECKING:
    from plant_fmu.model.compiled import CompiledPlant

DEFAULT_MAX_SUBSTEP = 0.01  # s


def check_finite(values: np.ndarray, names: tuple[str, ...], what: str) -> None:
    """Raise ValueError naming the first non-finite entry of ``values``."""
    if not np.all(np.isfinite(values)):
        bad = int(np.flatnonzero(~np.isfinite(values))[0])
        raise ValueError(f"{what} {names[bad]} = {float(values[bad])!r}: expected a finite number")


def advance(
    model: PlantModel,
    x: np.ndarray,
    inputs: np.ndarray,
    h: float,
    max_substep: float = DEFAULT_MAX_SUBSTEP,
    compiled: CompiledPlant | None = None,
) -> np.ndarray:
    """The state after h seconds from x with the inputs held constant (RK4, projected).

    Args:
        model: the plant.
        x: state, ``STATE_NAMES`` order (not modified).
        inputs: inputs, ``INPUT_NAMES`` order.
        h: step, s (> 0).
        max_substep: longest internal RK4 step, s (> 0).
        compiled: the compiled path of ``model`` (:mod:`plant_fmu.model.compiled`), or
            None for this module's reference loop; both do the same arithmetic.

    Raises:
        ValueError: a non-finite state or input, a non-positive step, or a state that
            became non-finite (the vehicle left the model's range, e.g. pitch at 90 deg).
    """
    start = x
    x = np.array(start, dtype=float)
    inputs = np.asarray(inputs, dtype=float)
    if x.shape != (N_STATES,) or inputs.shape != (N_INPUTS,):
        raise ValueError(
            f"expected a state of {N_STATES} and inputs of {N_INPUTS} values, "
            f"got shapes {x.shape} and {inputs.shape}"
        )
    if not (h > 0.0 and math.isfinite(h)):
        raise ValueError(f"step h = {h!r}: expected a finite number of seconds > 0")
    if not (max_substep > 0.0 and math.isfinite(max_substep)):
        raise ValueError(f"max_substep = {max_substep!r}: expected a finite number of s > 0")
    n = max(1, math.ceil(h / max_substep - 1e-9))
    dt = h / n
    if compiled is not None:
        if compiled.advance(x, inputs, n, dt) == 0:
            return x
        # A non-finite input or state: the reference below repeats the step from the start
        # and reports what went wrong in its own words (an OverflowError, a named state).
        x = np.array(start, dtype=float)
    check_finite(inputs, INPUT_NAMES, "input")
    check_finite(x, STATE_NAMES, "state")
    f = model.derivative
    # An input far outside the model's range (a fault's gain of 1e308) overflows on the way:
    # the check below says so in one line, numpy's warnings would reach the host's stderr.
    with np.errstate(all="ignore"):
        model.project(x)
        for _ in range(n):
            k1 = f(x, inputs)
            k2 = f(model.project(x + 0.5 * dt * k1), inputs)
            k3 = f(model.project(x + 0.5 * dt * k2), inputs)
            k4 = f(model.project(x + dt * k3), inputs)
            x = model.project(x + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4), collide=True)
    check_finite(x, STATE_NAMES, "state after the step:")
    return x


def simulate(
    model: PlantModel,
    x0: np.ndarray,
    inputs: np.ndarray,
    duration: float,
    h: float,
    max_substep: float = DEFAULT_MAX_SUBSTEP,
    compiled: CompiledPlant | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop run with constant inputs: (times [n+1], states [n+1, N_STATES]);
    ``compiled`` as in :func:`advance`."""
    steps = round(duration / h)
    if steps < 1 or not math.isclose(steps * h, duration, rel_tol=1e-9, abs_tol=1e-12):
        raise ValueError(f"duration {duration!r} s is not a whole number of steps h = {h!r} s")
    states = np.empty((steps + 1, N_STATES))
    states[0] = model.project(np.array(x0, dtype=float))
    for k in range(steps):
        states[k + 1] = advance(model, states[k], inputs, h, max_substep, compiled)
    return np.arange(steps + 1) * h, states
