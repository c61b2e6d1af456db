"""``auv-cosim analyze``: equilibria (table and JSON), sweeps and phase portraits.

Expected numbers are the dissertation's (Example 5.1, 5.2, Sec. 6.3.3's T = 4 N case and
Example 5.4's fold), so a regression in the model or the analysis shows up here too.
"""

from __future__ import annotations

import csv
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from process_group import run_in_group
from read_only import read_only_prefix, writable_again
from reference_values import dissertation

import cosim
from cosim.analysis.bifurcation import Q_PROP
from cosim.cli import build_parser, main
from plant_fmu.model.dynamics import STATE_INDEX, STATE_NAMES, Variant
from plant_fmu.model.parameters import load_vehicle

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _run(capsys, *argv: str) -> tuple[int, str, str]:
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_equilibria_json_is_the_documented_list(capsys):
    """A list of {state: {name: value}, eigenvalues: [[re, im]], stable, units}, as
    cosim/analysis/analyze.py documents it."""
    code, out, _ = _run(capsys, "analyze", "equilibria", "--json")
    assert code == 0
    records = json.loads(out)
    assert len(records) == 3
    for record in records:
        assert set(record) == {"state", "eigenvalues", "stable", "units"}
        assert list(record["state"]) == list(STATE_NAMES)
        assert len(record["eigenvalues"]) == 3  # u, v, r of the horizontal variant
        assert all(len(pair) == 2 for pair in record["eigenvalues"])
        has_unstable = any(re > 0 for re, _ in record["eigenvalues"])
        assert record["stable"] is not has_unstable
    by_v = sorted(records, key=lambda r: r["state"]["v"])
    # Example 5.1 (5.1.50): the turning pair is stable, the straight line is not.
    assert [r["stable"] for r in by_v] == [True, False, True]
    u, v, r = dissertation("example_5_1.turn_positive_v")
    assert by_v[2]["state"]["u"] == pytest.approx(u, abs=6e-4)
    assert by_v[2]["state"]["v"] == pytest.approx(v, abs=6e-5)
    assert by_v[2]["state"]["r"] == pytest.approx(r, abs=6e-5)


@pytest.mark.slow
def test_equilibria_low_speed_lateral_json(capsys):
    """Sec. 6.3.3 (T = 4 N): [1.017, 0, 0] unstable, [0.8467, +-0.1147, -+0.1541] stable."""
    code, out, _ = _run(
        capsys, "analyze", "equilibria", "--variant", "1", "--thrust", "4", "--json"
    )
    assert code == 0
    by_v = sorted(json.loads(out), key=lambda r: r["state"]["v"])
    assert [r["stable"] for r in by_v] == [True, False, True]
    assert by_v[1]["state"]["u"] == pytest.approx(
        dissertation("low_speed.straight_line")[0], rel=5e-3
    )
    turn = dissertation("low_speed.turn_positive_v")
    for name, value in zip(("u", "v", "r"), turn, strict=False):
        assert by_v[2]["state"][name] == pytest.approx(value, rel=5e-3)
    assert len(by_v[0]["eigenvalues"]) == 5  # u, v, p, r, roll


def test_equilibria_table_for_the_long_fins(capsys):
    """Example 5.2: one equilibrium, stable."""
    code, out, _ = _run(capsys, "analyze", "equilibria", "--vehicle", "remus100-long-fins")
    assert code == 0
    assert "1 equilibrium in 0 < u < 2" in out
    row = [line for line in out.splitlines() if line.strip().startswith("1.52")]
    assert len(row) == 1 and " yes " in row[0]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["analyze", "equilibria", "--vehicle", "nosuch"], "unknown vehicle 'nosuch'"),
        (["analyze", "equilibria", "--roll-torque", "-1"], "horizontal variant"),
        (
            ["analyze", "sweep", "mass_position", "0", "-0.1", "--variant", "1"],
            "mass_position = -0.1 m",
        ),
        (["analyze", "sweep", "mu", "1", "1"], "two different finite values"),
        (["analyze", "sweep", "eta", "1", "2", "--steps", "1"], "--steps 1"),
        (
            ["analyze", "sweep", "eta", "1", "2", "--steps", "100000000"],
            "--steps 100000000: expected at most 100000",
        ),
        (["analyze", "phase-portrait", "--current-east", "0.2"], "still water"),
        (["analyze", "equilibria", "--thrust", "-inf"], "--thrust -inf: expected a finite"),
    ],
)
def test_bad_input_exits_1_with_a_one_line_reason(capsys, tmp_path, argv, message):
    code, _, err = _run(
        capsys, *argv, *(["--out", str(tmp_path)] if argv[1] != "equilibria" else [])
    )
    assert code == 1
    assert message in err
    assert len(err.strip().splitlines()) == 1
    assert "Error:" not in err  # a reason, not an exception's type name


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["mu", "1", "0"], "TO: mu = 0.0: expected a finite factor > 0"),
        (["eta", "-1", "1"], "FROM: eta = -1.0: expected a finite factor > 0"),
        (["mu", "1", "1"], "two different finite values"),
        (["eta", "1", "2", "--steps", "1"], "--steps 1: expected at least 2"),
    ],
)
def test_a_refused_sweep_names_the_argument_and_makes_no_folder(capsys, tmp_path, argv, message):
    """A sweep refused for its arguments leaves no empty output folder behind, and a
    refused argument is named as the command line names it (FROM, TO, --steps)."""
    out = tmp_path / "analysis"
    code, _, err = _run(capsys, "analyze", "sweep", *argv, "--out", str(out))
    assert code == 1
    assert message in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["equilibria", "--variant", "1", "--roll-torque", "-5e-1"], {"roll_torque": -0.5}),
        (["equilibria", "--current-east", "-1E-2"], {"current_east": -0.01}),
        (["sweep", "roll_torque", "-5e-1", "2.5e-1"], {"start": -0.5, "stop": 0.25}),
        (["sweep", "mass_position", "-.01", "-1e-3"], {"start": -0.01, "stop": -0.001}),
    ],
)
def test_negative_numbers_in_exponent_form_are_numbers_not_options(argv, expected):
    """argparse before Python 3.13 took "-5e-1" for an unknown option: "--roll-torque
    -5e-1" failed with "expected one argument", a sweep from -5e-1 with "the following
    arguments are required: TO"."""
    args = build_parser().parse_args(["analyze", *argv])
    assert {name: getattr(args, name) for name in expected} == expected


@pytest.mark.parametrize(
    ("given", "code"),
    [("full", 0), ("lateral", 1), ("Horizontal", 2), ("0", 0), ("1", 1), ("2", 2)],
)
def test_the_variant_is_taken_by_name_as_in_a_scenario_file(given: str, code: int) -> None:
    """The help's default reads "lateral" and a scenario file writes variant = "lateral",
    but --variant lateral failed with "invalid int value: 'lateral'"."""
    args = build_parser().parse_args(["analyze", "equilibria", "--variant", given])
    assert args.variant == code


def test_an_unknown_variant_names_the_value_and_the_choices(capsys) -> None:
    with pytest.raises(SystemExit):
        build_parser().parse_args(["analyze", "equilibria", "--variant", "6dof"])
    err = capsys.readouterr().err
    assert "'6dof': expected one of full (0), lateral (1), horizontal (2)" in err


@pytest.mark.parametrize(
    ("analysis", "what"),
    [(["sweep", "eta", "1", "2"], "the sweep outputs"), (["phase-portrait"], "the phase portrait")],
)
def test_an_output_folder_that_cannot_be_made_is_refused_before_computing(
    capsys, tmp_path, monkeypatch, analysis, what
):
    """A sweep of many steps or a phase portrait takes minutes: a --out that names a file
    is refused at once, not after the work."""
    import cosim.analysis.analyze as analyze

    def computed(*args, **kwargs):
        raise AssertionError("computed before the output folder was checked")

    monkeypatch.setattr(analyze, "sweep", computed)
    monkeypatch.setattr(analyze, "find_equilibria", computed)
    taken = tmp_path / "taken"
    taken.write_text("a file, not a folder", encoding="utf-8")
    code, _, err = _run(capsys, "analyze", *analysis, "--out", str(taken))
    assert code == 1
    assert f"cannot write {what} to {taken}: it is not a folder" in err
    assert len(err.strip().splitlines()) == 1


# the analysis in a process of its own (the folder made read-only for it), its work
# replaced by a failure: the folder must be refused before it
_UNWORKED = """
import sys
from pathlib import Path
import cosim.analysis.analyze as analyze
from cosim.cli import main

def computed(*args, **kwargs):
    raise AssertionError("computed before the output folder was checked")

analyze.sweep = analyze.find_equilibria = computed
sys.exit(main(sys.argv[1:]))
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    ("analysis", "what"),
    [(["sweep", "eta", "1", "2"], "the sweep outputs"), (["phase-portrait"], "the phase portrait")],
)
def test_an_output_folder_that_cannot_be_written_is_refused_before_computing(
    tmp_path, analysis, what
):
    """An --out folder that exists but cannot be written (the default ``analysis/`` of a
    read-only working folder) was found out after the minutes of work, and the refusal
    did not say how to go on: it names the folder and --out, before any work."""
    out = tmp_path / "analysis"
    out.mkdir()
    packages = Path(cosim.__file__).resolve().parents[1]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(packages), os.environ.get("PYTHONPATH")])),
    }
    command = [sys.executable, "-c", _UNWORKED, "analyze", *analysis, "--out", str(out)]
    try:
        done = run_in_group([*read_only_prefix(out), *command], timeout=300, env=env)
    finally:
        writable_again(out)
    assert done.returncode == 1, done.stderr
    assert re.fullmatch(
        f"auv-cosim analyze {analysis[0]}: cannot write {what} to {re.escape(str(out))}: "
        "(Permission denied|Read-only file system); name a folder you can write with --out\n",
        done.stderr,
    ), done.stderr


@pytest.mark.slow
def test_roll_torque_sweep_writes_figure_and_csv_with_one_fold(capsys, tmp_path):
    """Example 5.4: one fold between 4 and 5 Q_prop, in the CSV and on stdout."""
    code, out, _ = _run(
        capsys,
        "analyze", "sweep", "roll_torque", "0", str(5.5 * Q_PROP),
        "--variant", "1", "--steps", "30", "--out", str(tmp_path),
    )  # fmt: skip
    assert code == 0
    figure = tmp_path / "sweep_roll_torque.png"
    assert figure.read_bytes()[:8] == PNG_SIGNATURE and figure.stat().st_size > 20_000
    with (tmp_path / "sweep_roll_torque.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert {"branch", "roll_torque [N.m]", "u [m/s]", "v [m/s]", "r [rad/s]", "p [rad/s]",
            "roll [rad]", "stable"} <= set(rows[0])  # fmt: skip
    assert {r["stable"] for r in rows} == {"0", "1"}
    torques = [float(r["roll_torque [N.m]"]) for r in rows]
    assert min(torques) == pytest.approx(5.5 * Q_PROP) and max(torques) == 0.0
    with (tmp_path / "sweep_roll_torque_special_points.csv").open() as f:
        special = list(csv.DictReader(f))
    folds = [s for s in special if s["kind"] == "fold"]
    assert len(folds) == 1
    assert 4.0 < float(folds[0]["roll_torque [N.m]"]) / Q_PROP < 5.0
    assert "fold" in out and "Q_prop" in out


@pytest.mark.slow
def test_mass_position_sweep_reports_the_cg_offset(capsys, tmp_path):
    code, out, _ = _run(
        capsys,
        "analyze", "sweep", "mass_position", "0", "-0.06",
        "--variant", "1", "--steps", "30", "--out", str(tmp_path),
    )  # fmt: skip
    assert code == 0
    with (tmp_path / "sweep_mass_position.csv").open() as f:
        rows = list(csv.DictReader(f))
    # y_g = m_v g y_v / W: one sixth of y_v for m_v = m/6 and W ~ m g.
    for row in rows[::25]:
        assert float(row["cg_offset_y_g [m]"]) == pytest.approx(
            float(row["mass_position [m]"]) / 6, rel=3e-3
        )
    assert "y_g = -0.8" in out  # the fold, Sec. 5.1.4: "slightly larger than 0.8 cm"
    # the conditions printed (and the figure's title) name the swept parameter as swept,
    # not with the fixed value it does not keep
    assert "mass position swept" in out and "mass position 0 m" not in out


def test_sweep_title_names_the_swept_parameter() -> None:
    from cosim.analysis.analyze import describe
    from cosim.analysis.bifurcation import OperatingConditions
    from plant_fmu.model.parameters import load_vehicle

    conditions = OperatingConditions(load_vehicle("remus100"))
    assert "mass position 0 m" in describe(conditions)
    for swept, fixed in (("mass_position", "mass position 0 m"), ("roll_torque", "roll torque")):
        text = describe(conditions, swept=swept)
        assert f"{swept.replace('_', ' ')} swept" in text
        assert fixed + " " not in text.replace(f"{swept.replace('_', ' ')} swept", "")


@pytest.mark.slow
def test_phase_portrait_writes_a_png(capsys, tmp_path):
    code, out, _ = _run(capsys, "analyze", "phase-portrait", "--out", str(tmp_path))
    assert code == 0
    figure = tmp_path / "phase_portrait.png"
    assert figure.read_bytes()[:8] == PNG_SIGNATURE and figure.stat().st_size > 20_000
    assert "29 trajectories" in out  # 27 grid starts + 2 on the unstable manifold of x0


@pytest.mark.slow
def test_console_entry_point_runs_in_a_fresh_process():
    result = subprocess.run(
        [sys.executable, "-m", "cosim.cli", "analyze", "equilibria", "--json"],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert len(json.loads(result.stdout)) == 3


@pytest.mark.parametrize("failing", ["figure", "special points"])
def test_a_sweep_output_the_disk_has_no_room_for_is_named_and_not_left_half(
    capsys, tmp_path, monkeypatch, failing
):
    """A full disk left a sweep's figure or CSV written in part (0 bytes) beside the
    message, which named the folder only."""
    import errno

    from matplotlib.figure import Figure

    import cosim.analysis.analyze as analyze

    def full(path, first):  # writes the start of the file, then finds the disk full
        path.write_text(first, encoding="utf-8")
        raise OSError(errno.ENOSPC, "No space left on device")

    if failing == "figure":
        monkeypatch.setattr(Figure, "savefig", lambda fig, path, **kw: full(path, "\x89PNG"))
        name = "sweep_eta.png"
    else:
        monkeypatch.setattr(analyze, "_write_special_points", lambda result, path: full(path, "k"))
        name = "sweep_eta_special_points.csv"
    code, _, err = _run(capsys, "analyze", "sweep", "eta", "1", "2", "--steps", "10",
                        "--out", str(tmp_path))  # fmt: skip
    assert code == 1
    assert err == (
        f"auv-cosim analyze sweep: cannot write the sweep outputs to {tmp_path}: "
        f"{tmp_path / name}: No space left on device\n"
    )
    assert not (tmp_path / name).exists() and not list(tmp_path.glob(".*.tmp"))
    assert (tmp_path / "sweep_eta.csv").stat().st_size > 0  # written before: kept, whole


@pytest.mark.parametrize("thrust", ["0", "-2"])
def test_an_analysis_without_thrust_is_refused(capsys, thrust):
    """`analyze equilibria --thrust 0` listed u = 3.6e-163 as a stable equilibrium in the
    box 0 < u < 2: eigenvalues of -1e-5 the finite-difference step made, of a Jacobian
    that is zero at rest."""
    code, out, err = _run(capsys, "analyze", "equilibria", "--thrust", thrust)
    assert code == 1 and out == ""
    assert f"--thrust {float(thrust)!r}: expected a thrust > 0" in err


@pytest.mark.parametrize("current", ["1e10", "-100.5"])
def test_a_current_faster_than_the_plant_integrates_is_refused(capsys, current):
    """`analyze equilibria --current-east 1e10` printed three equilibria moving east at
    1e+10 m/s over ground: the equilibria are of the motion relative to the water, and a
    steady current carries the vehicle at its own speed, beyond the velocities over ground
    the plant integrates (MAX_SPEED, 100 m/s)."""
    code, out, err = _run(capsys, "analyze", "equilibria", "--current-east", current)
    assert code == 1 and out == ""
    assert f"--current-east {float(current)!r}: expected |current_east| <= 100 m/s" in err
    assert len(err.strip().splitlines()) == 1


def test_the_fastest_current_the_plant_integrates_is_taken(capsys):
    code, out, _ = _run(capsys, "analyze", "equilibria", "--current-east", "-100")
    assert code == 0 and "current east -100 m/s" in out


def test_printed_tables_give_every_quantity_its_unit() -> None:
    """The search box said '|v|, |p|, |r| <= 0.4' (m/s and rad/s alike), the eigenvalues
    and the special points' states had no unit, and a roll-torque fold read
    'roll_torque = -2.28613 (4.21 Q_prop)'."""
    from cosim.analysis.analyze import equilibria_table, special_points_table
    from cosim.analysis.bifurcation import OperatingConditions, SpecialPoint, Sweep

    conditions = OperatingConditions(load_vehicle("remus100"), Variant.LATERAL)
    table = equilibria_table(conditions, [])
    assert table.startswith(
        "0 equilibria in 0 < u < 2 m/s, |v| <= 0.4 m/s, |p|, |r| <= 0.4 rad/s, |roll| < 90 deg:"
    ), table
    assert "eigenvalues [1/s]" in table
    state = {"roll": -0.3777, "u": 1.468, "v": -0.0657, "p": 0.0, "r": 0.143}
    fold = SpecialPoint("fold", -2.28613, state, np.zeros(5), branch=1)
    result = Sweep("roll_torque", 0.0, -3.0, tuple(state), [], [fold])
    assert special_points_table(result, conditions).splitlines() == [
        "0 branch(es) over roll_torque from 0 N.m to -3 N.m; 1 special point(s):",
        "  fold         at roll_torque = -2.28613 N.m (4.21 Q_prop): roll = -21.64 deg, "
        "u = 1.468 m/s, v = -0.0657 m/s, p = 0 rad/s, r = 0.143 rad/s",
    ]


def test_printed_tables_show_a_numerical_zero_as_0() -> None:
    """A fold of `analyze sweep roll_torque 0 -2.9865 --variant 1` printed
    'p = -6.842e-31 rad/s' and `analyze equilibria` '2.27238e-32' for a roll rate that is
    zero at every equilibrium; below 1e-12 of the largest |value| of its unit in the table
    a value is printed as 0, a small value that is not noise as it is."""
    from cosim.analysis.analyze import equilibria_table, special_points_table
    from cosim.analysis.bifurcation import OperatingConditions, SpecialPoint, Sweep
    from cosim.analysis.equilibria import Equilibrium

    conditions = OperatingConditions(load_vehicle("remus100"), Variant.LATERAL)
    state = {"roll": -0.3777, "u": 1.468, "v": -0.0657, "p": -6.842e-31, "r": 2e-9}
    fold = SpecialPoint("fold", -2.28613, state, np.zeros(5), branch=1)
    result = Sweep("roll_torque", 0.0, -3.0, tuple(state), [], [fold])
    line = special_points_table(result, conditions).splitlines()[1]
    assert line.endswith("p = 0 rad/s, r = 2e-09 rad/s"), line
    full = np.zeros(len(STATE_NAMES))
    for name, value in state.items():
        full[STATE_INDEX[name]] = value
    eigenvalues = -np.ones(len(conditions.free_states))
    equilibrium = Equilibrium(full, conditions.free_states, np.eye(5), eigenvalues)
    row = equilibria_table(conditions, [equilibrium]).splitlines()[2].split()
    values = dict(zip(conditions.free_states, row, strict=False))
    assert values["p"] == "0" and values["r"] == "2e-09", row


def _a_sweep(parameter: str) -> tuple:
    """A two-point lateral sweep with one fold, made by hand (no continuation)."""
    from cosim.analysis.bifurcation import Branch, OperatingConditions, SpecialPoint, Sweep

    conditions = OperatingConditions(load_vehicle("remus100"), Variant.LATERAL)
    names = conditions.free_states
    states = np.array([[0.1, 1.4, -0.05, 0.0, 0.1], [0.2, 1.3, -0.1, 0.0, 0.2]])
    branch = Branch(names, np.array([0.0, -0.01]), states, np.full((2, 5), -1.0 + 0j))
    fold = SpecialPoint("fold", -0.005, dict(zip(names, states[0], strict=True)), states[0], 0)
    return conditions, Sweep(parameter, 0.0, -0.01, names, [branch], [fold])


@pytest.mark.parametrize("parameter", ["roll_torque", "mass_position", "mu"])
def test_sweep_csv_headers_name_every_column_unit(tmp_path, parameter: str) -> None:
    """The sweep CSVs' headers read 'roll_torque,roll,u,v,p,r,...': a reader of the file
    alone could not tell N.m from Q_prop, rad from deg, nor m/s from knots."""
    from cosim.analysis.analyze import write_branches_csv, write_special_points_csv
    from plant_fmu.model.dynamics import STATE_INDEX, STATE_UNITS

    conditions, result = _a_sweep(parameter)
    unit = {"roll_torque": "N.m", "mass_position": "m", "mu": "1"}[parameter]
    states = [f"{n} [{STATE_UNITS[STATE_INDEX[n]]}]" for n in result.free_states]
    with write_branches_csv(result, conditions, tmp_path / "b.csv").open() as f:
        header = next(csv.reader(f))
    cg = ["cg_offset_y_g [m]"] if parameter == "mass_position" else []
    assert header == [
        "branch",
        f"{parameter} [{unit}]",
        *cg,
        *states,
        "stable",
        "max_real_eigenvalue [1/s]",
    ]
    with write_special_points_csv(result, tmp_path / "s.csv").open() as f:
        assert next(csv.reader(f)) == ["kind", "branch", f"{parameter} [{unit}]", *states]


def test_equilibria_json_names_the_unit_of_every_number(capsys) -> None:
    """`analyze equilibria --json` gave states and eigenvalues with no unit anywhere: the
    JSON alone did not say whether roll was in rad or deg, nor r in rad/s or deg/s."""
    from plant_fmu.model.dynamics import STATE_UNITS

    code, out, _ = _run(capsys, "analyze", "equilibria", "--json")
    assert code == 0
    for record in json.loads(out):
        assert record["units"] == {
            "state": dict(zip(STATE_NAMES, STATE_UNITS, strict=True)),
            "eigenvalues": "1/s",
        }


def test_a_sweep_says_which_earlier_outputs_it_replaced(capsys, tmp_path) -> None:
    """A second `analyze sweep eta ...` (at another thrust) into the same folder wrote
    over the first one's figure and CSV files without a word."""
    argv = ["analyze", "sweep", "eta", "1", "1.5", "--steps", "10", "--out", str(tmp_path)]
    code, out, _ = _run(capsys, *argv)
    assert code == 0 and "replaced" not in out
    code, out, _ = _run(capsys, *argv, "--thrust", "8")
    assert code == 0
    for name in ("sweep_eta.png", "sweep_eta.csv", "sweep_eta_special_points.csv"):
        assert f"{tmp_path / name} (replaced the earlier one)" in out, out


@pytest.mark.slow
def test_a_phase_portrait_says_it_replaced_an_earlier_one(capsys, tmp_path) -> None:
    """`analyze phase-portrait` wrote over an earlier phase_portrait.png without a word."""
    (tmp_path / "phase_portrait.png").write_bytes(PNG_SIGNATURE)
    code, out, _ = _run(capsys, "analyze", "phase-portrait", "--out", str(tmp_path))
    assert code == 0
    assert f"{tmp_path / 'phase_portrait.png'} (replaced the earlier one)" in out, out


@pytest.mark.slow
def test_a_special_point_whose_rates_are_all_solver_noise_prints_them_as_0(capsys, tmp_path):
    """The straight line's branch point over mu: every rad/s value of the table was solver
    noise, so none was the largest to compare with, and the line read "roll = -8.941e-22
    deg, ..., p = 3.675e-33 rad/s, r = -1.005e-22 rad/s"."""
    code, out, _ = _run(
        capsys, "analyze", "sweep", "mu", "0.2", "3", "--variant", "1", "--out", str(tmp_path)
    )
    assert code == 0
    point = next(line for line in out.splitlines() if "branch point" in line)
    assert "roll = 0 deg" in point and "p = 0 rad/s" in point and "r = 0 rad/s" in point, point
