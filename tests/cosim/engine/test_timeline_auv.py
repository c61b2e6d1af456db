"""Events and faults on the AUV: bs-3 turned to a new heading by an
event under Jacobi, Gauss-Seidel and step multiples; the actuator faults; what the
plant's extrapolated inputs follow across a jump and from a slower instance."""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cosim.engine import master
from cosim.engine.master import RunResult
from cosim.scenario.spec import SCENARIO_FOLDER, scenario_from_toml

TURN = '\n[[events]]\nname = "turn"\ntime = {time}\nset = {{ "controller.yaw_setpoint" = 0.5 }}\n'
RECORD = (
    '[output]\nrecord = ["plant.yaw", "plant.mass_position", "plant.tunnel_force", '
    '"plant.mass_position_cmd", "controller.yaw_setpoint"]\n'
)


def bs3(
    fmu_dir: Path,
    extra: str,
    stop_time: float = 45.0,
    coupling: str = "",
    algorithm: str = "gauss-seidel",
) -> RunResult:
    """bs-3 to ``stop_time`` with ``extra`` TOML (events, faults), more coupling lines."""
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 60.0", f"stop_time = {stop_time}")
    text = text.replace('algorithm = "gauss-seidel"', f'algorithm = "{algorithm}"')
    text = text.replace(
        'order = ["controller", "plant"]', f'order = ["controller", "plant"]\n{coupling}'
    )
    scenario = scenario_from_toml(text + RECORD + extra, "bs3", SCENARIO_FOLDER, fmu_dir)
    result = master.run(scenario)
    assert result.complete, result.error
    return result


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_bs3_turns_to_the_new_heading_set_at_20_s(fmu_dir: Path, algorithm: str) -> None:
    result = bs3(fmu_dir, TURN.format(time=20.0), algorithm=algorithm)
    assert result.events == [
        {"name": "turn", "time": 20.0, "set": {"controller.yaw_setpoint": 0.5}}
    ]
    t, yaw = result.times, result.column("plant.yaw")
    setpoint = result.column("controller.yaw_setpoint")
    assert np.array_equal(setpoint, np.where(t >= 20.0, 0.5, 0.0))  # the recorded input follows
    assert np.max(np.abs(yaw[(t >= 15.0) & (t <= 20.0)])) < math.radians(1.0)  # following 0
    assert np.max(np.abs(yaw[t >= 40.0] - 0.5)) < math.radians(1.0)


@pytest.mark.slow
def test_with_the_controller_every_2_steps_the_event_fires_at_the_next_point(
    fmu_dir: Path,
) -> None:
    # 20.005 s: the first point at or after it is t = 20.01 (n = 2001), where the
    # controller (due at even n) is not due: it sees the setpoint at its step from 20.02
    coupling = "step_multiples = { controller = 2 }"
    result = bs3(fmu_dir, TURN.format(time=20.005), stop_time=20.05, coupling=coupling)
    assert [e["time"] for e in result.events] == [pytest.approx(20.01, abs=1e-12)]
    t, cmd = result.times, result.column("plant.mass_position_cmd")
    setpoint = result.column("controller.yaw_setpoint")
    assert setpoint[t < 20.005].max() == 0.0 and setpoint[t > 20.005].min() == 0.5
    # plant.mass_position_cmd in row n is what the plant was given at t_{n-1}: the
    # controller's command from its step at 20.00 holds over rows 2001-2002 and changes
    # only with its step from t = 20.02 (row 2003): the new setpoint, seen then
    n = int(np.argmin(np.abs(t - 20.0)))
    assert cmd[n + 1] == cmd[n + 2] and cmd[n + 3] != cmd[n + 2]


@pytest.mark.slow
def test_mass_jam_holds_the_mass_and_thruster_off_zeroes_the_thruster(fmu_dir: Path) -> None:
    turn = TURN.format(time=20.0)
    jam = bs3(fmu_dir, turn + '[[faults]]\nkind = "mass-jam"\nstart = 15.0\n', stop_time=30.0)
    t, mass = jam.times, jam.column("plant.mass_position")
    after = t >= 15.0
    assert np.ptp(mass[after]) < 1e-4  # jammed (it settles from its speed at 15 s)
    assert np.all(jam.column("plant.mass_position_cmd")[1:][t[:-1] >= 15.0] == mass[t == 15.0])
    off = bs3(fmu_dir, turn + '[[faults]]\nkind = "thruster-off"\nstart = 15.0\n', stop_time=30.0)
    force = off.column("plant.tunnel_force")  # row n: what the plant was given at t_{n-1}
    assert np.all(force[1:][off.times[:-1] >= 15.0] == 0.0)
    assert np.max(np.abs(force[1:][off.times[:-1] < 15.0])) > 1.0
    assert np.ptp(off.column("plant.mass_position")[after]) > 0.05  # the mass still moves
    assert np.array_equal(off.column("fault.fault-1"), after.astype(float))


def test_an_actuator_fault_on_an_unconnected_input_holds_it_then_lets_go(fmu_dir: Path) -> None:
    text = (
        'id = "plant-alone"\nstop_time = 1.0\n[coupling]\nstep = 0.01\n'
        '[instances.plant]\nfmu = "AuvPlant"\n[instances.plant.start]\n'
        "variant = 1\nu_0 = 1.5\ntunnel_force = 5.0\n"
        '[[faults]]\nkind = "thruster-off"\nstart = 0.5\nstop = 0.8\n'
    )
    result = master.run(scenario_from_toml(text, "plant-alone", fmu_dir=fmu_dir))
    t, force = result.times, result.column("plant.tunnel_force")
    off = (t >= 0.5 - 1e-9) & (t < 0.8 - 1e-9)
    assert np.all(force[off] == 0.0) and np.all(force[~off] == 5.0)


@pytest.mark.parametrize("first, second", [((0.3, 0.6), (0.5, 0.8)), ((0.3, 0.8), (0.5, 0.6))])
def test_overlapping_actuator_faults_on_an_unconnected_input_let_go_once_both_stop(
    fmu_dir: Path, first: tuple[float, float], second: tuple[float, float]
) -> None:
    # two thruster-off faults on the plant's unconnected tunnel_force (5 N), overlapping:
    # the thruster is off while either acts and back at 5 N once both have stopped
    faults = "".join(
        f'[[faults]]\nkind = "thruster-off"\nstart = {start}\nstop = {stop}\n'
        for start, stop in (first, second)
    )
    text = (
        'id = "plant-alone"\nstop_time = 1.0\n[coupling]\nstep = 0.01\n'
        '[instances.plant]\nfmu = "AuvPlant"\n[instances.plant.start]\n'
        "variant = 1\nu_0 = 1.5\ntunnel_force = 5.0\n" + faults
    )
    result = master.run(scenario_from_toml(text, "plant-alone", fmu_dir=fmu_dir))
    t, force = result.times, result.column("plant.tunnel_force")
    end = max(first[1], second[1])
    off = (t >= 0.3 - 1e-9) & (t < end - 1e-9)
    assert np.all(force[off] == 0.0), force[off]
    assert np.all(force[~off] == 5.0), f"after both faults stopped: {force[t >= end - 1e-9]}"


@pytest.mark.slow
@pytest.mark.parametrize("fault", ['kind = "gain"\nvalue = 1e308', 'kind = "noise"\nstd = 1e300'])
def test_a_fault_driving_the_plant_out_of_range_is_one_line_without_warnings(
    fmu_dir: Path, tmp_path: Path, fault: str
) -> None:
    """A fault gain of 1e308 or noise of std 1e300 printed numpy's RuntimeWarnings (from
    the plant, in the host's process) before the reason."""
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 60.0", "stop_time = 1.0")
    scenario = tmp_path / "f.toml"
    scenario.write_text(text + f'[[faults]]\ntarget = "plant.mass_position_cmd"\n{fault}\n')
    command = [sys.executable, "-m", "cosim.cli", "run", str(scenario), "--no-rrd", "--quiet"]
    command += ["--out", str(tmp_path / "out"), "--fmu-dir", str(fmu_dir)]
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert "Warning" not in done.stderr
    assert "= nan: expected a finite number" in done.stderr


def _followed(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch, text: str, variable: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The scenario ``text`` run with the plant's input ``variable`` spied on: the
    plant's points t (s), the value given there, and the value the polynomial it follows
    over its step of 0.01 s reaches at the step's end (held: the value given)."""
    from cosim.engine import points

    seen: list[tuple[float, float, float]] = []
    giver = points.inputs_giver

    def spying_giver(z: np.ndarray, timeline: object) -> points.Give:
        give = giver(z, timeline)  # type: ignore[arg-type]

        def spied(slave, n: int, t: float, again: bool = False) -> None:
            give(slave, n, t, again)
            if slave.name == "plant" and not again:
                vr = slave.instance.variable(variable).valueReference
                i = list(slave.input_vrs).index(vr)
                rates = slave.input_rates
                sent = rates.derivatives(t) if rates is not None else None
                first, second = (0.0, 0.0) if sent is None else (sent[0][i], sent[1][i])
                h = 0.01
                seen.append((t, slave.inputs[i], slave.inputs[i] + h * first + h * h / 2 * second))

        return spied

    monkeypatch.setattr(master, "inputs_giver", spying_giver)
    result = master.run(scenario_from_toml(text, "spied", SCENARIO_FOLDER, fmu_dir))
    assert result.complete, result.error
    t, given, reached = (np.array(column) for column in zip(*seen, strict=True))
    return t, given, reached


def _followed_inputs(
    fmu_dir: Path,
    monkeypatch: pytest.MonkeyPatch,
    algorithm: str,
    order: str,
    series: Path | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """depth-steps to 10.1 s (its set-point steps from 1 m to 3 m at 10 s, and the
    stern-plane command jumps to its 25 deg limit) under ``algorithm`` and ``order``,
    quadratic inputs, its events replaced by a ``series`` file if given: :func:`_followed`
    of the plant's fin_angle (rad)."""
    text = (SCENARIO_FOLDER / "depth-steps.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 110.0", "stop_time = 10.1")
    text = text.replace('algorithm = "gauss-seidel"', f'algorithm = "{algorithm}"')
    text = text.replace('order = ["controller", "plant"]', f"order = {order}")
    if series is not None:
        text = text[: text.index("[[events]]")]
        text += f'[[events]]\nname = "profile"\nseries = "{series.as_posix()}"\n'
    return _followed(fmu_dir, monkeypatch, text, "fin_angle")


@pytest.mark.parametrize(
    ("algorithm", "order"),
    [
        ("jacobi", '["controller", "plant"]'),
        ("gauss-seidel", '["plant", "controller"]'),
        ("gauss-seidel", '["controller", "plant"]'),
    ],
)
def test_no_input_is_extrapolated_across_a_jump_its_source_makes_after_an_event(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch, algorithm: str, order: str
) -> None:
    """An event sets the autopilot's depth set-point at 10 s; its fin command jumps from
    -5.3 to +25 deg (its limit). Under Jacobi, or with the plant before the autopilot,
    the plant gets the jump one point later than the event, where its input history
    had already started again: extrapolated through the jump, the plant followed the fin
    to 55 deg over the next step and back to -5.3 deg over the one after. Now the polynomial
    the plant follows never leaves the range of the commands it was given."""
    t, given, reached = _followed_inputs(fmu_dir, monkeypatch, algorithm, order)
    window = (t > 9.9) & (t < 10.1)
    low, high = given[window].min(), given[window].max()
    slack = 1e-6 * (high - low)
    outside = window & ((reached < low - slack) | (reached > high + slack))
    shown = [f"{a:.2f} s: {math.degrees(b):.1f} deg" for a, b in zip(t, reached, strict=True)]
    assert not outside.any(), [line for line, out in zip(shown, outside, strict=True) if out]


@pytest.mark.parametrize(
    ("algorithm", "order"),
    [("gauss-seidel", '["controller", "plant"]'), ("jacobi", '["controller", "plant"]')],
)
def test_no_input_is_extrapolated_across_a_step_of_a_held_series(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch, tmp_path: Path, algorithm: str, order: str
) -> None:
    """A series (held between its times) steps the depth set-point from 1 m to 3 m at
    10 s: it wrote the new value without starting any input history again, so even
    with the autopilot first the plant followed its stern plane through the command's
    jump to 55 deg. Now a series' step is a jump as an event's is."""
    series = tmp_path / "profile.csv"
    series.write_text("time,controller.depth_setpoint\n0,1.0\n10,3.0\n", encoding="utf-8")
    t, given, reached = _followed_inputs(fmu_dir, monkeypatch, algorithm, order, series)
    window = (t > 9.9) & (t < 10.1)
    low, high = given[window].min(), given[window].max()
    assert high - low > 0.5  # the command jumped
    slack = 1e-6 * (high - low)
    outside = window & ((reached < low - slack) | (reached > high + slack))
    shown = [f"{a:.2f} s: {math.degrees(b):.1f} deg" for a, b in zip(t, reached, strict=True)]
    assert not outside.any(), [line for line, out in zip(shown, outside, strict=True) if out]


def test_an_input_from_a_slower_instance_is_not_extrapolated_through_its_stairs(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """bs-3 with the autopilot stepping every 2 steps (step_multiples) and quadratic
    inputs: the plant took the held command (the same value at two points in a row, then
    a new one) as points of a smooth signal, and the polynomial through those stairs
    zigzagged, missing the next command by 2.99 N where holding it misses by at most the
    largest change between two points (1.49 N). Now an input whose source steps less
    often than its instance is held."""
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 60.0", "stop_time = 3.0")
    text = text.replace(
        'order = ["controller", "plant"]',
        'order = ["controller", "plant"]\nstep_multiples = { controller = 2 }',
    )
    t, given, reached = _followed(fmu_dir, monkeypatch, text, "tunnel_force")
    missed = np.abs(reached[:-1] - given[1:])
    assert missed.max() <= np.abs(np.diff(given)).max() * (1 + 1e-12), (
        f"{missed.max():.3g} N at {t[np.argmax(missed)]:.2f} s"
    )
