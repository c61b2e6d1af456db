"""AuvPlant.fmu through fmpy : equilibria of Examples 5.1 and 5.3,
equality with the in-process model, energy conservation, state save/restore, bad input,
independent instances and a complete, valid modelDescription.xml."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.validation import validate_fmu
from fmu_harness import STATUS_DISCARD, STATUS_ERROR, STATUS_OK, Harness, status_of
from reference_values import dissertation

from cosim.fmus.validation import validate_fmus
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import STATE_NAMES, PlantModel, Variant
from plant_fmu.model.kinematics import quaternion_from_euler
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import VehicleParameters, builtin_vehicles, load_vehicle
from plant_fmu.model.stepping import MAX_SUBSTEPS, advance, simulate

H = 0.01
OUTPUTS = (*STATE_NAMES, "u_rel", "v_rel", "w_rel", "kinetic_energy")


@pytest.fixture(scope="module")
def plant(fmu_paths) -> Path:
    return fmu_paths["AuvPlant"]


@pytest.fixture(scope="module")
def unzip_dir(plant) -> str:
    return extract(str(plant))


def _harness(plant, unzip_dir, instance="plant", **values) -> Harness:
    return Harness(plant, instance=instance, unzip_dir=unzip_dir, **values)


# --- dissertation examples and equality with the in-process model ---------------------------


@pytest.mark.slow
@pytest.mark.parametrize(
    ("variant", "names", "printed", "tolerance"),
    [
        # Example 5.1 (T = 9 N): the stable turning equilibrium [u, v, r], printed to 3-4
        # digits (u = 1.282: ours is 1.2821).
        (Variant.HORIZONTAL, ("u", "v", "r"), "example_5_1.turn_positive_v", 2e-4),
        # Example 5.3 (lateral 5-DOF): [u, v, r, p, phi], printed to 3-4 digits.
        (Variant.LATERAL, ("u", "v", "r", "p", "roll"), "example_5_3.turn_positive_v", 5e-4),
    ],
)
def test_simulate_fmu_settles_on_the_dissertation_equilibrium_like_the_model(
    plant, remus, variant, names, printed, tolerance
):
    result = simulate_fmu(
        str(plant),
        start_values={"variant": int(variant), "v_0": 0.01},
        stop_time=60.0,
        output_interval=H,
    )
    final = np.array([result[n][-1] for n in names])
    np.testing.assert_allclose(final, dissertation(printed), atol=tolerance)

    _, states = simulate(
        PlantModel(remus, variant), state_vector(dict(v=0.01)), input_vector(thrust=9.0), 60.0, H
    )
    fmu_states = np.column_stack([result[n] for n in STATE_NAMES])
    assert fmu_states.shape == states.shape
    assert np.max(np.abs(fmu_states - states)) <= 1e-12


@pytest.mark.slow
def test_ideal_fluid_with_neutral_buoyancy_conserves_kinetic_energy(plant, unzip_dir):
    fmu = _harness(
        plant, unzip_dir, ideal_fluid=True, B=298.9, W=298.9, z_g=0.0, thrust=0.0,
        u_0=1.5, v_0=0.1, w_0=0.05, p_0=0.2, q_0=0.05, r_0=0.2,
    )  # fmt: skip
    energy_0 = fmu.get("kinetic_energy")[0]
    rows = fmu.run(60.0, H, ("kinetic_energy", "r", "roll"))
    fmu.close()
    assert energy_0 > 30.0
    assert np.max(np.abs(rows[:, 0] - energy_0)) < 1e-6
    assert np.ptp(rows[:, 1]) > 0.3 and np.ptp(rows[:, 2]) > 1.0  # it really tumbles


def test_restored_state_continues_bit_identically(plant, unzip_dir):
    fmu = _harness(plant, unzip_dir, variant=1, u_0=1.5, v_0=-0.05)
    fmu.set(mass_position_cmd=0.03, tunnel_force=2.0)
    fmu.run(5.0, H, ())

    def to_ten_seconds() -> np.ndarray:
        first = fmu.run(2.0, H, OUTPUTS)
        fmu.set(current_east=0.2)  # a current step at 7 s exercises the jump bookkeeping
        second = fmu.run(3.0, H, OUTPUTS)
        fmu.set(current_east=0.0)
        return np.vstack([first, second])

    saved = fmu.slave.getFMUstate()
    serialized = fmu.slave.serializeFMUstate(saved)
    original = to_ten_seconds()
    fmu.slave.setFMUstate(saved)
    fmu.time = 5.0
    replay = to_ten_seconds()
    fmu.slave.setFMUstate(fmu.slave.deSerializeFMUstate(serialized))
    fmu.time = 5.0
    replay_serialized = to_ten_seconds()
    fmu.close()
    assert np.array_equal(original, replay)
    assert np.array_equal(original, replay_serialized)
    assert np.ptp(original[:, OUTPUTS.index("yaw")]) > 0.01  # the state did evolve


def test_the_current_is_the_velocity_the_water_moves_towards_as_documented(
    plant, unzip_dir, fmu_paths
):
    """The current's inputs read "uniform current, north component, earth frame": a tidal
    planner cannot tell from that whether +current_east is water moving towards the east
    (oceanographic) or coming from it (meteorological). The descriptions say "towards",
    and a hull without thrust, left in the current, drifts that way."""
    for fmu_name in ("AuvPlant", "AuvAutopilot", "AuvGuidance"):
        md = read_model_description(str(fmu_paths[fmu_name]))
        for v in md.modelVariables:
            if v.name in ("current_north", "current_east", "current_down"):
                assert "moves towards" in v.description, (fmu_name, v.name, v.description)
    fmu = _harness(plant, unzip_dir, variant=0, u_0=0.0, thrust=0.0, down_0=2.0,
                   current_north=0.3, current_east=-0.4)  # fmt: skip
    fmu.run(30.0, H, ())
    north, east = fmu.get("north", "east")
    fmu.close()
    # the water moves 15 m in 30 s, bearing 307 deg; the hull, from rest, drifts that way
    # (within 10 deg: the buoyant hull rises, and glides a little through the water)
    assert np.hypot(north, east) > 0.5 * 15.0
    bearing = np.degrees(np.arctan2(east, north)) % 360.0
    assert bearing == pytest.approx(np.degrees(np.arctan2(-0.4, 0.3)) % 360.0, abs=10.0)


def test_an_ignored_current_is_warned_of_once_however_often_the_plant_initialises(plant, unzip_dir):
    """A lateral plant given current_down = 0.3 m/s: the run printed "plant logged:
    [Warning] variant 1 (lateral) ignores the input(s) current_down" twice, as a master
    that reads an output in initialisation mode and then writes a start value makes the
    plant initialise twice. One warning, naming the input, whatever the order."""
    fmu = _harness(plant, unzip_dir, initialize=False)
    fmu.slave.setupExperiment(startTime=0.0)
    fmu.slave.enterInitializationMode()
    fmu.set(variant=1, current_down=0.3)
    fmu.get("u_rel")  # a read in initialisation mode initialises the plant
    fmu.set(thrust=9.0)  # a write after it: initialised again as it leaves the mode
    fmu.slave.exitInitializationMode()
    fmu.initialised = True
    fmu.close()
    warned = [text for _, text in fmu.log if "ignores the input(s) current_down" in text]
    assert len(warned) == 1, fmu.log


def test_current_step_applies_the_velocity_jump_at_the_next_step(plant, unzip_dir, remus):
    fmu = _harness(plant, unzip_dir, variant=1, u_0=1.5)
    fmu.run(1.0, H, ())
    before = fmu.get_all(STATE_NAMES)
    relative_before = fmu.get("u_rel", "v_rel")
    fmu.set(current_east=0.2)
    # Outputs are held over the step: setting an input changes no output (dependencies "").
    assert np.array_equal(fmu.get_all(STATE_NAMES), before)
    assert np.array_equal(fmu.get("u_rel", "v_rel"), relative_before)
    after = fmu.run(H, H, STATE_NAMES)[0]
    fmu.close()

    model = PlantModel(remus, Variant.LATERAL)
    inputs = input_vector(dict(current_east=0.2), thrust=9.0)
    x = before.copy()
    jump = model.current_change_velocity_jump(x, np.array([0.0, 0.2, 0.0]))
    x[6:12] += jump
    assert abs(jump[1]) > 0.1  # the hull is carried along with the water
    np.testing.assert_array_equal(after, advance(model, x, inputs, H, compiled=_fmu_path(model)))


def test_mass_command_of_five_metres_stays_within_the_stroke(plant, unzip_dir):
    fmu = _harness(plant, unzip_dir, variant=1, u_0=1.5, mass_position_cmd=5.0)
    positions = fmu.run(10.0, H, ("mass_position",))[:, 0]
    fmu.close()
    assert np.max(np.abs(positions)) <= 0.06
    assert positions[-1] == pytest.approx(0.06)


def test_two_instances_with_different_parameters_are_independent(plant, unzip_dir, remus):
    slow = _harness(plant, unzip_dir, "slow", variant=2, v_0=0.01, thrust=4.0)
    heavy = _harness(plant, unzip_dir, "heavy", variant=2, v_0=0.01, m=35.0, W=343.0)
    rows_slow, rows_heavy = [], []
    for _ in range(500):
        rows_slow.append(slow.run(H, H, STATE_NAMES)[0])
        rows_heavy.append(heavy.run(H, H, STATE_NAMES)[0])
    slow.close()
    heavy.close()
    x0 = state_vector(dict(v=0.01))
    slow_model = PlantModel(remus, Variant.HORIZONTAL)
    heavy_model = PlantModel(remus.replace(m=35.0, W=343.0), Variant.HORIZONTAL)
    _, expected_slow = _simulate_as_fmu(slow_model, x0, input_vector(thrust=4.0), 5.0)
    _, expected_heavy = _simulate_as_fmu(heavy_model, x0, input_vector(thrust=9.0), 5.0)
    np.testing.assert_array_equal(np.array(rows_slow), expected_slow[1:])
    np.testing.assert_array_equal(np.array(rows_heavy), expected_heavy[1:])


def test_vehicle_picks_the_set_and_written_parameters_override_it(plant, unzip_dir):
    printed = load_vehicle("remus100-printed")
    fmu = _harness(plant, unzip_dir, vehicle="remus100-printed", variant=0, X_uu=-5.0, u_0=1.5)
    in_use = fmu.get("M_uq", "X_uu")
    rows = fmu.run(2.0, H, STATE_NAMES)
    fmu.close()
    assert in_use[0] == printed.M_uq != load_vehicle("remus100").M_uq
    assert in_use[1] == -5.0
    model = PlantModel(printed.replace(X_uu=-5.0), Variant.FULL)
    _, expected = _simulate_as_fmu(model, state_vector(dict(u=1.5)), input_vector(thrust=9.0), 2.0)
    np.testing.assert_array_equal(rows, expected[1:])


@pytest.mark.slow
@pytest.mark.parametrize("moving_mass_model", [0, 1])
def test_moving_mass_model_is_selected_by_its_parameter(plant, unzip_dir, remus, moving_mass_model):
    """The FMU runs the model it is asked for, bit for bit (model 0 is the default)."""
    values = dict(variant=1, u_0=1.5, v_0=-0.05, mass_position_cmd=0.04, roll_torque=0.2)
    if moving_mass_model:
        values["moving_mass_model"] = moving_mass_model
    fmu = _harness(plant, unzip_dir, **values)
    rows = fmu.run(3.0, H, STATE_NAMES)
    fmu.close()
    x0 = state_vector(dict(u=1.5, v=-0.05))
    inputs = input_vector(dict(thrust=9.0, mass_position_cmd=0.04, roll_torque=0.2))
    expected = {
        m: _simulate_as_fmu(
            PlantModel(remus, Variant.LATERAL, moving_mass_model=m), x0, inputs, 3.0
        )[1]
        for m in (0, 1)
    }
    np.testing.assert_array_equal(rows, expected[moving_mass_model][1:])
    assert np.max(np.abs(expected[1] - expected[0])) > 1e-4  # the two models differ


def test_reset_returns_to_a_fresh_instance(plant, unzip_dir):
    fmu = _harness(plant, unzip_dir, variant=2, v_0=0.01)
    first = fmu.run(1.0, H, STATE_NAMES)
    fmu.slave.reset()
    fmu.initialize(variant=2, v_0=0.01)
    again = fmu.run(1.0, H, STATE_NAMES)
    fmu.close()
    np.testing.assert_array_equal(first, again)


@pytest.mark.parametrize(
    ("variant", "frozen"), [(1, {"pitch_0": 0.3}), (2, {"roll_0": 0.3, "pitch_0": -0.2})]
)
def test_initial_quaternion_is_the_attitude_of_the_angles_a_reduced_variant_keeps(
    plant, unzip_dir, variant, frozen
):
    """A reduced variant holds its frozen angles at 0 (and warns that their start values
    are ignored): the quaternion it outputs at t = 0, which the recording draws the
    vehicle with, is then that of the roll, pitch and yaw it outputs, not of the start
    values it ignored."""
    fmu = _harness(plant, unzip_dir, variant=variant, u_0=1.5, yaw_0=0.4, **frozen)
    euler = fmu.get("roll", "pitch", "yaw")
    quaternion = fmu.get("quat_w", "quat_x", "quat_y", "quat_z")
    warnings = fmu.messages(1)
    fmu.close()
    assert "their initial values are ignored" in warnings
    assert euler[1] == 0.0 and euler[2] == 0.4
    np.testing.assert_allclose(quaternion, quaternion_from_euler(*euler), atol=1e-15)


# --- bad input ---------------------------------------------------------------------------------


def test_unknown_vehicle_fails_initialisation_listing_the_known_sets(plant, unzip_dir):
    fmu = Harness(plant, unzip_dir=unzip_dir, initialize=False)
    statuses = fmu.try_initialize(vehicle="remus999")
    status = fmu.step(H)
    errors = fmu.messages(3)
    fmu.close()
    assert statuses == (STATUS_OK, STATUS_ERROR)  # initialisation fails: fmi2Error
    assert status == STATUS_ERROR  # then the instance is in the error state
    assert "initialisation failed" in errors and "remus999" in errors
    assert all(name in errors for name in builtin_vehicles())


def test_a_hull_rising_out_of_the_water_is_warned_of_once_when_it_leaves(plant, unzip_dir, remus):
    """The model has no free surface: a buoyant vehicle at rest rises through the surface
    and on into the air with the buoyancy, added mass and drag of a submerged hull. It did
    so silently; the plant now logs one Warning, at the step after which the whole hull is
    above the surface (down < -diameter / 2), naming the time, the depth and the missing
    free surface, and steps on (the results are the model's, flagged)."""
    fmu = _harness(plant, unzip_dir, thrust=0.0)
    top = -remus.diameter / 2
    depths = fmu.run(3.0, H, ["down"])[:, 0]
    fmu.close()
    out = int(np.flatnonzero(depths < top)[0])  # the first step after which it is out
    warned = [text for status, text in fmu.log if status == 1 and "free surface" in text]
    assert len(warned) == 1, fmu.log
    assert f"t = {(out + 1) * H:.6g} s" in warned[0], (warned, out)
    assert f"down = {depths[out]:.4g} m" in warned[0], (warned, depths[out])


def test_a_hull_top_breaking_the_surface_from_below_is_warned_of_once(plant, unzip_dir, remus):
    """The model has no free surface, so a hull part out of the water keeps the buoyancy
    of a submerged one; the plant warned only once the whole hull had left the water
    (down < -diameter / 2), some steps after it first broke the surface. A hull that
    started with its top under water now gets one Warning at the step after which its
    top is above the surface (down < diameter / 2), naming the time and the depth; one
    starting there (down_0 = 0, vert-1's set-up, the dissertation's own) does not."""
    fmu = _harness(plant, unzip_dir, thrust=0.0, down_0=0.3)
    depths = fmu.run(3.0, H, ["down"])[:, 0]
    fmu.close()
    top = remus.diameter / 2
    broken = int(np.flatnonzero(depths < top)[0])  # the first step after which it is out
    warned = [text for status, text in fmu.log if status == 1 and "breaks the surface" in text]
    assert len(warned) == 1, fmu.log
    assert f"t = {(broken + 1) * H:.6g} s" in warned[0], (warned, broken)
    assert f"down = {depths[broken]:.4g} m < diameter/2 = {top:g} m" in warned[0], warned
    assert "free surface" in warned[0], warned
    at_surface = _harness(plant, unzip_dir, thrust=0.0, down_0=0.0)
    at_surface.run(1.0, H, ["down"])
    at_surface.close()
    assert not [text for _, text in at_surface.log if "breaks the surface" in text]


def test_a_start_above_the_surface_is_warned_of_as_the_plant_initialises(plant, unzip_dir, remus):
    """down_0 = -1 m starts the hull in the air, where the model has no surface to know:
    a Warning as the plant initialises, naming down_0; a start at the surface (down_0 = 0,
    vert-1's, half the hull out) is the dissertation's own and is not warned of."""
    fmu = _harness(plant, unzip_dir, down_0=-1.0)
    fmu.close()
    at_surface = _harness(plant, unzip_dir, down_0=0.0)
    at_surface.close()
    warned = [text for status, text in fmu.log if status == 1 and "free surface" in text]
    assert len(warned) == 1 and "down_0 = -1 m" in warned[0], fmu.log
    assert f"(down < -diameter/2 = {-remus.diameter / 2:g} m)" in warned[0], warned
    assert not [text for _, text in at_surface.log if "free surface" in text], at_surface.log


def test_a_start_pitch_beyond_90_deg_is_refused_naming_the_same_attitude_within_it(
    plant, unzip_dir
):
    """The plant's Euler angles keep |pitch| <= 90 deg (the other triple of the same
    attitude has roll and yaw turned by 180 deg). pitch_0 = 2 rad initialised and output
    pitch = 2 until the first step turned it into roll = yaw = 180 deg, pitch = 65 deg: a
    jump in three outputs no motion made. It is refused as the plant initialises, naming
    the value and the start that states the same attitude; pitch_0 = 90 deg is taken."""
    fmu = Harness(plant, unzip_dir=unzip_dir, initialize=False)
    statuses = fmu.try_initialize(pitch_0=2.0)
    errors = fmu.messages(3)
    fmu.close()
    assert statuses == (STATUS_OK, STATUS_ERROR), errors
    assert "pitch_0 = 2 rad: expected |pitch_0| <= pi/2" in errors, errors
    assert "roll_0 + pi, pitch_0 = pi - 2 = 1.14159 rad, yaw_0 + pi" in errors, errors
    vertical = _harness(plant, unzip_dir, pitch_0=np.pi / 2)
    assert vertical.step(H) == STATUS_OK
    assert np.all(np.isfinite(vertical.get(*OUTPUTS)))
    vertical.close()


def test_invalid_parameter_values_are_refused_naming_them(plant, unzip_dir, tmp_path):
    """A value outside its declared range is refused when written (fmi2Error, the old
    value stays and the instance initialises); one only the model can judge fails the
    initialisation (fmi2Error, then the error state)."""
    bad_file = tmp_path / "bad.toml"
    bad_file.write_text('base = "remus100"\nm = -1.0\n')
    for values, expected, at_write in [
        ({"vehicle": str(bad_file)}, "m = -1.0", False),
        ({"variant": 7}, "variant = 7", True),
        ({"moving_mass_model": 2}, "moving_mass_model = 2", True),
        ({"I_xx": -0.1}, "I_xx = -0.1", True),
        ({"mass_position_0": 0.2}, "mass_position_0 = 0.2", False),
        # a heading whose place within its turn rounding has lost (a double's spacing at
        # 1e300 is 1e284 rad): once taken silently
        ({"yaw_0": 1e300}, "yaw_0 = 1e+300", True),
        ({"roll_0": -1.5e6}, "roll_0 = -1500000.0", True),
    ]:
        fmu = Harness(plant, unzip_dir=unzip_dir, initialize=False)
        statuses = fmu.try_initialize(**values)
        status = fmu.step(H)
        errors = fmu.messages(3)
        fmu.close()
        if at_write:
            assert (statuses, status) == ((STATUS_ERROR, STATUS_OK), STATUS_OK), values
        else:
            assert (statuses, status) == ((STATUS_OK, STATUS_ERROR), STATUS_ERROR), values
        assert expected in errors, errors


def test_parameter_written_after_initialisation_is_refused(plant, unzip_dir):
    fmu = _harness(plant, unzip_dir, variant=2)
    refused = status_of(fmu.set, m=40.0)
    message = fmu.messages(3)
    unchanged = fmu.get("m")[0]
    same_value = status_of(fmu.set, m=unchanged)  # writing the value in use is harmless
    stepped = fmu.step(H)
    fmu.close()
    assert refused == STATUS_ERROR and "m = 40.0 refused" in message
    assert unchanged == 30.5
    assert (same_value, stepped) == (STATUS_OK, STATUS_OK)


@pytest.mark.slow
def test_nan_thrust_is_refused_and_the_host_survives(plant, run_python):
    result = run_python(
        """
        import json, sys
        from fmu_harness import Harness, status_of
        fmu = Harness(sys.argv[1], variant=2, u_0=1.5)
        ok = fmu.step(0.01)
        refused = status_of(fmu.set, thrust=float("nan"))
        after = fmu.step(0.01)  # discarded: it would use the thrust it had
        u_after = float(fmu.get("u")[0])
        fmu.set(thrust=9.0)
        recovered = fmu.step(0.01)
        fmu.close()
        print(json.dumps(dict(ok=ok, refused=refused, after=after, recovered=recovered,
                              u=u_after, errors=fmu.messages(3))))
        """,
        plant,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    statuses = (report["ok"], report["refused"], report["after"], report["recovered"])
    assert statuses == (0, STATUS_ERROR, STATUS_DISCARD, 0)
    assert "thrust = nan refused" in report["errors"]
    assert "so the step would use the value before it" in report["errors"]
    assert np.isfinite(report["u"])


@pytest.mark.slow
def test_a_step_thrown_out_of_range_by_a_huge_thrust_is_discarded_saying_so(plant, run_python):
    # 1e8 N of thrust (a fault's gain gone wild) spins the 6-DOF vehicle so fast that the
    # compiled step divided by a zero quaternion norm: the FMU logged "division by zero".
    result = run_python(
        """
        import json, sys
        from fmu_harness import Harness
        fmu = Harness(sys.argv[1], variant=0, u_0=1.5)
        fmu.set(thrust=1e8)
        thrown = fmu.step(0.1)
        u_after = float(fmu.get("u")[0])
        fmu.set(thrust=9.0)
        next_step = fmu.step(0.01)
        fmu.close()
        print(json.dumps(dict(thrown=thrown, u=u_after, next=next_step,
                              errors=fmu.messages(3))))
        """,
        plant,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert (report["thrown"], report["u"], report["next"]) == (STATUS_DISCARD, 1.5, STATUS_OK)
    assert "left the model's range in a step of 0.1 s" in report["errors"]


@pytest.mark.slow
def test_a_step_too_long_to_take_is_discarded_unstarted_and_the_host_steps_on(plant, run_python):
    # In its own process: the step of 1e12 s (1e14 RK4 sub-steps) used to be started, a hang
    # no signal reaches inside the compiled loop; the timeout turns that into a failure.
    result = run_python(
        """
        import json, sys
        from fmu_harness import Harness
        fmu = Harness(sys.argv[1], variant=2, u_0=1.5)
        huge = fmu.step(1e12)
        time_after, u_after = fmu.time, float(fmu.get("u")[0])
        next_step = fmu.step(0.01)
        fmu.close()
        print(json.dumps(dict(huge=huge, time=time_after, u=u_after, next=next_step,
                              errors=fmu.messages(3))))
        """,
        plant,
        timeout=60.0,
    )
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout.strip().splitlines()[-1])
    assert (report["huge"], report["time"], report["u"], report["next"]) == (
        STATUS_DISCARD, 0.0, 1.5, STATUS_OK)  # fmt: skip
    assert (
        f"takes 1e+14 sub-steps of at most max_substep = 0.01 s: expected at most {MAX_SUBSTEPS}"
        in report["errors"]
    )


@pytest.mark.slow
def test_fresh_process_runs_the_code_shipped_in_the_fmu(plant, run_python):
    """A process that never imported the project runs the plant from the FMU's resources,
    under the FMU's own package name, never the source tree's ``plant_fmu``."""
    result = run_python(
        """
        import sys
        from fmpy import simulate_fmu
        simulate_fmu(sys.argv[1], stop_time=0.1, output_interval=0.01)
        shipped = [m for m in sys.modules if m.endswith(".plant_fmu.model.dynamics")]
        print(shipped, sys.modules[shipped[0]].__file__, "plant_fmu" in sys.modules)
        """,
        plant,
    )
    assert result.returncode == 0, result.stderr
    *_, path, source_tree_imported = result.stdout.split()
    package = Path(path).parents[2]
    assert re.fullmatch(r"auvfmu_[0-9a-f]{12}", package.name), path
    assert package.parent.name == "resources", path
    assert source_tree_imported == "False"


# --- model description -------------------------------------------------------------------------

# The contract (docs/interfaces.md#auvplant): name -> (unit, start) of the inputs, unit of
# the outputs.
CONTRACT_INPUTS = {
    "thrust": ("N", 9.0),
    "roll_torque": ("N.m", 0.0),
    "tunnel_force": ("N", 0.0),
    "fin_angle": ("rad", 0.0),
    "mass_position_cmd": ("m", 0.0),
    "current_north": ("m/s", 0.0),
    "current_east": ("m/s", 0.0),
    "current_down": ("m/s", 0.0),
}
CONTRACT_OUTPUTS = {
    **dict.fromkeys(("north", "east", "down", "mass_position"), "m"),
    **dict.fromkeys(("roll", "pitch", "yaw"), "rad"),
    **dict.fromkeys(("u", "v", "w", "u_rel", "v_rel", "w_rel", "mass_velocity"), "m/s"),
    **dict.fromkeys(("p", "q", "r"), "rad/s"),
    "kinetic_energy": "J",
    **dict.fromkeys(("quat_w", "quat_x", "quat_y", "quat_z"), "1"),
}


def test_model_description_is_valid_complete_and_matches_the_contract(plant):
    assert validate_fmu(str(plant)) == []
    md = read_model_description(str(plant))
    variables = {v.name: v for v in md.modelVariables}
    inputs = {v.name: (v.unit, float(v.start)) for v in md.modelVariables if v.causality == "input"}
    outputs = {v.name: v.unit for v in md.modelVariables if v.causality == "output"}
    assert inputs == CONTRACT_INPUTS
    assert outputs == CONTRACT_OUTPUTS
    assert all(v.description for v in md.modelVariables)
    assert all(v.unit for v in md.modelVariables if v.type == "Real")
    # from the initial state, the vehicle and the currents: read in initialisation mode,
    # they give the values the plant starts from
    assert all(variables[n].initial == "calculated" for n in outputs)
    parameters = {v.name for v in md.modelVariables if v.causality == "parameter"}
    expected = {f"{n}_0" for n in STATE_NAMES} | {
        "variant", "moving_mass_model", "ideal_fluid", "vehicle", "current_shear_dUdy",
        "max_substep",
    } | {n for n, f in VehicleParameters.field_info().items() if f.kind is float}  # fmt: skip
    assert parameters == expected
    assert (variables["I_xx"].unit, variables["K_p"].unit) == ("kg.m2", "N.m.s")
    assert md.coSimulation.needsExecutionTool is False
    assert md.coSimulation.canGetAndSetFMUstate and md.coSimulation.canSerializeFMUstate
    assert {u.variable.name for u in md.outputs} == set(outputs)
    assert all(u.dependencies == [] for u in md.outputs)
    assert float(md.defaultExperiment.stepSize) == H


@pytest.mark.slow
def test_our_validation_finds_no_problem(plant):
    assert validate_fmus({"AuvPlant": plant}) == []


def _fmu_path(model: PlantModel) -> compiled.CompiledPlant | None:
    """The stepping path the plant FMU takes for ``model``: the compiled one when it covers
    the model (bit for bit the FMU's arithmetic), else the reference."""
    return compiled.CompiledPlant(model) if compiled.supports(model) == "" else None


def _simulate_as_fmu(model: PlantModel, x0, inputs, duration: float):
    """``simulate`` on the path the FMU takes (see :func:`_fmu_path`), step H."""
    return simulate(model, x0, inputs, duration, H, compiled=_fmu_path(model))
