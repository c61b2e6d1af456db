"""Chapter 6's closed-loop simulations: the built-in scenarios run through our master
(``cosim.run``) and checked against what the text says about them.

Expensive (tens of seconds a run): ``auv-cosim reproduce --skip-scenarios`` leaves them
out. The vehicle is ``remus100`` as shipped (W = m g, g = 9.8), as in Chapter 6.
"""

from __future__ import annotations

import math
import shutil
import time
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path

import numpy as np

from cosim.analysis.reference_values import Reference
from cosim.metrics.key_figures import settling_time
from cosim.reproduction.context import Context, RunData
from cosim.reproduction.record import (
    Absolute,
    Claim,
    Cost,
    Figure,
    Finding,
    LastDigit,
    Relative,
    Section,
    Tolerance,
    unit_text,
)

BAND = math.radians(1.0)  # "back to zero": |psi| < 1 deg for good
ABOUT = 5.0  # s: the slack an "about N seconds" of the text is tested with
LAST = 10.0  # s: the window of a steady state at the end of a run
REPORT_FIGURES = ("velocities", "attitude_actuators", "trajectory", "depth")
FIGURE_SCENARIOS = ("lqr-2", "bs-3", "cur-2", "vert-2")
LQR_2 = (
    "with the mass on its stop (y_v = -6 cm) the yaw moment it can make is capped and the "
    "heading comes back on the slow closed-loop mode. An independent reproduction of this "
    "case (continuous LQR gains, RK4 at 0.2 ms) also needs 28-34 s to stay within 1 deg, so "
    "the 20 s claim does not hold for this model. Like the dissertation (Sec. 6.3.1 bounds "
    "y_v and y_vel only), the scenario leaves the servo command unsaturated; saturating it "
    "at the 6 cm stroke slows the mass to ~6 cm/s and the settling to 43 s."
)


def runner(
    work: Path, log: Callable[[str], None] | None = None, fmu_dir: Path | None = None
) -> Callable[[str], RunData]:
    """Runs a built-in scenario into ``work/<id>`` (no recording; the FMUs in ``fmu_dir``,
    default: the master's) and reads its results."""
    options = {} if fmu_dir is None else {"fmu_dir": fmu_dir}

    def run(scenario_id: str) -> RunData:
        from cosim.outputs.results import read_csv
        from cosim.runner import run_scenario

        started = time.perf_counter()
        outcome = run_scenario(scenario_id, work / scenario_id, no_rrd=True, **options)
        if log is not None:
            log(f"  {scenario_id}: ran in {time.perf_counter() - started:.0f} s")
        if not outcome.result.complete:
            raise RuntimeError(f"the run did not complete: {outcome.result.error}")
        columns, values = read_csv(outcome.paths["results"])
        table = {name: values[:, k] for k, name in enumerate(columns)}
        return RunData(table, work / scenario_id)

    return run


def _time(value: float | None) -> str:
    return "never" if value is None else f"{value:.1f} s"


def heading_summary(run: RunData) -> tuple[str, float | None]:
    """'peak |psi| ..., |psi| < 1 deg first at ..., for good from ...' and the settling
    time (for good, s; None if never)."""
    t, yaw = run["time"], run["plant.yaw"]
    k0 = int(np.argmax(np.abs(yaw)))
    inside = np.flatnonzero(np.abs(yaw[k0:]) < BAND)
    first = float(t[k0 + inside[0]]) if inside.size else None
    settled = settling_time(t, yaw, BAND, angle=True)
    text = (
        f"peak |psi| {math.degrees(abs(yaw[k0])):.1f} deg at {t[k0]:.1f} s; "
        f"|psi| < {math.degrees(BAND):.0f} deg first at {_time(first)}, "
        f"for good from {_time(settled)}"
    )
    return text, settled


def _heading_back(scenario_id: str, within: float, ctx: Context) -> Finding:
    text, settled = heading_summary(ctx.run(scenario_id))
    return Finding(shown=text, holds=settled is not None and settled <= within)


def _lqr_2(stop_cm: float, within: float, ctx: Context) -> Finding:
    run = ctx.run("lqr-2")
    text, settled = heading_summary(run)
    saturated = float(np.min(run["plant.mass_position"]))
    peak = math.degrees(float(np.max(np.abs(run["plant.yaw"]))))
    rail_speed = 100 * float(np.max(np.abs(run["plant.mass_velocity"])))
    return Finding(
        shown=f"min y_v = {100 * saturated:.2f} cm; {text}",
        holds=abs(saturated - stop_cm / 100) < 1e-3 and settled is not None and settled <= within,
        note=f"Ours peaks at {peak:.1f} deg of yaw where Fig. 6.14's axis ends at 10 deg, "
        f"with rail speeds up to {rail_speed:.0f} cm/s (its axis: +-50 cm/s).",
    )


def _course(run: RunData) -> tuple[float, float, np.ndarray]:
    """Course over ground (deg) and east speed (m/s) over the last 10 s, and that window."""
    t = run["time"]
    last = t >= t[-1] - LAST
    v_north = np.polyfit(t[last], run["plant.north"][last], 1)[0]
    v_east = np.polyfit(t[last], run["plant.east"][last], 1)[0]
    return math.degrees(math.atan2(v_east, v_north)), float(v_east), last


def _current_drift(ctx: Context) -> Finding:
    run = ctx.run("cur-1")
    course, v_east, _ = _course(run)
    yaw = math.degrees(run["plant.yaw"][-1])
    return Finding(
        shown=f"heading {yaw:.2f} deg, course over ground {course:.2f} deg, "
        f"east drift {v_east:.3f} m/s",
        holds=abs(yaw) < 1.0 and v_east > 0.15,
    )


def _current_track(scenario_id: str, target_deg: float, within: float, ctx: Context) -> Finding:
    run = ctx.run(scenario_id)
    course, _, last = _course(run)
    yaw = run["plant.yaw"]
    settled = settling_time(run["time"], yaw - math.radians(target_deg), 0.5 * BAND, angle=True)
    return Finding(
        shown=f"heading {math.degrees(float(np.mean(yaw[last]))):.2f} deg (within 0.5 deg of "
        f"psi_d from {_time(settled)}), course over ground {course:.2f} deg",
        holds=settled is not None and settled <= within and abs(course) < 1.0,
    )


def _roll_keeps_oscillating(ctx: Context) -> Finding:
    run = ctx.run("vert-1")
    t = run["time"]
    swing = math.degrees(float(np.ptp(run["plant.roll"][t >= t[-1] - 2 * LAST])))
    return Finding(
        shown=f"roll swings {swing:.2f} deg peak to peak over the last 20 s", holds=swing > 1.0
    )


def _steady_mean(column: str, scale: float, ctx: Context) -> Finding:
    """The mean of ``column`` of vert-2 over its last 10 s, times ``scale``."""
    run = ctx.run("vert-2")
    t = run["time"]
    return Finding(values=(scale * float(np.mean(run[column][t >= t[-1] - LAST])),))


def _report_figure(scenario_id: str, name: str, ctx: Context, path: Path) -> None:
    """Copy the run report's ``name`` figure of ``scenario_id`` (if it draws one)."""
    from cosim.viz.report import write_report

    run = ctx.run(scenario_id)
    index = ctx.memo(("report", scenario_id), lambda: write_report(run.folder))
    figure = index.parent / f"{name}.png"
    if figure.is_file():
        shutil.copy(figure, path)


def _figures() -> tuple[Figure, ...]:
    return tuple(
        Figure(f"{sid}_{name}.png", partial(_report_figure, sid, name), Cost.SCENARIO)
        for sid in FIGURE_SCENARIOS
        for name in REPORT_FIGURES
    )


def _depth_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    """vert-2's steady state: w, theta and delta_s, each with its tolerance."""
    steady = refs["scenarios.depth_steady_state"]
    claims = []
    means: tuple[tuple[str, str, float, Tolerance], ...] = (
        ("w", "plant.w", 1.0, LastDigit()),
        ("theta", "plant.pitch", 1.0, Relative(0.25)),
        ("mean delta_s", "controller.fin_angle", math.degrees(1.0), Absolute(1.5)),
    )
    for k, (name, column, scale, tolerance) in enumerate(means):
        claims.append(
            Claim(
                f"6-DOF, mass locked after 15 s: {name} ~ {steady.text[k]}",
                "Figs. 6.46-6.49; Sec. 6.3.4 (vert-2)",
                (steady.text[k],),
                unit_text(steady, [k]),
                partial(_steady_mean, column, scale),
                tolerance=tolerance,
                cost=Cost.SCENARIO,
                note="mean over the last 10 s",
            )
        )
    return tuple(claims)


def _scenario(claim: str, source: str, printed: str, ours: Callable[[Context], Finding]) -> Claim:
    return Claim(claim, source, printed, "-", ours, cost=Cost.SCENARIO)


def _heading_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    """lqr-1 to bs-3 and slow-1: the heading comes back to zero."""
    lqr_1, bs_3 = refs["scenarios.lqr_1_settling_time"], refs["scenarios.bs_3_settling_time"]
    stop, lqr_2 = refs["scenarios.lqr_2_mass_stop"], refs["scenarios.lqr_2_settling_time"]
    within = float(lqr_1.value) + ABOUT
    test = "tested: |psi| < 1 deg for good"
    lqr_2_claim = Claim(
        f"LQR, v0 = -0.05: y_v saturates at {stop.text} cm, heading back within {lqr_2.text} s",
        "Figs. 6.13-6.14 (lqr-2)",
        f"{stop.text} cm; {lqr_2.text} s ({test} by {lqr_2.text} s)",
        "-",
        partial(_lqr_2, float(stop.value), float(lqr_2.value)),
        cost=Cost.SCENARIO,
        explained=LQR_2,
    )
    return (
        _scenario(
            f"LQR, v0 = -0.01: converges within ~{lqr_1.text} s",
            "Figs. 6.11-6.12 (lqr-1)",
            f"~{lqr_1.text} s ({test} by {within:.0f} s)",
            partial(_heading_back, "lqr-1", within),
        ),
        lqr_2_claim,
        _scenario(
            "LQR, psi0 = 30 deg: heading returns",
            "Figs. 6.15-6.16 (lqr-3)",
            f"returns ({test} within the run)",
            partial(_heading_back, "lqr-3", math.inf),
        ),
        _scenario(
            "backstepping + thruster, v0 = -0.05: fast convergence",
            "Figs. 6.17-6.19 (bs-1)",
            f"fast ({test} by 15 s)",
            partial(_heading_back, "bs-1", 15.0),
        ),
        _scenario(
            "backstepping, psi0 = 30 deg: back within a short time",
            "Figs. 6.20-6.22 (bs-2)",
            f"short ({test} by 20 s)",
            partial(_heading_back, "bs-2", 20.0),
        ),
        _scenario(
            f"backstepping, v0 = -0.10: psi back to 0 within {bs_3.text} s",
            "Figs. 6.23-6.25 (bs-3)",
            f"{bs_3.text} s ({test} by {bs_3.text} s)",
            partial(_heading_back, "bs-3", float(bs_3.value)),
        ),
    )


def _current_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    """cur-1, cur-2, slow-1, slow-2 and vert-1."""
    speed, cur_2 = refs["current.speed"], refs["scenarios.cur_2_settling_time"]
    slow_2, h9, h4 = (
        refs["scenarios.slow_2_settling_time"],
        refs["current.heading_9_newton"],
        refs["current.heading_4_newton"],
    )
    return (
        _scenario(
            f"{speed.text} m/s current east, psi_d = 0: drifts east with sideslip",
            "Figs. 6.26-6.28 (cur-1)",
            "drifts east",
            _current_drift,
        ),
        _scenario(
            f"psi_d = -beta = {h9.text} deg: tracks along north, steady after about {cur_2.text} s",
            "Figs. 6.29-6.31 (cur-2)",
            f"course 0; ~{cur_2.text} s (tested: within 0.5 deg of psi_d, course within "
            f"1 deg, by {float(cur_2.value) + ABOUT:.0f} s)",
            partial(_current_track, "cur-2", float(h9.value), float(cur_2.value) + ABOUT),
        ),
        _scenario(
            "T = 4 N, v0 = -0.1: stabilised",
            "Figs. 6.32-6.33 (slow-1)",
            "stabilised (tested: |psi| < 1 deg for good within the run)",
            partial(_heading_back, "slow-1", math.inf),
        ),
        _scenario(
            f"T = 4 N, current, psi_d = {h4.text} deg: converges in ~{slow_2.text} s",
            "Figs. 6.34-6.39 (slow-2)",
            f"~{slow_2.text} s (tested as cur-2)",
            partial(_current_track, "slow-2", float(h4.value), float(slow_2.value) + ABOUT),
        ),
        _scenario(
            "6-DOF, z_d = 1 m: roll keeps oscillating",
            "Figs. 6.41-6.45 (vert-1)",
            "oscillates (tested: > 1 deg peak to peak over the last 20 s)",
            _roll_keeps_oscillating,
        ),
    )


def closed_loop(refs: Mapping[str, Reference]) -> Section:
    """The Chapter 6 scenarios and the figures of four of them."""
    claims = _heading_claims(refs) + _current_claims(refs) + _depth_claims(refs)
    return Section("Closed-loop scenarios (Ch. 6)", claims, _figures())
