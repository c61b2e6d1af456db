"""Our FMUs as another FMI tool runs them: fmpy's ``simulate_fmu`` with the options a tool
user sets (a relative tolerance, ...), each FMU alone. What the FMU ignores or refuses is
said in its log, with what to do instead."""

from __future__ import annotations

import contextlib
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException

from cosim.fmus.build import FMUS

STATUS_WARNING = 1
# a word of the description beyond the variable's own symbol (``X_u|u|`` has none)
WORD = re.compile(r"[a-z]{3,}")


def _run(path: Path | str, **options) -> tuple[Any, list[tuple[int, str]]]:
    """fmpy's ``simulate_fmu`` on ``path``: its result (None if fmpy raised on a call) and
    the (status, message) pairs the FMU logged meanwhile."""
    messages: list[tuple[int, str]] = []

    def logger(_component, _instance, status, _category, message):
        messages.append((status, message.decode()))

    result = None
    with contextlib.suppress(FMICallException):
        result = simulate_fmu(str(path), logger=logger, **options)
    return result, messages


def _simulate(path: Path, **options) -> list[tuple[int, str]]:
    """Run ``path`` for 0.1 s: the (status, message) pairs the FMU logged, until the end or
    the call fmpy raised on."""
    return _run(path, stop_time=0.1, **options)[1]


@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_relative_tolerance_the_fmu_ignores_is_warned_of(name, fmu_paths):
    """fmpy passes ``relative_tolerance`` on to fmi2SetupExperiment; none of our FMUs has an
    error-controlled integrator, so it must say it ignores the tolerance, and how to
    control the accuracy instead, rather than take it silently with fmi2OK."""
    assert _simulate(fmu_paths[name]) == []  # no tolerance given: nothing to say
    warnings = [text for status, text in _simulate(fmu_paths[name], relative_tolerance=1e-8)
                if status == STATUS_WARNING]  # fmt: skip
    assert len(warnings) == 1, warnings
    assert "tolerance = 1e-08 ignored" in warnings[0], warnings[0]


@pytest.mark.parametrize("name", sorted(FMUS))
def test_every_variable_has_a_description_beyond_its_symbol(name, fmu_paths):
    """A tool lists each variable with its description beside the name: a description that
    only spells the symbol again (``Y_uv``: "Y_uv") tells its user nothing."""
    variables = read_model_description(str(fmu_paths[name])).modelVariables
    bare = {v.name: v.description for v in variables if not WORD.search(v.description or "")}
    assert bare == {}


@pytest.mark.parametrize("name", ["AuvAutopilot", "AuvGuidance"])
def test_a_cross_current_the_compensation_cannot_hold_says_what_to_change(name, fmu_paths):
    """With compensate_current on, a cross-current as fast as the design speed stops the FMU
    (at initialisation or at the first step); its message named the condition only, and
    must say which parameters to change."""
    start = {"compensate_current": True, "current_east": 2.0, "heading_mode": 1}
    if name == "AuvGuidance":
        del start["heading_mode"]
    errors = [text for status, text in _simulate(fmu_paths[name], start_values=start)
              if "cross-current 2 m/s" in text]  # fmt: skip
    assert errors, "no message names the cross-current"
    assert "turn compensate_current off or raise design_speed" in errors[0], errors[0]


# the inputs a reduced variant of the plant has no degree of freedom for
IGNORED_INPUTS = {1: ("fin_angle", "current_down"), 2: ("roll_torque", "fin_angle", "current_down")}
STATES = ["north", "east", "down", "roll", "pitch", "yaw", "u", "v", "w", "p", "q", "r"]


@pytest.mark.parametrize("variant", sorted(IGNORED_INPUTS))
def test_an_input_the_plants_variant_ignores_is_warned_of_and_described(variant, fmu_paths):
    """A tool user writing fin_angle to the lateral plant got fmi2OK and no effect at all:
    the variant has no heave or pitch. The plant must warn that it ignores the value, and
    each input's description must name the variants that ignore it."""
    plant = str(fmu_paths["AuvPlant"])
    start = {"variant": variant, "u_0": 1.5, "v_0": 0.05, "roll_0": 0.1 * (variant == 1)}
    reference = simulate_fmu(plant, stop_time=1.0, start_values=start, output=STATES)
    described = {v.name: v.description for v in read_model_description(plant).modelVariables}
    variant_name = {1: "lateral", 2: "horizontal"}[variant]
    for name in IGNORED_INPUTS[variant]:
        result, messages = _run(
            plant, stop_time=1.0, start_values={**start, name: 0.2}, output=STATES
        )
        assert all((result[s] == reference[s]).all() for s in STATES), name  # truly ignored
        warned = [text for status, text in messages if status == STATUS_WARNING]
        assert any(name in text and "ignore" in text for text in warned), (name, messages)
        assert variant_name in described[name], (name, described[name])


def test_a_step_a_fast_initial_rotation_breaks_names_the_cause_and_the_remedy(fmu_paths):
    """r_0 = 30 rad/s (within its declared range) made the first step blow up, and the
    message blamed an input or a vehicle file, neither of which the user had touched; it
    must name the initial velocity and the remedy, which works: a smaller max_substep."""
    plant = fmu_paths["AuvPlant"]
    result, messages = _run(plant, stop_time=0.5, start_values={"r_0": 30.0})
    assert result is None  # fmpy raised on the step the plant refused
    left = [text for _, text in messages if "left the model's range" in text]
    assert left, messages
    assert "an initial velocity" in left[0] and "a smaller max_substep" in left[0], left[0]
    result, messages = _run(plant, stop_time=0.5, start_values={"r_0": 30.0, "max_substep": 1e-4})
    assert result is not None and messages == [], messages


@pytest.mark.parametrize("name", sorted(FMUS))
def test_angles_offer_degrees_as_their_display_unit(name, fmu_paths):
    """A tool shows and takes a variable in its displayUnit: every angle (rad) and turn rate
    (rad/s) offers degrees (deg, deg/s; FMI 2.0 DisplayUnit, value_deg = factor * value_rad),
    so a user types 30 deg where the FMU takes 0.5236 rad. A natural frequency in rad/s
    (declared ``quantity="AngularFrequency"``: command_filter_frequency, 10 rad/s, was shown
    as 573 deg/s) and the sliding mode's reaching rate are no turn rates: no display unit."""
    md = read_model_description(str(fmu_paths[name]))
    factors = {
        (unit.name, display.name): display.factor
        for unit in md.unitDefinitions
        for display in unit.displayUnits
    }
    frequencies = {"AuvAutopilot": ["smc_eta", "command_filter_frequency"],
                   "AuvPlant": ["mass_natural_frequency"]}.get(name, [])  # fmt: skip
    shown = [v for v in md.modelVariables if v.name in frequencies]
    assert [(v.name, v.displayUnit) for v in shown] == [(n, None) for n in frequencies]
    angles = [
        v for v in md.modelVariables if v.unit in ("rad", "rad/s") and v.name not in frequencies
    ]
    assert angles
    for variable in angles:
        expected = {"rad": "deg", "rad/s": "deg/s"}[variable.unit]
        assert variable.displayUnit == expected, variable.name
        assert factors[(variable.unit, expected)] == pytest.approx(math.degrees(1.0), rel=1e-15)


@pytest.mark.parametrize("name", ["AuvPlant", "AuvAutopilot"])
def test_a_vehicle_file_not_found_says_where_a_relative_path_was_looked_for(
    name, fmu_paths, tmp_path, monkeypatch
):
    """A tool runs from a working directory of its own, which its user may not know: a
    relative vehicle path that names no file must say which folder it was taken from, and
    that an absolute path avoids the question."""
    monkeypatch.chdir(tmp_path)
    _, messages = _run(fmu_paths[name], stop_time=0.1, start_values={"vehicle": "mine.toml"})
    refused = [text for _, text in messages if "unknown vehicle 'mine.toml'" in text]
    assert refused, messages
    assert f"the working directory, {tmp_path}" in refused[0], refused[0]
    assert "an absolute path" in refused[0], refused[0]


WRONG_WRITES = """
import sys
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

path = sys.argv[1]
md = read_model_description(path)
vr = {v.name: v.valueReference for v in md.modelVariables}
fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), instanceName="plant",
                modelIdentifier=md.coSimulation.modelIdentifier)
fmu.instantiate()  # fmpy's own logger: the FMU's messages on stdout
for name in ("yaw", "variant"):  # an output, an Integer
    try:
        fmu.setReal([vr[name]], [1.0])
    except Exception:
        pass
fmu.freeInstance()
"""


def test_a_refused_write_names_the_kind_of_variable_in_words(fmu_paths, run_python):
    """A Real written to an output or an Integer (as a host's script can) said "yaw = 1.0
    refused: a output cannot be set" and "variant is a Integer, not a Real"."""
    done = run_python(WRONG_WRITES, fmu_paths["AuvPlant"])
    assert done.returncode == 0, done.stderr[-3000:]
    assert "yaw = 1.0 refused: an output cannot be set" in done.stdout, done.stdout
    assert "variant is an Integer, not a Real" in done.stdout, done.stdout


@pytest.mark.slow  # the autopilot's backstepping compiled in this process first
def test_a_tunable_parameter_an_input_table_rewrites_at_each_step_is_logged_as_it_changes(
    fmu_paths,
):
    """fmpy's ``input=`` table writes a tunable parameter's column at every step, changed
    or not: the autopilot's debug log (logAutopilotTuning) said "the law takes
    heading_mode = 1" at each of them (100 lines for 1 s), burying the one switch. It must
    log the changes only, at the step the law switches."""
    times = np.linspace(0.0, 1.0, 101)  # s
    columns = [("time", float), ("u_rel", float), ("yaw_setpoint", float)]
    table = np.zeros(times.size, dtype=[*columns, ("heading_mode", np.int32)])
    table["time"], table["u_rel"], table["yaw_setpoint"] = times, 1.5, 0.3  # m/s, rad
    table["heading_mode"] = np.where(times < 0.5, 1, 3)  # LQR, then backstepping + thruster
    result, messages = _run(
        fmu_paths["AuvAutopilot"], stop_time=1.0, output_interval=0.01, input=table,
        start_values={"heading_mode": 1}, debug_logging=True, output=["tunnel_force"],
    )  # fmt: skip
    taken = [text for _, text in messages if "the law takes" in text]
    assert taken == ["t = 0.5 s: the law takes heading_mode = 3"], taken[:3]
    thruster = result["tunnel_force"] != 0.0  # the LQR steers with the moving mass only
    assert not thruster[result["time"] <= 0.5].any() and thruster[-1], result


@pytest.mark.slow  # the autopilot's LQR designed in three fresh instances
def test_a_hosts_one_shorter_step_is_not_taken_for_the_communication_step(fmu_paths):
    """fmpy steps at output_interval = design_step (0.01 s) but shortens the last step to
    end at a stop time off its grid, and a step to end at an input table's step: the
    autopilot warned "communication step 0.005 s differs from design_step = 0.01 s ...
    (set it to the communication step)", advice that would design the LQR for the one
    short step instead of all the others. The last step says nothing; a shorter step
    elsewhere says the advice holds only for a host that steps so throughout."""
    autopilot = fmu_paths["AuvAutopilot"]
    start = {"heading_mode": 1, "u_rel": 1.5, "yaw_setpoint": 0.3}  # LQR, m/s, rad
    for stop_time in (1.0, 0.995):  # s: on the grid, off it
        _, messages = _run(autopilot, stop_time=stop_time, output_interval=0.01, start_values=start)
        assert messages == [], (stop_time, messages)
    table = np.zeros(4, dtype=[("time", float), ("yaw_setpoint", float)])
    table["time"], table["yaw_setpoint"] = [0.0, 0.505, 0.505, 1.0], [0.0, 0.0, 0.3, 0.3]
    del start["yaw_setpoint"]
    _, messages = _run(autopilot, stop_time=1.0, output_interval=0.01, start_values=start,
                       input=table)  # fmt: skip
    warned = [text for status, text in messages if status == STATUS_WARNING]
    assert len(warned) == 1 and "0.005" in warned[0], messages
    assert "if the host steps so throughout" in warned[0], warned[0]


# One fmpy call with a logger of its own, then one with none: the plant's Warning of
# the second (the hull out of the water, at 1.4 s) goes to the first call's logger.
LOGGER_OF_AN_EARLIER_CALL = """
import sys
from fmpy import simulate_fmu

def first(_component, _instance, _status, _category, message):
    print("the first call's logger got:", message.decode(), flush=True)

simulate_fmu(sys.argv[1], stop_time=0.1, output_interval=0.01, logger=first)
simulate_fmu(sys.argv[1], stop_time=2.0, output_interval=0.01)
"""


@pytest.mark.slow  # the plant loaded twice in a fresh process
def test_fmpy_gives_a_later_call_without_a_logger_the_logger_of_an_earlier_one(
    fmu_paths, run_python
):
    """docs/hosts.md warns that fmpy 0.3.25's native logging proxy keeps one logger for the
    whole process: a call with ``logger=`` makes it the logger of every FMU instance
    created after it, one with no ``logger=`` too, so a message after that function is gone
    crashes the host. If fmpy changes that, this fails and the warning goes."""
    done = run_python(LOGGER_OF_AN_EARLIER_CALL, fmu_paths["AuvPlant"])
    assert done.returncode == 0, done.stderr[-3000:]
    got = "the first call's logger got: at t = 1.4 s the hull is out of the water"
    assert got in done.stdout, done.stdout
