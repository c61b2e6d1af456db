"""AuvGuidance: waypoint missions (LOS guidance) as an FMI 2.0 co-simulation slave.

The pythonfmu script of ``AuvGuidance.fmu`` (modelIdentifier ``AuvGuidance``): FMI
variables on one side, :class:`controller_fmu.los_guidance.LosGuidance` on the other. No
guidance law lives here.

A third FMU rather than a mode of the autopilot: guidance (where to go) and control (how
to get the actuators to do it) run at their own rates in real vehicles, the autopilot FMU
stays exactly the heading/depth autopilot the Ch. 6 scenarios use, and the mission layer
can be swapped (another guidance law, a planner, a human in the loop) without touching
either of the other two FMUs: a master connects them by name.

Inputs (Real, named like the plant's outputs; start 0):
    north, east (m), the vehicle's position; yaw (rad), its heading (the set-points are
    given on its branch: within pi of it); current_north, current_east (m/s), the
    measured current, used with compensate_current only
Outputs (Real, named like the autopilot's inputs where they feed it):
    yaw_setpoint (rad, psi_d), depth_setpoint (m, z_d), course_setpoint (rad, chi_d),
    cross_track_error (m, > 0 starboard of the active leg), legs_completed (1, a whole
    number: Real so that a master records it beside the others), waypoint_north,
    waypoint_east, waypoint_down (m, the active leg's end)

Parameters (all fixed; names, units, defaults and descriptions come from
:class:`controller_fmu.los_guidance.GuidanceConfig`):
    waypoints (String, "north, east, down; ..." in m), lookahead (m), acceptance_radius (m),
    integral_gain (1), compensate_current (Boolean), design_speed (m/s)

Timing: like the autopilot, a sampled system. ``doStep(t, h)`` computes the set-points from
the position as set at t, publishes them at once (held over [t, t + h)) and advances the
integral LOS state over h; no output depends directly on an input in the FMI sense. A
Gauss-Seidel master with the order guidance -> controller -> plant closes the loop without
delay. After initialisation the outputs are those for the inputs' start values (the
vehicle at the origin unless the importer set them).

Bad input: a waypoint string that does not parse (the log names the entry, e.g.
``waypoint 3 ('40, x, 2'): east = 'x' is not a finite number``) or any parameter out of
range fails initialisation with the reason logged, and every later doStep returns
Discard; a NaN/inf input is refused by the base class (doStep then returns Discard).
"""

from __future__ import annotations

from typing import Any, ClassVar

from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability
from pythonfmu.variables import Boolean, Real, String

from controller_fmu.los_guidance import (
    GuidanceConfig,
    GuidanceOutput,
    GuidanceState,
    LosGuidance,
    field_unit,
)
from fmu_runtime.safe_slave import SafeSlave
from fmu_runtime.variables import field_bounds, item_getter, item_setter

INPUTS: dict[str, tuple[str, str]] = {  # name -> (unit, description)
    "north": ("m", "vehicle position north (NED)"),
    "east": ("m", "vehicle position east (NED)"),
    "yaw": (
        "rad",
        "measured yaw psi, clockwise from north: the set-points are given within pi of it",
    ),
    "current_north": (
        "m/s",
        "measured current, north component (with compensate_current): > 0 the water "
        "moves towards north",
    ),
    "current_east": (
        "m/s",
        "measured current, east component (with compensate_current): > 0 the water "
        "moves towards east",
    ),
}
OUTPUTS: dict[str, tuple[str, str]] = {
    "yaw_setpoint": (
        "rad",
        "desired heading psi_d, clockwise from north: chi_d, or chi_d - beta (6.3.74)",
    ),
    "depth_setpoint": (
        "m",
        "desired depth z_d (down positive): the path's depth one lookahead ahead",
    ),
    "course_setpoint": ("rad", "desired course over ground chi_d, clockwise from north (LOS law)"),
    "cross_track_error": ("m", "cross-track error on the active leg, > 0 to starboard"),
    "legs_completed": ("1", "number of legs completed (a whole number)"),
    "waypoint_north": ("m", "north of the active leg's end waypoint"),
    "waypoint_east": ("m", "east of the active leg's end waypoint"),
    "waypoint_down": ("m", "depth of the active leg's end waypoint (down positive)"),
}
_DEFAULTS = GuidanceConfig()


class AuvGuidance(SafeSlave):
    """Line-of-sight waypoint guidance for heading and depth (a sampled system)."""

    # the first set-point is for the start position
    initial_dependencies: ClassVar[dict[str, tuple[str, ...]]] = dict.fromkeys(
        OUTPUTS, tuple(INPUTS)
    )

    description = (
        "Waypoint guidance of the REMUS 100: line-of-sight (proportional or integral) steering "
        "for heading and depth, with the current compensation of B. Li, FAU 2016 (6.3.74)"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=60.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._params: dict[str, Any] = _DEFAULTS.as_dict()
        self._guidance: LosGuidance | None = None
        self._register_variables()
        # views of the FMU's value buffers (the runtime reads and writes them in C)
        self._inputs = self.values_of(INPUTS)
        self._outputs = self.values_of(OUTPUTS)

    def _register_variables(self) -> None:
        for name, (unit, description) in INPUTS.items():
            self.register(
                Real(
                    name,
                    causality=Fmi2Causality.input,
                    variability=Fmi2Variability.continuous,
                    description=description,
                ),
                unit=unit,
            )
        for name, (unit, description) in OUTPUTS.items():
            self.register(
                Real(
                    name,
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.discrete,
                    initial=Fmi2Initial.calculated,  # from the waypoints and the inputs
                    description=description,
                ),
                unit=unit,
            )
        fixed = {"causality": Fmi2Causality.parameter, "variability": Fmi2Variability.fixed}
        for name, field in GuidanceConfig.field_info().items():
            kinds: dict[object, Any] = {bool: Boolean, str: String, float: Real}
            kind = kinds[field.kind]
            variable = kind(
                name,
                description=field.description,
                getter=item_getter(self._params, name),
                setter=item_setter(self._params, name),
                **fixed,
            )
            minimum, maximum = field_bounds(field) if kind is Real else (None, None)
            self.register(
                variable,
                unit=field_unit(name) if kind is Real else None,
                minimum=minimum,
                maximum=maximum,
            )

    # --- SafeSlave hooks ---------------------------------------------------------------------

    def _initialize(self) -> None:
        self._guidance = LosGuidance(GuidanceConfig.build(**self._params))
        self._publish_outputs(self._evaluate(self._guidance, 0.0))

    def _step(self, current_time: float, step_size: float) -> None:
        guidance = self._guidance
        assert guidance is not None, "SafeSlave steps only an initialised instance"
        before = guidance.state
        try:
            output = self._evaluate(guidance, step_size)
        except Exception:
            guidance.state = before
            raise
        self._publish_outputs(output)

    def _evaluate(self, guidance: LosGuidance, step_size: float) -> GuidanceOutput:
        values = self._inputs.tolist()
        i = {name: values[k] for k, name in enumerate(INPUTS)}
        return guidance.step(
            i["north"], i["east"], i["current_north"], i["current_east"], step_size, i["yaw"]
        )

    def _publish_outputs(self, output: GuidanceOutput) -> None:
        published = {
            "yaw_setpoint": output.yaw_setpoint,
            "depth_setpoint": output.depth_setpoint,
            "course_setpoint": output.course_setpoint,
            "cross_track_error": output.cross_track_error,
            "legs_completed": float(output.legs_completed),
            "waypoint_north": output.target.north,
            "waypoint_east": output.target.east,
            "waypoint_down": output.target.down,
        }
        self._outputs[:] = [published[name] for name in OUTPUTS]

    def _state_snapshot(self) -> dict[str, Any]:
        # the inputs and outputs are in the value buffers, saved with them
        state: dict[str, Any] = {}
        if self._guidance is not None:
            s = self._guidance.state
            state["guidance"] = [s.leg, s.legs_completed, s.integral]
        return state

    def _restore_snapshot(self, snapshot: dict[str, Any]) -> None:
        saved = snapshot.get("guidance")
        if saved is None or not self.initialized:  # built again by _initialize
            self._guidance = None
            return
        config = GuidanceConfig.build(**self._params)
        if self._guidance is None or self._guidance.config != config:
            self._guidance = LosGuidance(config)
        leg, completed, integral = saved
        self._guidance.state = GuidanceState(int(leg), int(completed), float(integral))
