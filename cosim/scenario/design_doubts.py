"""Scenario values that are valid but leave the autopilot's design other than the user
meant: its laws designed for another vehicle than the plant's, or for another speed than
the thrust it sends drives the plant at, a gain given to a law the scenario never runs, or
a law designed for its command held over each step (the LQR, the sampled sliding mode)
whose command the coupling extrapolates or hands on late, or a gain fault on it, past its
loop's margins, or a moving-mass command limit short of the plant's rail.

The autopilot designs its heading laws on its own ``vehicle`` parameter set
(:class:`controller_fmu.lateral_model.LateralDesignModel`), not on the plant's: a scenario
that gives the plant another set and not the autopilot runs gains designed for a vehicle
it does not steer. A robustness study may mean exactly that, so it is not refused; a run
says so in one warning line each, as it does for an angle that looks like degrees
(:mod:`cosim.scenario.unit_doubts`, whose ``warn`` shows them, as :class:`DesignWarning`).
"""

from __future__ import annotations

import cmath
import functools
import itertools
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from controller_fmu.modes import DepthMode, HeadingMode, unused_parameters
from cosim.metrics.key_figures import MASS_COMMAND_ACTIVITY

if TYPE_CHECKING:
    from cosim.scenario.spec import Instance, Scenario
    from cosim.scenario.timeline_spec import Fault
    from plant_fmu.model.parameters import VehicleParameters

PLANT, AUTOPILOT, GUIDANCE = "AuvPlant", "AuvAutopilot", "AuvGuidance"
_SHOWN_DIFFERENCES = 3  # parameters named when two vehicle sets differ
_LABELS = ("name", "description")  # fields of a vehicle set that are no physics


class DesignWarning(UserWarning):
    """A valid scenario whose autopilot design is likely not the one meant."""


def design_doubts(scenario: Scenario, live: bool = False) -> list[str]:
    """One line for each autopilot designed for another vehicle set than a plant's, and
    for each law-specific autopilot parameter given (a start value or an event's ``set``)
    that no law the scenario selects reads (not in a ``live`` run: its keys and control
    endpoint may switch the heading law to any)."""
    found: list[str] = []
    for name, autopilot in _instances(scenario, AUTOPILOT).items():
        plants = _steered(scenario, name)
        found += [_vehicle_doubt(name, autopilot, p, plant) for p, plant in plants.items()]
        found += [_speed_doubt(scenario, name, autopilot, p, plant) for p, plant in plants.items()]
        found += [
            _command_limit_doubt(scenario, name, autopilot, p, plant) for p, plant in plants.items()
        ]
        found.append(_extrapolated_command_doubt(scenario, name, autopilot))
        found.append(_late_command_doubt(scenario, name, autopilot))
        found += _gain_fault_doubts(scenario, name, autopilot)
        found.append(_pitch_doubt(scenario, name, autopilot, plants))
        if not live:
            found += _unused_gains(scenario, name, autopilot)
        found += _fast_gains(scenario, name, autopilot)
    return [line for line in found if line]


GAIN_UNIT = "1/s"  # a rate of convergence: the autopilot's backstepping gains k0 ... k4
FASTEST_GAIN_STEPS = 2.0
"""The largest gain (1/s) times the autopilot's sampling interval (s) left unremarked: a
command held over a step h that corrects an error at k per second gives the error
e(n+1) = (1 - k h) e(n), which over-corrects past k h = 1 and grows past k h = 2."""


def _fast_gains(scenario: Scenario, name: str, autopilot: Instance) -> list[str]:
    """Warnings for the gains in 1/s given to ``name`` (start values and events' ``set``)
    whose product with its sampling interval (its ``sample_period``, at least its step
    multiple of the communication step) is past :data:`FASTEST_GAIN_STEPS`: a gain typed
    orders of magnitude too large, which runs with the actuators on their stops."""
    interval = _sample_time(scenario, name, autopilot)
    given = [(f"instances.{name}.start.{v}", v, x) for v, x in autopilot.start.items()]
    for event in scenario.events:
        given += [
            (f"events.{event.name}.set.{ref}", ref.partition(".")[2], value)
            for ref, value in event.set.items()
            if ref.partition(".")[0] == name
        ]
    variables = autopilot.interface.variables
    return [
        f"{key} = {value:g} {GAIN_UNIT} with the {name} acting every {interval:g} s: "
        f"{variable} * {interval:g} s = {value * interval:.2g}, past {FASTEST_GAIN_STEPS:g}, "
        "where a loop whose command is held over a step over-corrects its error within the "
        f"step; the default is {variable} = {variables[variable].start:g}"
        for key, variable, value in given
        if variables[variable].unit == GAIN_UNIT
        and isinstance(value, float)
        and value * interval > FASTEST_GAIN_STEPS
    ]


def _sample_time(scenario: Scenario, name: str, autopilot: Instance) -> float:
    """The time (s) between two of ``name``'s samples: its ``sample_period``, at least its
    step (its step multiple of the communication step): it samples at doSteps only."""
    multiple = scenario.coupling.step_multiples.get(name, 1)
    return max(float(_start(autopilot, "sample_period")), scenario.coupling.step * multiple)


def _steered(scenario: Scenario, autopilot: str) -> dict[str, Instance]:
    """The plants the autopilot ``autopilot`` is checked against: those a connection joins
    to it either way (of two vehicles, its own), else every plant of the scenario."""
    plants = _instances(scenario, PLANT)
    joined = {
        end
        for c in scenario.connections
        for end in (c.source_instance, c.target_instance)
        if autopilot in (c.source_instance, c.target_instance)
    }
    return {name: plant for name, plant in plants.items() if name in joined} or plants


def _instances(scenario: Scenario, model: str) -> dict[str, Instance]:
    return {
        name: inst
        for name, inst in scenario.instances.items()
        if inst.interface.model_identifier == model
    }


def _start(inst: Instance, variable: str) -> Any:
    """The instance's start value of ``variable``, its FMU's default where not given."""
    if variable in inst.start:
        return inst.start[variable]
    return inst.interface.variables[variable].start


def plant_parameters(plant: Instance) -> VehicleParameters:
    """The parameter set the plant runs: its ``vehicle`` with the physical parameters the
    scenario gives it written over (as :class:`plant_fmu.auv_plant.AuvPlant` builds it)."""
    from cosim.scenario.spec import plant_vehicle

    return plant_vehicle(str(_start(plant, "vehicle")), plant.start)


def _vehicle_doubt(name: str, autopilot: Instance, plant_name: str, plant: Instance) -> str:
    """The warning if the autopilot's vehicle set differs from the plant's ('' if not)."""
    from plant_fmu.model.parameters import load_vehicle

    ours = str(_start(autopilot, "vehicle"))
    mine, plants = load_vehicle(ours).as_dict(), plant_parameters(plant).as_dict()
    differ = [key for key in mine if key not in _LABELS and mine[key] != plants[key]]
    if not differ:
        return ""
    shown = ", ".join(
        f"{key} {plants[key]!r} vs {mine[key]!r}" for key in differ[:_SHOWN_DIFFERENCES]
    )
    more = len(differ) - _SHOWN_DIFFERENCES
    more_text = f" and {more} more" if more > 0 else ""
    theirs = _short(str(_start(plant, "vehicle")))
    written = [key for key in differ if key in plant.start]
    given = f" with {', '.join(written)} written over" if written else ""
    return (
        f"{plant_name} runs vehicle {theirs!r}{given} but {name} designs its laws for vehicle "
        f"{_short(ours)!r} (instances.{name}.start.vehicle): the sets differ in {shown}"
        f"{more_text}; give {name} the plant's vehicle too (a set with the same values), "
        "unless the mismatch is meant"
    )


def _speed_doubt(
    scenario: Scenario, name: str, autopilot: Instance, plant_name: str, plant: Instance
) -> str:
    """The warning if the autopilot's thrust, connected to the plant, drives the plant's
    vehicle on a straight run at a speed more than :data:`SPEED_TOLERANCE` from the
    ``design_speed`` its laws are designed for ('' if not, or if no law runs)."""
    pairs = {(c.source, c.target) for c in scenario.connections}
    if (f"{name}.thrust", f"{plant_name}.thrust") not in pairs:
        return ""
    modes = {_start(autopilot, "heading_mode"), _start(autopilot, "depth_mode")}
    if modes <= {0, "off"}:
        return ""
    thrust, design = (
        float(_start(autopilot, "thrust_command")),
        float(_start(autopilot, "design_speed")),
    )
    speed = straight_run_speed(plant_parameters(plant), thrust)
    if speed is None and thrust <= 0.0:
        return (
            f"{name}.design_speed = {design!r} m/s but its thrust_command = {thrust!r} N "
            f"drives {plant_name} forward at no speed (a thrust <= 0 stops it or backs it): "
            "its laws are designed for a forward run at design_speed"
        )
    if speed is None or abs(speed - design) <= SPEED_TOLERANCE * design:
        return ""
    return (
        f"{name}.design_speed = {design!r} m/s but its thrust_command = {thrust!r} N drives "
        f"{plant_name} straight at {speed:.4g} m/s: its laws are designed for another speed "
        f"than they steer at; set design_speed = {speed:.4g}, unless the mismatch is meant"
    )


def _command_limit_doubt(
    scenario: Scenario, name: str, autopilot: Instance, plant_name: str, plant: Instance
) -> str:
    """The warning if a heading law of ``name`` runs with a moving-mass command limit (m)
    short of the stroke of ``plant_name``'s vehicle ('' if not): the autopilot never uses
    the rail's ends, and its default limit is REMUS 100's stroke, whatever the vehicle."""
    if not _heading_modes(scenario, name, autopilot) - {HeadingMode.OFF}:
        return ""
    limit = float(_start(autopilot, "mass_position_cmd_limit"))
    stroke = plant_parameters(plant).mass_stroke
    if limit >= stroke:
        return ""
    default = (
        "" if "mass_position_cmd_limit" in autopilot.start else " (its default, REMUS 100's stroke)"
    )
    return (
        f"{name}.mass_position_cmd_limit = {limit:g} m{default} is short of {plant_name}'s "
        f"mass_stroke = {stroke:g} m: the autopilot never moves the mass past {limit:g} m of "
        f"its {stroke:g} m rail; set mass_position_cmd_limit = {stroke:g}, unless that is meant"
    )


_FASTEST = 1e4  # m/s: the bracket widens (doubling) until past this
SPEED_TOLERANCE = 0.05
"""How far (relative) the straight-run speed may be from the design speed unremarked."""


@functools.lru_cache(maxsize=256)
def straight_run_speed(vehicle: VehicleParameters, thrust: float) -> float | None:
    """The surge speed (m/s, through the water) of ``vehicle`` running straight on
    ``thrust`` N: the root of the plant's own u' (horizontal variant, v = r = 0) in
    (0, 2e4] m/s; None without one (no forward thrust, or a thrust beyond any vehicle's).
    Computed once a process for a vehicle (immutable, compared by value) and thrust: a
    study checks every point, most with the same."""
    from plant_fmu.model.dynamics import STATE_INDEX, PlantModel, Variant
    from plant_fmu.model.linearization import input_vector, state_vector
    from plant_fmu.model.root_finding import brent_root

    model = PlantModel(vehicle, Variant.HORIZONTAL)
    inputs = input_vector({"thrust": thrust})

    def surge_rate(u: float) -> float:
        return float(model.derivative(state_vector({"u": u}), inputs)[STATE_INDEX["u"]])

    low, high = 1e-6, 20.0
    if not surge_rate(low) > 0.0:
        return None  # no forward thrust: the vehicle stops or backs
    while surge_rate(high) > 0.0 and high < _FASTEST:
        high *= 2.0  # a strong thrust: widen the bracket
    if not surge_rate(high) < 0.0:
        return None
    return brent_root(surge_rate, low, high, xtol=1e-9)


def _short(vehicle: str) -> str:
    """A vehicle value as a message shows it: a set given inline by its first line."""
    first, _, rest = vehicle.partition("\n")
    return f"{first} ..." if rest else vehicle


_DISCRETE_LAWS = (HeadingMode.LQR, HeadingMode.SLIDING_MODE)
"""The heading laws designed on the plant discretised with their command held over a
step (docs/model.md: the LQR, the sampled sliding mode)."""


def _extrapolated_command_doubt(scenario: Scenario, name: str, autopilot: Instance) -> str:
    """The warning if ``name`` runs a heading law designed for its command held over each
    step (:data:`_DISCRETE_LAWS`, at its start or after an event) while the coupling
    extrapolates that command across the step ('' if not)."""
    extrapolation = scenario.coupling.extrapolation
    command = f"{name}.mass_position_cmd"
    if extrapolation == "none" or not any(c.source == command for c in scenario.connections):
        return ""
    discrete = sorted(_heading_modes(scenario, name, autopilot) & set(_DISCRETE_LAWS))
    if not discrete:
        return ""
    laws = " and ".join(mode.name.lower() for mode in discrete)
    return (
        f"{name} runs heading_mode {laws}, a design for its command held over each step, but "
        f"coupling.extrapolation = {extrapolation!r} extrapolates {command} across the step: "
        "the loop run is not the one designed (lqr-1 so banged its mass command between -100 "
        'and +100 m every step); set extrapolation = "none", as lqr-1 to lqr-3 do'
    )


def _late_command_doubt(scenario: Scenario, name: str, autopilot: Instance) -> str:
    """The warning if ``name`` runs a law designed for its command held over each step
    (:data:`_DISCRETE_LAWS`, at its start or after an event) and the coupling hands its mass
    command to the plant one communication step late (Jacobi, or a Gauss-Seidel order with
    the plant first) while its loop, its gains (designed for design_step) sampled as it
    samples and delayed so (by at most one sample), is unstable (:func:`_unstable_when_late`;
    '' if not)."""
    laws = [law for law in _DISCRETE_LAWS if law in _heading_modes(scenario, name, autopilot)]
    for plant in _commanded(scenario, name).values():
        cause = _late_cause(scenario, name, plant)
        if not cause:
            continue
        sample = _sample_time(scenario, name, autopilot)
        step = _plant_step(scenario, plant)
        for law in laws:
            if _unstable_when_late(autopilot, sample, min(step, sample), law):
                return _late_command_text(name, autopilot, (sample, step), cause, plant, law)
        return ""
    return ""


def _commanded(scenario: Scenario, name: str) -> dict[str, str]:
    """The inputs ``name``'s mass command is connected to, each with its instance."""
    command = f"{name}.mass_position_cmd"
    targets = (c.target for c in scenario.connections if c.source == command)
    return {t: t.partition(".")[0] for t in targets if t.partition(".")[0] != name}


def _late_cause(scenario: Scenario, name: str, plant: str) -> str:
    """Why the coupling hands ``name``'s outputs to ``plant`` one step late, as a warning
    says it ('' where ``plant`` gets them at once: Gauss-Seidel, ``name`` first)."""
    coupling = scenario.coupling
    if coupling.algorithm == "jacobi":
        return f"coupling.algorithm = {coupling.algorithm!r}"
    if coupling.order.index(plant) < coupling.order.index(name):
        return f"coupling.order = {list(coupling.order)} steps {plant} before {name}: it"
    return ""


def _plant_step(scenario: Scenario, plant: str) -> float:
    """The time (s) between two of ``plant``'s steps."""
    return scenario.coupling.step * scenario.coupling.step_multiples.get(plant, 1)


def _gain_fault_doubts(scenario: Scenario, name: str, autopilot: Instance) -> list[str]:
    """A warning for each gain or delay fault on ``name``'s mass command (where `auv-cosim
    analyze margins` breaks the loop) under which its loop of a law of
    :data:`_DISCRETE_LAWS`, as it samples and as late as the coupling hands the command on
    (:func:`_worst_pole`), is unstable: a gain past the upper gain margin makes the command
    chatter between its limits while the key figures look better than a stable loop's, a
    delay past the delay margin makes it swing ever wider (docs/model.md#lqr). Then one
    for each set of faults on the same command, on together, that none of which is
    unstable alone, under which the loop is (:func:`_combined_lines`)."""
    laws = [law for law in _DISCRETE_LAWS if law in _heading_modes(scenario, name, autopilot)]
    found: list[str] = []
    sample = _sample_time(scenario, name, autopilot)
    fleet = len(_instances(scenario, PLANT)) > 1  # key figures named after their plant
    for target, plant in _commanded(scenario, name).items():
        step = _plant_step(scenario, plant)
        late = min(step, sample) if _late_cause(scenario, name, plant) else 0.0
        figure = f"{plant}.{MASS_COMMAND_ACTIVITY}" if fleet else MASS_COMMAND_ACTIVITY
        faults = [f for f in scenario.faults if _loop_fault(f, target, scenario.stop_time)]
        alone = []
        for fault in faults:
            until = _until(fault.stop, scenario.stop_time, "its stop")
            times = (sample, step, late)
            words = (until, figure)
            lines = (_fault_line(name, autopilot, fault, times, law, words) for law in laws)
            line = next(filter(None, lines), "")  # one line a fault
            found += [line] if line else []
            alone += [fault.name] if line else []
        loop = (name, autopilot, sample, step, late)
        found += _combined_lines(scenario, loop, laws, faults, set(alone))
    return found


def _loop_fault(fault: Fault, target: str, stop_time: float) -> bool:
    """Whether ``fault`` is a gain or delay fault on ``target`` that is on before the
    run's ``stop_time`` (s): what the loop's margins judge."""
    judged = (fault.kind == "gain" and fault.value is not None) or (
        fault.kind == "delay" and fault.steps is not None
    )
    return judged and fault.target == target and fault.start < stop_time


def _until(stop: float | None, stop_time: float, which: str) -> str:
    """ " until t = <stop> s (<which>)" for a fault that stops at ``stop`` (s) before the
    run's ``stop_time``, "" for one on to its end: the loop is unstable only while it is on."""
    return "" if stop is None or stop >= stop_time else f" until t = {stop:g} s ({which})"


def _combined_lines(
    scenario: Scenario,
    loop: tuple[str, Instance, float, float, float],
    laws: list[HeadingMode],
    faults: list[Fault],
    alone: set[str],
) -> list[str]:
    """A line for each set of two or more of ``faults`` (on one command) on together,
    none of them among ``alone`` (named by its own line), under which the loop is
    unstable: gains multiply, delays add, on the plant's own linearisation
    (:func:`_worst_pole`); from the first time they are all on until the first stops.
    ``loop``: the autopilot's name and instance, its sample, the target's step and the
    coupling's own delay (s)."""
    name, autopilot, sample, step, late = loop
    times = sorted({0.0, *(f.start for f in faults), *(f.stop for f in faults if f.stop)})
    found: list[str] = []
    seen: set[tuple[str, ...]] = set()
    for start in (t for t in times if t < scenario.stop_time):
        on = [f for f in faults if f.start <= start and (f.stop is None or f.stop > start)]
        names = tuple(f.name for f in on)
        if len(on) < 2 or names in seen or alone & set(names):
            continue
        seen.add(names)
        gain = math.prod(f.value for f in on if f.kind == "gain" and f.value is not None)
        delay = late + sum(f.steps for f in on if f.kind == "delay" and f.steps) * step
        for law in laws:
            worst = _worst_pole(autopilot, sample, delay, gain, law)
            if _grows(worst) and not _grows(_worst_pole(autopilot, sample, late, law=law)):
                stop = min((f.stop for f in on if f.stop is not None), default=None)
                until = _until(stop, scenario.stop_time, "a fault's stop")
                found.append(_combined_text(name, on, (gain, delay - late), law, start, until))
                break
    return found


def _combined_text(
    name: str,
    on: list[Fault],
    faulted: tuple[float, float],
    law: HeadingMode,
    start: float,
    until: str,
) -> str:
    """:func:`_combined_lines`'s line for the faults ``on`` together, their ``faulted``
    gain and delay (s) of ``name``'s command under ``law`` from ``start`` (s)."""
    gain, delay = faulted
    steps = sum(f.steps for f in on if f.kind == "delay" and f.steps)
    parts = [f"a gain of {gain:.4g}"] if any(f.kind == "gain" for f in on) else []
    if steps:
        parts.append(f"a delay of {steps} step{'s' if steps != 1 else ''} ({delay:g} s)")
    listed = ", ".join(f"faults.{f.name}" for f in on[:-1]) + f" and faults.{on[-1].name}"
    return (
        f"{listed} together (on {on[0].target}, the command of {name}'s heading_mode "
        f"{law.name.lower()}: {' and '.join(parts)}) are past that loop's margins "
        f"({_MARGINS_OF[law]}), though none is alone, so from t = {start:g} s{until} it is "
        f"unstable: the command ({name}.mass_position_cmd) shows it"
    )


def _fault_line(
    name: str,
    autopilot: Instance,
    fault: Fault,
    times: tuple[float, float, float],
    law: HeadingMode,
    words: tuple[str, str],
) -> str:
    """:func:`_gain_fault_doubts`'s line for ``fault`` under ``law`` ('' where the loop
    takes it, or the fault is neither a gain nor a delay): ``times`` as
    :func:`_delay_fault_line`'s; ``words``: (``until`` as :func:`_until` says of its stop,
    the run's key figure of the command's activity)."""
    if fault.kind == "gain" and fault.value is not None:
        sample, _, late = times
        worst = _worst_pole(autopilot, sample, late, fault.value, law)
        if worst is None or not _grows(worst):
            return ""
        return _gain_fault_text(name, fault, worst, sample, law, words)
    if fault.kind == "delay" and fault.steps is not None:
        return _delay_fault_line(name, autopilot, fault, times, law, words[0])
    return ""


def _grows(worst: complex | None) -> bool:
    """Whether a loop's largest pole ``worst`` (None: no loop) is outside the unit circle."""
    return worst is not None and abs(worst) >= 1.0


def _delay_fault_line(
    name: str,
    autopilot: Instance,
    fault: Fault,
    times: tuple[float, float, float],
    law: HeadingMode,
    until: str = "",
) -> str:
    """:func:`_gain_fault_doubts`'s line for the delay fault ``fault`` ('' where the loop
    takes it): ``times`` are ``name``'s sample, the target's step and the coupling's own
    delay (s); the fault adds its ``steps`` of the target's steps to that delay."""
    sample, step, late = times
    assert fault.steps is not None
    delay = late + fault.steps * step
    worst = _worst_pole(autopilot, sample, delay, law=law)
    if not _grows(worst) or _grows(_worst_pole(autopilot, sample, late, law=law)):
        return ""  # stable; or unstable without the fault, as the late command's line says
    assert worst is not None

    def excess(d: float) -> float:
        pole = _worst_pole(autopilot, sample, d, law=law)
        return abs(pole if pole is not None else 0.0) - 1.0

    # here, not with the module: scipy.optimize takes ~0.4 s of CPU to import, and every
    # run and study checks its scenario through this module
    from scipy.optimize import brentq

    margin = brentq(excess, late, delay, xtol=1e-6 * sample) - late
    angle = abs(cmath.phase(worst))
    growth = math.log(abs(worst)) / sample  # 1/s
    swing = f"swinging at {angle / sample:.3g} rad/s, " if angle > 1e-6 else ""
    pace = f"doubling every {math.log(2.0) / growth:.2g} s" if growth > 0.0 else "not decaying"
    steps = f"{fault.steps} step{'s' if fault.steps != 1 else ''}"
    return (
        f"faults.{fault.name}: a delay of {steps} ({fault.steps * step:g} s) on {fault.target} "
        f"(the command of {name}'s heading_mode {law.name.lower()}) is past that loop's delay "
        f"margin of {margin:.3g} s ({_MARGINS_OF[law]}; its command held between samples), "
        f"so from t = {fault.start:g} s{until} it is "
        f"unstable, {swing}its error {pace} (|z| = {abs(worst):.4g} a sample) until the "
        f"command's limits hold it: the command ({name}.mass_position_cmd) shows it"
    )


_MARGINS_OF = {  # where a law's loop margins are read, as its warnings name it
    HeadingMode.LQR: "auv-cosim analyze margins",
    HeadingMode.SLIDING_MODE: "its loop inside the boundary layer, docs/model.md#sliding-mode",
}


def _gain_fault_text(
    name: str,
    fault: Fault,
    worst: complex,
    sample: float,
    law: HeadingMode,
    words: tuple[str, str],
) -> str:
    """:func:`_gain_fault_doubts`'s line for ``fault``, the loop's worst pole ``worst``
    (z, of a sample of ``sample`` s) under ``law``; ``words``: (``until`` as :func:`_until`
    says of its stop, the run's key figure of the command's activity: its total variation
    per second, which shows the chatter)."""
    until, figure = words
    angle = abs(cmath.phase(worst))
    line = (
        f"faults.{fault.name}: a gain of {fault.value:.4g} on {fault.target} (the command of "
        f"{name}'s heading_mode {law.name.lower()}) is outside that loop's gain margins "
        f"({_MARGINS_OF[law]}), so from t = {fault.start:g} s{until} it is unstable"
    )
    if angle < math.pi / 2:  # how fast from the pole: a reversed command's doubles a sample
        growth = math.log(abs(worst)) / sample  # 1/s
        pace = f"doubling every {math.log(2.0) / growth:.2g} s" if growth > 0.0 else "not decaying"
        return f"{line} (|z| = {abs(worst):.4g} a sample): its heading turns away, its error {pace}"
    every = (
        "at every step" if angle > 0.9 * math.pi else f"every {2 * math.pi * sample / angle:.2g} s"
    )
    return (
        f"{line} at {angle / sample:.3g} rad/s (|z| = {abs(worst):.4g} a sample): its command "
        f"swings between its limits {every}, the mass on its stops, while the heading "
        "strays less than a stable loop's: its yaw settling time does not show it, the "
        f"command ({name}.mass_position_cmd) and its activity (the key figure {figure}) do"
    )


def _late_command_text(
    name: str,
    autopilot: Instance,
    times: tuple[float, float],
    cause: str,
    plant: str,
    law: HeadingMode = HeadingMode.LQR,
) -> str:
    """:func:`_late_command_doubt`'s line: ``name`` samples every ``times[0]`` s under
    ``law`` and ``cause`` hands its command to ``plant``, stepping every ``times[1]`` s,
    one step late."""
    sample, step = times
    design_step = float(_start(autopilot, "design_step"))
    command = f"{name}.mass_position_cmd"
    handed = f"{cause} hands {command} to {plant} one {step:g} s step late"
    mode = law.name.lower()
    lqr_1 = "(lqr-1 so banged its mass command between -100 and +100 m and never settled)"
    if law is HeadingMode.SLIDING_MODE:
        lqr_1 = (
            "(lqr-1 with heading_mode sliding_mode so banged its mass command between -100 "
            "and +100 m, its heading 47 deg off after 40 s)"
        )
    advice = (
        f'use algorithm = "gauss-seidel" with {name} before {plant} in the order, as '
        "lqr-1 to lqr-3 do"
    )
    if math.isclose(sample, design_step, rel_tol=1e-9):
        under = f"one of its {design_step:g} s samples" if step >= design_step else f"{step:g} s"
        return (
            f"{name} runs heading_mode {mode}, whose delay margin is under {under} "
            f"({_MARGINS_OF[law]}), but {handed}: the loop is unstable {lqr_1}; {advice}"
        )
    if _unstable_when_late(autopilot, sample, 0.0, law):
        advice = (
            "its gains are unstable at that sample time even with the command on time: set "
            f"design_step = {sample:g} s, the time it samples at"
        )
    return (
        f"{name} runs heading_mode {mode} designed for {design_step:g} s samples (design_step) "
        f"but sampling every {sample:g} s, whose loop so sampled is unstable with its "
        f"command {min(step, sample):g} s late, and {handed} {lqr_1}; {advice}"
    )


def _unstable_when_late(
    autopilot: Instance, sample: float, delay: float, law: HeadingMode = HeadingMode.LQR
) -> bool:
    """Whether the autopilot's loop under ``law`` (:func:`_worst_pole`) has a pole outside
    the unit circle with its command ``delay`` s late; False where the law cannot be
    designed (the autopilot refuses that itself). The REMUS 100's LQR takes 0.92 to 1.05
    steps of delay at design steps of 50 to 1 ms (``analyze margins --step``) sampled at
    them; its sliding mode 0.98 at 10 ms."""
    return _grows(_worst_pole(autopilot, sample, delay, law=law))


def _worst_pole(
    autopilot: Instance,
    sample: float,
    delay: float,
    gain: float = 1.0,
    law: HeadingMode = HeadingMode.LQR,
) -> complex | None:
    """The largest pole z of the autopilot's loop under ``law``, its gains designed on its
    own design model (its vehicle at its design_speed, sampled every design_step), times
    ``gain``, sampled every ``sample`` s, with its command ``delay`` s late
    (:func:`controller_fmu.lqr.delayed_poles`); None where the law cannot be designed.
    Computed once a process for the values that decide it (:func:`_largest_pole`): a study
    checks every point, most with the same loop."""
    from plant_fmu.model.parameters import load_vehicle

    weights = ("r", "p", "roll", "yaw", "mass_position", "mass_velocity")
    try:  # the same object while its files hold the same text: a key that follows them
        vehicle = load_vehicle(str(_start(autopilot, "vehicle")))
    except ValueError:
        return None
    design = (
        vehicle,
        float(_start(autopilot, "design_speed")),
        float(_start(autopilot, "design_step")),
        tuple(float(_start(autopilot, f"lqr_q_{weight}")) for weight in weights),
        float(_start(autopilot, "lqr_r")),
    )
    layer = (
        (float(_start(autopilot, "smc_eta")), float(_start(autopilot, "smc_boundary_layer")))
        if law is HeadingMode.SLIDING_MODE
        else None
    )
    return _largest_pole(design, layer, sample, delay, gain)


_Design = tuple["VehicleParameters", float, float, tuple[float, ...], float]
"""The autopilot's vehicle, design_speed (m/s), design_step (s), LQR weights Q_y and R_u."""


@functools.lru_cache(maxsize=1024)
def _largest_pole(
    design: _Design, layer: tuple[float, float] | None, sample: float, delay: float, gain: float
) -> complex | None:
    """:func:`_worst_pole` of the loop :func:`_loop` designs, times ``gain``."""
    from controller_fmu.lqr import delayed_poles

    loop = _loop(design, layer)
    if loop is None:
        return None
    a, b, linear = loop
    poles = delayed_poles(a, b, gain * linear, sample, delay)
    return complex(poles[np.argmax(np.abs(poles))])


@functools.lru_cache(maxsize=64)
def _loop(
    design: _Design, layer: tuple[float, float] | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The plant (A, B) a heading law is designed on and its linear feedback gain: the
    LQR's, or with ``layer`` (eta, the boundary layer Phi) the sliding mode's inside its
    boundary layer, linear there (6.3.45): y_d = -(k + h eta / (Phi w^T Bd) w)^T x, the
    plant's remainder f*_hat of second order at the straight run; None where the law
    cannot be designed. The arrays are read-only: a cache shares them."""
    from controller_fmu.lateral_model import LateralDesignModel
    from controller_fmu.lqr import LqrHeading
    from controller_fmu.sliding_mode import SlidingModeHeading

    vehicle, speed, step, q_y, r_u = design
    try:
        model = LateralDesignModel(vehicle, speed, False)
        if layer is not None:
            smc = SlidingModeHeading(model, step, *layer, list(q_y), r_u)
            a, b = smc.A, smc.B
            linear = smc.k + step * smc.eta / (smc.boundary_layer * smc.w_bd) * smc.w
        else:
            lqr = LqrHeading(model, step, list(q_y), r_u)
            a, b, linear = lqr.A, lqr.B, lqr.gain
    except ValueError:
        return None
    arrays = tuple(np.array(x, dtype=float) for x in (a, b, linear))
    for array in arrays:
        array.setflags(write=False)
    return arrays[0], arrays[1], arrays[2]


def _pitch_doubt(
    scenario: Scenario, name: str, autopilot: Instance, plants: Mapping[str, Instance]
) -> str:
    """The warning if ``name``'s depth loop, with no ``depth_pitch_limit``, asks for more
    than 90 deg of pitch between the depths the scenario gives: the plants' start depths,
    its depth set-point (unless connected) and every event's, or along the legs of a
    waypoint guidance feeding its depth set-point (:func:`_guided_pitch_doubt`; '' if
    not)."""
    names = autopilot.interface.variables["depth_mode"].names
    modes = {_mode(DepthMode, _start(autopilot, "depth_mode"), names)}
    if DepthMode.PD not in modes or float(_start(autopilot, "depth_pitch_limit")) != 0.0:
        return ""
    return _set_point_pitch_doubt(scenario, name, autopilot, plants) or _guided_pitch_doubt(
        scenario, name, autopilot, plants
    )


def _set_point_pitch_doubt(
    scenario: Scenario, name: str, autopilot: Instance, plants: Mapping[str, Instance]
) -> str:
    """:func:`_pitch_doubt` between the start depths and the depth set-points given."""
    setpoint = f"{name}.depth_setpoint"
    depths = [float(_start(plant, "down_0")) for plant in plants.values()]
    if not any(c.target == setpoint for c in scenario.connections):
        depths.append(float(_start(autopilot, "depth_setpoint")))
    depths += [float(e.set[setpoint]) for e in scenario.events if setpoint in e.set]
    gamma = float(_start(autopilot, "depth_gamma"))
    pitch = abs(gamma) * (max(depths) - min(depths))
    if pitch <= math.pi / 2:
        return ""
    return (
        f"{name}'s depth loop (depth_gamma = {gamma!r} rad/m) asks for a pitch of up to "
        f"{pitch:.3g} rad ({math.degrees(pitch):.0f} deg) between the depths {min(depths):g} m "
        f"and {max(depths):g} m of this scenario (plant.down_0, its depth_setpoint and "
        "events), beyond the 90 deg any pitch can be: its fins stay on their stop until the "
        f"vehicle pitches over; set depth_pitch_limit (rad, at most {math.pi / 2:.4g}), unless "
        "that is meant"
    )


def _guided_pitch_doubt(
    scenario: Scenario, name: str, autopilot: Instance, plants: Mapping[str, Instance]
) -> str:
    """:func:`_pitch_doubt` along the legs of a waypoint guidance (``AuvGuidance``) whose
    ``depth_setpoint`` feeds ``name``'s: its set-point is the path's depth one lookahead
    ahead, so on leg k it lies ``|z_k+1 - z_k| min(Delta / L, 1)`` from a vehicle at the
    leg's start depth (leg 1: from each plant's start depth)."""
    from controller_fmu.los_guidance import parse_waypoints

    gamma = float(_start(autopilot, "depth_gamma"))
    starts = [float(_start(plant, "down_0")) for plant in plants.values()]
    for guidance in _guidances_feeding(scenario, f"{name}.depth_setpoint"):
        waypoints = parse_waypoints(str(scenario.start_value(guidance, "waypoints")))
        lookahead = float(scenario.start_value(guidance, "lookahead"))  # type: ignore[arg-type]
        for k, (a, b) in enumerate(itertools.pairwise(waypoints), start=1):
            length = math.hypot(b.north - a.north, b.east - a.east)
            ahead = a.down + (b.down - a.down) * min(lookahead / length, 1.0)
            lead = max(abs(ahead - z) for z in (starts or [a.down] if k == 1 else [a.down]))
            pitch = abs(gamma) * lead
            if pitch > math.pi / 2:
                return (
                    f"{name}'s depth loop (depth_gamma = {gamma!r} rad/m) asks for a pitch of "
                    f"up to {pitch:.3g} rad ({math.degrees(pitch):.0f} deg) on leg {k} of "
                    f"{guidance}'s waypoints (waypoint {k} -> {k + 1}, from {a.down:g} m to "
                    f"{b.down:g} m depth over {length:.4g} m): its depth set-point, "
                    f"{lookahead:g} m ahead along the leg, is {lead:.3g} m from the vehicle, "
                    "beyond the 90 deg any pitch can be: its fins stay on their stop until the "
                    f"vehicle pitches over; set depth_pitch_limit (rad, at most "
                    f"{math.pi / 2:.4g}) or lengthen the leg, unless that is meant"
                )
    return ""


def _guidances_feeding(scenario: Scenario, target: str) -> list[str]:
    """The waypoint guidances (``AuvGuidance``) whose output is connected to ``target``."""
    return [
        c.source_instance
        for c in scenario.connections
        if c.target == target
        and scenario.instances[c.source_instance].interface.model_identifier == GUIDANCE
    ]


def _heading_modes(scenario: Scenario, name: str, autopilot: Instance) -> set[HeadingMode]:
    """The heading modes ``name`` runs: its start value and every event's."""
    names = autopilot.interface.variables["heading_mode"].names
    modes = {_mode(HeadingMode, _start(autopilot, "heading_mode"), names)}
    for event in scenario.events:
        for ref, value in event.set.items():
            if ref == f"{name}.heading_mode":
                modes.add(_mode(HeadingMode, value, names))
    return modes


def _unused_gains(scenario: Scenario, name: str, autopilot: Instance) -> list[str]:
    """Warnings for the law-specific parameters given to ``name`` that no law it runs
    reads (its heading modes: the start value and every event's)."""
    modes = _heading_modes(scenario, name, autopilot)
    given = {f: f"instances.{name}.start.{f} = {v!r}" for f, v in autopilot.start.items()}
    for event in scenario.events:
        for ref, value in event.set.items():
            instance, _, variable = ref.partition(".")
            if instance == name:
                given.setdefault(variable, f"events.{event.name}.set.{ref} = {value!r}")
    depth = _mode(DepthMode, _start(autopilot, "depth_mode"), {})
    running = ", ".join(m.name.lower() for m in sorted(modes))
    return [
        f"{given[variable]} is read only by {readers}, and {name} runs heading_mode "
        f"{running} with depth_mode {depth.name.lower()}: the value is not used"
        for variable, readers in unused_parameters(given, modes, depth).items()
    ]


def _mode(kind: type[HeadingMode] | type[DepthMode], value: Any, names: Mapping[str, int]) -> Any:
    """A mode from a start or event value (its number, or its name)."""
    return kind(names[value] if isinstance(value, str) else int(value))
