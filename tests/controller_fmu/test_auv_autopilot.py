"""AuvAutopilot.fmu through fmpy : coupled to AuvPlant.fmu by a minimal
loop it reproduces the in-process closed loop (bs-3) to 1e-9; its variables match the
contract; FMU state save/restore; bad input gives a non-OK status with a logged reason and
the host survives."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.validation import validate_fmu
from fmu_harness import STATUS_DISCARD, STATUS_ERROR, STATUS_OK, Harness, status_of

from controller_fmu.autopilot import (
    COMMAND_NAMES,
    MEASUREMENT_NAMES,
    TUNABLE_PARAMETERS,
    Autopilot,
    AutopilotConfig,
    field_unit,
)
from cosim.analysis.closed_loop import simulate_closed_loop
from cosim.fmus.validation import validate_fmus
from plant_fmu.model.dynamics import STATE_NAMES, PlantModel, Variant
from plant_fmu.model.linearization import state_vector
from plant_fmu.model.parameters import load_vehicle

H = 0.01
# The controller inputs the plant FMU provides (the current and set-points stay at 0 here).
PLANT_OUTPUTS = [
    n for n in MEASUREMENT_NAMES if not n.endswith("_setpoint") and not n.startswith("current_")
]


@pytest.fixture(scope="module")
def autopilot_fmu(fmu_paths) -> Path:
    return fmu_paths["AuvAutopilot"]


@pytest.fixture(scope="module")
def unzip_dirs(fmu_paths) -> dict[str, str]:
    return {name: extract(str(path)) for name, path in fmu_paths.items()}


def _controller(fmu_paths, unzip_dirs, instance="controller", **values) -> Harness:
    path = fmu_paths["AuvAutopilot"]
    return Harness(path, instance=instance, unzip_dir=unzip_dirs["AuvAutopilot"], **values)


@pytest.mark.slow
def test_fmu_closed_loop_reproduces_the_in_process_bs3_to_1e_9(fmu_paths, unzip_dirs):
    """The scenarios' coupling: each step the controller samples the plant's outputs at t,
    then the plant steps with the new commands (Gauss-Seidel, controller first)."""
    stop_time = 20.0
    plant = Harness(
        fmu_paths["AuvPlant"], unzip_dir=unzip_dirs["AuvPlant"], variant=1, u_0=1.5, v_0=-0.1
    )
    controller = _controller(fmu_paths, unzip_dirs, heading_mode=3)
    states = [plant.get_all(STATE_NAMES)]
    for _ in range(round(stop_time / H)):
        controller.set(**dict(zip(PLANT_OUTPUTS, plant.get_all(PLANT_OUTPUTS), strict=True)))
        assert controller.step(H) == STATUS_OK, controller.messages(3)
        plant.set(**dict(zip(COMMAND_NAMES, controller.get_all(COMMAND_NAMES), strict=True)))
        assert plant.step(H) == STATUS_OK, plant.messages(3)
        states.append(plant.get_all(STATE_NAMES))
    plant.close()
    controller.close()

    reference = simulate_closed_loop(
        Autopilot(AutopilotConfig.build(heading_mode=3)),
        PlantModel(load_vehicle("remus100"), variant=Variant.LATERAL),
        state_vector({"u": 1.5, "v": -0.1}),
        stop_time,
        H,
    )
    np.testing.assert_allclose(np.array(states), reference.states, rtol=0.0, atol=1e-9)
    assert np.abs(np.degrees(reference.state("yaw")[-500:])).max() < 1.0  # it did settle


@pytest.mark.slow
def test_variables_follow_the_contract(autopilot_fmu):
    md = read_model_description(str(autopilot_fmu))
    assert md.coSimulation.modelIdentifier == "AuvAutopilot"
    by_causality: dict[str, set[str]] = {}
    for var in md.modelVariables:
        by_causality.setdefault(var.causality, set()).add(var.name)
        assert var.description, var.name
    assert by_causality["input"] == set(MEASUREMENT_NAMES)
    assert by_causality["output"] == set(COMMAND_NAMES)
    assert by_causality["parameter"] == set(AutopilotConfig.field_info())
    variables = {v.name: v for v in md.modelVariables}
    for name, field in AutopilotConfig.field_info().items():
        if field.kind is float:
            assert variables[name].unit == field_unit(name), name
        tunable = name in TUNABLE_PARAMETERS
        assert variables[name].variability == ("tunable" if tunable else "fixed"), name
    assert variables["heading_mode"].type == "Integer"
    assert variables["compensate_current"].type == "Boolean"
    assert variables["vehicle"].type == "String"
    # Sampled outputs: none depends directly on an input (no algebraic loop for importers).
    assert all(not unknown.dependencies for unknown in md.outputs)
    assert validate_fmu(str(autopilot_fmu)) == []
    assert validate_fmus({"AuvAutopilot": autopilot_fmu}) == []


@pytest.mark.slow
def test_restored_state_continues_bit_identically(fmu_paths, unzip_dirs):
    controller = _controller(fmu_paths, unzip_dirs, heading_mode=3, k0=0.3, k1=0.8)

    def drive(steps: int) -> np.ndarray:
        rows = []
        for k in range(steps):
            t = controller.time
            controller.set(yaw=0.2 * np.cos(t), v_rel=-0.05 + 0.01 * k / steps, r=0.01, roll=0.1)
            assert controller.step(H) == STATUS_OK, controller.messages(3)
            rows.append(controller.get_all(COMMAND_NAMES))
        return np.array(rows)

    drive(100)
    state = controller.slave.getFMUstate()
    serialized = controller.slave.serializeFMUstate(state)
    t_saved = controller.time
    first = drive(100)
    controller.slave.setFMUstate(controller.slave.deSerializeFMUstate(serialized))
    controller.time = t_saved
    again = drive(100)
    controller.slave.freeFMUstate(state)
    controller.close()
    assert np.array_equal(first, again)
    assert np.abs(first[:, 1]).max() > 0.0  # the thruster was active


@pytest.mark.slow
def test_heading_mode_and_mass_lock_are_tunable_while_stepping(fmu_paths, unzip_dirs):
    """Written between steps, heading_mode and mass_lock_time apply at the next doStep (and
    a restored state brings back the mode it was saved in); a fixed parameter is refused."""
    controller = _controller(fmu_paths, unzip_dirs, heading_mode=0)
    controller.set(yaw=0.3, v_rel=-0.1, u_rel=1.5)

    def commands() -> np.ndarray:
        assert controller.step(H) == STATUS_OK, controller.messages(3)
        return controller.get_all(COMMAND_NAMES)

    off = commands()
    state = controller.slave.getFMUstate()
    t_saved = controller.time
    controller.set(heading_mode=3)
    steering = commands()
    controller.set(mass_lock_time=controller.time)
    locked = commands()
    assert off[:2].tolist() == [0.0, 0.0]
    assert steering[0] != 0.0 and steering[1] != 0.0
    assert locked[0] == 0.0 and locked[1] != 0.0  # the thruster still steers
    assert status_of(controller.set, k0=0.3) == STATUS_ERROR
    assert "k0 = 0.3 refused: a fixed parameter" in controller.messages(3)
    controller.slave.setFMUstate(state)  # back to heading off, mass free
    controller.time = t_saved
    assert commands()[:2].tolist() == [0.0, 0.0]
    controller.slave.freeFMUstate(state)
    controller.close()


@pytest.mark.slow
def test_a_step_other_than_the_design_step_is_logged_as_a_warning(fmu_paths, unzip_dirs):
    controller = _controller(fmu_paths, unzip_dirs, heading_mode=1, design_step=0.01)
    assert controller.step(0.02) == STATUS_OK
    controller.close()
    assert "differs from design_step = 0.01" in controller.messages(1)


@pytest.mark.slow
def test_a_shorter_step_is_logged_when_no_stop_time_is_defined(fmu_paths, unzip_dirs):
    """Without a stop time from setupExperiment (the harness defines none) no step ends
    at one: a host stepping 0.005 s throughout, half the design step, must still hear
    that the LQR gains are designed for another step."""
    controller = _controller(fmu_paths, unzip_dirs, heading_mode=1, design_step=0.01)
    assert controller.step(0.005) == STATUS_OK
    controller.close()
    assert "communication step 0.005 s differs from design_step = 0.01" in controller.messages(1)


@pytest.mark.slow
def test_a_step_longer_than_the_sample_period_is_logged_as_a_warning(fmu_paths, unzip_dirs):
    """A digital LQR (sample_period = design_step = 0.01 s) stepped every 0.04 s samples
    every 0.04 s, and did so without a word (lqr-1 --step 0.04: the mass to its stops)."""
    controller = _controller(
        fmu_paths, unzip_dirs, heading_mode=1, design_step=0.01, sample_period=0.01
    )
    assert controller.step(0.04) == STATUS_OK
    controller.close()
    assert "communication step 0.04 s differs from design_step = 0.01" in controller.messages(1)


@pytest.mark.slow
def test_nan_measurement_is_refused_and_the_host_survives(autopilot_fmu, run_python):
    result = run_python(
        """
        import json, sys
        from fmu_harness import Harness, status_of
        fmu = Harness(sys.argv[1], instance="controller", heading_mode=3)
        ok = fmu.step(0.01)
        refused = status_of(fmu.set, v_rel=float("nan"))
        after = fmu.step(0.01)  # discarded: it would use the measurement it had
        fmu.set(v_rel=0.01)
        recovered = fmu.step(0.01)
        commands = fmu.get("mass_position_cmd", "tunnel_force").tolist()
        fmu.close()
        print(json.dumps(dict(ok=ok, refused=refused, after=after, recovered=recovered,
                              commands=commands, errors=fmu.messages(3))))
        """,
        autopilot_fmu,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    statuses = (report["ok"], report["refused"], report["after"], report["recovered"])
    assert statuses == (STATUS_OK, STATUS_ERROR, STATUS_DISCARD, STATUS_OK)
    assert "v_rel = nan refused" in report["errors"]
    assert "so the step would use the value before it" in report["errors"]
    assert all(np.isfinite(report["commands"]))


@pytest.mark.slow
def test_unknown_heading_mode_is_refused_with_the_reason_and_the_host_survives(
    autopilot_fmu, run_python
):
    result = run_python(
        """
        import json, sys
        from fmu_harness import Harness
        fmu = Harness(sys.argv[1], instance="controller", initialize=False)
        statuses = fmu.try_initialize(heading_mode=7)
        status = fmu.step(0.01)  # discarded: it would use the heading mode it had
        fmu.close()
        print(json.dumps(dict(statuses=statuses, status=status, errors=fmu.messages(3))))
        """,
        autopilot_fmu,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert (report["statuses"], report["status"]) == ([STATUS_ERROR, STATUS_OK], STATUS_DISCARD)
    assert "heading_mode = 7 refused: expected 0 <= heading_mode <= 3" in report["errors"]
