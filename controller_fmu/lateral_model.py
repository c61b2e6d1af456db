"""The heading controllers' design model: the plant's own lateral equations at u = U0.

Every heading controller of Sec. 6.3 is designed on the lateral dynamics (6.3.13) with the
surge speed frozen at the design speed U0 ("we neglect the equation in surge ... and take
u = U0"). Rather than re-typing the dissertation's coefficient formulas (G'', H'', eta_2, ...)
this module evaluates and linearises :class:`plant_fmu.model.dynamics.PlantModel` in its LATERAL
variant, so the controllers always use exactly the physics the plant integrates, for
whichever vehicle parameter set is active.

The controller state (the order of (6.3.17)) is::

    x = [v, r, p, phi, psi - psi_d, y_v, y_vel]        (m/s, rad/s, rad/s, rad, rad, m, m/s)

with v the sway velocity relative to the water (Sec. 6.3.3: in a steady uniform current the
relative velocities replace the absolute ones), and the input is the servo command y_d (m).
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np

from plant_fmu.model import compiled
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

CONTROL_STATES: tuple[str, ...] = ("v", "r", "p", "roll", "yaw", "mass_position", "mass_velocity")
"""Plant state names of the controller state x, in order (``yaw`` holds psi - psi_d)."""

_PLANT_INDEX = [STATE_INDEX[name] for name in CONTROL_STATES]
_V, _R, _P, _ROLL = (STATE_INDEX[n] for n in ("v", "r", "p", "roll"))
_YV, _YVEL = STATE_INDEX["mass_position"], STATE_INDEX["mass_velocity"]
_Y_D = INPUT_INDEX["mass_position_cmd"]
_F_T = INPUT_INDEX["tunnel_force"]


class LateralDesignModel:
    """The LATERAL plant at u = design_speed, no current, as the controllers see it.

    Args:
        params: the vehicle parameter set the controller is designed for.
        design_speed: U0, the surge speed relative to the water, m/s (> 0).
        use_compiled: evaluate the plant through its compiled derivative when numba is
            usable (False: always the numpy reference, as the agreement tests compare).

    Raises:
        ValueError: design_speed is not a finite positive number.
    """

    def __init__(
        self, params: VehicleParameters, design_speed: float, use_compiled: bool = True
    ) -> None:
        if not (np.isfinite(design_speed) and design_speed > 0.0):
            raise ValueError(f"design_speed = {design_speed!r}: expected a finite speed > 0 m/s")
        self.params = params
        self.design_speed = float(design_speed)
        self.plant = PlantModel(params, variant=Variant.LATERAL)
        self._x0 = state_vector({"u": self.design_speed})
        self._u0 = input_vector()
        # The plant's compiled derivative (same arithmetic, ~50x cheaper) when numba is
        # usable: static_mass_rates runs at every backstepping step.
        usable = use_compiled and compiled.AVAILABLE
        self._fast = compiled.CompiledPlant(self.plant) if usable else None
        self._x_work, self._u_work = self._x0.copy(), self._u0.copy()

    @property
    def compiled_plant(self) -> compiled.CompiledPlant | None:
        """The plant's compiled derivative, or None when numba is off."""
        return self._fast

    @property
    def design_state(self) -> np.ndarray:
        """The plant state of the straight run at U0 (a copy), plant order."""
        return self._x0.copy()

    @property
    def design_inputs(self) -> np.ndarray:
        """The plant inputs of the straight run (a copy): all 0."""
        return self._u0.copy()

    def linearize(self) -> tuple[np.ndarray, np.ndarray]:
        """A (7x7) and B (7x1) of x_dot = A x + B y_d about the straight run at U0, no roll,
        mass centred (6.3.17); the plant's own Jacobians, so (6.3.19) up to its two known
        misprints (docs/model.md#corrections-and-choices)."""
        return linearize(self.plant, self._x0, self._u0, CONTROL_STATES, ["mass_position_cmd"])

    def derivative(self, x: np.ndarray, y_d: float) -> np.ndarray:
        """x_dot = f(x) + g y_d of the lateral plant (6.3.13) at u = U0, controller order."""
        return self.plant.derivative(self._plant_state(x), self._inputs(y_d))[_PLANT_INDEX]

    def static_mass_rates(
        self, v: float, r: float, p: float, phi: float, y_v: float
    ) -> tuple[float, float, float]:
        """(v_dot, r_dot, p_dot) with the mass held still at y_v (y_d = y_v, y_vel = 0): the
        vehicle part of (6.3.48)-(6.3.50) with the inertia force m_v y_v'' removed."""
        derivative = self.plant.derivative if self._fast is None else self._fast.derivative
        return self._rates(derivative, v, r, p, phi, y_v)

    def _rates(
        self,
        derivative: Callable[[np.ndarray, np.ndarray], np.ndarray],
        v: float,
        r: float,
        p: float,
        phi: float,
        y_v: float,
    ) -> tuple[float, float, float]:
        """(v_dot, r_dot, p_dot) from ``derivative`` (the reference's or the compiled one)."""
        x, inputs = self._x_work, self._u_work
        x[_V], x[_R], x[_P], x[_ROLL], x[_YV] = v, r, p, phi, y_v
        inputs[_Y_D] = y_v
        rates: list[float] = derivative(x, inputs).tolist()
        return rates[_V], rates[_R], rates[_P]

    def static_mass_jacobian(self) -> dict[str, float]:
        """Partial derivatives of (v_dot, r_dot, p_dot) with the mass held still, at the
        straight run, keyed ``"<rate>/<variable>"`` (e.g. ``"r/v"`` = d r_dot / d v);
        plus ``"v/tunnel_force"``, the sway acceleration per newton of tunnel thrust.

        A function of the parameter set and U0 alone, so computed once per process for
        each (:func:`_static_mass_jacobian`): every run of a study designs the same law."""
        return dict(_static_mass_jacobian(self.params, self.design_speed))

    def _plant_state(self, x: np.ndarray) -> np.ndarray:
        full = self._x0.copy()
        full[_PLANT_INDEX] = x
        return full

    def _inputs(self, y_d: float) -> np.ndarray:
        inputs = self._u0.copy()
        inputs[_Y_D] = y_d
        return inputs


@functools.lru_cache(maxsize=32)
def _static_mass_jacobian(
    params: VehicleParameters, design_speed: float
) -> tuple[tuple[str, float], ...]:
    """:meth:`LateralDesignModel.static_mass_jacobian` by central differences of the
    reference derivative (a parameter set is frozen and hashable, so it keys the cache)."""
    model = LateralDesignModel(params, design_speed, use_compiled=False)
    names = ("v", "r", "p", "roll", "mass_position")
    rates = ("v", "r", "p")
    step = 1e-6
    jac: dict[str, float] = {}
    for k, name in enumerate(names):
        plus, minus = np.zeros(5), np.zeros(5)
        plus[k], minus[k] = step, -step
        # the reference derivative: a central difference divides its rounding by 2e-6,
        # so the gains must not depend on whether numba is usable
        rates_plus = model._rates(model.plant.derivative, *plus)
        diff = (np.array(rates_plus) - model._rates(model.plant.derivative, *minus)) / (2 * step)
        for i, rate in enumerate(rates):
            jac[f"{rate}/{name}"] = float(diff[i])
    _, b_t = linearize(model.plant, model._x0, model._u0, ["v"], ["tunnel_force"])
    jac["v/tunnel_force"] = float(b_t[0, 0])
    return tuple(jac.items())
