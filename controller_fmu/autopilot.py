"""The autopilot: guidance + heading controller + depth controller, as one sampled object.

``Autopilot(config)`` builds the controllers the configuration selects from the plant's own
equations (vehicle parameter set ``config.vehicle``, linearised at ``design_speed``), once.
``step(t, measurements)`` computes the commands from the measurements at the start of a
communication step; the caller holds them over the step (a sampled controller). All state
lives on the instance; ``snapshot()`` / ``restore()`` save and roll it back exactly.

Measurements (:data:`MEASUREMENT_NAMES`) are named like the plant's outputs plus the two
set-points; commands (:data:`COMMAND_NAMES`) like the plant's inputs, so the FMU wrapper
(:mod:`controller_fmu.auv_autopilot`) and a master can connect them by name.

The configuration (:class:`AutopilotConfig`) is also the FMU's parameter list: every field
becomes an FMU parameter of the same name, unit and description.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from controller_fmu import compiled_autopilot as fast
from controller_fmu.autopilot_config import AutopilotConfig as AutopilotConfig
from controller_fmu.autopilot_config import AutopilotConfigError as AutopilotConfigError
from controller_fmu.autopilot_config import field_quantity as field_quantity
from controller_fmu.autopilot_config import field_unit as field_unit
from controller_fmu.backstepping import (
    BacksteppingGains,
    BacksteppingHeading,
    BacksteppingSnapshot,
)
from controller_fmu.depth_pd import (
    DepthPd,
    check_depth_loop,
)
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.lqr import LqrHeading
from controller_fmu.modes import DepthMode, HeadingMode
from controller_fmu.setpoint_shaping import desired_heading, mass_locked, wrap_angle
from controller_fmu.sliding_mode import SlidingModeHeading
from plant_fmu.model.parameters import load_vehicle

MEASUREMENT_NAMES: tuple[str, ...] = (
    "yaw", "r", "p", "roll", "v_rel", "u_rel", "down", "pitch", "q", "w_rel",
    "mass_position", "mass_velocity", "current_north", "current_east",
    "yaw_setpoint", "depth_setpoint",
)  # fmt: skip
MEASUREMENT_UNITS: tuple[str, ...] = (
    "rad", "rad/s", "rad/s", "rad", "m/s", "m/s", "m", "rad", "rad/s", "m/s",
    "m", "m/s", "m/s", "m/s", "rad", "m",
)  # fmt: skip
COMMAND_NAMES: tuple[str, ...] = ("mass_position_cmd", "tunnel_force", "fin_angle", "thrust")
COMMAND_UNITS: tuple[str, ...] = ("m", "N", "rad", "N")


# What an importer may change while a run goes on (FMI tunable parameters), taking effect
# at the next step: the heading law switches (designed then, its state fresh) and the
# moving mass locks (or, with a negative time, is released).
TUNABLE_PARAMETERS: tuple[str, ...] = ("heading_mode", "mass_lock_time")


class Commands(NamedTuple):
    """The actuator commands held over one communication step (plant input names); a
    named tuple, immutable, in :data:`COMMAND_NAMES` order (a frozen dataclass costs ~1 us
    to build, a tenth of the autopilot's step)."""

    mass_position_cmd: float = 0.0  # m
    tunnel_force: float = 0.0  # N
    fin_angle: float = 0.0  # rad
    thrust: float = 0.0  # N

    def values(self) -> tuple[float, float, float, float]:
        """In :data:`COMMAND_NAMES` order."""
        return self.mass_position_cmd, self.tunnel_force, self.fin_angle, self.thrust


@dataclass(frozen=True)
class AutopilotSnapshot:
    """Everything :meth:`Autopilot.step` changes, for :meth:`Autopilot.restore`."""

    commands: Commands  # the commands last computed
    heading_setpoint: float  # psi_d of the last step, rad
    backstepping: BacksteppingSnapshot | None  # None unless heading_mode is BACKSTEPPING
    next_sample: float | None = None  # s, a digital autopilot's next sample time

    def to_json(self) -> dict[str, Any]:
        """A JSON-serialisable form (part of the FMU's serialised state)."""
        return {
            "commands": list(self.commands.values()),
            "heading_setpoint": self.heading_setpoint,
            "backstepping": None if self.backstepping is None else self.backstepping.to_json(),
            "next_sample": self.next_sample,
        }

    @classmethod
    def from_json(cls, data: Mapping[str, Any]) -> AutopilotSnapshot:
        """The snapshot :meth:`to_json` wrote."""
        backstepping = data["backstepping"]
        return cls(
            commands=Commands(*data["commands"]),
            heading_setpoint=data["heading_setpoint"],
            backstepping=None
            if backstepping is None
            else BacksteppingSnapshot.from_json(backstepping),
            next_sample=data.get("next_sample"),
        )


HeadingLaw = Callable[[float, tuple[float, ...], bool], tuple[float, float]]
"""A heading law: (time s, x = (v_rel, r, p, roll, yaw - psi_d, mass_position,
mass_velocity) in SI, whether the measurements went linearly from the last sample to these
(a law with filters follows them so; else they were held)) -> the unsaturated
(mass_position_cmd m, tunnel_force N)."""


def _no_heading_control(time: float, x: tuple[float, ...], ramp: bool) -> tuple[float, float]:
    return 0.0, 0.0


def _mass_only(command: Callable[[np.ndarray], float]) -> HeadingLaw:
    """A heading law from a mass-command law y_d(x) that leaves the thruster at 0."""

    def law(time: float, x: tuple[float, ...], ramp: bool) -> tuple[float, float]:
        return command(np.array(x)), 0.0

    return law


def _clip(value: float, limit: float) -> float:
    return min(max(value, -limit), limit)


def _design_heading_controller(
    mode: HeadingMode, c: AutopilotConfig, design: LateralDesignModel
) -> tuple[LqrHeading | None, SlidingModeHeading | None, BacksteppingHeading | None]:
    """The controller ``mode`` selects, designed for ``c`` on the plant's linearisation
    ``design``, in its slot of (LQR, sliding mode, backstepping); None elsewhere."""
    q_y = (c.lqr_q_r, c.lqr_q_p, c.lqr_q_roll, c.lqr_q_yaw, c.lqr_q_mass_position,
           c.lqr_q_mass_velocity)  # fmt: skip
    if mode is HeadingMode.LQR:
        return LqrHeading(design, c.design_step, q_y, c.lqr_r), None, None
    if mode is HeadingMode.SLIDING_MODE:
        eta, layer = c.smc_eta, c.smc_boundary_layer
        return None, SlidingModeHeading(design, c.design_step, eta, layer, q_y, c.lqr_r), None
    if mode is HeadingMode.BACKSTEPPING:
        gains = BacksteppingGains(
            c.k0, c.k1, c.k2, c.k3, c.k4,
            c.eta0, c.thruster_boundary_layer, c.command_filter_frequency,
        )  # fmt: skip
        return None, None, BacksteppingHeading(design, gains)
    return None, None, None


class Autopilot:
    """The sampled autopilot of Ch. 6.

    Args:
        config: an :class:`AutopilotConfig`.
        vehicles: the folder of the built-in vehicle sets ``config.vehicle`` may name
            (default :func:`plant_fmu.model.parameters.vehicle_folder`; an FMU instance
            passes its own extraction's).

    Raises:
        VehicleParameterError: ``config.vehicle`` is unknown or invalid.
        ValueError: a controller cannot be designed for these parameters.
    """

    def __init__(self, config: AutopilotConfig, vehicles: Path | None = None) -> None:
        # the compiled sample's configuration, published values and scratch
        # (compiled_autopilot's layout); the published values are this object's commands
        # and heading set-point
        self._work = np.zeros(fast.WORK_SIZE)
        self._set_config(config)
        self.params = load_vehicle(config.vehicle, folder=vehicles)
        self.design = LateralDesignModel(self.params, config.design_speed)
        self.lqr: LqrHeading | None
        self.sliding_mode: SlidingModeHeading | None
        self.backstepping: BacksteppingHeading | None
        self._heading_law: HeadingLaw
        self._kernel: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self._use_heading_mode(config)
        self.depth: DepthPd | None = None
        if DepthMode(config.depth_mode) is DepthMode.PD:
            self.depth = DepthPd(
                config.depth_gamma,
                config.depth_k_p,
                config.depth_tau_d,
                config.fin_angle_limit,
                config.depth_pitch_limit,
            )
            check_depth_loop(self.depth, self.params, config.design_speed, config.design_step)
        self.reset()
        if self._kernel is not None:  # compile (or load) the sample now, not in the first step
            p, law, state = self._kernel
            inputs, outputs = np.zeros(len(MEASUREMENT_NAMES)), np.zeros(len(COMMAND_NAMES))
            work = self._work.copy()
            fast.sample(p, law.copy(), state.copy(), work, inputs, inputs, outputs, 0.0)

    def retune(self, **values: Any) -> None:
        """Change tunable parameters (:data:`TUNABLE_PARAMETERS`) between steps: a new
        ``heading_mode`` designs its law now and starts it fresh (the backstepping's filters
        from zero); ``mass_lock_time`` applies from the next step.

        Raises:
            AutopilotConfigError: a name that is not tunable, or a value out of range.
            ValueError: the new law cannot be designed; the autopilot is then unchanged.
        """
        fixed = sorted(set(values) - set(TUNABLE_PARAMETERS))
        if fixed:
            raise AutopilotConfigError(
                f"{', '.join(fixed)}: not tunable while running (tunable: "
                f"{', '.join(TUNABLE_PARAMETERS)})"
            )
        config = self.config.replace(**values)
        if config.heading_mode == self.config.heading_mode:
            self._set_config(config)
            return
        self._use_heading_mode(config)

    def _use_heading_mode(self, config: AutopilotConfig) -> None:
        """Take ``config`` with the heading law its ``heading_mode`` selects, designed now
        (the autopilot is unchanged if the design fails)."""
        mode = HeadingMode(config.heading_mode)
        lqr, sliding_mode, backstepping = _design_heading_controller(mode, config, self.design)
        self._set_config(config)
        self.heading_mode = mode
        self.lqr, self.sliding_mode, self.backstepping = lqr, sliding_mode, backstepping
        self._kernel = self._compiled_sample(mode, backstepping)
        if lqr is not None:
            self._heading_law = _mass_only(lqr.command)
        elif sliding_mode is not None:
            self._heading_law = _mass_only(sliding_mode.command)
        elif backstepping is not None:
            self._heading_law = self._backstepping_law
        else:
            self._heading_law = _no_heading_control
        # True if the heading law's gains hold only at the sample time design_step.
        self.designed_for_step = mode in (HeadingMode.LQR, HeadingMode.SLIDING_MODE)

    def _set_config(self, config: AutopilotConfig) -> None:
        """Take ``config``, also into the compiled sample's configuration."""
        self.config = config
        work, k = self._work, fast
        work[k.HEADING] = 1.0 if config.heading_mode == HeadingMode.BACKSTEPPING else 0.0
        work[k.COMPENSATE] = 1.0 if config.compensate_current else 0.0
        work[k.DESIGN_SPEED], work[k.LOCK_TIME] = config.design_speed, config.mass_lock_time
        work[k.DEPTH] = 1.0 if DepthMode(config.depth_mode) is DepthMode.PD else 0.0
        work[k.GAMMA], work[k.K_P] = config.depth_gamma, config.depth_k_p
        work[k.TAU_D], work[k.FIN_LIMIT] = config.depth_tau_d, config.fin_angle_limit
        work[k.PITCH_LIMIT] = config.depth_pitch_limit
        work[k.MASS_LIMIT] = config.mass_position_cmd_limit
        work[k.TUNNEL_LIMIT] = config.tunnel_force_limit
        work[k.THRUST] = config.thrust_command

    def _compiled_sample(
        self, mode: HeadingMode, backstepping: BacksteppingHeading | None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """The arrays :func:`compiled_autopilot.sample` takes besides the work (its design
        plant's parameters, the law, its state), or None where the reference steps: the
        LQR and the sliding mode, or numba off."""
        plant = self.design.compiled_plant
        if plant is None or mode not in (HeadingMode.OFF, HeadingMode.BACKSTEPPING):
            return None
        if backstepping is None:
            return plant.parameters, np.zeros(1), np.zeros(1)
        if backstepping.law is None:
            return None
        return plant.parameters, backstepping.law, backstepping.state

    @property
    def commands(self) -> Commands:
        """The commands last computed."""
        published = self._work[fast.PUBLISHED + 1 : fast.PUBLISHED + 5].tolist()
        return Commands(*published)

    @commands.setter
    def commands(self, commands: Commands) -> None:
        self._work[fast.PUBLISHED + 1 : fast.PUBLISHED + 5] = commands.values()

    @property
    def heading_setpoint(self) -> float:
        """psi_d of the last step, rad."""
        return float(self._work[fast.PUBLISHED])

    @heading_setpoint.setter
    def heading_setpoint(self, psi_d: float) -> None:
        self._work[fast.PUBLISHED] = psi_d

    def _backstepping_law(
        self, time: float, x: tuple[float, ...], ramp: bool
    ) -> tuple[float, float]:
        v, r, p, phi, psi_e, y_v, _ = x
        assert self.backstepping is not None, "set with this law by _use_heading_mode"
        return self.backstepping.command_values(time, v, r, p, phi, psi_e, y_v, ramp)

    def reset(self) -> None:
        """Back to the state right after construction."""
        self.commands = Commands(thrust=self.config.thrust_command)
        self.heading_setpoint = 0.0  # psi_d of the last step, rad
        self.next_sample: float | None = None  # s, a digital autopilot's next sample time
        if self.backstepping is not None:
            self.backstepping.reset()

    def snapshot(self) -> AutopilotSnapshot:
        """Everything :meth:`step` changes, for :meth:`restore`."""
        bs = self.backstepping.snapshot() if self.backstepping is not None else None
        return AutopilotSnapshot(self.commands, self.heading_setpoint, bs, self.next_sample)

    def restore(self, snapshot: AutopilotSnapshot) -> None:
        """Back to the state of :meth:`snapshot` (taken from an autopilot of this config)."""
        self.commands = snapshot.commands
        self.heading_setpoint = snapshot.heading_setpoint
        self.next_sample = snapshot.next_sample
        if self.backstepping is not None:
            if snapshot.backstepping is None:
                raise ValueError("the snapshot holds no backstepping state: not of this config")
            self.backstepping.restore(snapshot.backstepping)

    def step_into(
        self, time: float, measurements: np.ndarray, commands: np.ndarray, rates: np.ndarray
    ) -> None:
        """:meth:`step` from and into arrays: ``measurements`` in :data:`MEASUREMENT_NAMES`
        order, the commands into ``commands`` (:data:`COMMAND_NAMES` order), ``rates`` the
        measurements' first time derivatives the importer set (0.0 where none: the step
        is ``varying`` when one is not 0). With the heading law off or backstepping, no
        ``sample_period`` and numba usable, one compiled call that allocates nothing
        (:func:`controller_fmu.compiled_autopilot.sample`, the same arithmetic); else,
        and to raise what a refused sample gets, :meth:`step`.

        Raises:
            ValueError: as :meth:`step`; the autopilot is then as before the call.
        """
        kernel = self._kernel
        if kernel is not None and self.config.sample_period == 0.0:
            p, law, state = kernel
            work = self._work
            done = fast.sample(p, law, state, work, measurements, rates, commands, time)
            if done == fast.NEEDS_TRANSITION and self.backstepping is not None:
                self.backstepping.add_transition(time)
                done = fast.sample(p, law, state, work, measurements, rates, commands, time)
            if done == fast.OK:
                return
        # (a method of its own: its comprehension's cell would be allocated at every call)
        self._step_reference(time, measurements, commands, rates)

    def _step_reference(
        self, time: float, measurements: np.ndarray, commands: np.ndarray, rates: np.ndarray
    ) -> None:
        """:meth:`step_into` through :meth:`step`."""
        values = measurements.tolist()
        named = {name: values[i] for i, name in enumerate(MEASUREMENT_NAMES)}
        commands[:] = self.step(time, named, bool(rates.any())).values()

    def step(
        self, time: float, measurements: Mapping[str, float], varying: bool = False
    ) -> Commands:
        """The commands to hold from ``time`` (s) over the next communication step.

        Args:
            time: current time, s.
            measurements: every name of :data:`MEASUREMENT_NAMES`, SI.
            varying: the measurements went linearly from the last sample's to these
                (the importer extrapolates them: input derivatives), so the
                backstepping's filters follow them so (a first-order hold, second-order
                accurate in the step) instead of holding the last sample's. A digital
                autopilot (``sample_period`` > 0) samples at its own times only, at the
                first call at or after each multiple of the period, holding its
                commands from one sample to the next and its filters' inputs too.

        Raises:
            ValueError: a measurement is missing or not finite, or (with the depth
                loop on) the depth set-point is above the surface (< 0 m), or (with
                ``compensate_current``) the cross-current reaches the design speed, or a
                command came out non-finite; the autopilot is then as before the call.
        """
        m = _checked(time, measurements)
        if self.depth is not None and m["depth_setpoint"] < 0.0:
            raise ValueError(
                f"depth_setpoint = {m['depth_setpoint']!r} m is above the surface: expected a "
                "depth >= 0 m (down positive); the plant has no free surface, so a vehicle "
                "sent above it keeps its buoyancy and drag and flies"
            )
        c = self.config
        next_sample = self.next_sample
        if c.sample_period > 0.0:
            slack = sample_slack(time, c.sample_period)
            if next_sample is not None and time < next_sample - slack:
                return self.commands
            next_sample = next_sample_time(time + slack, c.sample_period)
            varying = False
        psi_d = desired_heading(
            m["yaw_setpoint"], m["current_north"], m["current_east"], c.design_speed,
            c.compensate_current,
        )  # fmt: skip
        psi_e = wrap_angle(m["yaw"] - psi_d)
        x = (m["v_rel"], m["r"], m["p"], m["roll"], psi_e, m["mass_position"],
             m["mass_velocity"])  # fmt: skip
        saved = None if self.backstepping is None else self.backstepping.state_values()
        mass_cmd, tunnel = self._heading_law(time, x, varying)
        if mass_locked(time, c.mass_lock_time):
            mass_cmd = 0.0
        fin = 0.0
        if self.depth is not None:
            fin = self.depth.fin_angle(m["depth_setpoint"], m["down"], m["pitch"], m["q"])
        mass_cmd = _clip(mass_cmd, c.mass_position_cmd_limit)
        tunnel = _clip(tunnel, c.tunnel_force_limit)
        commands = Commands(mass_cmd, tunnel, fin, c.thrust_command)
        if not (math.isfinite(mass_cmd) and math.isfinite(tunnel) and math.isfinite(fin)):
            if saved is not None and self.backstepping is not None:
                self.backstepping.load_state_values(saved)
            raise ValueError(f"the autopilot computed a non-finite command {commands}")
        self.commands = commands
        self.heading_setpoint = psi_d
        self.next_sample = next_sample
        return commands


_SAMPLE_SLACK = 1e-9  # of the time (at least of 1 s), as the FMU's check of a host's time
_MOST_SLACK = 1e-3  # of a sample period: the slack never reaches the next sample
_EXACT_COUNT = 2.0**53  # periods a double counts one by one (beyond, n + 1 rounds to n)


def next_sample_time(time: float, period: float) -> float:
    """The first multiple of ``period`` (s) after ``time`` (s); ``time`` itself where the
    period is below the spacing of doubles there (|time / period| of 2**53 or more, or
    overflowing to inf with a subnormal period): every call is then a sample, as with any
    period shorter than the communication step."""
    periods = time / period
    if not abs(periods) < _EXACT_COUNT:
        return time
    return (math.floor(periods) + 1) * period


def sample_slack(time: float, period: float) -> float:
    """How far (s) before a sample time a call at ``time`` (s) may be and be at it: a host's
    time off by a rounding, its sum t += h too (1e-9 of the time, at least 1 ns, as the
    FMU's own check of the host's time allows), at most a thousandth of ``period`` (s)."""
    return min(_SAMPLE_SLACK * max(1.0, abs(time)), _MOST_SLACK * period)


def _checked(time: float, measurements: Mapping[str, float]) -> dict[str, float]:
    if not math.isfinite(time):
        raise ValueError(f"time = {time!r}: expected a finite number of seconds")
    try:  # the hot path: one comprehension, one finiteness check over all
        values = {name: float(measurements[name]) for name in MEASUREMENT_NAMES}
        if all(map(math.isfinite, values.values())):
            return values
    except (KeyError, TypeError, ValueError):
        pass
    for name, unit in zip(MEASUREMENT_NAMES, MEASUREMENT_UNITS):
        if name not in measurements:
            raise ValueError(f"measurement {name!r} is missing: expected {list(MEASUREMENT_NAMES)}")
        value = float(measurements[name])
        if not math.isfinite(value):
            raise ValueError(f"measurement {name} = {value!r}: expected a finite number ({unit})")
    raise AssertionError("unreachable: the hot path accepted every measurement")
