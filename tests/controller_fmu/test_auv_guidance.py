"""AuvGuidance.fmu through fmpy: its variables, outputs equal to the in-process guidance
step for step, FMU state save/restore, and bad waypoints or inputs reported with their
reason (a failed initialisation, then Discard) while the host survives."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmu_harness import STATUS_DISCARD, STATUS_ERROR, STATUS_OK, Harness, status_of
from reference_values import dissertation

from controller_fmu.auv_guidance import INPUTS, OUTPUTS
from controller_fmu.los_guidance import GuidanceConfig, LosGuidance, field_unit
from cosim.fmus.validation import validate_fmus

H = 0.01
MISSION = "0, 0, 2; 30, 0, 2; 30, 15, 4; 0, 15, 4"
SETTINGS = {"lookahead": 6.0, "acceptance_radius": 3.0, "integral_gain": 0.4}


@pytest.fixture(scope="module")
def guidance_fmu(fmu_paths) -> Path:
    return fmu_paths["AuvGuidance"]


@pytest.fixture(scope="module")
def unzip_dir(guidance_fmu: Path) -> str:
    return extract(str(guidance_fmu))


def _guidance(guidance_fmu, unzip_dir, **values) -> Harness:
    return Harness(guidance_fmu, instance="guidance", unzip_dir=unzip_dir, **values)


def _path(t: float) -> tuple[float, float, float]:
    """(north, east, yaw): a position history that flies (roughly) the mission, and a yaw
    that turns on past several whole turns (the set-points follow its branch)."""
    return 1.5 * t + 0.8 * math.sin(0.3 * t), 0.6 * max(0.0, t - 18.0) - 0.5, 0.25 * t - 1.0


@pytest.mark.slow
def test_variables_follow_the_guidance_config(guidance_fmu):
    md = read_model_description(str(guidance_fmu))
    assert md.coSimulation.modelIdentifier == "AuvGuidance"
    variables = {v.name: v for v in md.modelVariables}
    by_causality: dict[str, set[str]] = {}
    for var in md.modelVariables:
        by_causality.setdefault(var.causality, set()).add(var.name)
        assert var.description, var.name
    assert by_causality["input"] == set(INPUTS)
    assert by_causality["output"] == set(OUTPUTS)
    assert by_causality["parameter"] == set(GuidanceConfig.field_info())
    for name, field in GuidanceConfig.field_info().items():
        if field.kind is float:
            assert variables[name].unit == field_unit(name), name
    assert variables["waypoints"].type == "String"
    assert variables["compensate_current"].type == "Boolean"
    # named like the autopilot's inputs, so a master connects them by default
    assert {"yaw_setpoint", "depth_setpoint"} <= by_causality["output"]
    assert all(not unknown.dependencies for unknown in md.outputs)  # sampled: no feedthrough
    assert validate_fmus({"AuvGuidance": guidance_fmu}) == []


@pytest.mark.slow
def test_outputs_equal_the_in_process_guidance_step_for_step(guidance_fmu, unzip_dir):
    fmu = _guidance(guidance_fmu, unzip_dir, waypoints=MISSION, **SETTINGS)
    reference = LosGuidance(GuidanceConfig.build(waypoints=MISSION, **SETTINGS))
    rows, expected = [], []
    for k in range(round(60.0 / H)):
        north, east, yaw = _path(k * H)
        fmu.set(north=north, east=east, yaw=yaw)
        assert fmu.step(H) == STATUS_OK, fmu.messages(3)
        rows.append(fmu.get_all(OUTPUTS))
        out = reference.step(north, east, step=H, yaw=yaw)
        expected.append([out.yaw_setpoint, out.depth_setpoint, out.course_setpoint,
                         out.cross_track_error, out.legs_completed, out.target.north,
                         out.target.east, out.target.down])  # fmt: skip
    fmu.close()
    rows, expected = np.array(rows), np.array(expected)
    np.testing.assert_array_equal(rows, expected)
    legs = rows[:, list(OUTPUTS).index("legs_completed")]
    assert legs[-1] == 2 and np.all(np.diff(legs) >= 0)  # two legs flown, none undone
    assert np.ptp(rows[:, list(OUTPUTS).index("depth_setpoint")]) == pytest.approx(2.0)
    yaw = np.array([_path(k * H)[2] for k in range(len(rows))])
    offset = rows[:, list(OUTPUTS).index("yaw_setpoint")] - yaw
    assert np.abs(offset).max() <= math.pi and np.ptp(yaw) > 4.0 * math.pi


@pytest.mark.slow
def test_restored_state_continues_bit_identically(guidance_fmu, unzip_dir):
    fmu = _guidance(guidance_fmu, unzip_dir, waypoints=MISSION, **SETTINGS)

    def drive(steps: int) -> np.ndarray:
        rows = []
        for _ in range(steps):
            fmu.set(**dict(zip(("north", "east", "yaw"), _path(fmu.time), strict=True)))
            assert fmu.step(H) == STATUS_OK, fmu.messages(3)
            rows.append(fmu.get_all(OUTPUTS))
        return np.array(rows)

    drive(1500)  # on the second leg, the integral running
    state = fmu.slave.getFMUstate()
    serialized = fmu.slave.serializeFMUstate(state)
    t_saved = fmu.time
    first = drive(1000)
    fmu.slave.setFMUstate(state)
    fmu.time = t_saved
    np.testing.assert_array_equal(drive(1000), first)
    fmu.slave.setFMUstate(fmu.slave.deSerializeFMUstate(serialized))
    fmu.time = t_saved
    np.testing.assert_array_equal(drive(1000), first)
    fmu.slave.freeFMUstate(state)
    fmu.close()


def test_a_bad_waypoint_fails_initialisation_naming_the_entry(guidance_fmu, unzip_dir):
    fmu = Harness(guidance_fmu, instance="guidance", unzip_dir=unzip_dir, initialize=False)
    statuses = fmu.try_initialize(waypoints="0, 0, 2; 30, 0, 2; 30, x, 4")
    assert statuses == (STATUS_OK, STATUS_ERROR)  # initialisation fails: fmi2Error
    assert "initialisation failed: waypoint 3 ('30, x, 4'): east = 'x' is not a finite" in (
        fmu.messages(3)
    )
    assert fmu.step(H) == STATUS_ERROR  # the instance is in the error state
    assert "doStep at t = 0.0 s refused: the FMU is in the error state" in fmu.messages(3)
    fmu.close()


def test_a_nan_position_is_refused_and_the_next_valid_one_accepted(guidance_fmu, unzip_dir):
    fmu = _guidance(guidance_fmu, unzip_dir, waypoints=MISSION)
    assert status_of(fmu.set, north=float("nan")) == STATUS_ERROR
    assert "north = nan refused: expected a finite number" in fmu.messages(3)
    fmu.set(north=1.0)
    assert fmu.step(H) == STATUS_OK
    assert np.isfinite(fmu.get_all(OUTPUTS)).all()
    fmu.close()


def test_a_cross_current_faster_than_the_vehicle_is_a_discard(guidance_fmu, unzip_dir):
    fmu = _guidance(guidance_fmu, unzip_dir, waypoints=MISSION, compensate_current=True)
    fmu.set(current_east=dissertation("current.speed"))
    assert fmu.step(H) == STATUS_OK
    yaw = fmu.get("yaw_setpoint")[0]
    printed = dissertation("current.heading_9_newton")  # (6.3.74): the first leg runs north
    assert math.degrees(yaw) == pytest.approx(printed, abs=0.02)
    fmu.set(current_east=3.0)
    assert fmu.step(H) == STATUS_DISCARD
    assert "cross-current 3 m/s is not slower than the design speed" in fmu.messages(3)
    assert fmu.get("yaw_setpoint")[0] == yaw  # the outputs of the last good step stay
    fmu.close()
