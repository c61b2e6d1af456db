"""AuvAutopilot: the Ch. 6 autopilot as an FMI 2.0 co-simulation slave.

The slave class of ``AuvAutopilot.fmu`` (modelIdentifier ``AuvAutopilot``; the build ships
this module in ``controller_fmu`` and a generated pythonfmu entry module that imports the
class, see :mod:`fmu_runtime.entry`): FMI variables on one side,
:class:`controller_fmu.autopilot.Autopilot` on the other. No control law lives here.

Inputs (Real, named like the plant's outputs; start 0):
    yaw, r, p, roll, v_rel, u_rel, down, pitch, q, w_rel, mass_position, mass_velocity,
    current_north, current_east, yaw_setpoint (rad), depth_setpoint (m)
Outputs (Real, named like the plant's inputs):
    mass_position_cmd (m), tunnel_force (N), fin_angle (rad), thrust (N; start 9)

Parameters (names, units, defaults, descriptions and ranges (``min``/``max``; a write
outside is refused) come from :class:`controller_fmu.autopilot.AutopilotConfig`; all fixed
but ``heading_mode`` and ``mass_lock_time``, tunable: a new value takes effect at the next
doStep, see :data:`controller_fmu.autopilot.TUNABLE_PARAMETERS`):
    heading_mode (Integer: 0 off, 1 LQR, 2 sliding mode, 3 backstepping + tunnel thruster)
    depth_mode (Integer: 0 off, 1 PD pitch + P depth)
    mass_lock_time (s; < 0 never), compensate_current (Boolean), design_speed (m/s, 1.525),
    vehicle (String, "remus100": read from this instance's resources/), design_step (s, 0.01),
    thrust_command (N, 9: the value of the thrust output; 4 N for the slow scenarios)
    LQR:           lqr_q_r, lqr_q_p, lqr_q_roll, lqr_q_yaw, lqr_q_mass_position,
                   lqr_q_mass_velocity, lqr_r            (Q_y, R_u of Sec. 6.3.1)
    sliding mode:  smc_eta (rad/s, 1.0), smc_boundary_layer (rad, 0.5)
    backstepping:  k0 (0.5), k1 (1.0), k2, k3, k4 (1.0) (1/s), eta0 (m/s2, 0.08),
                   thruster_boundary_layer (m/s, 0.01), command_filter_frequency (rad/s, 10)
    depth:         depth_gamma (rad/m, -0.772), depth_k_p (10.345), depth_tau_d (s, 0.21),
                   fin_angle_limit (rad, 25 deg), depth_pitch_limit (rad, 0: none)
    limits:        mass_position_cmd_limit (m, 0.06), tunnel_force_limit (N, 10)

Timing (a sampled controller). ``doStep(t, h)`` computes the commands from the inputs as set
at t and publishes them at once; they are meant to be held over [t, t + h). A master that
steps the controller before the plant at each t (Gauss-Seidel, order controller -> plant)
therefore closes the loop without delay, exactly like
:func:`cosim.analysis.closed_loop.simulate_closed_loop`; a Jacobi master adds one step of
delay. No output depends directly on an input in the FMI sense (they change only in
doStep), so ModelStructure declares no dependencies and importers see no algebraic loop.
After initialisation the outputs are zero commands and ``thrust`` = ``thrust_command``.

Input derivatives (``canInterpolateInputs="true"``): when the importer extrapolates the
inputs (``fmi2SetRealInputDerivatives``), the step takes them as going linearly from the
last sample's values to these: the backstepping's command filters then follow the
continuous-time law with a first-order hold (second order in the step) instead of holding
the last sample's alphas. The laws themselves are evaluated at the sample.

Digital autopilot: ``sample_period`` > 0 makes it sample at the first doStep at or after
each multiple of the period and hold its commands in between, whatever the communication
step (input derivatives are then ignored); 0 (the default) samples at every doStep. A
doStep a host's rounding puts before a multiple (within 1e-9 of its time, at least 1 ns,
at most a thousandth of the period) is at it.

Sample time. The discrete LQR and the sampled sliding mode are designed at initialisation
for the parameter ``design_step`` (default 0.01 s), not for the first doStep's step size,
so every design error is reported by exitInitializationMode and a master with varying steps
gets one well-defined design. If a communication step differs from ``design_step`` the FMU
logs a warning (once) and carries on, but not for a shorter last step ending at the stop
time setupExperiment defined (a host ends a run off its grid so; with no stop time defined
a shorter step warns); the backstepping's filters are exact for any step.

Bad input: a NaN/inf input or parameter is refused with a logged reason (doStep then
returns Discard); an unknown mode or vehicle, or any parameter out of range, fails
initialisation with the reason logged, and every later doStep returns Discard.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from enum import IntEnum
from typing import Any, ClassVar

from pythonfmu.default_experiment import DefaultExperiment
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability
from pythonfmu.variables import Boolean, Integer, Real, String

from controller_fmu.autopilot import (
    COMMAND_NAMES,
    COMMAND_UNITS,
    MEASUREMENT_NAMES,
    MEASUREMENT_UNITS,
    TUNABLE_PARAMETERS,
    Autopilot,
    AutopilotConfig,
    AutopilotSnapshot,
    Commands,
    field_quantity,
    field_unit,
)
from controller_fmu.depth_pd import MAX_PITCH_LIMIT
from controller_fmu.modes import DepthMode, HeadingMode
from fmu_runtime.safe_slave import SafeSlave
from fmu_runtime.variables import field_bounds, item_getter, item_setter
from plant_fmu.model.parameters import vehicle_folder

INPUT_DESCRIPTIONS: dict[str, str] = {
    "yaw": "measured yaw angle psi, clockwise from north, on any turn",
    "r": "measured yaw rate",
    "p": "measured roll rate",
    "roll": "measured roll angle phi",
    "v_rel": "measured sway velocity relative to the water",
    "u_rel": "measured surge velocity relative to the water (not used by the laws)",
    "down": "measured depth z (down positive)",
    "pitch": "measured pitch angle theta",
    "q": "measured pitch rate",
    "w_rel": "measured heave velocity relative to the water (not used by the laws)",
    "mass_position": "measured moving-mass position y_v",
    "mass_velocity": "measured moving-mass rail speed y_v'",
    "current_north": (
        "measured current, north component, earth frame: > 0 the water moves towards north"
    ),
    "current_east": (
        "measured current, east component, earth frame: > 0 the water moves towards east"
    ),
    "yaw_setpoint": (
        "desired heading psi_d, clockwise from north, on any turn (the error is taken within "
        "+-pi), or desired course with compensate_current (6.3.74)"
    ),
    "depth_setpoint": "desired depth z_d (down positive)",
}
OUTPUT_DESCRIPTIONS: dict[str, str] = {
    "mass_position_cmd": "moving-mass servo command y_d, |y_d| <= mass_position_cmd_limit",
    "tunnel_force": "tunnel-thruster sway force F_t, |F_t| <= tunnel_force_limit",
    "fin_angle": "stern-plane angle delta_s, |delta_s| <= fin_angle_limit",
    "thrust": "propeller thrust (the thrust_command parameter)",
}
_DEFAULTS = AutopilotConfig()
LOG_LIMITS = "logAutopilotLimits"  # debug log category: a command reaching or leaving its limit
LOG_TUNING = "logAutopilotTuning"  # debug log category: tunable parameters taken in a run
# Integer parameters that choose among named modes (their range and names in the FMU)
_MODES: dict[str, type[IntEnum]] = {"heading_mode": HeadingMode, "depth_mode": DepthMode}
# the range a field's own check keeps (declared here: a ge/le of the field would replace
# that check's message, which says what 0 means)
_CHECKED_RANGES: dict[str, tuple[float, float]] = {"depth_pitch_limit": (0.0, MAX_PITCH_LIMIT)}


def _noting_setter(values: dict[str, Any], written: set[str], key: str) -> Callable[[Any], None]:
    """A pythonfmu setter storing its value in ``values[key]`` and adding ``key`` to
    ``written``. It holds the two containers, not the slave: a closure over the slave would
    make a reference cycle that keeps every freed instance alive until a collection."""
    store = item_setter(values, key)

    def setter(value: Any) -> None:
        store(value)
        written.add(key)

    return setter


class AuvAutopilot(SafeSlave):
    """Heading (LQR / sliding mode / backstepping + thruster) and depth (PD) autopilot."""

    interpolates_inputs: ClassVar[bool] = True  # input derivatives: the module docstring
    tolerance_note: ClassVar[str] = (
        "the autopilot has no error-controlled integrator; it samples its laws at the "
        "communication points (or every sample_period), designed for design_step"
    )

    # pythonfmu's five and the autopilot's debug categories (SafeSlave.set_debug_logging)
    log_categories: ClassVar[dict[str, str]] = {
        **SafeSlave.log_categories,
        LOG_LIMITS: "Debug: a command (mass_position_cmd, tunnel_force, fin_angle) reaching "
        "or leaving its limit.",
        LOG_TUNING: "Debug: tunable parameters changed during the run, as the law takes them.",
    }

    description = (
        "Autopilot of the REMUS 100 with internal actuators: moving-mass heading control "
        "(LQR, sliding mode, backstepping + tunnel thruster) and depth PD, B. Li, FAU 2016 Ch. 6"
    )
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=60.0, step_size=0.01)

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        self._vehicles = vehicle_folder(self.resources)  # this extraction's data
        self._params: dict[str, Any] = _DEFAULTS.as_dict()
        self._autopilot: Autopilot | None = None
        self._step_warned = False
        self._tuned: set[str] = set()  # tunable parameters written since the autopilot took them
        self._at_limit: set[str] = set()  # commands at their limit after the last step (logged)
        self._register_variables()
        # views of the FMU's value buffers (the runtime reads and writes them in C): the
        # step reads the measurements and writes the commands in place
        self._inputs = self.values_of(MEASUREMENT_NAMES)
        self._outputs = self.values_of(COMMAND_NAMES)
        # the measurements' first derivatives set for the next step (input derivatives)
        self._rates = self.derivatives_of(MEASUREMENT_NAMES)[0]
        self._outputs[:] = Commands(thrust=_DEFAULTS.thrust_command).values()

    def _register_variables(self) -> None:
        for name, unit in zip(MEASUREMENT_NAMES, MEASUREMENT_UNITS):
            self.register(
                Real(
                    name,
                    causality=Fmi2Causality.input,
                    variability=Fmi2Variability.continuous,
                    description=INPUT_DESCRIPTIONS[name],
                ),
                unit=unit,
                # a depth set-point above the surface (z_d < 0, down positive) is refused
                minimum=0.0 if name == "depth_setpoint" else None,
            )
        for name, unit in zip(COMMAND_NAMES, COMMAND_UNITS):
            self.register(
                Real(
                    name,
                    causality=Fmi2Causality.output,
                    variability=Fmi2Variability.discrete,
                    # computed by _initialize (thrust from thrust_command, the others 0):
                    # the FMU's own, so no host may set them (FMI 2.0 lets a host set an
                    # initial="exact" output before initialisation, which the runtime refuses)
                    initial=Fmi2Initial.calculated,
                    description=OUTPUT_DESCRIPTIONS[name],
                ),
                unit=unit,
            )
        for name, field in AutopilotConfig.field_info().items():
            kinds: dict[object, Any] = {int: Integer, bool: Boolean, str: String, float: Real}
            kind = kinds[field.kind]
            variable = kind(
                name,
                description=field.description,
                getter=item_getter(self._params, name),
                setter=_noting_setter(self._params, self._tuned, name)
                if name in TUNABLE_PARAMETERS
                else item_setter(self._params, name),
                causality=Fmi2Causality.parameter,
                variability=Fmi2Variability.tunable
                if name in TUNABLE_PARAMETERS
                else Fmi2Variability.fixed,
            )
            minimum, maximum = field_bounds(field) if kind is Real else (None, None)
            minimum, maximum = _CHECKED_RANGES.get(name, (minimum, maximum))
            self.register(
                variable,
                unit=field_unit(name) if kind is Real else None,
                minimum=minimum,
                maximum=maximum,
                names=_MODES.get(name),
                quantity=field_quantity(name) or None,
            )

    # --- SafeSlave hooks ---------------------------------------------------------------------

    def _initialize(self) -> None:
        self._autopilot = Autopilot(AutopilotConfig.build(**self._params), self._vehicles)
        self._outputs[:] = self._autopilot.commands.values()
        self._step_warned = False
        self._tuned.clear()

    def _step(self, current_time: float, step_size: float) -> None:
        autopilot = self._autopilot
        assert autopilot is not None, "SafeSlave steps only an initialised instance"
        if self._tuned:  # retuned first: the step-size warning is about the law in use
            self._retune(autopilot, current_time)
        if autopilot.designed_for_step and not self._step_warned:
            self._check_step_size(autopilot, current_time, step_size)
        # a failed step leaves the autopilot as it was (Autopilot.step), so the FMU discards
        # the step with its state unchanged. (No comprehension or closure in this method:
        # its cell would be allocated at every step.)
        autopilot.step_into(current_time, self._inputs, self._outputs, self._rates)
        if LOG_LIMITS in self.debug_categories:  # nothing formatted unless the host asks
            self._log_limits(autopilot.config, current_time + step_size)

    def _log_limits(self, config: AutopilotConfig, time: float) -> None:
        """A debug message of :data:`LOG_LIMITS` for each command that reached or left its
        limit (``config``'s) in the step ending at ``time`` (s)."""
        limits = {
            "mass_position_cmd": config.mass_position_cmd_limit,
            "tunnel_force": config.tunnel_force_limit,
            "fin_angle": config.fin_angle_limit,
        }
        for name, limit in limits.items():
            value = float(self._outputs[COMMAND_NAMES.index(name)])
            at_limit = abs(value) >= limit
            if at_limit == (name in self._at_limit):
                continue
            unit = COMMAND_UNITS[COMMAND_NAMES.index(name)]
            if at_limit:
                self._at_limit.add(name)
                what = f"reached its limit ({value:+.6g} {unit}, |limit| = {limit:g} {unit})"
            else:
                self._at_limit.discard(name)
                what = f"left its limit ({value:+.6g} {unit})"
            self.log(f"t = {time:.6g} s: {name} {what}", category=LOG_LIMITS)

    def _retune(self, autopilot: Autopilot, time: float) -> None:
        """The tunable parameters written since the last step to the autopilot, for the
        step from ``time`` (s). A value written again unchanged (fmpy's ``input=`` table
        writes a tunable column at every step) is no change: neither taken nor logged."""
        changed = sorted(n for n in self._tuned if self._params[n] != getattr(autopilot.config, n))
        if changed:
            if LOG_TUNING in self.debug_categories:
                taken = ", ".join(f"{n} = {self._params[n]!r}" for n in changed)
                self.log(f"t = {time:.6g} s: the law takes {taken}", category=LOG_TUNING)
            autopilot.retune(**{n: self._params[n] for n in TUNABLE_PARAMETERS})
        self._tuned.clear()  # not if it failed: the step is discarded, the next retries

    def _check_step_size(self, autopilot: Autopilot, current_time: float, step_size: float) -> None:
        """Warn (once) when the law's sample time (``sample_period``, else the
        communication step; the step when it is the longer: the law samples at doSteps
        only) is not the step the LQR or the sliding mode is designed for. A shorter last
        step, ending at the stop time (a host ends a run off its grid so), is no sign of
        it; another shorter one may be a host's step to an input event (fmpy's ``input=``
        table), so the advice says it holds for a host stepping so throughout."""
        design_step = autopilot.config.design_step
        period = autopilot.config.sample_period
        sampled = max(period, step_size) if period else step_size  # the law's sample time
        if math.isclose(sampled, design_step, rel_tol=1e-9):
            return
        digital = period and not sampled > period * (1 + 1e-9)
        shorter = sampled < design_step and not digital  # a step, not the sample_period
        if shorter and self._ends_at_stop_time(current_time + step_size):
            return
        what = "sample_period" if digital else "communication step"
        advice = f"set it to the {what}"
        if shorter:
            advice += (
                " if the host steps so throughout; a single shorter step, as a host takes "
                "to an input event, needs no change"
            )
        self.log(
            f"{what} {sampled!r} s differs from design_step = {design_step!r} s: the "
            f"LQR / sliding-mode gains are designed for design_step ({advice})",
            Fmi2Status.warning,
        )
        self._step_warned = True

    def _ends_at_stop_time(self, end: float) -> bool:
        """Whether a step ending at ``end`` (s) ends at setupExperiment's stop time (within
        the relative 1e-9 the runtime allows a host's communication points); never when
        setupExperiment defined none (``_stop_time`` is then inf)."""
        stop = self._stop_time
        return math.isfinite(stop) and abs(end - stop) <= 1e-9 * max(abs(stop), 1.0)

    def _state_snapshot(self) -> dict[str, Any]:
        # the measurements and the commands are in the value buffers, saved with them
        state: dict[str, Any] = {
            "warned": self._step_warned,
            "tuned": {name: self._params[name] for name in TUNABLE_PARAMETERS},
        }
        if self._autopilot is not None:
            state["autopilot"] = self._autopilot.snapshot().to_json()
            # the tunable values in effect (a value set since the last step applies at the next)
            config = self._autopilot.config
            state["applied"] = {name: getattr(config, name) for name in TUNABLE_PARAMETERS}
        return state

    def _restore_snapshot(self, snapshot: dict[str, Any]) -> None:
        self._step_warned = snapshot["warned"]
        self._params.update(snapshot["tuned"])
        saved = snapshot.get("autopilot")
        self._tuned.clear()
        if saved is None or not self.initialized:  # built again by _initialize
            self._autopilot = None
            return
        # those written but not yet applied when the state was saved:
        self._tuned.update(n for n, v in snapshot["tuned"].items() if snapshot["applied"][n] != v)
        config = AutopilotConfig.build(**{**self._params, **snapshot["applied"]})
        if self._autopilot is None or self._autopilot.config != config:
            self._autopilot = Autopilot(config, self._vehicles)
        self._autopilot.restore(AutopilotSnapshot.from_json(saved))
