"""Robustness margins of the shipped LQR heading loop (``auv-cosim analyze margins``).

The LQR autopilot (:mod:`controller_fmu.lqr`, (6.3.17)-(6.3.19)) is a sampled state
feedback ``y_d[k] = -K x[k]`` held over each step ``h``. Broken at the plant input (the
servo command ``y_d``), its loop is

    L(z) = K (z I - Ad)^-1 Bd,

``(Ad, Bd)`` the zero-order hold at ``h`` of the plant's own lateral linearisation
(:meth:`controller_fmu.lateral_model.LateralDesignModel.linearize`) on the vehicle and at
the speed the loop runs at, which a robustness check may take other than the design's:
``K`` is always designed as the autopilot designs it, on its own vehicle at its
``design_speed``. python-control gives the frequency response and the margins
(``stability_margins``) up to the Nyquist frequency ``pi / h``.

Units: frequencies in rad/s, gain margins as factors on the loop gain (and dB), phase
margins in deg, the delay margin in s (an extra delay at the plant input that the loop
takes before it loses stability), the sensitivity peak ``Ms = max |1 / (1 + L)|`` in 1.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import control
import numpy as np
from scipy.optimize import brentq

from controller_fmu.depth_pd import DepthPd, closed_plane
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.lqr import LqrHeading
from cosim.analysis.bifurcation import AnalysisError
from plant_fmu.model.parameters import VehicleParameterError, VehicleParameters


@dataclass(frozen=True)
class Crossing:
    """One margin and the frequency it is read at."""

    value: float  # a gain factor (1) or a phase margin (deg)
    frequency: float  # rad/s


@dataclass(frozen=True)
class LoopMargins:
    """The margins of a sampled loop, read from its frequency response.

    Attributes:
        step: the sample time h, s.
        gain_margins: the factors (1) on the loop gain that put a closed-loop pole on the
            unit circle, each at its phase crossover (rad/s), lowest frequency first; a
            factor < 1 is a gain reduction, > 1 an increase.
        phase_margins: deg, at each gain crossover (rad/s), lowest frequency first.
        sensitivity_peak: Ms = max |1 / (1 + L)| up to the Nyquist frequency, 1, and
            ``sensitivity_frequency`` where it is, rad/s.
        poles: the closed-loop poles z.
    """

    step: float
    gain_margins: tuple[Crossing, ...]
    phase_margins: tuple[Crossing, ...]
    sensitivity_peak: float
    sensitivity_frequency: float
    poles: np.ndarray

    @property
    def stable(self) -> bool:
        """Every closed-loop pole strictly inside the unit circle."""
        return bool(np.all(np.abs(self.poles) < 1.0))

    @property
    def lower_gain_margin(self) -> Crossing | None:
        """The largest factor < 1 the loop gain may not fall to (None if none)."""
        below = [c for c in self.gain_margins if c.value < 1.0]
        return max(below, key=lambda c: c.value) if below else None

    @property
    def upper_gain_margin(self) -> Crossing | None:
        """The smallest factor > 1 the loop gain may not rise to (None if none)."""
        above = [c for c in self.gain_margins if c.value > 1.0]
        return min(above, key=lambda c: c.value) if above else None

    @property
    def phase_margin(self) -> Crossing | None:
        """The smallest phase margin, deg (None: the loop gain never crosses 1)."""
        return min(self.phase_margins, key=lambda c: c.value) if self.phase_margins else None

    @property
    def delay_margin(self) -> Crossing | None:
        """The smallest extra input delay (s) that makes the loop lose stability, with the
        gain crossover (rad/s) whose phase margin it eats: min over the crossovers of
        PM / w_c, PM taken in [0, 360) deg, the phase lag a delay must add there (exact
        for delays of whole steps; None without a crossover)."""
        delays = [
            Crossing(math.radians(c.value % 360.0) / c.frequency, c.frequency)
            for c in self.phase_margins
        ]
        return min(delays, key=lambda c: c.value) if delays else None

    @property
    def continuous_poles(self) -> np.ndarray:
        """The closed-loop poles as s = ln(z) / h, 1/s (a pole at z = 0 is left out)."""
        z = self.poles[np.abs(self.poles) > 0.0].astype(complex)
        s: np.ndarray = np.log(z) / self.step
        return s


def check_loop_arguments(speeds: Mapping[str, float | None], step: float) -> None:
    """Refuse an operating point no loop runs at, naming the value (as the command's
    option: ``speeds`` by option, None where not given; ``--step``) and what is expected.

    Raises:
        AnalysisError: a speed that is not a finite number > 0 m/s, or a step that is
            not a finite number > 0 s.
    """
    for name, value in speeds.items():
        if value is not None and not (math.isfinite(value) and value > 0.0):
            raise AnalysisError(
                f"{name} {value!r}: expected a finite forward speed > 0 m/s (the plant is "
                "linearised on a straight run ahead)"
            )
    if not (math.isfinite(step) and step > 0.0):
        raise AnalysisError(f"--step {step!r}: expected a finite sample time > 0 s")


def scaled_vehicle(params: VehicleParameters, factors: Mapping[str, float]) -> VehicleParameters:
    """``params`` with each named physical parameter multiplied by its factor (1).

    Raises:
        AnalysisError: an unknown parameter, a factor that is not finite, or a result
            the vehicle's own checks refuse.
    """
    values = params.as_dict()
    changes = {}
    for name, factor in factors.items():
        if not isinstance(values.get(name), float):
            known = sorted(k for k, v in values.items() if isinstance(v, float))
            raise AnalysisError(
                f"--scale {name}={factor!r}: unknown parameter {name!r}; expected one of {known}"
            )
        if not math.isfinite(factor):
            raise AnalysisError(f"--scale {name}={factor!r}: expected a finite factor")
        changes[name] = values[name] * factor
        try:  # alone first, to name the factor that gives a refused value
            params.replace(**{name: changes[name]})
        except VehicleParameterError as exc:
            raise AnalysisError(
                f"--scale {name}={factor!r} (the vehicle's {name} = {values[name]:g} times "
                f"{factor:g}): {_reason(exc)}"
            ) from None
    try:
        return params.replace(**changes) if changes else params
    except VehicleParameterError as exc:  # the factors together (the mass matrix)
        given = " ".join(f"{name}={factor!r}" for name, factor in factors.items())
        raise AnalysisError(f"--scale {given}: {_reason(exc)}") from None


def _reason(exc: VehicleParameterError) -> str:
    """The vehicle's refusal without its lead ("vehicle 'remus100 (modified)': ")."""
    return re.sub(r"^vehicle '[^']*': ", "", str(exc))


def lqr_loop(
    design: VehicleParameters,
    design_speed: float,
    step: float,
    plant: VehicleParameters | None = None,
    speed: float | None = None,
) -> control.StateSpace:
    """L(z) = K (z I - Ad)^-1 Bd of the shipped LQR (module docstring): ``K`` designed on
    ``design`` at ``design_speed`` (m/s) for sample time ``step`` (s), the plant ``plant``
    (default ``design``) at ``speed`` (m/s, default ``design_speed``)."""
    check_loop_arguments({"--design-speed": design_speed, "--speed": speed}, step)
    try:
        gain = LqrHeading(LateralDesignModel(design, design_speed), step).gain
    except ValueError as exc:
        raise AnalysisError(str(exc)) from None
    at = LateralDesignModel(plant or design, design_speed if speed is None else speed)
    A, B = at.linearize()
    sampled = control.c2d(control.ss(A, B, gain[None, :], 0.0), step, method="zoh")
    loop: control.StateSpace = sampled
    return loop


def depth_loop(
    params: VehicleParameters, step: float, speed: float, law: DepthPd | None = None
) -> control.StateSpace:
    """L(z) of the depth PD (Fig. 6.40; ``law``, default Table 6.2's gains) broken at the
    plant input (the fin angle delta_s): the plant's own depth plane (w, q, z, theta) of
    ``params`` at ``speed`` (m/s), sampled every ``step`` (s), as the autopilot's design
    check closes it (:func:`controller_fmu.depth_pd.closed_plane`)."""
    check_loop_arguments({"--speed": speed}, step)
    A, B, gain = closed_plane(law or DepthPd(), params, speed)
    # the law adds gain @ x to the fins: negative feedback of -gain @ x
    sampled = control.c2d(control.ss(A, B, -gain[None, :], 0.0), step, method="zoh")
    loop: control.StateSpace = sampled
    return loop


def loop_margins(loop: control.StateSpace) -> LoopMargins:
    """The margins of a discrete, strictly proper loop ``loop`` (D = 0, as
    :func:`lqr_loop`'s; negative feedback of its output to its input), with the
    closed-loop poles; no margins (empty, Ms infinite) when the closed loop is unstable."""
    step = float(loop.dt)
    poles = np.linalg.eigvals(loop.A - loop.B @ loop.C)
    if not np.all(np.abs(poles) < 1.0):
        return LoopMargins(step, (), (), math.inf, math.nan, poles)
    omega, response = _response(loop)
    gains = [
        Crossing(-1.0 / float(np.real(_at(loop, w))), w)
        for w in _roots(loop, omega, np.imag(response), lambda L: float(np.imag(L)))
        if np.real(_at(loop, w)) < 0.0
    ]
    phases = [  # 180 deg + the phase of L there, in (-180, 180] deg
        Crossing(180.0 - (-math.degrees(float(np.angle(_at(loop, w)))) % 360.0), w)
        for w in _roots(loop, omega, np.abs(response) - 1.0, lambda L: abs(L) - 1.0)
    ]
    sensitivity = np.abs(1.0 / (1.0 + response))
    worst = int(np.argmax(sensitivity))
    return LoopMargins(
        step=step,
        gain_margins=tuple(gains),
        phase_margins=tuple(phases),
        sensitivity_peak=float(sensitivity[worst]),
        sensitivity_frequency=float(omega[worst]),
        poles=poles,
    )


# Why the crossings are found here and not by python-control's ``stability_margins``: on
# these loops (a free heading integrator, an unstable sway-yaw mode, poles near z = 1) its
# root finding on the unit circle returns gain margins whose factor moves no closed-loop
# pole to the unit circle (x 0.116 at 10 rad/s for the shipped LQR, already unstable),
# invents a phase crossover at 0 rad/s, misses the one at the Nyquist frequency (where
# L(-1) is real) and sometimes returns no sensitivity at all. A sign change on a dense
# grid of python-control's frequency response, refined by scipy's brentq, finds them all.
_GRID = 20000  # frequencies, log-spaced from _LOWEST up to and with pi/h
_LOWEST = 1e-4  # rad/s


def _response(loop: control.StateSpace) -> tuple[np.ndarray, np.ndarray]:
    """(omega rad/s, L(e^{j omega h})) on the grid, the Nyquist frequency its last point."""
    nyquist = math.pi / float(loop.dt)
    omega = np.logspace(math.log10(_LOWEST), math.log10(nyquist), _GRID)
    omega[-1] = nyquist
    response = np.asarray(control.frequency_response(loop, omega).complex).ravel()
    return omega, response


def _at(loop: control.StateSpace, omega: float) -> complex:
    """L(e^{j omega h}) at one frequency (rad/s)."""
    return complex(control.evalfr(loop, np.exp(1j * omega * float(loop.dt))))


def _roots(
    loop: control.StateSpace,
    omega: np.ndarray,
    values: np.ndarray,
    function: Callable[[complex], float],
) -> list[float]:
    """The frequencies (rad/s) where ``function(L)`` is 0: each sign change of ``values``
    on the grid, refined; a zero at the Nyquist frequency itself included."""
    found = [
        float(brentq(lambda w: function(_at(loop, w)), omega[k], omega[k + 1], xtol=1e-12))
        for k in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0).tolist()
    ]
    if abs(values[-1]) < 1e-9 * max(1.0, float(np.abs(values).max())):
        found.append(float(omega[-1]))
    return found
