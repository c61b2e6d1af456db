"""AuvPlant: the REMUS 100 with internal actuators as an FMI 2.0 co-simulation slave.

The slave class of ``AuvPlant.fmu`` (modelIdentifier ``AuvPlant``; the build ships this
module in ``plant_fmu`` and a generated pythonfmu entry module that imports the class, see
:mod:`fmu_runtime.entry`): FMI variables on one side,
:class:`plant_fmu.model.dynamics.PlantModel` and :func:`plant_fmu.model.stepping.advance`
on the other. No physics lives here.

Variables (``docs/interfaces.md#auvplant`` lists every one):

* inputs ``thrust`` (N, start 9), ``roll_torque`` (N.m), ``tunnel_force`` (N),
  ``fin_angle`` (rad), ``mass_position_cmd`` (m; the rail stops bound the mass, not the command),
  ``current_north``, ``current_east``, ``current_down`` (m/s, earth frame);
* outputs: the 14 states (``north`` ... ``r``, ``mass_position``, ``mass_velocity``), the
  attitude quaternion ``quat_w``, ``quat_x``, ``quat_y``, ``quat_z`` (body to earth, scalar
  first; the full variant integrates it, and roll, pitch and yaw are its Euler angles with
  |pitch| <= 90 deg, roll and yaw continuing the previous ones by whole turns, so yaw runs
  on past +-180 deg), ``u_rel``, ``v_rel``, ``w_rel`` (m/s, nu - U, U the current in
  body axes: ``PlantModel.current_in_body``) and ``kinetic_energy`` (J, 1/2 nu_r^T (M_RB +
  M_A) nu_r; with model 1 the moving mass's too). All are refreshed after initialisation and
  after each step, so none depends directly on an input (ModelStructure dependencies "").
  They depend on the parameters (``initial="calculated"``): read in initialisation mode,
  they give the values the plant will start from;
* parameters (fixed): the initial state ``north_0`` ... ``r_0``, ``mass_position_0``,
  ``mass_velocity_0`` (default 0; a write of |``roll_0``|, |``pitch_0``| or |``yaw_0``|
  beyond ``MAX_START_ANGLE``, 1e6 rad, is refused; the full variant refuses |``pitch_0``|
  beyond 90 deg, naming the start of the same attitude within it), ``variant`` (0 full
  6-DOF, 1 lateral (6.3.13), 2 horizontal (5.1.30); a write outside 0..2 is refused),
  ``moving_mass_model`` (0 the dissertation's (6.3.11)-(6.3.13), 1 hull and moving mass as
  two bodies (6.2.28); a write outside 0..1 is refused), ``ideal_fluid``, ``vehicle`` (a
  built-in set name, read from this instance's ``resources/``, or a .toml path),
  ``current_shear_dUdy`` (1/s), ``max_substep`` (s, longest internal RK4 step: a doStep
  needing more than :data:`~plant_fmu.model.stepping.MAX_SUBSTEPS` sub-steps is discarded
  unstarted), and every field of :class:`VehicleParameters` (``m``, ``W``, ``B``, ``z_g``,
  ``I_xx``, ``a22``, ``X_uu``, ``m_v``, ...), unit, description and range
  (``min``/``max``) from its declaration.

Physical parameters: ``vehicle`` picks the base set; each physical parameter the importer
writes overrides it; the result is validated as a whole (``VehicleParameters.replace``).
After initialisation the physical parameters read back the values in use. The start
values in modelDescription.xml are those of ``remus100``.

Speed: the plant steps with the compiled path of :mod:`plant_fmu.model.compiled` (numba)
when it covers the model; with ``moving_mass_model = 1`` it steps the reference
(:func:`plant_fmu.model.stepping.advance`'s numpy loop), and in a host where numba cannot
be used (not installed: numba is optional, or ``AUV_COSIM_NO_JIT=1``) it steps the
reference and logs a Warning, once per instance, saying why and what it costs. Both do
the same arithmetic (agreement to 1e-12 is tested).

Currents: the uniform current inputs at initialisation set the start; an initialisation
or a step with one beyond ``MAX_SPEED`` (100 m/s) is refused naming it
(``stepping.check_current``). When they change
between steps, the hull's velocity over ground jumps by
``PlantModel.current_change_velocity_jump`` (the impulse of the (Mbar + M_A) nuc_dot term),
applied at the start of the next step; inputs are held over each step.

The surface: the model has none (``docs/model.md#the-envelope``). A start with the whole
hull above it (``down_0`` < -diameter/2), the first step after which the top of a hull that
started under water (``down_0`` >= diameter/2) breaks the surface, and the first after which
the hull has risen out of the water are each logged as a Warning, once per instance; the
plant steps on, with the buoyancy and drag of a submerged hull.

Input derivatives (``canInterpolateInputs="true"``): an importer that extrapolates its
values (``fmi2SetRealInputDerivatives``, orders 1 and 2) gets them used inside the step,
every RK4 stage taking the actuator inputs at its own time (``stepping.advance`` with
``rates``), so a closed loop converges at second or third order in the communication step
instead of first. The currents stay held over a step (see above).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real, String

from fmu_runtime.safe_slave import SafeSlave
from fmu_runtime.variables import field_bounds, item_getter, item_setter
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.jit import compiled_entry
from plant_fmu.model.moving_mass import MovingMassModel
from plant_fmu.model.parameters import VehicleParameters, load_vehicle, vehicle_folder
from plant_fmu.model.state_layout import (
    CURRENT,
    DOWN,
    INPUT_NAMES,
    INPUT_UNITS,
    MASS_POSITION,
    MAX_SPEED,
    MAX_START_ANGLE,
    MAX_TURN_RATE,
    NU,
    PITCH,
    QUATERNION_NAMES,
    STATE_NAMES,
    STATE_UNITS,
    STEP_STATE_NAMES,
)
from plant_fmu.model.stepping import (
    DEFAULT_MAX_SUBSTEP,
    advance,
    check_current,
    stepping_state,
    substeps,
)

INPUT_DESCRIPTIONS: dict[str, str] = {
    "thrust": "propeller surge thrust T",
    "roll_torque": "propeller roll torque Q",
    "tunnel_force": "tunnel-thruster sway force F_t (6.3.79)",
    "fin_angle": "stern-plane angle delta_s (Table 6.1)",
    "mass_position_cmd": "moving-mass servo command y_d (6.3.12); the stops bound the mass",
    "current_north": (
        "uniform current, north component, earth frame: > 0 the water moves towards north"
    ),
    "current_east": (
        "uniform current, east component, earth frame: > 0 the water moves towards east"
    ),
    "current_down": (
        "uniform current, down component, earth frame: > 0 the water moves towards down"
    ),
}
INPUT_STARTS: dict[str, float] = {"thrust": 9.0}
# what the model does above the surface (docs/model.md#the-envelope)
_NO_SURFACE = (
    "the model has no free surface, so it keeps the buoyancy, added mass and drag of a "
    "submerged hull there, and a buoyant vehicle rises on into the air"
)
# the inputs a reduced variant has no degree of freedom for (fin_angle acts in heave and
# pitch, roll_torque in roll, current_down along the body's down axis): taken, not used
IGNORED_INPUTS: dict[Variant, tuple[str, ...]] = {
    Variant.FULL: (),
    Variant.LATERAL: ("fin_angle", "current_down"),
    Variant.HORIZONTAL: ("roll_torque", "fin_angle", "current_down"),
}


def input_description(name: str) -> str:
    """The description of input ``name``, naming the variants that ignore it."""
    ignoring = [v.name.lower() for v in Variant if name in IGNORED_INPUTS[v]]
    if not ignoring:
        return INPUT_DESCRIPTIONS[name]
    return f"{INPUT_DESCRIPTIONS[name]}; the {' and '.join(ignoring)} variants ignore it"


STATE_DESCRIPTIONS: dict[str, str] = {
    "north": "position north (NED)",
    "east": "position east (NED)",
    "down": "depth z, position down (NED), down positive: 0 at the surface",
    "roll": "roll angle phi, > 0 starboard down; counts whole turns",
    "pitch": "pitch angle theta, > 0 bow up",
    "yaw": "yaw angle psi, clockwise from north seen from above (NED); counts whole turns",
    "u": "surge velocity over ground, body frame",
    "v": "sway velocity over ground, body frame",
    "w": "heave velocity over ground, body frame",
    "p": "roll rate, > 0 rolling starboard down",
    "q": "pitch rate, > 0 bow rising",
    "r": "yaw rate, > 0 turning clockwise (to starboard)",
    "mass_position": "moving-mass position y_v on its rail",
    "mass_velocity": "moving-mass rail speed y_v'",
    "quat_w": "attitude quaternion (body to earth), scalar part",
    "quat_x": "attitude quaternion (body to earth), x part",
    "quat_y": "attitude quaternion (body to earth), y part",
    "quat_z": "attitude quaternion (body to earth), z part",
}
RELATIVE_VELOCITIES = ("u_rel", "v_rel", "w_rel")
LOG_STEPS = "logPlantSteps"  # debug log category: sub-step count and path of the steps
# |initial velocity| the model takes (a step beyond it is refused) and |initial angle| whose
# place within its turn a double still holds: declared as a range
_INITIAL_BOUNDS = {**dict.fromkeys(("u", "v", "w"), MAX_SPEED),
                   **dict.fromkeys(("p", "q", "r"), MAX_TURN_RATE),
                   **dict.fromkeys(("roll", "pitch", "yaw"), MAX_START_ANGLE)}  # fmt: skip
# the inputs whose derivatives the step uses: all but the currents (module docstring)
_ACTUATOR_INPUTS = list(
    i for i in range(len(INPUT_NAMES)) if i not in range(len(INPUT_NAMES))[CURRENT]
)
PHYSICAL_PARAMETERS: tuple[str, ...] = tuple(
    name for name, field in VehicleParameters.field_info().items() if field.kind is float
)


def field_unit_and_description(name: str) -> tuple[str, str]:
    """(FMI unit, description) of a VehicleParameters field from its description
    ``"<meaning>, <unit>[ (<note>)]"``; ``kg m^2`` becomes ``kg.m2``."""
    text = VehicleParameters.field_info()[name].description
    meaning, _, unit = text.rpartition(", ")
    unit, _, note = unit.partition(" (")
    if not meaning or not unit:
        raise ValueError(f"VehicleParameters.{name}: description {text!r} names no unit")
    description = f"{meaning} ({note}" if note else meaning
    return unit.replace(" ", ".").replace("^", ""), description


class AuvPlant(SafeSlave):
    """REMUS 100 AUV plant with moving mass, tunnel thruster and stern planes."""

    interpolates_inputs: ClassVar[bool] = True  # uses input derivatives (module docstring)
    tolerance_note: ClassVar[str] = (
        "the plant integrates with fixed-step RK4 in sub-steps of at most max_substep; "
        "a smaller max_substep (s) makes it more accurate"
    )

    # pythonfmu's five and the plant's debug categories (SafeSlave.set_debug_logging)
    log_categories: ClassVar[dict[str, str]] = {
        **SafeSlave.log_categories,
        LOG_STEPS: "Debug: how the plant steps, when it changes: the RK4 sub-step count "
        "and whether the compiled path or the numpy reference takes the step.",
    }

    description = (
        "REMUS 100 AUV with internal actuators (moving mass, tunnel thruster, stern planes): "
        "6-DOF / lateral / horizontal plant, B. Li, FAU 2016"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=60.0, step_size=0.01)
    # the velocities relative to the water, and the energy of that motion, start from the
    # current; every other output from the parameters alone
    initial_dependencies: ClassVar[dict[str, tuple[str, ...]]] = dict.fromkeys(
        (*RELATIVE_VELOCITIES, "kinetic_energy"), ("current_north", "current_east", "current_down")
    )

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._vehicles = vehicle_folder(self.resources)  # this extraction's data
        self._model: PlantModel | None = None
        self._compiled: compiled.CompiledPlant | None = None
        # the compiled step with every array bound: stepper(n, dt) -> code (_bind_stepper)
        self._stepper: Callable[[int, float], int] | None = None
        self._model_key: tuple[object, ...] | None = None
        self._told_not_compiled = False  # the reference path's cost said once per instance
        self._logged_steps: tuple[int, bool] | None = None  # (sub-steps, compiled) logged last
        self._physical = _default_physical_parameters(self._vehicles)
        self.variant = int(Variant.FULL)
        self.moving_mass_model = int(MovingMassModel.DISSERTATION)
        self.ideal_fluid = False
        self.vehicle = "remus100"
        self.current_shear_dUdy = 0.0
        self.max_substep = DEFAULT_MAX_SUBSTEP
        self._register_variables()
        # The inputs, the outputs and the initial state live in the FMU's value buffers,
        # which the FMU's runtime reads and writes in C: these are views of them, and the
        # step reads and writes them in place.
        self._inputs = self.values_of(INPUT_NAMES)
        self._inputs[:] = [INPUT_STARTS.get(name, 0.0) for name in INPUT_NAMES]
        # the stepping state (state + quaternion), then u_rel, v_rel, w_rel, kinetic_energy
        self._x = self.values_of(STEP_STATE_NAMES)
        self._derived = self.values_of((*RELATIVE_VELOCITIES, "kinetic_energy"))
        self._initial_state = self.values_of(f"{name}_0" for name in STATE_NAMES)
        # the input derivatives set for the next step (2 x inputs, 1/s and 1/s^2)
        self._rates = self.derivatives_of(INPUT_NAMES)
        self._x[:] = stepping_state(self._initial_state)
        self._last_current = self._inputs[CURRENT].copy()  # the currents of the last step
        self._warned: set[str] = set()  # the initialisation warnings logged (once each)
        self._above_water = -np.inf  # down (m) above which the whole hull is out of the water
        self._top_out = -np.inf  # down (m) above which the hull's top breaks the surface
        self._step_scratch = np.empty(compiled.STEP_SCRATCH)  # the compiled step's arrays

    # --- variables ---------------------------------------------------------------------------

    def _register_variables(self) -> None:
        self._register_inputs_and_outputs()
        self._register_parameters()

    def _register_inputs_and_outputs(self) -> None:
        for name, unit in zip(INPUT_NAMES, INPUT_UNITS):
            self.register(
                Real(
                    name,
                    causality=Fmi2Causality.input,
                    variability=Fmi2Variability.continuous,
                    description=input_description(name),
                ),
                unit=unit,
            )
        output = {
            "causality": Fmi2Causality.output,
            "variability": Fmi2Variability.continuous,
            "initial": Fmi2Initial.calculated,  # from the initial state and the currents
        }
        units = STATE_UNITS + ("1",) * len(QUATERNION_NAMES)
        for name, unit in zip(STEP_STATE_NAMES, units):
            self.register(Real(name, description=STATE_DESCRIPTIONS[name], **output), unit=unit)
        for name in RELATIVE_VELOCITIES:
            axis = name[0]
            self.register(
                Real(
                    name,
                    description=f"{axis} relative to the water, {axis} - current_{axis} (body)",
                    **output,
                ),
                unit="m/s",
            )
        self.register(
            Real(
                "kinetic_energy",
                description="kinetic energy 1/2 nu_r^T (M_RB + M_A) nu_r (+ the mass's, model 1)",
                **output,
            ),
            unit="J",
        )

    def _register_parameters(self) -> None:
        fixed = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        for name, unit in zip(STATE_NAMES, STATE_UNITS):
            bound = _INITIAL_BOUNDS.get(name)  # the model's range of a velocity or angle
            self.register(
                Real(f"{name}_0", description=f"initial {STATE_DESCRIPTIONS[name]}", **fixed),
                unit=unit,
                minimum=None if bound is None else -bound,
                maximum=bound,
            )
        self.register(
            Integer(
                "variant",
                description="0 full 6-DOF, 1 lateral u-v-r-p-phi-psi (6.3.13), "
                "2 horizontal u-v-r-psi (5.1.30)",
                **fixed,
            ),
            names=Variant,
        )
        self.register(
            Integer(
                "moving_mass_model",
                description="0 dissertation: its moving mass (6.3.11)-(6.3.13), "
                "1 two_body: hull and moving mass as two bodies (6.2.28)",
                **fixed,
            ),
            names=MovingMassModel,
        )
        self.register(
            Boolean("ideal_fluid", description="drop the viscous terms (Thm 5.1)", **fixed)
        )
        self.register(
            String(
                "vehicle",
                description=(
                    "built-in parameter set name, .toml file path (a relative one from the "
                    "host's working directory) or the set's TOML text"
                ),
                **fixed,
            )
        )
        self.register(
            Real(
                "current_shear_dUdy",
                description="horizontal current shear d(current_north)/d(east)",
                **fixed,
            ),
            unit="1/s",
        )
        self.register(
            Real("max_substep", description="longest internal RK4 step (> 0)", **fixed),
            unit="s",
            minimum=0.0,
        )
        for name in PHYSICAL_PARAMETERS:
            unit, description = field_unit_and_description(name)
            field = VehicleParameters.field_info()[name]
            minimum, maximum = field_bounds(field)
            self.register(
                Real(
                    name,
                    description=description,
                    getter=item_getter(self._physical, name),
                    setter=item_setter(self._physical, name),
                    **fixed,
                ),
                unit=unit,
                minimum=minimum,
                maximum=maximum,
                quantity=field.quantity or None,
            )

    # --- SafeSlave hooks ---------------------------------------------------------------------

    def _initialize(self) -> None:
        model = self._build_model()
        x = self._initial_state.copy()
        _check_start(x, model.params.mass_stroke, "pitch" in model.variant.states)
        check_current(model, x, self._inputs)  # the outputs to start from take it
        frozen = [
            n
            for i, n in enumerate(STATE_NAMES[:MASS_POSITION])
            if n not in model.variant.states and x[i]
        ]
        if frozen:
            self._warn_once(
                f"variant {int(model.variant)} ({model.variant.name.lower()}) keeps "
                f"{', '.join(frozen)} at 0: their initial values are ignored"
            )
        self._warn_ignored_inputs(model.variant)
        self._above_water = -0.5 * model.params.diameter
        # a hull starting with its top under water is warned of when the top breaks the
        # surface; one starting through it (vert-1's down_0 = 0, the dissertation's) is not
        top_out = 0.5 * model.params.diameter
        self._top_out = top_out if x[DOWN] >= top_out else -np.inf
        if x[DOWN] < self._above_water:
            self._warn_once(
                f"down_0 = {float(x[DOWN]):g} m starts the hull out of the water (down < "
                f"-diameter/2 = {self._above_water:g} m): {_NO_SURFACE}"
            )
            self._above_water = -np.inf  # said once
        self._x[:] = stepping_state(model.project(x))  # the quaternion of the kept angles
        self._last_current[:] = self._inputs[CURRENT]
        self._refresh_outputs()
        if self._compiled is not None:  # compile now, not in the first doStep
            self._compiled.warm_up(self._x, self._inputs, self._rates)

    def _warn_ignored_inputs(self, variant: Variant) -> None:
        """A Warning naming the inputs written non-zero that ``variant`` ignores (checked as
        the plant initialises: a step does not look, each input's description says it)."""
        given = [n for n in IGNORED_INPUTS[variant] if self._inputs[INPUT_NAMES.index(n)]]
        if given:
            self._warn_once(
                f"variant {int(variant)} ({variant.name.lower()}) ignores the input(s) "
                f"{', '.join(given)}: it has no degree of freedom they act on (variant 0, "
                "full, uses them)"
            )

    def _warn_once(self, message: str) -> None:
        """Log ``message`` as a Warning unless logged before: the plant initialises again
        when a value is written after a read in initialisation mode."""
        if message not in self._warned:
            self._warned.add(message)
            self.log(message, Fmi2Status.warning)

    def _step(self, current_time: float, step_size: float) -> None:
        """From the value buffers to the compiled integrator and back, allocating nothing
        (:func:`plant_fmu.model.compiled.step_into`); the reference path (numpy, the same
        arithmetic) where the compiled one does not apply: numba off, the two-body moving
        mass, a change of the currents, or a step it refuses (the reference then says why).
        Both take the input derivatives the importer set (module docstring)."""
        n = substeps(step_size, self.max_substep)  # raises on a step it would hang in
        compiled_step = self._compiled_step(n, step_size)
        if not compiled_step:
            self._reference_step(step_size)
        if LOG_STEPS in self.debug_categories:  # nothing formatted unless the host asks
            self._log_steps(current_time, step_size, n, compiled_step)
        if self._x[DOWN] < self._top_out:
            self._broke_the_surface(current_time + step_size)
        if self._x[DOWN] < self._above_water:
            self._left_the_water(current_time + step_size)

    def _log_steps(self, time: float, step_size: float, n: int, compiled_step: bool) -> None:
        """A debug message of :data:`LOG_STEPS` when the step from ``time`` (s) of
        ``step_size`` (s) took another sub-step count ``n`` or path than the one logged
        last."""
        if (n, compiled_step) == self._logged_steps:
            return
        self._logged_steps = (n, compiled_step)
        path = "the compiled path" if compiled_step else "the numpy reference"
        self.log(
            f"t = {time:.6g} s: a step of {step_size!r} s in {n} RK4 sub-step"
            f"{'s' if n > 1 else ''} of {step_size / n:.6g} s, by {path}",
            category=LOG_STEPS,
        )

    def _compiled_step(self, n: int, step_size: float) -> bool:
        """Whether the compiled path took the step, in ``n`` sub-steps (False: it does
        not apply or refused, and the reference is to take it)."""
        if self._stepper is None:
            return False
        try:
            return self._stepper(n, step_size / n) == 0
        except ArithmeticError:  # numba's division by zero, the state left unchanged
            return False  # the reference repeats the step and names what left the range

    def _broke_the_surface(self, time: float) -> None:
        """A Warning, once per instance, that the top of a hull that started under water
        is above the surface at ``time`` (s): from here the model, which has no free
        surface, keeps the buoyancy of a hull part out of the water
        (docs/model.md#the-envelope)."""
        top_out, self._top_out = self._top_out, -np.inf  # said once
        self._warn_once(
            f"at t = {time:.6g} s the hull's top breaks the surface (down = "
            f"{float(self._x[DOWN]):.4g} m < diameter/2 = {top_out:g} m): {_NO_SURFACE}"
        )

    def _left_the_water(self, time: float) -> None:
        """A Warning, once per instance, that the whole hull is above the surface at
        ``time`` (s): the model has no free surface (docs/model.md#the-envelope)."""
        self._above_water = -np.inf  # said once
        self._warn_once(
            f"at t = {time:.6g} s the hull is out of the water (down = "
            f"{float(self._x[DOWN]):.4g} m < -diameter/2): {_NO_SURFACE}"
        )

    def _reference_step(self, step_size: float) -> None:
        """:meth:`_step` through :func:`plant_fmu.model.stepping.advance` (raises on a state
        or input it cannot step, leaving the instance unchanged)."""
        model = self._model
        assert model is not None, "SafeSlave steps only an initialised instance"
        inputs = self._inputs.copy()
        x = self._x
        current = inputs[CURRENT].tolist()
        if current != self._last_current.tolist():
            x = x.copy()
            change = np.subtract(current, self._last_current)
            x[NU] += model.current_change_velocity_jump(x, change)
        rates = self._input_rates()
        x = advance(model, x, inputs, step_size, self.max_substep, self._compiled, rates)
        self._x[:] = x
        self._last_current[:] = current
        self._refresh_outputs(inputs)

    def _input_rates(self) -> np.ndarray | None:
        """(2, inputs): the first and second time derivatives the importer set for this
        step's actuator inputs (1/s, 1/s^2; the currents' taken as 0), None if every
        actuator input's derivatives are 0 (held, as :func:`compiled.step_into`)."""
        rates = np.zeros((2, len(INPUT_NAMES)))
        rates[:, _ACTUATOR_INPUTS] = self._rates[:, _ACTUATOR_INPUTS]
        return rates if rates.any() else None

    def _state_snapshot(self) -> dict[str, Any]:
        # the state, the outputs and the inputs are in the value buffers, saved with them
        return {"last_current": self._last_current.tolist()}

    def _restore_snapshot(self, snapshot: dict[str, Any]) -> None:
        if self.initialized and self._model_key != self._parameter_key():
            self._build_model()
        self._last_current[:] = snapshot["last_current"]

    # --- internals ---------------------------------------------------------------------------

    def _build_model(self) -> PlantModel:
        """Validate the parameters into a PlantModel; the physical parameters then read back
        the values in use. Raises ValueError naming the bad parameter."""
        if self.variant not in tuple(Variant):
            raise ValueError(
                f"variant = {self.variant!r}: expected 0 (full 6-DOF), 1 (lateral) or "
                "2 (horizontal)"
            )
        if not self.max_substep > 0.0:
            raise ValueError(f"max_substep = {self.max_substep!r} s: expected a number > 0")
        base = load_vehicle(self.vehicle, folder=self._vehicles)
        overrides = {n: self._physical[n] for n in PHYSICAL_PARAMETERS if self.was_written(n)}
        params = base.replace(**overrides) if overrides else base
        model = PlantModel(
            params,
            variant=Variant(self.variant),
            ideal_fluid=bool(self.ideal_fluid),
            current_shear=float(self.current_shear_dUdy),
            moving_mass_model=MovingMassModel(self.moving_mass_model),
        )
        self._physical.update({n: float(getattr(params, n)) for n in PHYSICAL_PARAMETERS})
        self._model = model
        self._model_key = self._parameter_key()
        self._compiled = self._stepper = None
        if compiled.supports(model) == "":
            self._compiled = compiled.CompiledPlant(model)
            self._stepper = self._bind_stepper(self._compiled)
        elif not compiled.AVAILABLE and not self._told_not_compiled:
            self._told_not_compiled = True
            self.log(  # the cost measured by scripts/bench_no_numba.py (docs/performance.md)
                f"the compiled plant is off ({compiled.NO_JIT_REASON}): stepping the numpy "
                "reference, same results, each step about 16 times as long (0.17 ms instead "
                f"of 0.011 ms); {compiled.NO_JIT_FIX}",
                Fmi2Status.warning,
            )
        return model

    def _bind_stepper(self, fast: compiled.CompiledPlant) -> Callable[[int, float], int]:
        """:func:`compiled.step_into` on this instance's buffers (views bound once, never
        replaced) and ``fast``'s parameters: ``stepper(n, dt)`` steps n RK4 steps of dt s
        and returns step_into's code, without numba's typing of the seven arrays at every
        call (:func:`compiled_entry`)."""
        arrays = (fast.parameters, self._inputs, self._rates, self._x, self._derived,
                  self._last_current, self._step_scratch)  # fmt: skip
        entry = compiled_entry(compiled.step_into, (*arrays, 1, 1.0))
        return functools.partial(entry, *arrays)

    def _parameter_key(self) -> tuple[object, ...]:
        """Everything the model is built from (to rebuild it after a state restore)."""
        return (
            self.vehicle,
            self.variant,
            self.moving_mass_model,
            bool(self.ideal_fluid),
            self.current_shear_dUdy,
            tuple(self._physical[n] for n in PHYSICAL_PARAMETERS),
            tuple(n for n in PHYSICAL_PARAMETERS if self.was_written(n)),
        )

    def _refresh_outputs(self, inputs: np.ndarray | None = None) -> None:
        inputs = self._inputs if inputs is None else inputs
        if self._compiled is not None:
            self._derived[:] = self._compiled.outputs(self._x, inputs)
            return
        model = self._model
        assert model is not None, "outputs are refreshed only once the model is built"
        nu_r = model.relative_velocity(self._x, inputs)
        self._derived[:3] = nu_r[:3].tolist()
        self._derived[3] = model.kinetic_energy(self._x, inputs)


def _check_start(x: np.ndarray, stroke: float, pitches: bool) -> None:
    """Raise ValueError naming a start value of the state ``x`` the plant cannot start
    from: the moving mass beyond its stop (``stroke``, m), or, where the variant
    ``pitches``, |pitch_0| beyond 90 deg (the outputs' Euler angles keep |pitch| <= 90 deg;
    the message names the start of the same attitude within it)."""
    mass_position_0 = float(x[MASS_POSITION])
    if abs(mass_position_0) > stroke:
        raise ValueError(
            f"mass_position_0 = {mass_position_0!r} m: expected "
            f"|mass_position_0| <= mass_stroke = {stroke!r} m"
        )
    pitch_0 = float(x[PITCH])
    if pitches and abs(pitch_0) > 0.5 * math.pi:
        other = math.copysign(math.pi, pitch_0) - pitch_0
        formula = f"pi - {pitch_0:g}" if pitch_0 > 0 else f"-pi - ({pitch_0:g})"
        raise ValueError(
            f"pitch_0 = {pitch_0:g} rad: expected |pitch_0| <= pi/2 = {0.5 * math.pi:.6g} rad, "
            "as the plant's Euler angles keep |pitch| <= 90 deg; the same attitude is "
            f"roll_0 + pi, pitch_0 = {formula} = {other:g} rad, yaw_0 + pi"
        )


def _default_physical_parameters(folder: Path) -> dict[str, float]:
    """The remus100 values in ``folder`` (the parameters' start values); NaN if the set
    cannot be read, which the getter reports and initialisation then explains."""
    try:
        params = load_vehicle("remus100", folder=folder)
        return {name: float(getattr(params, name)) for name in PHYSICAL_PARAMETERS}
    except Exception:
        return dict.fromkeys(PHYSICAL_PARAMETERS, float("nan"))
