"""An autopilot designed for another vehicle than the plant's, or given a gain that no law
it runs reads, is valid (a robustness study means the first), so it runs: a run says so
in one warning line each, naming the key and the value."""

from __future__ import annotations

import math
import warnings
from pathlib import Path
from typing import Any

import pytest

import cosim
from cosim.scenario.design_doubts import DesignWarning, design_doubts
from cosim.scenario.spec import scenario_from_toml

SWITCH = """
[[events]]
name = "switch"
time = 1.0
set = { "controller.heading_mode" = "sliding_mode" }
"""


def _load(fmu_paths: dict[str, Path], scenario: str | Path) -> cosim.Scenario:
    return cosim.load_scenario(scenario, fmu_dir=fmu_paths["AuvPlant"].parent)


def test_a_plant_of_another_vehicle_than_the_design_is_named(
    fmu_paths: dict[str, Path],
) -> None:
    """lqr-1 with plant.vehicle = remus100-long-fins ran without a word, its LQR designed
    on remus100's fins (Y_uv -17.9 where the plant has -25.2)."""
    scenario = _load(fmu_paths, "lqr-1").with_start({"plant.vehicle": "remus100-long-fins"})
    (line,) = design_doubts(scenario)
    assert line.startswith(
        "plant runs vehicle 'remus100-long-fins' but controller designs its laws for vehicle "
        "'remus100' (instances.controller.start.vehicle): the sets differ in Y_uv -25.2 vs "
        "-17.9"
    ), line
    both = scenario.with_start({"controller.vehicle": "remus100-long-fins"})
    assert design_doubts(both) == []
    written = _load(fmu_paths, "lqr-1").with_start({"plant.N_uv": -20.0})
    assert design_doubts(written) == [
        "plant runs vehicle 'remus100' with N_uv written over but controller designs its laws "
        "for vehicle 'remus100' (instances.controller.start.vehicle): the sets differ in "
        "N_uv -20.0 vs 4.57; give controller the plant's vehicle too (a set with the same "
        "values), unless the mismatch is meant"
    ]


def test_a_thrust_that_drives_another_speed_than_the_design_is_named(
    fmu_paths: dict[str, Path],
) -> None:
    """lqr-1 with thrust_command = 4 N ran at 1.017 m/s on an LQR designed for 1.525 m/s
    without a word (slow-1 sets both)."""
    slow = _load(fmu_paths, "lqr-1").with_start({"controller.thrust_command": 4.0})
    assert design_doubts(slow) == [
        "controller.design_speed = 1.525 m/s but its thrust_command = 4.0 N drives plant "
        "straight at 1.017 m/s: its laws are designed for another speed than they steer at; "
        "set design_speed = 1.017, unless the mismatch is meant"
    ]
    assert design_doubts(slow.with_start({"controller.design_speed": 1.017})) == []
    (astern,) = design_doubts(slow.with_start({"controller.thrust_command": -9.0}))
    assert astern.startswith("controller.design_speed = 1.525 m/s but its thrust_command = -9.0")
    assert "forward at no speed" in astern
    (fast,) = design_doubts(slow.with_start({"controller.thrust_command": 1e4}))
    assert "drives plant straight at 50.83 m/s" in fast
    off = slow.with_start({"controller.heading_mode": 0})  # no law: no design speed
    assert not [line for line in design_doubts(off) if "design_speed" in line]


def test_a_gain_no_selected_law_reads_is_named_with_its_value(
    fmu_paths: dict[str, Path],
) -> None:
    """smc_eta on backstepping, and lqr_q_yaw on the sliding mode (its reduced LQR drops
    the psi weight, (6.3.46)-(6.3.47)), were silently ignored."""
    scenario = _load(fmu_paths, "bs-3").with_start({"controller.smc_eta": 5.0})
    assert design_doubts(scenario) == [
        "instances.controller.start.smc_eta = 5.0 is read only by heading_mode sliding_mode, "
        "and controller runs heading_mode backstepping with depth_mode off: the value is not "
        "used"
    ]
    sliding = _load(fmu_paths, "lqr-1").with_start(
        {"controller.heading_mode": 2, "controller.lqr_q_yaw": 10.0, "controller.depth_k_p": 5}
    )
    assert [
        line.split(" is read only by ")[1].split(",")[0] for line in design_doubts(sliding)
    ] == [
        "heading_mode lqr",
        "depth_mode pd",
    ]
    (step,) = design_doubts(_load(fmu_paths, "bs-3").with_start({"controller.design_step": 0.02}))
    assert "read only by heading_mode lqr or sliding_mode or depth_mode pd," in step
    # the depth loop's gains are checked sampled at design_step: vert-2 reads it
    assert (
        design_doubts(_load(fmu_paths, "vert-2").with_start({"controller.design_step": 0.02})) == []
    )


def test_a_gain_of_a_law_an_event_or_a_live_key_switches_to_is_used(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    path = tmp_path / "switch.toml"
    path.write_text(text + SWITCH)
    scenario = _load(fmu_paths, path).with_start({"controller.smc_eta": 5.0})
    (held,) = design_doubts(scenario)  # the sliding mode switched to under "quadratic"
    assert held.startswith("controller runs heading_mode sliding_mode, a design for its"), held
    assert design_doubts(scenario.with_overrides(extrapolation="none")) == []
    # a live run's keys may switch to any law
    bs3 = _load(fmu_paths, "bs-3").with_start({"controller.smc_eta": 5.0})
    assert design_doubts(bs3, live=True) == [] != design_doubts(bs3)


@pytest.mark.parametrize("extrapolation", ["linear", "quadratic"])
def test_a_discrete_heading_law_whose_command_is_extrapolated_is_named(
    fmu_paths: dict[str, Path], extrapolation: str
) -> None:
    """The LQR and the sliding mode are designed on the plant discretised with its command
    held over each step. `auv-cosim run lqr-1 --extrapolation linear` extrapolated that
    command across the step instead: the mass command banged between -100 and +100 m every
    step (quadratic: the same, its yaw settling time reported as 0 s), without a word."""
    lqr = _load(fmu_paths, "lqr-1").with_overrides(extrapolation=extrapolation)
    assert design_doubts(lqr) == [
        "controller runs heading_mode lqr, a design for its command held over each step, but "
        f"coupling.extrapolation = {extrapolation!r} extrapolates controller.mass_position_cmd "
        "across the step: the loop run is not the one designed (lqr-1 so banged its mass "
        'command between -100 and +100 m every step); set extrapolation = "none", as '
        "lqr-1 to lqr-3 do"
    ]
    sliding = lqr.with_start({"controller.heading_mode": "sliding_mode"})
    (line,) = design_doubts(sliding)
    assert line.startswith("controller runs heading_mode sliding_mode, a design for its")
    assert design_doubts(_load(fmu_paths, "bs-3")) == []  # quadratic: a continuous design


def test_an_lqr_whose_command_reaches_the_plant_a_step_late_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """The shipped LQR's delay margin is just under one sample (`auv-cosim analyze
    margins`). `auv-cosim run lqr-1 --algorithm jacobi` hands the plant each command one
    step late: the run ended in a limit cycle, the mass command banging between -100 and
    +100 m and the heading never settling, without a word; so does a Gauss-Seidel order
    that steps the plant before the controller."""
    jacobi = _load(fmu_paths, "lqr-1").with_overrides(algorithm="jacobi")
    (line,) = design_doubts(jacobi)
    assert line.startswith(
        "controller runs heading_mode lqr, whose delay margin is under one of its 0.01 s "
        "samples (auv-cosim analyze margins), but coupling.algorithm = 'jacobi' hands "
        "controller.mass_position_cmd to plant one 0.01 s step late"
    ), line
    text = (Path(cosim.__file__).parent / "scenarios" / "lqr-1.toml").read_text()
    plant_first = tmp_path / "plant-first.toml"
    plant_first.write_text(text.replace('["controller", "plant"]', '["plant", "controller"]'))
    (line,) = design_doubts(_load(fmu_paths, plant_first))
    assert "coupling.order = ['plant', 'controller'] steps plant before controller" in line
    assert design_doubts(_load(fmu_paths, "lqr-1")) == []  # the command reaches it at once


def test_a_late_lqr_command_is_checked_at_the_step_the_autopilot_samples_at(
    fmu_paths: dict[str, Path],
) -> None:
    """lqr-1 designed for 2 ms, sampled and coupled every 4 ms under Jacobi: the check
    closed the loop of its 2 ms design with the command one 2 ms sample late, stable (its
    delay margin is over a step at 2 ms), and said nothing; the gains the autopilot runs,
    sampled every 4 ms and handed on 4 ms late, leave the loop unstable (|z| = 1.41). A
    loop those gains cannot hold even on time is named for its design step, not for the
    coupling."""
    late = (
        _load(fmu_paths, "lqr-1")
        .with_start({"controller.design_step": 0.002, "controller.sample_period": 0.004})
        .with_overrides(step=0.004, algorithm="jacobi")
    )
    (line,) = design_doubts(late)
    assert line.startswith(
        "controller runs heading_mode lqr designed for 0.002 s samples (design_step) but "
        "sampling every 0.004 s, whose loop so sampled is unstable with its command 0.004 s "
        "late, and coupling.algorithm = 'jacobi' hands controller.mass_position_cmd to plant "
        "one 0.004 s step late"
    ), line
    assert 'use algorithm = "gauss-seidel"' in line, line
    on_time = late.with_overrides(algorithm="gauss-seidel")
    assert design_doubts(on_time) == []  # the 2 ms gains sampled every 4 ms, on time: stable
    slower = late.with_start({"controller.design_step": 0.001})  # unstable even on time
    (line,) = design_doubts(slower)
    assert line.endswith(
        "its gains are unstable at that sample time even with the command on time: set "
        "design_step = 0.004 s, the time it samples at"
    ), line


def _gain_fault(fmu_paths: dict[str, Path], tmp_path: Path, gain: float) -> cosim.Scenario:
    """lqr-1 with a gain fault of ``gain`` on its command to plant.mass_position_cmd from
    t = 1 s: the loop broken where `auv-cosim analyze margins` breaks it."""
    text = (Path(cosim.__file__).parent / "scenarios" / "lqr-1.toml").read_text()
    text += '\n[[faults]]\nname = "servo"\ntarget = "plant.mass_position_cmd"\n'
    text += f'kind = "gain"\nvalue = {gain!r}\nstart = 1.0\n'
    path = tmp_path / f"gain-{gain!r}.toml"
    path.write_text(text)
    return _load(fmu_paths, path)


def test_a_gain_fault_past_the_lqr_loops_gain_margins_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """lqr-1 with a gain fault of 1.1 times the upper gain margin `auv-cosim analyze
    margins` prints on its mass command ran without a word: the command swung between its
    +-100 m limits at every step and rattled the mass on its stops, while the key figures
    looked better than the stable loop's (the heading strays less: the servo filters the
    314 rad/s command). The warning is given exactly outside the margins, and says where
    to look; below the lower margin the heading turns away instead."""
    from cosim.analysis.margins import loop_margins, lqr_loop
    from plant_fmu.model.parameters import load_vehicle

    margins = loop_margins(lqr_loop(load_vehicle("remus100"), 1.525, 0.01))
    upper, lower = margins.upper_gain_margin, margins.lower_gain_margin
    assert upper is not None and lower is not None
    (line,) = design_doubts(_gain_fault(fmu_paths, tmp_path, 1.1 * upper.value))
    assert line.startswith(
        f"faults.servo: a gain of {1.1 * upper.value:.4g} on plant.mass_position_cmd (the "
        "command of controller's heading_mode lqr) is outside that loop's gain margins "
        "(auv-cosim analyze margins), so from t = 1 s it is unstable at 314 rad/s"
    ), line
    # the key figures show it since they have the commands' activity (a chattering
    # command's total variation per second): the line said they did not
    assert line.endswith(
        "its command swings between its limits at every step, the mass on its stops, while "
        "the heading strays less than a stable loop's: its yaw settling time does not show "
        "it, the command (controller.mass_position_cmd) and its activity (the key figure "
        "mass_position_cmd_variation_m_per_s) do"
    ), line
    assert design_doubts(_gain_fault(fmu_paths, tmp_path, 0.9 * upper.value)) == []
    (line,) = design_doubts(_gain_fault(fmu_paths, tmp_path, 0.8 * lower.value))
    assert "its heading turns away, its error doubling every" in line, line
    assert design_doubts(_gain_fault(fmu_paths, tmp_path, 1.25 * lower.value)) == []


def test_a_gain_fault_that_reverses_the_command_is_not_called_slow(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A gain of -1 (a command wired reversed) puts lqr-1's loop pole at z = 2.02 a
    0.01 s sample, an error doubling every 10 ms, and the warning said "its heading turns
    away, slowly", as it does of a gain just under the lower margin (doubling in 22 s).
    The line gives the pace from the pole, as the time the error takes to double."""
    (line,) = design_doubts(_gain_fault(fmu_paths, tmp_path, -1.0))
    assert "slowly" not in line, line
    assert line.endswith("its heading turns away, its error doubling every 0.0099 s"), line
    import control

    from cosim.analysis.margins import lqr_loop
    from plant_fmu.model.parameters import load_vehicle

    loop = lqr_loop(load_vehicle("remus100"), 1.525, 0.01)  # the linear loop at a gain of 0.1
    slowest = max(control.poles(control.feedback(0.1 * loop, 1.0)), key=abs)
    doubling = math.log(2.0) / (math.log(abs(slowest)) / 0.01)
    (line,) = design_doubts(_gain_fault(fmu_paths, tmp_path, 0.1))
    assert line.endswith(f"its heading turns away, its error doubling every {doubling:.2g} s")


def _delay_fault(
    fmu_paths: dict[str, Path], tmp_path: Path, steps: int, step: float = 0.01
) -> cosim.Scenario:
    """lqr-1 at a communication step of ``step`` s with a delay fault of ``steps`` of the
    plant's steps on its command to plant.mass_position_cmd from t = 1 s."""
    text = (Path(cosim.__file__).parent / "scenarios" / "lqr-1.toml").read_text()
    text += '\n[[faults]]\nname = "late"\ntarget = "plant.mass_position_cmd"\n'
    text += f'kind = "delay"\nsteps = {steps}\nstart = 1.0\n'
    path = tmp_path / f"delay-{steps}.toml"
    path.write_text(text)
    return _load(fmu_paths, path).with_overrides(step=step)


def test_a_delay_fault_past_the_lqr_loops_delay_margin_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """lqr-1 with a delay fault of one step on its mass command ran without a word,
    though one step is past its 0.987-step delay margin and the command grows at 104
    rad/s (docs/model.md#lqr): the loop's poles took a delay of one sample at most. The
    warning names the fault, the margin and how fast it grows; it is given exactly
    outside the margin `auv-cosim analyze margins` prints (the plant stepping every 1 ms,
    the autopilot sampling every 10 ms: 9 steps inside the 9.87 ms, 10 outside)."""
    from cosim.analysis.margins import loop_margins, lqr_loop
    from plant_fmu.model.parameters import load_vehicle

    margin = loop_margins(lqr_loop(load_vehicle("remus100"), 1.525, 0.01)).delay_margin
    assert margin is not None
    (line,) = design_doubts(_delay_fault(fmu_paths, tmp_path, 1))
    assert line.startswith(
        "faults.late: a delay of 1 step (0.01 s) on plant.mass_position_cmd (the command of "
        "controller's heading_mode lqr) is past that loop's delay margin of 0.00992 s "
        "(auv-cosim analyze margins; its command held between samples)"
    ), line
    assert math.isclose(0.00992, margin.value, rel_tol=0.01)  # analyze margins' PM / w_c
    assert "so from t = 1 s it is unstable, swinging at 104 rad/s" in line, line
    assert line.endswith("the command (controller.mass_position_cmd) shows it"), line
    inside, outside = math.floor(margin.value / 0.001), math.ceil(margin.value / 0.001)
    assert (inside, outside) == (9, 10)
    assert design_doubts(_delay_fault(fmu_paths, tmp_path, inside, 0.001)) == []
    (line,) = design_doubts(_delay_fault(fmu_paths, tmp_path, outside, 0.001))
    assert line.startswith("faults.late: a delay of 10 steps (0.01 s) on"), line


def test_every_fault_past_the_loops_margins_is_named_not_only_the_first(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """lqr-1 with a gain fault of 3 (past the upper gain margin, ~1.99) and a delay fault
    of one step (past the delay margin): each gets its line, in the file's order."""
    text = (Path(cosim.__file__).parent / "scenarios" / "lqr-1.toml").read_text()
    for name, kind in (
        ("servo", 'kind = "gain"\nvalue = 3.0'),
        ("late", 'kind = "delay"\nsteps = 1'),
    ):
        text += f'\n[[faults]]\nname = "{name}"\ntarget = "plant.mass_position_cmd"\n'
        text += f"{kind}\nstart = 1.0\n"
    path = tmp_path / "two-faults.toml"
    path.write_text(text)
    lines = design_doubts(_load(fmu_paths, path))
    assert [line.split(":", 1)[0] for line in lines] == ["faults.servo", "faults.late"], lines


def test_the_sliding_mode_s_late_command_and_gain_faults_are_named_as_the_lqr_s(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """lqr-1 with heading_mode sliding_mode under Jacobi banged its mass command between
    -100 and +100 m from its first seconds, its heading 47 deg off after 40 s, and a gain
    fault of 2.12 on its command chattered it between its limits at every step (1.74 did
    not; 0.018 turned its heading away), without a word: the warnings covered the LQR only.
    Inside its boundary layer the sliding mode is a linear law, whose loop has a delay
    margin of 0.98 samples and gain margins of 0.023 and 1.93: it is warned of where that
    loop is unstable, as the LQR is."""
    sliding = {"controller.heading_mode": "sliding_mode"}
    jacobi = _load(fmu_paths, "lqr-1").with_overrides(algorithm="jacobi").with_start(sliding)
    (line,) = design_doubts(jacobi)
    assert line.startswith(
        "controller runs heading_mode sliding_mode, whose delay margin is under one of its "
        "0.01 s samples (its loop inside the boundary layer, docs/model.md#sliding-mode), but "
        "coupling.algorithm = 'jacobi' hands controller.mass_position_cmd to plant one 0.01 s "
        "step late"
    ), line
    assert design_doubts(_load(fmu_paths, "lqr-1").with_start(sliding)) == []

    def faulted(gain: float) -> list[str]:
        return design_doubts(_gain_fault(fmu_paths, tmp_path, gain).with_start(sliding))

    (line,) = faulted(2.12)
    assert line.startswith(
        "faults.servo: a gain of 2.12 on plant.mass_position_cmd (the command of "
        "controller's heading_mode sliding_mode) is outside that loop's gain margins (its "
        "loop inside the boundary layer, docs/model.md#sliding-mode), so from t = 1 s it is "
        "unstable"
    ), line
    assert line.endswith("its activity (the key figure mass_position_cmd_variation_m_per_s) do")
    assert faulted(1.74) == []
    (line,) = faulted(0.018)
    assert "its heading turns away, its error doubling every" in line, line


@pytest.mark.slow
@pytest.mark.parametrize("design_step", [0.001, 0.002, 0.004, 0.01, 0.05])
def test_a_late_lqr_command_is_named_only_where_the_delay_margin_is_under_a_step(
    fmu_paths: dict[str, Path], design_step: float
) -> None:
    """lqr-1 designed for, sampled and coupled at 1 ms under Jacobi was warned of as "the
    loop is unstable", yet settled as lqr-1 does (yaw within 1 deg after 16.1 s): at
    1 to 3 ms the delay margin `auv-cosim analyze margins --step H` prints is more than
    one step (1.05 steps at 1 ms). The warning is given exactly where that margin is
    under the step the command arrives late by."""
    from cosim.analysis.margins import loop_margins, lqr_loop
    from plant_fmu.model.parameters import load_vehicle

    h = design_step
    late = (
        _load(fmu_paths, "lqr-1")
        .with_start({"controller.design_step": h, "controller.sample_period": h})
        .with_overrides(step=h, algorithm="jacobi")
    )
    margin = loop_margins(lqr_loop(load_vehicle("remus100"), 1.525, h)).delay_margin
    assert margin is not None
    doubts = design_doubts(late)
    assert len(doubts) == (1 if margin.value < h else 0), (margin, doubts)


def test_depth_set_points_further_apart_than_any_pitch_can_follow_are_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """depth-steps with its 2 m step made 50 m ran without a word: Table 6.2's gamma asks
    0.772 rad of pitch per metre, -38.6 rad for 50 m, and with no depth_pitch_limit the
    vehicle pitched over the vertical and looped. Its own 2 m step asks 88 deg: no doubt."""
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "depth-steps.toml").read_text()
    path = tmp_path / "deep.toml"
    path.write_text(
        text.replace('"controller.depth_setpoint" = 3.0', '"controller.depth_setpoint" = 51.0')
    )
    deep = _load(fmu_paths, path)
    assert design_doubts(deep) == [
        "controller's depth loop (depth_gamma = -0.772 rad/m) asks for a pitch of up to "
        "38.6 rad (2212 deg) between the depths 1 m and 51 m of this scenario (plant.down_0, "
        "its depth_setpoint and events), beyond the 90 deg any pitch can be: its fins stay on "
        "their stop until the vehicle pitches over; set depth_pitch_limit (rad, at most "
        "1.571), unless that is meant"
    ]
    assert design_doubts(deep.with_start({"controller.depth_pitch_limit": 0.5})) == []
    assert design_doubts(deep.with_start({"controller.depth_mode": "off"})) == []
    start = _load(fmu_paths, "depth-steps").with_start({"plant.down_0": 30.0})
    (line,) = design_doubts(start)
    assert "between the depths 1 m and 30 m" in line


def test_every_law_parameter_listed_is_an_autopilot_parameter() -> None:
    from controller_fmu.autopilot import AutopilotConfig
    from controller_fmu.modes import DEPTH_LAW_PARAMETERS, HEADING_LAW_PARAMETERS

    fields = set(AutopilotConfig.field_info())
    assert set(HEADING_LAW_PARAMETERS) | set(DEPTH_LAW_PARAMETERS) <= fields


BUILT_IN = sorted(
    p.stem for p in (Path(__file__).parents[3] / "cosim" / "scenarios").glob("*.toml")
)


@pytest.mark.parametrize("scenario", BUILT_IN)
def test_the_built_in_scenarios_raise_no_doubt(fmu_paths: dict[str, Path], scenario: str) -> None:
    assert design_doubts(_load(fmu_paths, scenario)) == []


@pytest.mark.slow
def test_a_run_warns_and_still_runs(fmu_paths: dict[str, Path]) -> None:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = cosim.run(
            "bs-3", stop_time=0.1, start={"controller.k0": 0.3, "controller.smc_eta": 2.0},
            fmu_dir=fmu_paths["AuvPlant"].parent,
        )  # fmt: skip
    lines = [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]
    assert result.complete
    assert len(lines) == 1 and lines[0].startswith("instances.controller.start.smc_eta = 2.0")


def test_a_waypoint_dive_steeper_than_any_pitch_can_follow_is_named(
    fmu_paths: dict[str, Path],
) -> None:
    """The survey with its second waypoint at 150 m depth, 50 m on, ran without a word: the
    guidance's depth set-point, one 8 m lookahead along a leg falling 148 m in 50 m, is
    23.7 m below the vehicle, Table 6.2's gamma asks 18.3 rad of pitch for it, and with no
    depth_pitch_limit the vehicle pitched to -80 deg and sank 40 m in 80 s, 19 m on. The
    same depths given by events were named; given by waypoints they were not."""
    survey = _load(fmu_paths, "survey")
    assert design_doubts(survey) == []  # a level mission
    deep = survey.with_start({"guidance.waypoints": "0, 0, 2; 50, 0, 150; 100, 0, 2"})
    (line,) = design_doubts(deep)
    assert line.startswith(
        "controller's depth loop (depth_gamma = -0.772 rad/m) asks for a pitch of up to "
        "18.3 rad (1047 deg) on leg 1 of guidance's waypoints (waypoint 1 -> 2, from 2 m to "
        "150 m depth over 50 m)"
    ), line
    assert design_doubts(deep.with_start({"controller.depth_pitch_limit": 0.5})) == []
    gentle = survey.with_start({"guidance.waypoints": "0, 0, 2; 200, 0, 10"})
    assert design_doubts(gentle) == []  # 8 m over 200 m: the set-point leads by 0.32 m


def test_a_gain_faster_than_the_autopilot_samples_is_named(fmu_paths: dict[str, Path]) -> None:
    """bs-3 with k1 = 1e6 (a gain typed a million times too large) ran without a word, its
    moving mass banging on the rail's stops: a loop that corrects its error at k per
    second but acts only every h seconds over-corrects within one step once k h > 2."""
    bs3 = _load(fmu_paths, "bs-3")
    (line,) = design_doubts(bs3.with_start({"controller.k1": 1e6}))
    assert line == (
        "instances.controller.start.k1 = 1e+06 1/s with the controller acting every 0.01 s: "
        "k1 * 0.01 s = 1e+04, past 2, where a loop whose command is held over a step "
        "over-corrects its error within the step; the default is k1 = 1"
    ), line
    assert design_doubts(bs3.with_start({"controller.k1": 150.0})) == []  # k h = 1.5
    sampled = bs3.with_start({"controller.k1": 150.0, "controller.sample_period": 0.05})
    (line,) = design_doubts(sampled)
    assert "acting every 0.05 s: k1 * 0.05 s = 7.5, past 2" in line, line


def test_a_mass_command_limit_short_of_the_vehicles_stroke_is_named(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """bs-3 on a vehicle of a 9 cm stroke ran without a word with the autopilot's default
    mass_position_cmd_limit, REMUS 100's 6 cm: the autopilot never moved the mass past
    6 cm, a third of its rail unused, whatever vehicle it was given."""
    wide = tmp_path / "wide-rail.toml"
    wide.write_text('base = "remus100"\nname = "wide-rail"\n[moving_mass]\nmass_stroke = 0.09\n')
    vehicle = {"plant.vehicle": str(wide), "controller.vehicle": str(wide)}
    bs3 = _load(fmu_paths, "bs-3").with_start(vehicle)
    assert design_doubts(bs3) == [
        "controller.mass_position_cmd_limit = 0.06 m (its default, REMUS 100's stroke) is "
        "short of plant's mass_stroke = 0.09 m: the autopilot never moves the mass past "
        "0.06 m of its 0.09 m rail; set mass_position_cmd_limit = 0.09, unless that is meant"
    ]
    assert design_doubts(bs3.with_start({"controller.mass_position_cmd_limit": 0.09})) == []
    assert design_doubts(bs3.with_start({"controller.heading_mode": "off"})) == []
    given = bs3.with_start({"controller.mass_position_cmd_limit": 0.05})
    (line,) = design_doubts(given)
    assert line.startswith("controller.mass_position_cmd_limit = 0.05 m is short of"), line


def test_two_vehicles_each_autopilot_is_checked_against_its_own_plant(
    fmu_paths: dict[str, Path],
) -> None:
    """Two vehicles of two parameter sets, each autopilot designed for its own plant's:
    each autopilot was checked against every plant, so the run warned twice that an
    autopilot was designed for the other vehicle's set, which it never steers. A
    mismatch within one vehicle is still named, once."""
    from two_vehicles import two_vehicles_toml

    fmu_dir = fmu_paths["AuvPlant"].parent
    fins = {"plant_b.vehicle": "remus100-long-fins", "ctrl_b.vehicle": "remus100-long-fins"}
    scenario = scenario_from_toml(two_vehicles_toml(), fmu_dir=fmu_dir).with_start(fins)
    assert design_doubts(scenario) == []
    mismatched = scenario.with_start({"ctrl_b.vehicle": "remus100"})
    (line,) = design_doubts(mismatched)
    assert line.startswith("plant_b runs vehicle 'remus100-long-fins' but ctrl_b designs"), line


def test_a_gain_fault_of_one_of_two_vehicles_names_that_vehicles_key_figure(
    fmu_paths: dict[str, Path],
) -> None:
    """The gain fault's warning names the key figure that shows the chatter; of two
    vehicles, the one of the faulted vehicle (each plant's figures carry its name)."""
    from two_vehicles import two_vehicles_toml

    from cosim.metrics.key_figures import ACTIVITY_FIGURES

    fault = '[[faults]]\nname = "servo"\ntarget = "plant_a.mass_position_cmd"\n'
    text = f'{two_vehicles_toml()}\n{fault}kind = "gain"\nvalue = 3.0\nstart = 1.0\n'
    scenario = scenario_from_toml(text, fmu_dir=fmu_paths["AuvPlant"].parent)
    (line,) = design_doubts(scenario)
    assert line.startswith("faults.servo: a gain of 3 on plant_a.mass_position_cmd"), line
    figure = "plant_a.mass_position_cmd_variation_m_per_s"
    assert line.endswith(f"its activity (the key figure {figure}) do"), line
    assert figure.removeprefix("plant_a.") in ACTIVITY_FIGURES


def test_a_study_s_points_with_the_same_loop_design_it_once(
    fmu_paths: dict[str, Path], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study checks every grid point: lqr-1 under Jacobi designed its LQR again and
    found its straight-run speed again at each (86 ms a point on a busy machine, a
    1000-point study waiting a minute before its first run). A point that differs from
    another only where the loop does not (the plant's start sway) designs nothing again,
    and is warned of as the first."""
    import controller_fmu.lqr
    import plant_fmu.model.root_finding

    designed: list[object] = []
    lqr, root = controller_fmu.lqr.LqrHeading, plant_fmu.model.root_finding.brent_root

    def counted(original: Any) -> Any:
        def call(*args: Any, **kwargs: Any) -> Any:
            designed.append(original)
            return original(*args, **kwargs)

        return call

    monkeypatch.setattr(controller_fmu.lqr, "LqrHeading", counted(lqr))
    monkeypatch.setattr(plant_fmu.model.root_finding, "brent_root", counted(root))
    jacobi = _load(fmu_paths, "lqr-1").with_overrides(algorithm="jacobi")
    (first,) = design_doubts(jacobi.with_start({"plant.v_0": -0.02}))
    designed.clear()
    (second,) = design_doubts(jacobi.with_start({"plant.v_0": -0.03}))
    assert designed == []
    assert second == first
    assert "whose delay margin is under one of its 0.01 s samples" in first, first
