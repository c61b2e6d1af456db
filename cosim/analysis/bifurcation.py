"""Equilibria, their continuation over a parameter, and folds (dissertation Sec. 5.1.2-5.1.4).

Physics-side analysis on the plant's own equations (:class:`PlantModel`): no plotting, no
command line. Three tools:

* :func:`find_equilibria` - every equilibrium in the dissertation's search box
  D = {0 < u < 2, |v| <= 0.4, |r| <= 0.4} (5.1.50), plus |roll| < 90 deg for the lateral
  variant (Sec. 5.1.4: "x5 in (-pi/2, pi/2)"). Method: a root finder
  (:func:`cosim.analysis.equilibria.find_equilibrium`, scipy's hybr) seeded on a fixed grid over
  the box, then deduplication. Why not continuation alone: continuation needs a known
  point on every branch and cannot reach a branch that is not connected to it (an isola),
  whereas the equilibria of this small system (3 to 5 unknowns, a handful of isolated
  roots) are all hit by a few hundred seeds spread over the box. The grid and the order are
  fixed, so the result is deterministic. The seeded search also supplies the starting
  points of the continuation below.
* :func:`sweep` - pseudo-arclength continuation of every equilibrium branch over
  ``roll_torque`` (Q, Sec. 5.1.3, Fig. 5.9), ``mass_position`` (the moving mass held at
  y_v, Sec. 5.1.4, Fig. 5.12), the fin-arm factor ``mu`` (5.1.62, Fig. 5.6) or the
  fin-area factor ``eta`` (5.1.63, Fig. 5.7), with the stability of every point and the
  location of its special points: folds (saddle-node), branch points (pitchforks of the
  symmetric vehicle) and Hopf points.
* :func:`with_fin_arm`, :func:`with_fin_area`, :func:`cg_offset` - how the dissertation's
  parameters map onto a :class:`VehicleParameters` and onto the moving mass.

Written by hand because no maintained Python package does pseudo-arclength continuation of
a small ODE's equilibria (AUTO-07p needs Fortran and a build, PyDSTool is unmaintained):
about a hundred lines here, with scipy's ``root`` as the corrector.

How the dissertation's parameters map onto our model
----------------------------------------------------
* mu, the fin-arm factor of (5.1.62): the fins' moment arm x_fin becomes mu x_fin. The fin
  force is proportional to the fin's local sway velocity v + x_fin r, and its yaw moment
  carries one more x_fin, so (5.1.62) scales beta4 = Y_ur/(m + a22) and
  gamma3 = N_uv/(I_zz + a66) by mu and gamma4 = N_ur/(I_zz + a66) by mu^2, leaving
  beta3 = Y_uv/(m + a22) alone: Y_ur -> mu Y_ur, N_uv -> mu N_uv, N_ur -> mu^2 N_ur.
  As in the dissertation the whole coefficient is scaled ("neglecting the contribution
  of the main body").
* eta, the fin-area factor of (5.1.63): the fin force scales with its planform area, so
  beta3, beta4, gamma3, gamma4 all scale by eta: Y_uv, Y_ur, N_uv, N_ur -> eta times.
* mass_position: Sec. 5.1.4 offsets the centre of gravity sideways by y_g, which adds the
  roll torque W y_g cos(phi) and ignores every other coupling. Our moving mass m_v held
  at rest at y_v (command y_d = y_v, so the servo force k_v (y_v - y_d) - ... is zero)
  adds the roll torque m_v g y_v cos(theta) cos(phi) and the yaw torque
  m_v g y_v sin(theta), which is zero in the lateral variant (theta = 0). The two agree
  when W y_g = m_v g y_v, i.e. y_g = m_v g y_v / W (= y_v / 6 for m_v = m/6, W = m g).
  The rail's x position (x_v = 0.50 m, Sec. 6.3.1, which puts the fixed mass at
  x_w = -0.10 m so that x_g = 0) only weights the servo reaction x_v F_mm, which vanishes
  at rest, so it does not move an equilibrium.
* With a uniform current the turning equilibria are equilibria of the motion relative to
  the water only (5.2.10-5.2.15: over ground they are limit cycles). We therefore solve
  the relative motion (the current-free equations, to which ours reduce exactly) and
  report the velocity over ground at the instant the vehicle heads north (yaw = 0).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property, lru_cache

import numpy as np
from scipy.optimize import root

from cosim.analysis.equilibria import Equilibrium, find_equilibrium, free_states
from cosim.errors import CosimError
from plant_fmu.model.dynamics import STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters
from plant_fmu.model.state_layout import MAX_SPEED


class AnalysisError(CosimError, ValueError):
    """A bad argument to an analysis (a sweep range, a step count, a factor): a ValueError
    to Python callers, and a one-line reason, without a type name, on the command line."""


# Search box D of (5.1.50): (low, high) per free state; u's lower bound is open.
SEARCH_BOX: dict[str, tuple[float, float]] = {
    "u": (0.0, 2.0),
    "v": (-0.4, 0.4),
    "w": (-0.4, 0.4),
    "p": (-0.4, 0.4),
    "q": (-0.4, 0.4),
    "r": (-0.4, 0.4),
    "roll": (-math.pi / 2, math.pi / 2),
    "pitch": (-math.pi / 2, math.pi / 2),
}

# Seeds of the grid search, per free state (states not listed start at 0). With 4 x 5 x 5
# (x 3 in roll) seeds every basin of the REMUS equilibria is hit several times over.
DEFAULT_SEEDS: dict[str, tuple[float, ...]] = {
    "u": (0.5, 1.0, 1.5, 1.9),
    "v": (-0.3, -0.15, 0.0, 0.15, 0.3),
    "r": (-0.3, -0.15, 0.0, 0.15, 0.3),
    "roll": (-0.5, 0.0, 0.5),
}

# Two roots closer than this (max-norm over the free states) are one equilibrium.
DEDUPLICATION_TOLERANCE = 1e-6

SWEEP_PARAMETERS = ("roll_torque", "mass_position", "mu", "eta")

# The most continuation steps a sweep takes across its range: a step of 1e-5 of the range
# (pseudo-arclength, the parameter scaled by the span) is ten times the difference step of
# the parameter's Jacobian column (_Continuation.jacobians), finer steps resolve nothing
# more, and 1e5 steps already take ~25 min here (~15 ms each).
MAX_STEPS = 100_000

Progress = Callable[[int, int], None]
"""Called as progress(done, total), in units of work, while a sweep proceeds."""
StepDone = Callable[[], None]
"""Called once per point a continuation adds to a branch."""

# Roll torque of the REMUS propeller, N m (Example 5.4): the unit of Figs. 5.9-5.11.
Q_PROP = -0.543


# --- Parameter maps ----------------------------------------------------------------------


def with_fin_arm(params: VehicleParameters, mu: float) -> VehicleParameters:
    """The vehicle with its vertical fins' moment arm scaled by mu (5.1.62):
    Y_ur -> mu Y_ur, N_uv -> mu N_uv, N_ur -> mu^2 N_ur (see the module docstring).

    Raises:
        AnalysisError: mu is not a finite factor > 0.
    """
    _check_positive("mu", mu)
    return _fin_arm(params, mu)


def _fin_arm(params: VehicleParameters, mu: float) -> VehicleParameters:
    """:func:`with_fin_arm` for any finite mu: the map is a polynomial in mu, so the
    continuation may evaluate it past a range's end (even at mu <= 0) on its way back."""
    return params.replace(Y_ur=mu * params.Y_ur, N_uv=mu * params.N_uv, N_ur=mu**2 * params.N_ur)


def with_fin_area(params: VehicleParameters, eta: float) -> VehicleParameters:
    """The vehicle with its vertical fins' planform area scaled by eta (5.1.63):
    Y_uv, Y_ur, N_uv, N_ur -> eta times (see the module docstring).

    Raises:
        AnalysisError: eta is not a finite factor > 0.
    """
    _check_positive("eta", eta)
    return _fin_area(params, eta)


def _fin_area(params: VehicleParameters, eta: float) -> VehicleParameters:
    """:func:`with_fin_area` for any finite eta (linear in eta: see :func:`_fin_arm`)."""
    return params.replace(
        Y_uv=eta * params.Y_uv,
        Y_ur=eta * params.Y_ur,
        N_uv=eta * params.N_uv,
        N_ur=eta * params.N_ur,
    )


def cg_offset(params: VehicleParameters, mass_position: float) -> float:
    """The lateral centre-of-gravity offset y_g of Sec. 5.1.4 (m) that gives the same roll
    torque as the moving mass at rest at ``mass_position`` (m): y_g = m_v g y_v / W."""
    return params.m_v * params.g * mass_position / params.W


def mass_position_for_cg_offset(params: VehicleParameters, y_g: float) -> float:
    """Inverse of :func:`cg_offset`: the mass position y_v (m) for an offset y_g (m)."""
    return y_g * params.W / (params.m_v * params.g)


def _check_positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0.0):
        raise AnalysisError(f"{name} = {value!r}: expected a finite factor > 0")


# --- Operating conditions ----------------------------------------------------------------


def keyword_given(name: str, value: float, unit: str) -> str:
    """A condition as a refusal names it to a Python caller: ``thrust = -1.0 N``."""
    return f"{name} = {value!r}{' ' + unit if unit else ''}"


def check_conditions(
    params: VehicleParameters,
    variant: Variant,
    thrust: float,
    roll_torque: float,
    mass_position: float,
    current_east: float,
    given: Callable[[str, float, str], str] = keyword_given,
) -> None:
    """Raise AnalysisError naming the first condition :class:`OperatingConditions` cannot
    take (SI: N, N m, m, m/s); ``given(name, value, unit)`` names it as its caller gave it
    (:func:`keyword_given`; the command line's flag, ``--thrust -1.0``)."""
    values = {"thrust": thrust, "roll_torque": roll_torque, "mass_position": mass_position,
              "current_east": current_east}  # fmt: skip
    for name, value in values.items():
        if not math.isfinite(value):
            raise AnalysisError(f"{given(name, value, '')}: expected a finite number")
    if not abs(current_east) <= MAX_SPEED:
        raise AnalysisError(
            f"{given('current_east', current_east, 'm/s')}: expected |current_east| <= "
            f"{MAX_SPEED:g} m/s (a steady current carries the vehicle at its speed, and the "
            "plant integrates no velocity over ground beyond that)"
        )
    if thrust <= 0.0:
        raise AnalysisError(
            f"{given('thrust', thrust, 'N')}: expected a thrust > 0 (the analyses look for "
            "equilibria at 0 < u < 2 m/s; without thrust the vehicle rests at u = 0, where "
            "the damping vanishes and the linearisation decides no stability)"
        )
    stroke = params.mass_stroke
    if abs(mass_position) > stroke:
        raise AnalysisError(
            f"{given('mass_position', mass_position, 'm')}: expected |y_v| <= the stroke "
            f"{stroke} m of vehicle {params.name!r}"
        )
    if Variant(variant) is Variant.HORIZONTAL:
        for name in ("roll_torque", "mass_position"):
            if values[name] != 0.0:
                raise AnalysisError(
                    f"{given(name, values[name], '')}: it acts through roll, which the "
                    "horizontal variant (2) holds at 0; use the lateral variant (1, "
                    "Sec. 5.1.3-5.1.4) or the full one (0)"
                )


@dataclass(frozen=True)
class OperatingConditions:
    """The vehicle, its free degrees of freedom and the constant inputs of an analysis.

    Args:
        params: the vehicle parameter set.
        variant: which degrees of freedom move (the horizontal one by default, as (5.1.30)).
        thrust: propeller thrust T, N.
        roll_torque: propeller roll torque Q, N m (acts only where roll is free).
        mass_position: moving-mass position y_v held at rest, m (|y_v| <= stroke).
        current_east: uniform current towards east, m/s (see the module docstring);
            |current_east| <= MAX_SPEED, the fastest velocity over ground the plant takes.
    """

    params: VehicleParameters
    variant: Variant = Variant.HORIZONTAL
    thrust: float = 9.0
    roll_torque: float = 0.0
    mass_position: float = 0.0
    current_east: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "variant", Variant(self.variant))
        check_conditions(
            self.params, self.variant, self.thrust, self.roll_torque, self.mass_position,
            self.current_east,
        )  # fmt: skip

    @cached_property
    def model(self) -> PlantModel:
        """The plant in still water (equilibria are those of the relative motion)."""
        return PlantModel(self.params, variant=self.variant)

    @cached_property
    def free_states(self) -> tuple[str, ...]:
        """The states an equilibrium solves for (moving mass and cyclic states excluded)."""
        return free_states(self.model, exclude=("mass_position", "mass_velocity"))

    def inputs(self) -> np.ndarray:
        """Input vector: thrust, roll torque, and the mass command y_d = y_v."""
        return input_vector(
            {
                "thrust": self.thrust,
                "roll_torque": self.roll_torque,
                "mass_position_cmd": self.mass_position,
            }
        )

    def state(self, values: Mapping[str, float] | None = None) -> np.ndarray:
        """A full state vector: the mass at rest at y_v, the named states, the rest 0."""
        return state_vector({"mass_position": self.mass_position, **(values or {})})

    def over_ground(self, state: np.ndarray) -> np.ndarray:
        """The relative-motion state with the current in body axes (as the plant sees it,
        :meth:`PlantModel.current_in_body`, at yaw = 0) added to the free linear velocities."""
        state = state.copy()
        if self.current_east == 0.0:
            return state
        at_zero_yaw = state.copy()
        at_zero_yaw[STATE_INDEX["yaw"]] = 0.0
        current = input_vector({"current_east": self.current_east})
        current_body = self.model.current_in_body(at_zero_yaw, current)
        for k, name in enumerate(("u", "v", "w")):
            if name in self.free_states:
                state[STATE_INDEX[name]] += current_body[k]
        return state

    def with_parameter(
        self, name: str, value: float, beyond_range: bool = False
    ) -> OperatingConditions:
        """These conditions with one sweep parameter (``SWEEP_PARAMETERS``) set; ``mu`` and
        ``eta`` are factors on the parameters of ``self`` (1 = unchanged), refused unless
        > 0 except ``beyond_range`` (a continuation's probe past the end of a range that
        is itself > 0: the factor maps hold for any real factor)."""
        if name == "roll_torque":
            return replace(self, roll_torque=value)
        if name == "mass_position":
            return replace(self, mass_position=value)
        if name == "mu":
            arm = _fin_arm if beyond_range else with_fin_arm
            return replace(self, params=arm(self.params, value))
        if name == "eta":
            area = _fin_area if beyond_range else with_fin_area
            return replace(self, params=area(self.params, value))
        raise AnalysisError(f"unknown sweep parameter {name!r}: expected one of {SWEEP_PARAMETERS}")


# --- Equilibria --------------------------------------------------------------------------


def in_box(names: Sequence[str], values: Sequence[float] | np.ndarray) -> bool:
    """True when every free state lies in the search box (0 < u < 2, |v|, |r| <= 0.4, ...)."""
    for name, value in zip(names, values, strict=True):
        low, high = SEARCH_BOX.get(name, (-math.inf, math.inf))
        if name == "u" and value <= low:
            return False
        if not low <= value <= high:
            return False
    return True


def find_equilibria(
    conditions: OperatingConditions,
    seeds: Mapping[str, Sequence[float]] | None = None,
) -> list[Equilibrium]:
    """Every equilibrium in the search box, sorted by (v, r, u).

    Args:
        conditions: vehicle, variant and inputs.
        seeds: grid of starting values per free state (default :data:`DEFAULT_SEEDS`;
            free states without seeds start at 0).

    Returns:
        Equilibria of the relative motion (the box bounds the velocities relative to the
        water); their ``state`` is over ground (see
        :meth:`OperatingConditions.over_ground`), their eigenvalues those of the Jacobian
        over ``conditions.free_states`` (the moving-mass servo, whose poles are
        -zeta omega_n +- i omega_n sqrt(1 - zeta^2) whatever the hull does, is left out).
    """
    return [
        replace(eq, state=conditions.over_ground(eq.state))
        for eq in _relative_equilibria(conditions, seeds)
    ]


def _relative_equilibria(
    conditions: OperatingConditions, seeds: Mapping[str, Sequence[float]] | None
) -> list[Equilibrium]:
    """:func:`find_equilibria` before the current is added back (still-water states)."""
    seeds = DEFAULT_SEEDS if seeds is None else seeds
    names = conditions.free_states
    axes = [tuple(seeds.get(name, (0.0,))) for name in names]
    model, inputs = conditions.model, conditions.inputs()
    found: list[Equilibrium] = []
    for values in itertools.product(*axes):
        guess = {"mass_position": conditions.mass_position, **dict(zip(names, values, strict=True))}
        try:
            eq = find_equilibrium(model, guess, inputs)
        except RuntimeError:
            continue  # this seed lies in no basin of a root: others cover the box
        z = [eq.value(name) for name in names]
        if not in_box(names, z):
            continue
        if any(
            max(abs(a - other.value(n)) for a, n in zip(z, names, strict=True))
            < DEDUPLICATION_TOLERANCE
            for other in found
        ):
            continue
        found.append(eq)
    found.sort(key=lambda e: tuple(round(e.value(n), 9) for n in ("v", "r", "u")))
    return found


# --- Continuation ------------------------------------------------------------------------


@dataclass(frozen=True)
class Branch:
    """One continued branch of equilibria: point k is (parameters[k], states[k])."""

    free_states: tuple[str, ...]
    parameters: np.ndarray  # [k]
    states: np.ndarray  # [k, len(free_states)]
    eigenvalues: np.ndarray  # [k, len(free_states)], complex

    @property
    def stable(self) -> np.ndarray:
        """Per point: every eigenvalue strictly in the left half-plane (to 1e-9)."""
        return np.all(self.eigenvalues.real < -1e-9, axis=1)

    def values(self, name: str) -> np.ndarray:
        """One free state along the branch."""
        return self.states[:, self.free_states.index(name)]


@dataclass(frozen=True)
class SpecialPoint:
    """A point where a branch changes stability or turns back in the parameter.

    ``kind`` is ``"fold"`` (saddle-node: a real eigenvalue crosses 0 and the branch turns
    back), ``"branch point"`` (a real eigenvalue crosses 0 where two branches meet, as the
    pitchforks of the symmetric vehicle in Figs. 5.6-5.7) or ``"hopf"`` (a complex pair
    crosses the imaginary axis).
    """

    kind: str
    parameter: float
    state: dict[str, float]
    eigenvalues: np.ndarray
    branch: int


@dataclass(frozen=True)
class Sweep:
    """The result of :func:`sweep`."""

    parameter: str
    start: float
    stop: float
    free_states: tuple[str, ...]
    branches: list[Branch]
    special_points: list[SpecialPoint] = field(default_factory=list)

    @property
    def folds(self) -> list[SpecialPoint]:
        return [s for s in self.special_points if s.kind == "fold"]


def _converged(residual: np.ndarray) -> bool:
    """The residual is zero to 1e-9 (hybr may report "no progress" once it is at 1e-16,
    so its success flag alone is not the test)."""
    return bool(np.all(np.isfinite(residual)) and np.max(np.abs(residual)) < 1e-9)


class _Continuation:
    """Pseudo-arclength continuation of H(y) = xdot_free(z, lambda) = 0 on y = (z, s_l),
    lambda = s_l * scale (scale = the swept span, so the parameter is O(1) like the states).

    Predictor y + ds t along the unit tangent t (the null vector of DH); corrector: scipy
    ``root`` on [H(y'); t.(y' - y) - ds] = 0 (Keller's pseudo-arclength condition).
    """

    def __init__(
        self,
        base: OperatingConditions,
        parameter: str,
        low: float,
        high: float,
        ds: float,
    ) -> None:
        if parameter == "mass_position":
            # The stroke is a stop the mass at rest never touches inside the range; widen
            # it so the predictor may overshoot the range's ends (checked by the caller).
            stroke = 2.0 * max(abs(low), abs(high), base.params.mass_stroke)
            base = replace(base, params=base.params.with_stroke(stroke))
        self.scale = high - low
        self.low, self.high = low / self.scale, high / self.scale
        if self.low > self.high:
            self.low, self.high = self.high, self.low
        self.ds_max = ds
        self.names = base.free_states
        self.index = [STATE_INDEX[n] for n in self.names]
        # the corrector and the difference steps probe past the range's ends; the range
        # itself was checked (check_sweep), and no point beyond it is kept (trace)
        self.conditions_at = lru_cache(maxsize=64)(
            lambda value: base.with_parameter(parameter, value, beyond_range=True)
        )

    def _parts(self, y: np.ndarray) -> tuple[OperatingConditions, np.ndarray, np.ndarray]:
        cond = self.conditions_at(float(y[-1] * self.scale))
        x = cond.state()
        x[self.index] = y[:-1]
        return cond, x, cond.inputs()

    def residual(self, y: np.ndarray) -> np.ndarray:
        cond, x, u = self._parts(y)
        return cond.model.derivative(x, u)[self.index]

    def jacobians(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(J_z over the free states, DH = [J_z, dH/ds_l])."""
        cond, x, u = self._parts(y)
        J, _ = linearize(cond.model, x, u, self.names)
        h = 1e-6 * max(1.0, abs(y[-1]))
        plus, minus = y.copy(), y.copy()
        plus[-1] += h
        minus[-1] -= h
        column = (self.residual(plus) - self.residual(minus)) / (2.0 * h)
        return J, np.column_stack([J, column])

    @staticmethod
    def tangent(DH: np.ndarray, previous: np.ndarray | None) -> np.ndarray:
        """Unit null vector of DH, oriented along ``previous`` (or with d lambda > 0)."""
        t = np.linalg.svd(DH)[2][-1]
        sign = np.sign(t[-1] if previous is None else t @ previous)
        return t * (sign if sign != 0 else 1.0)

    def correct(self, y: np.ndarray, t: np.ndarray, ds: float) -> np.ndarray | None:
        """The branch point at pseudo-arclength ds from y along t, or None."""

        def system(candidate: np.ndarray) -> np.ndarray:
            return np.append(self.residual(candidate), t @ (candidate - y) - ds)

        guess = y + ds * t
        solution = root(system, guess, method="hybr", tol=1e-12)
        if not _converged(self.residual(solution.x)):
            return None
        if np.linalg.norm(solution.x - guess) > max(abs(ds), 1e-12):
            return None  # jumped to another branch
        return solution.x

    def at_parameter(self, y0: np.ndarray, y1: np.ndarray, s_l: float) -> np.ndarray | None:
        """The branch point with the parameter fixed at s_l, from the segment y0-y1."""
        frac = (s_l - y0[-1]) / (y1[-1] - y0[-1])
        guess = y0 + frac * (y1 - y0)

        def system(z: np.ndarray) -> np.ndarray:
            return self.residual(np.append(z, s_l))

        solution = root(system, guess[:-1], method="hybr", tol=1e-12)
        if not _converged(system(solution.x)):
            return None
        return np.append(solution.x, s_l)

    def inside(self, y: np.ndarray) -> bool:
        return in_box(self.names, y[:-1])

    def trace(
        self,
        y0: np.ndarray,
        direction: float,
        max_points: int,
        traced: Sequence[np.ndarray],
        step_done: StepDone,
    ) -> list[tuple[np.ndarray, np.ndarray]]:
        """Points (y, t) from y0 (excluded) in ``direction`` (+1: towards the range's end)
        until the parameter range or the search box is left, or the trace runs along one
        of the ``traced`` branches (two points in a row on it: it merged, e.g. past a
        pitchfork; a single point is a crossing)."""
        _, DH = self.jacobians(y0)
        t = self.tangent(DH, None) * direction
        y, ds = y0, self.ds_max
        points: list[tuple[np.ndarray, np.ndarray]] = []
        on_old = 0
        while len(points) < max_points and on_old < 2:
            y_new = self.correct(y, t, ds)
            if y_new is None:
                ds /= 2.0
                if ds < self.ds_max / 256:
                    break  # cannot continue (a singular point the corrector cannot pass)
                continue
            if not self.low <= y_new[-1] <= self.high:
                edge = self.high if y_new[-1] > self.high else self.low
                if abs(y[-1] - edge) > 1e-12:
                    y_edge = self.at_parameter(y, y_new, edge)
                    if y_edge is not None and self.inside(y_edge):
                        _, DH = self.jacobians(y_edge)
                        points.append((y_edge, self.tangent(DH, t)))
                break
            if not self.inside(y_new):
                break
            _, DH = self.jacobians(y_new)
            t = self.tangent(DH, t)
            points.append((y_new, t))
            step_done()
            merged = any(self.on_branch(y_new, branch, 0.1 * self.ds_max) for branch in traced)
            on_old = on_old + 1 if merged else 0
            y, ds = y_new, min(2.0 * ds, self.ds_max)
        return points

    def on_branch(self, y: np.ndarray, branch: np.ndarray, tol: float) -> bool:
        """True when y lies within tol of the polyline through the branch's points."""
        if len(branch) == 1:
            return bool(np.linalg.norm(branch[0] - y) < tol)
        a, b = branch[:-1], branch[1:]
        d = b - a
        length2 = np.maximum(np.einsum("ij,ij->i", d, d), 1e-300)
        frac = np.clip(np.einsum("ij,ij->i", y - a, d) / length2, 0.0, 1.0)
        closest = a + frac[:, None] * d
        return bool(np.min(np.linalg.norm(closest - y, axis=1)) < tol)

    def n_unstable(self, J: np.ndarray) -> int:
        return int(np.sum(np.linalg.eigvals(J).real > 0.0))

    def locate(
        self, y: np.ndarray, t: np.ndarray, y_next: np.ndarray, t_next: np.ndarray
    ) -> tuple[str, np.ndarray] | None:
        """Classify and locate (by bisection in arclength) a special point between two
        consecutive branch points, or None when there is none."""
        J0, _ = self.jacobians(y)
        J1, _ = self.jacobians(y_next)
        turned = np.sign(t[-1]) != np.sign(t_next[-1])
        unstable0 = self.n_unstable(J0)
        if not turned and unstable0 == self.n_unstable(J1):
            return None

        def same_side(candidate: np.ndarray) -> bool:
            J, DH = self.jacobians(candidate)
            if turned:
                return bool(np.sign(self.tangent(DH, t)[-1]) == np.sign(t[-1]))
            return self.n_unstable(J) == unstable0

        s_low, s_high = 0.0, float(t @ (y_next - y))
        found = y_next
        for _ in range(40):
            s_mid = 0.5 * (s_low + s_high)
            candidate = self.correct(y, t, s_mid)
            if candidate is None:
                break
            if same_side(candidate):
                s_low = s_mid
            else:
                s_high, found = s_mid, candidate
        J, DH = self.jacobians(found)
        singular = np.linalg.svd(DH, compute_uv=False)
        rank_deficient = singular[-1] < 1e-4 * singular[0]
        eigenvalues = np.linalg.eigvals(J)
        nearest = eigenvalues[np.argmin(np.abs(eigenvalues.real))]
        if turned:
            kind = "branch point" if rank_deficient else "fold"
        elif abs(nearest.imag) > 1e-6:
            kind = "hopf"
        else:
            kind = "branch point"
        return kind, found


def sweep(
    conditions: OperatingConditions,
    parameter: str,
    start: float,
    stop: float,
    steps: int = 200,
    seeds: Mapping[str, Sequence[float]] | None = None,
    search_points: int = 3,
    progress: Progress | None = None,
) -> Sweep:
    """Continue every equilibrium branch in the search box over ``parameter`` from
    ``start`` to ``stop``, with stability and special points (folds, branch points, Hopf).

    Branches start from :func:`find_equilibria` at ``search_points`` parameter values
    evenly spread over [start, stop] (the ends included, so branches born or ending inside
    the range are found too); each is traced both ways with a step of 1/``steps`` of the
    range (in pseudo-arclength, the parameter scaled by the span), and a start that lies
    on a branch already traced is skipped.

    Args:
        conditions: the base vehicle, variant and inputs; the swept quantity replaces its
            own (``mu``, ``eta``: factors on ``conditions.params``).
        parameter: one of :data:`SWEEP_PARAMETERS`.
        start, stop: the range (N m for roll_torque, m for mass_position, 1 for mu, eta).
        steps: continuation steps across the range (2 to :data:`MAX_STEPS`).
        seeds: grid for the equilibrium search (:data:`DEFAULT_SEEDS`).
        search_points: parameter values the equilibrium search runs at (>= 2).
        progress: called as progress(done, total) while the work proceeds.

    Raises:
        ValueError: unknown parameter, an empty range, too few steps, or a parameter value
            the vehicle cannot take (e.g. a mass position beyond the stroke).
    """
    check_sweep(conditions, parameter, start, stop, steps, search_points)
    cont = _Continuation(conditions, parameter, start, stop, ds=1.0 / steps)
    counter = _WorkCounter(search_points, progress)
    starts = _branch_starts(cont, start, stop, search_points, seeds, counter)
    counter.total += 2 * steps * len(starts)
    traced, tangents = _trace_branches(cont, starts, steps, counter)
    branches = [
        Branch(
            cont.names,
            ys[:, -1] * cont.scale,
            ys[:, :-1],
            np.array([np.linalg.eigvals(cont.jacobians(y)[0]) for y in ys]),
        )
        for ys in traced
    ]
    specials = _special_points(cont, traced, tangents)
    specials.sort(key=lambda s: (s.parameter - start) / (stop - start))
    counter.finish()
    return Sweep(parameter, start, stop, cont.names, branches, specials)


def check_sweep(
    conditions: OperatingConditions,
    parameter: str,
    start: float,
    stop: float,
    steps: int,
    search_points: int = 3,
    names: tuple[str, str, str] = ("start", "stop", "steps ="),
) -> None:
    """Raise AnalysisError (a ValueError) naming the first bad argument of :func:`sweep`
    (in seconds, before any work); ``names`` name ``start``, ``stop`` and ``steps`` in
    the refusal (the command line's FROM, TO and ``--steps``)."""
    if parameter not in SWEEP_PARAMETERS:
        raise AnalysisError(
            f"unknown sweep parameter {parameter!r}: expected one of {SWEEP_PARAMETERS}"
        )
    if not (math.isfinite(start) and math.isfinite(stop)) or start == stop:
        raise AnalysisError(
            f"sweep range {start!r} .. {stop!r}: expected two different finite values"
        )
    if steps < 2:
        raise AnalysisError(f"{names[2]} {steps!r}: expected at least 2")
    if steps > MAX_STEPS:
        raise AnalysisError(
            f"{names[2]} {steps!r}: expected at most {MAX_STEPS} (a finer step resolves "
            "nothing more)"
        )
    if search_points < 2:
        raise AnalysisError(f"search_points = {search_points!r}: expected at least 2")
    for name, value in zip(names[:2], (start, stop), strict=True):
        try:
            conditions.with_parameter(parameter, value)  # raises for an impossible value
        except AnalysisError as exc:
            raise AnalysisError(f"{name}: {exc}") from None


class _WorkCounter:
    """Counts a sweep's units of work and reports them to a :data:`Progress` callback."""

    def __init__(self, total: int, report: Progress | None) -> None:
        self.total = total
        self.done = 0
        self._report = report

    def tick(self, amount: int = 1) -> None:
        self.done += amount
        if self._report is not None:
            self._report(self.done, self.total)

    def finish(self) -> None:
        if self._report is not None:
            self._report(self.total, self.total)


def _branch_starts(
    cont: _Continuation,
    start: float,
    stop: float,
    search_points: int,
    seeds: Mapping[str, Sequence[float]] | None,
    counter: _WorkCounter,
) -> list[np.ndarray]:
    """Continuation points (free states, scaled parameter) of every equilibrium found at
    ``search_points`` parameter values spread over [start, stop]."""
    starts: list[np.ndarray] = []
    for value in np.linspace(start, stop, search_points):
        for eq in _relative_equilibria(cont.conditions_at(float(value)), seeds):
            starts.append(np.append(eq.state[cont.index], value / cont.scale))
        counter.tick()
    return starts


def _trace_branches(
    cont: _Continuation, starts: Sequence[np.ndarray], steps: int, counter: _WorkCounter
) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each branch through a start not on a branch already traced, both ways: its points
    and unit tangents, ordered along increasing arclength."""
    traced: list[np.ndarray] = []
    tangents: list[np.ndarray] = []
    for y0 in starts:
        if any(cont.on_branch(y0, branch, 0.5 * cont.ds_max) for branch in traced):
            counter.tick(2 * steps)
            continue
        halves = []
        for direction in (-1.0, 1.0):
            budget = [0]

            def step_done(budget: list[int] = budget) -> None:
                budget[0] += 1
                if budget[0] <= steps:
                    counter.tick()

            halves.append(cont.trace(y0, direction, 20 * steps, traced, step_done))
            counter.tick(max(0, steps - budget[0]))
        backward, forward = halves
        _, DH = cont.jacobians(y0)
        t0 = cont.tangent(DH, None)
        points = [(y, -t) for y, t in reversed(backward)] + [(y0, t0)] + forward
        traced.append(np.array([y for y, _ in points]))
        tangents.append(np.array([t for _, t in points]))
    return traced, tangents


def _special_points(
    cont: _Continuation, traced: Sequence[np.ndarray], tangents: Sequence[np.ndarray]
) -> list[SpecialPoint]:
    """Folds, branch points and Hopf points between consecutive points of every branch,
    each once (a point reached along a second branch is not repeated)."""
    specials: list[SpecialPoint] = []
    for b, (ys, ts) in enumerate(zip(traced, tangents, strict=True)):
        for k in range(len(ys) - 1):
            located = cont.locate(ys[k], ts[k], ys[k + 1], ts[k + 1])
            if located is None:
                continue
            kind, y = located
            if any(
                s.kind == kind
                and abs(s.parameter / cont.scale - y[-1]) < 1e-4
                and max(abs(s.state[n] - v) for n, v in zip(cont.names, y[:-1], strict=True)) < 1e-4
                for s in specials
            ):
                continue  # the same point reached along a second branch
            specials.append(
                SpecialPoint(
                    kind=kind,
                    parameter=float(y[-1] * cont.scale),
                    state=dict(zip(cont.names, map(float, y[:-1]), strict=True)),
                    eigenvalues=np.linalg.eigvals(cont.jacobians(y)[0]),
                    branch=b,
                )
            )
    return specials
