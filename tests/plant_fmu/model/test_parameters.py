"""Vehicle parameter sets: the shipped data, and what bad input gets."""

import dataclasses
import math
import os
import re
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import pytest
from reference_values import dissertation
from repo_paths import ROOT

from plant_fmu.model.parameters import VehicleParameterError, builtin_vehicles, load_vehicle


def test_builtin_sets_are_shipped_and_load():
    assert {"remus100", "remus100-printed", "remus100-long-fins"} <= set(builtin_vehicles())
    for name in builtin_vehicles():
        assert load_vehicle(name).name == name


def test_remus100_matches_tables_5_1_and_5_4_and_servo_design():
    p = load_vehicle("remus100")
    assert (p.m, p.B, p.I_xx, p.I_zz, p.z_g, p.g) == (30.5, 306.0, 0.177, 3.45, 0.0196, 9.8)
    assert round(p.W) == 299  # Table 5.4 prints m g rounded
    # (6.3.16): omega_n^2 = k_v/m_v = 5.76 and 2 zeta omega_n = d_v/m_v = 4.32, the servo
    # row of (6.3.19): y_vel' = -k_v/m_v y_v - d_v/m_v y_vel + k_v/m_v y_d
    servo_row = dissertation("equation_6_3_19.A")[6]
    assert p.k_v / p.m_v == pytest.approx(-servo_row[5])
    assert p.d_v / p.m_v == pytest.approx(-servo_row[6])
    assert p.k_v / p.m_v == pytest.approx(dissertation("equation_6_3_19.B")[6])
    assert p.m_v == pytest.approx(p.m / 6)


# The dissertation's tables as printed (B. Li, FAU 2016), field by field: typed from the
# text, not from the vehicle files, so a mistyped parameter fails here.
TABLE_4_1 = {"length": 1.33, "diameter": 0.191}
TABLE_5_1 = {
    "m": 30.5, "I_zz": 3.45, "a11": 0.93, "a22": 35.5, "a26": -1.93, "a66": 4.88,
    "x_g": 0.0, "X_uu": -3.87, "Y_vv": -100.0, "Y_rr": 0.632, "N_vv": 7.38, "N_rr": -94.0,
    "Y_uv": -17.9, "Y_ur": 8.62, "N_uv": 4.57, "N_ur": -6.40,
}  # fmt: skip
TABLE_5_3 = {"Y_uv": -25.2, "Y_ur": 26.5, "N_uv": 40.0, "N_ur": -26.5}
TABLE_5_4 = {
    "B": 306.0, "I_xx": 0.177, "I_yy": 3.45, "a44": 0.0704, "a66": 4.88, "z_g": 0.0196,
    "K_p": -1.60e-3, "K_pp": -0.130,
}  # fmt: skip
TABLE_5_4_WEIGHT = 299.0
TABLE_6_1 = {"I_yy": 3.45, "a33": 35.5, "a35": 1.93, "a55": 4.88, "Z_ds": -50.6, "M_ds": -34.6}
TABLE_6_3 = {
    "Z_ww": -100.0, "Z_qq": -0.632, "M_ww": -7.38, "M_qq": -188.0, "Z_uw": -17.9,
    "Z_uq": -8.62, "M_uw": -4.57, "M_uq": 6.40,
}  # fmt: skip
SECTION_6_3_1 = {  # m_v = m/6 at x_v = 50 cm, |y_v| <= 6 cm; (6.3.16): zeta, omega_n
    "m_v": 30.5 / 6, "x_v": 0.50, "mass_stroke": 0.06, "mass_damping_ratio": 0.9,
    "mass_natural_frequency": 2.4,
}  # fmt: skip
CORRECTED = {"M_uq": -6.40}  # docs/model.md#corrections-and-choices, item 1


@pytest.mark.parametrize(
    ("name", "table"),
    [
        ("Table 4.1", TABLE_4_1),
        ("Table 5.1", TABLE_5_1),
        ("Table 5.4", TABLE_5_4),
        ("Table 6.1", TABLE_6_1),
        ("Table 6.3", TABLE_6_3),
        ("Sec. 6.3.1", SECTION_6_3_1),
    ],
)
def test_remus100_is_the_printed_tables(name, table):
    """Every remus100 parameter the dissertation prints has its printed value, but for the
    corrections docs/model.md states (M_uq's sign); the weight is m g, which Table 5.4
    prints rounded. (Table 6.1's a35 is the M_A entry; the sign (6.3.77) gives it is a
    model choice, docs/reproduction.md.)"""
    p = load_vehicle("remus100")
    for field, printed in table.items():
        expected = CORRECTED.get(field, printed)
        assert getattr(p, field) == pytest.approx(expected, rel=1e-12), f"{name}: {field}"
    assert round(p.W) == TABLE_5_4_WEIGHT


def test_the_other_sets_are_their_printed_tables():
    """remus100-long-fins: Table 5.3's coefficients over remus100; remus100-printed: Table
    6.3's M_uq as printed."""
    base, long_fins = load_vehicle("remus100"), load_vehicle("remus100-long-fins")
    for field in dataclasses.fields(base):
        expected = TABLE_5_3.get(field.name, getattr(base, field.name))
        if field.name not in ("name", "description"):
            assert getattr(long_fins, field.name) == expected, field.name
    assert load_vehicle("remus100-printed").M_uq == TABLE_6_3["M_uq"]


@pytest.mark.parametrize("name", builtin_vehicles())
def test_builtin_sets_use_one_gravity(name):
    """The weight is m g with the set's own g, the g the moving mass's weight uses."""
    p = load_vehicle(name)
    assert abs(p.W - p.m * p.g) <= 1e-12 * p.W


def test_a_set_must_state_its_gravity(tmp_path):
    table = (ROOT / "plant_fmu/model/vehicles/remus100.toml").read_text()
    assert "\ng = 9.8 " in table
    without_g = tmp_path / "no-g.toml"
    without_g.write_text(table.replace("\ng = 9.8 ", "\n# g = 9.8 "))
    with pytest.raises(VehicleParameterError, match="g is missing"):
        load_vehicle(without_g)


def test_variant_sets_differ_only_where_documented():
    base = load_vehicle("remus100").as_dict()
    printed = load_vehicle("remus100-printed").as_dict()
    long_fins = load_vehicle("remus100-long-fins").as_dict()
    ignore = {"name", "description"}
    assert {k for k in base if base[k] != printed[k]} - ignore == {"M_uq"}
    assert (base["M_uq"], printed["M_uq"]) == (-6.40, 6.40)
    changed = {k for k in base if base[k] != long_fins[k]} - ignore
    assert changed == {"Y_uv", "Y_ur", "N_uv", "N_ur"}
    assert (long_fins["Y_uv"], long_fins["Y_ur"], long_fins["N_uv"], long_fins["N_ur"]) == (
        -25.2,
        26.5,
        40.0,
        -26.5,
    )


def test_parameters_are_immutable():
    p = load_vehicle()
    with pytest.raises(dataclasses.FrozenInstanceError, match="cannot assign to field 'm'"):
        p.m = 1.0


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"m": -1.0}, r"m = -1\.0: expected a number greater than 0"),
        ({"m": 0.0}, r"m = 0\.0: expected a number greater than 0"),
        ({"I_yy": -3.45}, r"I_yy = -3\.45: expected a number greater than 0"),
        ({"a22": -1.0}, r"a22 = -1\.0: expected a number greater than or equal to 0"),
        ({"mass_stroke": 0.0}, r"mass_stroke = 0\.0"),
        ({"B": float("nan")}, r"B = nan"),
        ({"a26": 50.0}, r"M_RB \+ M_A must be positive definite.*smallest eigenvalue is -"),
        ({"m_v": 30.5}, r"m_v = 30\.5 kg: expected less than m = 30\.5 kg"),
        ({"m_v": 100.0, "m": 40.0}, r"m_v = 100\.0 kg: expected less than m = 40\.0 kg"),
        ({"W": "heavy"}, r"W = 'heavy'"),
    ],
)
def test_bad_values_name_field_value_and_range(change, expected):
    with pytest.raises(VehicleParameterError, match=expected):
        load_vehicle().replace(**change)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"x_v": 5.0}, r"x_v = 5\.0 m: expected \|x_v\| <= length = 1\.33 m"),
        ({"x_v": -1.4}, r"x_v = -1\.4 m: expected \|x_v\| <= length = 1\.33 m"),
        ({"x_g": 2.0, "I_yy": 300.0, "I_zz": 300.0}, r"x_g = 2\.0 m: expected \|x_g\| <= length"),
        ({"z_t": 3.0}, r"z_t = 3\.0 m: expected \|z_t\| <= diameter / 2 = 0\.0955 m"),
        ({"z_g": -0.1}, r"z_g = -0\.1 m: expected \|z_g\| <= diameter / 2 = 0\.0955 m"),
    ],
)
def test_a_part_placed_outside_the_hull_is_refused(change, expected):
    """The moving-mass rail, the tunnel thruster and the centre of gravity are inside the
    hull (the centre of gravity is an average of the vehicle's own material); the body
    origin, the centre of buoyancy, is too. A rail 5 m ahead of a 1.33 m vehicle's centre,
    or a thruster 3 m below a 19 cm hull, was accepted and gave moments from lever arms
    the vehicle does not have."""
    with pytest.raises(VehicleParameterError, match=expected):
        load_vehicle().replace(**change)


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        # m z_g^2 = 30.5 * 0.0196^2 = 0.0117 kg m^2; a44 = 0.0704 made M_RB + M_A definite
        ({"I_xx": 0.005}, r"I_xx = 0\.005 kg m\^2: expected more than m z_g\^2 = 0\.01172"),
        ({"x_g": 0.5, "I_yy": 9.0}, r"I_zz = 3\.45 kg m\^2: expected more than m x_g\^2 = 7\.625"),
        (
            {"x_g": 0.34, "I_zz": 5.0},
            r"I_yy = 3\.45 kg m\^2: expected more than m \(x_g\^2 \+ z_g\^2\) = 3\.538",
        ),
    ],
)
def test_a_rigid_body_inertia_below_the_parallel_axis_share_is_refused(change, expected):
    """The inertias about the body origin (the CB) of a body whose CG lies r_g from it are
    at least m times the CG's squared distance from the axis (the parallel-axis theorem):
    M_RB is positive definite. A set below that was taken whenever the added mass made
    M_RB + M_A positive definite, so a mistyped roll inertia ran as a body no material
    makes."""
    with pytest.raises(VehicleParameterError, match=expected):
        load_vehicle().replace(**change)


def test_a_moving_mass_stroke_beyond_the_hull_is_refused(tmp_path: Path):
    """The moving mass slides across the hull on a rail along body y, so its stops are
    inside the hull: |y_v| <= mass_stroke <= diameter / 2. A vehicle file with a 5 m stroke
    across a 19 cm hull was taken, and the autopilot could swing the mass 5 m out to roll
    the vehicle with a lever arm it does not have."""
    wide = tmp_path / "wide.toml"
    wide.write_text('base = "remus100"\nname = "wide"\n[moving_mass]\nmass_stroke = 5.0\n')
    expected = r"mass_stroke = 5\.0 m: expected mass_stroke <= diameter / 2 = 0\.0955 m"
    with pytest.raises(VehicleParameterError, match=rf"vehicle '.*wide\.toml': {expected}"):
        load_vehicle(wide)
    with pytest.raises(VehicleParameterError, match=expected):
        load_vehicle().replace(mass_stroke=5.0)
    assert load_vehicle().replace(mass_stroke=0.0955).mass_stroke == 0.0955


def test_the_model_may_still_move_the_stops_out_of_reach():
    """The model's own what-ifs (the two-body stepping before a stop, a continuation past
    the stroke) put the stops beyond the hull: a set no vehicle file may give."""
    p = load_vehicle()
    assert p.with_stroke(1e9).mass_stroke == 1e9
    with pytest.raises(VehicleParameterError, match=r"mass_stroke = -1\.0"):
        p.with_stroke(-1.0)


def test_parts_at_the_hull_are_taken():
    p = load_vehicle()
    p.replace(x_v=-p.length, z_t=p.diameter / 2)


def test_unknown_and_missing_keys_are_named(tmp_path: Path):
    bad = tmp_path / "bad.toml"
    bad.write_text('base = "remus100"\n[viscous]\nX_uuu = 1.0\n')
    with pytest.raises(VehicleParameterError, match=r"unknown key 'X_uuu' \(value 1\.0\)"):
        load_vehicle(bad)
    partial = tmp_path / "partial.toml"
    partial.write_text("[rigid_body]\nm = 30.5\n")
    with pytest.raises(VehicleParameterError, match="W is missing"):
        load_vehicle(partial)


def test_a_file_that_is_no_vehicle_set_is_named_so_in_a_short_line(tmp_path: Path):
    """A scenario file given as a vehicle (its path typed in the wrong place) was refused in
    a line of some 3000 characters: every key of the scenario as unknown, with its whole
    value, then each of the 48 parameters as missing."""
    scenario = (ROOT / "cosim" / "scenarios" / "lqr-1.toml").read_text(encoding="utf-8")
    wrong = tmp_path / "lqr-1.toml"
    wrong.write_text(scenario, encoding="utf-8")
    with pytest.raises(VehicleParameterError) as info:
        load_vehicle(wrong)
    message = str(info.value)
    assert message.startswith(
        f"vehicle {str(wrong)!r}: no vehicle parameter set: none of its keys (summary, "
        "stop_time, step, "
    ), message
    assert "is missing" not in message and len(message) < 400, message


def test_unknown_vehicle_lists_the_known_sets():
    with pytest.raises(
        VehicleParameterError, match=r"unknown vehicle 'remus600'.*remus100-printed"
    ):
        load_vehicle("remus600")


def test_file_with_base_overrides(tmp_path: Path):
    custom = tmp_path / "heavy.toml"
    custom.write_text('base = "remus100"\nname = "heavy"\n[rigid_body]\nW = 306.0\n')
    p = load_vehicle(custom)
    assert (p.name, p.W, p.B, p.m) == ("heavy", 306.0, 306.0, 30.5)


def test_base_loop_is_refused(tmp_path: Path):
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(f'base = "{b}"\n')
    b.write_text(f'base = "{a}"\n')
    with pytest.raises(VehicleParameterError, match="loops"):
        load_vehicle(a)


def test_a_relative_base_is_read_beside_the_file_that_names_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """``base = "heavy.toml"`` names the file beside the set, wherever the process runs
    (a scenario names the set by a path relative to itself; the base was looked for in
    the working directory)."""
    sets, elsewhere = tmp_path / "vehicles", tmp_path / "elsewhere"
    (sets / "more").mkdir(parents=True)
    elsewhere.mkdir()
    (sets / "heavy.toml").write_text('base = "remus100"\nname = "heavy"\n[rigid_body]\nW = 306.0\n')
    (sets / "more" / "heavier.toml").write_text('base = "../heavy.toml"\nname = "heavier"\n')
    monkeypatch.chdir(elsewhere)
    p = load_vehicle(sets / "more" / "heavier.toml")
    assert (p.name, p.W) == ("heavier", 306.0)
    (sets / "a.toml").write_text('base = "b.toml"\n')
    (sets / "b.toml").write_text('base = "a.toml"\n')
    with pytest.raises(VehicleParameterError, match="loops"):
        load_vehicle(sets / "a.toml")


def test_a_set_is_parsed_once_while_its_files_hold_the_same_text(tmp_path: Path):
    base, custom = tmp_path / "base.toml", tmp_path / "custom.toml"
    base.write_text('base = "remus100"\nname = "base"\n[rigid_body]\nW = 306.0\n')
    custom.write_text(f'base = "{base}"\nname = "custom"\n')
    first = load_vehicle(custom)
    assert load_vehicle(custom) is first  # the same immutable object, not parsed again
    # a file of the 'base' chain changes (same length, so neither size nor, within one
    # clock tick, the modification time tells): the set is read again
    base.write_text(base.read_text().replace("306.0", "307.0"))
    changed = load_vehicle(custom)
    assert (first.W, changed.W, changed.name) == (306.0, 307.0, "custom")
    base.unlink()
    with pytest.raises(VehicleParameterError, match="unknown vehicle"):
        load_vehicle(custom)


def test_a_built_in_set_loads_in_a_process_whose_working_directory_is_gone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """A host may run from a deleted folder; only a relative path depends on it."""
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    assert load_vehicle("remus100").name == "remus100"


@pytest.mark.parametrize("name", ["m", "I_zz", "a22"])
def test_a_mass_beyond_any_double_is_refused_without_a_warning(name: str) -> None:
    """m = 1e308 overflowed M_RB + M_A: numpy's RuntimeWarning reached an FMU host's stderr
    and the refusal read "Eigenvalues did not converge"."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(VehicleParameterError, match=r"M_RB \+ M_A overflows"):
            load_vehicle("remus100").replace(**{name: 1e308})


def test_a_vehicle_file_is_utf8_whatever_the_locale(tmp_path):
    """A vehicle set with a comment in UTF-8 (°) and a byte-order mark: read in the
    host's locale encoding, it failed to load under LANG=C (a host started without a
    locale) with a UnicodeDecodeError traceback; a file that is not UTF-8 is named."""
    heavy = tmp_path / "heavy.toml"
    text = '# 31 kg, trimmed at 0°\nbase = "remus100"\nname = "heavy"\n[rigid_body]\nm = 31.0\n'
    heavy.write_bytes(b"\xef\xbb\xbf" + text.encode("utf-8"))
    latin = tmp_path / "latin.toml"
    latin.write_bytes(text.encode("latin-1"))
    code = """
        import sys
        from plant_fmu.model.parameters import VehicleParameterError, load_vehicle
        print(load_vehicle(sys.argv[1]).m)
        try:
            load_vehicle(sys.argv[2])
        except VehicleParameterError as exc:
            print(exc)
    """
    env = {**os.environ, "LC_ALL": "C", "LANG": "C", "PYTHONUTF8": "0"}
    env["PYTHONIOENCODING"] = "utf-8"  # the test reads the child's output as UTF-8
    done = subprocess.run(
        [sys.executable, "-X", "utf8=0", "-c", textwrap.dedent(code), str(heavy), str(latin)],
        env=env, capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    mass, refusal = done.stdout.strip().splitlines()
    assert float(mass) == 31.0
    assert refusal.startswith(f"vehicle file {str(latin)!r}: not UTF-8")


@pytest.mark.parametrize(
    ("name", "value", "what"),
    [("mass_natural_frequency", 1e300, r" rad/s: expected at most (\S+) rad/s \(the servo "
      r"stiffness k_v = m_v omega_n\^2 \(6\.3\.16\)"),
     ("mass_damping_ratio", 1e308, r": expected at most (\S+) \(the servo damping "
      r"d_v = 2 zeta m_v omega_n \(6\.3\.16\)")],
)  # fmt: skip
def test_a_servo_whose_stiffness_or_damping_overflows_is_refused_by_name(name, value, what):
    """omega_n = 1e300 rad/s made k_v = m_v omega_n^2 (6.3.16) overflow: an FMU host read
    "initialisation failed: OverflowError: (34, 'Numerical result out of range')"; a
    damping ratio making d_v infinite would step NaN. The bound named is taken."""
    refusal = rf"{name} = {re.escape(repr(value))}{what}"
    with pytest.raises(VehicleParameterError, match=refusal) as refused:
        load_vehicle().replace(**{name: value})
    bound = float(re.search(what, str(refused.value)).group(1))
    servo = load_vehicle().replace(**{name: bound})
    assert math.isfinite(servo.k_v) and math.isfinite(servo.d_v)


@pytest.mark.parametrize("name", ["a22", "a55", "I_yy"])
@pytest.mark.parametrize("value", [1e18, 1e20, 1e300])
def test_a_huge_positive_inertia_is_not_refused_as_indefinite(name, value):
    """Raising a diagonal entry of M_RB + M_A keeps it positive definite, but from 1e17 up
    the eigenvalues' rounding (of the order of 1e-16 times the largest) made the smallest
    come out negative, and the set was refused "M_RB + M_A must be positive definite, but
    its smallest eigenvalue is -37.6875", a reason it does not have."""
    p = load_vehicle().replace(**{name: value})
    assert getattr(p, name) == value
