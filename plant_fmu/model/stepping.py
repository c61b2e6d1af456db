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

What is integrated is the stepping state (:mod:`plant_fmu.model.state_layout`). Each
sub-step integrates the attitude in one chart, chosen at its start
(:meth:`PlantModel.uses_quaternion`): the Euler angles, or, for the full variant beyond
``QUATERNION_CHART_PITCH``, the unit quaternion (normalised), so a vehicle passes pitch
+-90 deg; the other chart is refreshed from it at the sub-step's end
(:func:`_sync_attitude`). See :mod:`plant_fmu.model.dynamics` for why the derivative the
analysis tools use keeps Euler angles. With the two-body moving mass a sub-step in which
the mass reaches a stop ends at its arrival (:func:`_substep_through_stop`).
"""

from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING

import numpy as np

from plant_fmu.model.dynamics import PlantModel
from plant_fmu.model.kinematics import euler_from_quaternion, quaternion_from_euler
from plant_fmu.model.root_finding import brent_root
from plant_fmu.model.state_layout import (
    ANGULAR_VELOCITY,
    CURRENT,
    EULER,
    INPUT_NAMES,
    LINEAR_VELOCITY,
    MASS_POSITION,
    MAX_SPEED,
    MAX_TURN_RATE,
    N_INPUTS,
    N_STATES,
    N_STEP_STATES,
    QUATERNION,
    STATE,
    STATE_UNITS,
    STEP_STATE_NAMES,
)

if TYPE_CHECKING:
    from plant_fmu.model.compiled import CompiledPlant

DEFAULT_MAX_SUBSTEP = 0.01  # s
# Sub-steps one step may take: ~5 s of the compiled loop (a doStep of 10^4 s at the default
# max_substep, measured), minutes of the reference one. A host's doStep cannot be
# interrupted (compiled code ignores signals), so a step of 1e12 s is refused, not started.
MAX_SUBSTEPS = 1_000_000


def check_finite(values: np.ndarray, names: tuple[str, ...], what: str) -> None:
    """Raise ValueError naming the first non-finite entry of ``values``."""
    if not np.all(np.isfinite(values)):
        bad = int(np.flatnonzero(~np.isfinite(values))[0])
        raise ValueError(f"{what} {names[bad]} = {float(values[bad])!r}: expected a finite number")


def check_current(model: PlantModel, x: np.ndarray, inputs: np.ndarray) -> None:
    """Raise ValueError naming the first current component (m/s) beyond :data:`MAX_SPEED`:
    a current input, or the current at the vehicle, ``model.current_velocity`` (a sheared
    current_north grows with east without bound); a steady current carries the vehicle at
    its own speed, so no state in the model's range follows it."""
    for i in range(N_INPUTS)[CURRENT]:
        if not abs(inputs[i]) <= MAX_SPEED:
            name = INPUT_NAMES[i]
            raise ValueError(
                f"input {name} = {float(inputs[i]):g} m/s: expected |{name}| <= {MAX_SPEED:g} "
                f"m/s ({_CARRIED})"
            )
    north = float(model.current_velocity(x, inputs)[0])
    if not abs(north) <= MAX_SPEED:
        raise ValueError(
            f"the current at the vehicle, north = {north:g} m/s (current_north "
            f"{float(inputs[CURRENT][0]):g} m/s + current_shear_dUdy {model.current_shear:g} "
            f"1/s * east {float(x[1]):g} m): expected |current north| <= {MAX_SPEED:g} m/s "
            f"({_CARRIED})"
        )


_CARRIED = (
    "a steady current carries the vehicle at its speed, and the model takes no velocity over "
    "ground beyond that"
)


def stepping_state(x: np.ndarray) -> np.ndarray:
    """A new stepping state (``STEP_STATE_NAMES``) from a state (the quaternion of its
    Euler angles) or from a stepping state (copied, its quaternion normalised).

    Raises:
        ValueError: a vector of another length, or a zero quaternion.
    """
    x = np.asarray(x, dtype=float)
    if x.shape == (N_STATES,):
        return np.concatenate([x, quaternion_from_euler(*x[EULER].tolist())])
    if x.shape != (N_STEP_STATES,):
        raise ValueError(
            f"expected a state of {N_STATES} values (or {N_STEP_STATES} with the attitude "
            f"quaternion), got shape {x.shape}"
        )
    z = x.copy()
    w, a, b, c = z[QUATERNION].tolist()
    norm = math.sqrt(w * w + a * a + b * b + c * c)
    if not norm > 0.0:
        raise ValueError(f"attitude quaternion {z[QUATERNION].tolist()}: expected |q| > 0")
    z[QUATERNION] /= norm
    return z


def _sync_attitude(z: np.ndarray, quaternion: bool, previous: np.ndarray) -> None:
    """Refresh, in place, the chart a sub-step did not integrate: the Euler angles from the
    quaternion (the triple with |pitch| <= 90 deg, roll and yaw continued by whole turns
    from ``previous``: ``kinematics.euler_from_quaternion``), or the quaternion from the
    Euler angles."""
    if quaternion:
        z[EULER] = euler_from_quaternion(z[QUATERNION].tolist(), previous.tolist())
    else:
        z[QUATERNION] = quaternion_from_euler(*z[EULER].tolist())


def advance(
    model: PlantModel,
    x: np.ndarray,
    inputs: np.ndarray,
    h: float,
    max_substep: float = DEFAULT_MAX_SUBSTEP,
    compiled: CompiledPlant | None = None,
    rates: np.ndarray | None = None,
) -> np.ndarray:
    """The state after h seconds from x with the inputs held constant (RK4, projected),
    or, with ``rates``, following u(s) = u + s u' + s^2 / 2 u'' over the step.

    Args:
        model: the plant.
        x: a state (``STATE_NAMES``) or a stepping state (``STEP_STATE_NAMES``, its two
            attitudes in agreement, as every step leaves them; the first sub-step
            integrates the chart :meth:`PlantModel.uses_quaternion` picks); not modified. Callers
            that step through pitch +-90 deg carry the stepping state: a state's Euler
            angles hold the attitude there only to about 1e-16 / cos(pitch).
        inputs: inputs, ``INPUT_NAMES`` order.
        h: step, s (> 0).
        max_substep: longest internal RK4 step, s (> 0).
        compiled: the compiled path of ``model`` (:mod:`plant_fmu.model.compiled`), or
            None for this module's reference loop; both do the same arithmetic.
        rates: None (inputs held), or (2, inputs) their first and second time derivatives
            at the step's start (per s, per s^2: the master's input extrapolation, FMI
            input derivatives); each RK4 stage then takes the inputs at its own time, so
            the step's error in the inputs is third order instead of first. A sub-step in
            which the two-body mass reaches a stop holds its mid-sub-step inputs.

    Returns:
        the new state, as long as ``x`` (a stepping state for a stepping state).

    Raises:
        ValueError: a non-finite state or input, a non-positive step, or a state that
            became non-finite (the vehicle left the model's range).
    """
    x = np.asarray(x, dtype=float)
    inputs = np.asarray(inputs, dtype=float)
    if x.shape not in ((N_STATES,), (N_STEP_STATES,)) or inputs.shape != (N_INPUTS,):
        raise ValueError(
            f"expected a state of {N_STATES} values (or {N_STEP_STATES} with the attitude "
            f"quaternion) and inputs of {N_INPUTS}, got shapes {x.shape} and {inputs.shape}"
        )
    n = substeps(h, max_substep)
    dt = h / n
    if compiled is not None:
        z = np.empty(N_STEP_STATES)
        if compiled.advance(x, z, inputs, n, dt, rates) == 0:
            return z if len(x) == N_STEP_STATES else z[STATE]
        # A non-finite input or result: the reference below repeats the step from the
        # start and reports what went wrong in its own words (an OverflowError, a name).
    check_finite(x, STEP_STATE_NAMES, "state")
    check_finite(inputs, INPUT_NAMES, "input")
    check_current(model, x, inputs)
    if rates is not None:
        check_finite(np.ravel(rates), INPUT_NAMES * 2, "input derivative of")
    z = stepping_state(x)
    # An input far outside the model's range (a fault's gain of 1e308) overflows on the way:
    # the checks below say so in one line, numpy's warnings would reach the host's stderr.
    try:
        with np.errstate(all="ignore"):
            model.project(z)
            for j in range(n):
                if rates is None:
                    z = _substep(model, z, inputs, dt)
                else:
                    later = (_inputs_at(inputs, rates, (j + 0.5) * dt),
                             _inputs_at(inputs, rates, (j + 1) * dt))  # fmt: skip
                    z = _substep(model, z, _inputs_at(inputs, rates, j * dt), dt, later)
    except OverflowError:
        raise ValueError(_left_the_range("a value overflowed (OverflowError)", h, n)) from None
    except (ValueError, ZeroDivisionError) as error:  # math.cos(inf), or a quaternion
        # whose norm overflowed normalised to zero: a stage state thrown to infinity
        what = f"a value left the floating-point range ({error})"
        raise ValueError(_left_the_range(what, h, n)) from None
    _check_range(z, h, n)
    return z if len(x) == N_STEP_STATES else z[STATE]


def _check_range(z: np.ndarray, h: float, n: int) -> None:
    """Raise ValueError if the stepping state ``z`` after a step of ``h`` s in ``n``
    sub-steps is not finite or its velocities are beyond :data:`MAX_SPEED` and
    :data:`MAX_TURN_RATE` (the compiled step's test too)."""
    bounds = np.full(N_STEP_STATES, np.inf)
    bounds[LINEAR_VELOCITY], bounds[ANGULAR_VELOCITY] = MAX_SPEED, MAX_TURN_RATE
    outside = ~(np.abs(z) <= bounds)  # a nan is outside too
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        name, value = STEP_STATE_NAMES[i], float(z[i])
        if math.isfinite(value):  # beyond its bound: a velocity, which has a unit
            what = f"{name} = {value:.6g} {STATE_UNITS[i]}: expected |{name}| <= {bounds[i]:g}"
        else:
            what = f"{name} = {value!r}: expected a finite number"
        raise ValueError(_left_the_range(what, h, n))


def _left_the_range(what: str, h: float, n: int) -> str:
    return (
        f"the vehicle left the model's range in a step of {h!r} s ({n} RK4 sub-step(s) of "
        f"{h / n:.6g} s): {what}. Fast motion or forces make the plant stiffer than its "
        "sub-steps allow: an input or an initial velocity far beyond the vehicle's range, "
        "or a vehicle file with a faster moving-mass servo; a smaller max_substep keeps RK4 "
        "stable"
    )


@functools.lru_cache(maxsize=256)  # once per step length: a plant's doStep asks every time
def substeps(h: float, max_substep: float) -> int:
    """The number of equal RK4 sub-steps, each at most ``max_substep`` s, of a step of ``h``
    s.

    Raises:
        ValueError: a step or ``max_substep`` that is not a finite number > 0, or a step
            that would take more than :data:`MAX_SUBSTEPS` sub-steps.
    """
    if not (h > 0.0 and math.isfinite(h)):
        raise ValueError(f"step h = {h!r}: expected a finite number of seconds > 0")
    if not (max_substep > 0.0 and math.isfinite(max_substep)):
        raise ValueError(f"max_substep = {max_substep!r}: expected a finite number of s > 0")
    ratio = h / max_substep - 1e-9  # inf for a subnormal max_substep or a step near 1e308
    n: float = max(1, math.ceil(ratio)) if math.isfinite(ratio) else math.inf
    if n > MAX_SUBSTEPS:
        raise ValueError(
            f"a step of {h!r} s takes {n:.3g} sub-steps of at most max_substep = "
            f"{max_substep!r} s: expected at most {MAX_SUBSTEPS} (steps of at most "
            f"{MAX_SUBSTEPS * max_substep:.6g} s, or a longer max_substep)"
        )
    return int(n)


def _inputs_at(inputs: np.ndarray, rates: np.ndarray, tau: float) -> np.ndarray:
    """The inputs tau seconds into the step: u + tau u' + tau^2 / 2 u''."""
    at: np.ndarray = inputs + tau * rates[0] + 0.5 * tau * tau * rates[1]
    return at


def _rk4(
    model: PlantModel,
    z: np.ndarray,
    inputs: np.ndarray,
    dt: float,
    quaternion: bool,
    later: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """One classical RK4 step of dt seconds on a stepping state in one attitude chart
    (:meth:`PlantModel.uses_quaternion`), each stage projected; ``later``: the inputs at
    dt / 2 and dt when they vary (``inputs`` are then those at the start)."""
    stage = model.project
    middle, end_inputs = (inputs, inputs) if later is None else later

    def f(s: np.ndarray, u: np.ndarray) -> np.ndarray:
        return model.step_derivative(s, u, quaternion)

    k1 = f(z, inputs)
    k2 = f(stage(z + 0.5 * dt * k1), middle)
    k3 = f(stage(z + 0.5 * dt * k2), middle)
    k4 = f(stage(z + dt * k3), end_inputs)
    end: np.ndarray = z + (dt / 6.0) * (k1 + 2.0 * k2 + 2.0 * k3 + k4)
    return end


def _substep(
    model: PlantModel,
    z: np.ndarray,
    inputs: np.ndarray,
    dt: float,
    later: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """One RK4 sub-step, the constraints enforced at its end (a stop's impact included),
    the attitude chart it did not integrate refreshed; ``later`` as in :func:`_rk4`."""
    quaternion = model.uses_quaternion(z)
    end = _rk4(model, z, inputs, dt, quaternion, later)
    stroke = model.params.mass_stroke
    arrival = end[MASS_POSITION]
    if model.two_body and abs(arrival) > stroke > abs(z[MASS_POSITION]):
        stop = math.copysign(stroke, arrival)
        held = inputs if later is None else later[0]
        end = _substep_through_stop(model, z, held, dt, stop, quaternion)
    else:
        end = model.project(end, collide=True)
    _sync_attitude(end, quaternion, z[EULER])
    return end


def _substep_through_stop(
    model: PlantModel, z: np.ndarray, inputs: np.ndarray, dt: float, stop: float, quaternion: bool
) -> np.ndarray:
    """A two-body sub-step in which the mass reaches ``stop`` (m): integrate to the moment
    it arrives, let it hit the stop there, then integrate the rest of the sub-step (in the
    attitude chart ``quaternion`` says).

    Why: projecting an overshot mass back onto the stop at the step's end moves it without
    the time that takes; with the two-body model's mass matrix M(y_v) that shift changes
    the system's momentum and, on the velocity over ground, depends on the frame (a
    current's). Locating the arrival (Brent's method,
    :func:`plant_fmu.model.root_finding.brent_root`, on the
    RK4 step length: the mass's motion on its rail depends on nothing but the servo, so
    the arrival time is the same in every frame) leaves the impact alone to change the
    hull's momentum, by exactly the stop's impulse. Up to the arrival the stops are out of
    the way (:attr:`PlantModel.without_stops`): stage states a hair past the stop must not
    be held there.
    """
    free = model.without_stops

    def gap(length: float) -> float:
        return float(_rk4(free, z, inputs, length, quaternion)[MASS_POSITION] - stop)

    if gap(dt) * stop <= 0.0:  # with the stops out of the way it does not get there
        return model.project(_rk4(model, z, inputs, dt, quaternion), collide=True)
    arrival = brent_root(gap, 0.0, dt, xtol=1e-15, rtol=4.0 * np.finfo(float).eps)
    z = model.project(_rk4(free, z, inputs, arrival, quaternion), collide=True)
    if dt - arrival <= 0.0:
        return z
    return model.project(_rk4(model, z, inputs, dt - arrival, quaternion), collide=True)


def simulate(
    model: PlantModel,
    x0: np.ndarray,
    inputs: np.ndarray,
    duration: float,
    h: float,
    max_substep: float = DEFAULT_MAX_SUBSTEP,
    compiled: CompiledPlant | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Open-loop run with constant inputs: (times [n+1], states [n+1, len(x0)]), carrying
    the stepping state from step to step whatever x0 is (so the attitude is followed
    through pitch +-90 deg); ``compiled`` as in :func:`advance`."""
    steps = round(duration / h)
    if steps < 1 or not math.isclose(steps * h, duration, rel_tol=1e-9, abs_tol=1e-12):
        raise ValueError(f"duration {duration!r} s is not a whole number of steps h = {h!r} s")
    z = model.project(stepping_state(x0))
    states = np.empty((steps + 1, N_STEP_STATES))
    states[0] = z
    for k in range(steps):
        states[k + 1] = advance(model, states[k], inputs, h, max_substep, compiled)
    return np.arange(steps + 1) * h, states[:, : len(np.asarray(x0))]
