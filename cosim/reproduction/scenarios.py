"""Chapter 6's closed-loop simulations: the built-in scenarios run through our master and
checked against what the text says about them, every figure at a converged step
(:mod:`.runs`: the Richardson limit of 1.25 ms and 0.625 ms, with the coupling error).

Expensive (minutes): ``auv-cosim reproduce --skip-scenarios`` leaves them out. The
vehicle is ``remus100`` as shipped (W = m g, g = 9.8), as in Chapter 6. "Settled" means
|psi - psi_d| inside a band for good: 1 deg for "back to zero" after a disturbance; for a
step of the set-point ("reaches the steady state" at psi_d), the standard settling time,
2 % of the step.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Mapping
from functools import partial
from pathlib import Path

import numpy as np

from cosim.analysis.reference_values import Reference
from cosim.metrics.key_figures import settling_time
from cosim.reproduction.context import Context, RunData
from cosim.reproduction.record import (
    Claim,
    Cost,
    Figure,
    Finding,
    Section,
    printed,
    tolerance_of,
    unit_text,
)
from cosim.reproduction.runs import FINE, converged, finest

BAND = math.radians(1.0)  # "back to zero": |psi| < 1 deg for good
STEP_BAND = 0.02  # "reaches the steady state" after a set-point step: within 2 % of it
LAST = 10.0  # s: the window of a steady state at the end of a run
IN_PHASE = 0.5  # correlation above which two signals are "in the same phase"
DECAY_FROM, DECAY_WINDOW = 20.0, 5.0  # s: vert-2's roll decay, windows after the lock at 15 s
REPORT_FIGURES = ("velocities", "attitude_actuators", "trajectory", "depth")
FIGURE_SCENARIOS = ("lqr-2", "bs-3", "cur-2", "vert-1", "vert-2")
LQR_2 = (
    "with the mass on its stop (y_v = -6 cm) the yaw moment it can make is capped and the "
    "heading comes back on the slow closed-loop mode. An independent reproduction of this "
    "case (continuous LQR gains, RK4 at 0.2 ms) also needs 28-34 s to stay within 1 deg, so "
    "the 20 s claim does not hold for this model. Like the dissertation (Sec. 6.3.1 bounds "
    "y_v and y_vel only), the scenario leaves the servo command unsaturated; saturating it "
    "at the 6 cm stroke slows the mass to ~6 cm/s and the settling to 42 s."
)
FIRST_LQR = (
    "said of the first design (on (6.2.33), without the servo's dynamics), which we do not "
    "ship; ours is lqr-1, the second design (6.3.17)-(6.3.19), of whose Figs. 6.11-6.12 the "
    "text says only that the state 'converges quickly'"
)
IN_PHASE_DIFFERS = (
    "Qualitatively: in our vert-1 the roll keeps oscillating, as the text says, but "
    "(m + a33) p w is not locked in phase with the thruster. Why is not known."
)


def _settled(setpoint_deg: float, band: float, run: RunData) -> float | None:
    """When |psi - psi_d| stays inside ``band`` for good (s), or None."""
    error = run["plant.yaw"] - math.radians(setpoint_deg)
    return settling_time(run["time"], error, band, angle=True)


def _settling(scenario_id: str, setpoint_deg: float, band: float, ctx: Context) -> Finding:
    limit, error = converged(ctx, scenario_id, partial(_settled, setpoint_deg, band))
    return Finding(
        values=(limit,), errors=(error,), shown=f"{limit:.2f} s (coupling error {error:.1g} s)"
    )


def _step_settling(scenario_id: str, setpoint_deg: float, ctx: Context) -> Finding:
    """The settling time after a set-point step (2 % of it), the course over ground held
    north, and for comparison when the heading stays within 0.5 deg."""
    band = STEP_BAND * math.radians(abs(setpoint_deg))
    limit, error = converged(ctx, scenario_id, partial(_settled, setpoint_deg, band))
    run = finest(ctx, scenario_id)
    course = _course(run)[0]
    half_degree = _settled(setpoint_deg, math.radians(0.5), run)
    return Finding(
        values=(limit,),
        errors=(error,),
        shown=f"{limit:.2f} s (coupling error {error:.1g} s; within 0.5 deg from "
        f"{half_degree:.1f} s); course over ground {course:.2f} deg",
        holds=abs(course) < 1.0,
    )


def _mass_stop(run: RunData) -> float:
    return 100 * float(np.min(run["plant.mass_position"]))


def _lqr_2_stop(ctx: Context) -> Finding:
    limit, error = converged(ctx, "lqr-2", _mass_stop)
    run = finest(ctx, "lqr-2")
    peak = math.degrees(float(np.max(np.abs(run["plant.yaw"]))))
    rail = 100 * float(np.max(np.abs(run["plant.mass_velocity"])))
    return Finding(
        values=(limit,),
        errors=(error,),
        shown=f"{limit:.2f} (coupling error {error:.1g})",
        note=f"Ours peaks at {peak:.1f} deg of yaw where Fig. 6.14's axis ends at 10 deg, "
        f"with rail speeds up to {rail:.0f} cm/s (its axis: +-50 cm/s).",
    )


def _back_to_zero(scenario_id: str, within: float, ctx: Context) -> Finding:
    """Qualitative: settled (|psi| < 1 deg for good) within ``within`` s of the FINE run."""
    run = finest(ctx, scenario_id)
    t, yaw = run["time"], run["plant.yaw"]
    k = int(np.argmax(np.abs(yaw)))
    settled = settling_time(t, yaw, BAND, angle=True)
    when = "never" if settled is None else f"{settled:.1f} s"
    return Finding(
        shown=f"peak |psi| {math.degrees(abs(yaw[k])):.1f} deg at {t[k]:.1f} s; "
        f"|psi| < 1 deg for good from {when}",
        holds=settled is not None and settled <= within,
    )


def _course(run: RunData) -> tuple[float, float]:
    """Course over ground (deg) and east speed (m/s) over the last 10 s."""
    t = run["time"]
    last = t >= t[-1] - LAST
    v_north = np.polyfit(t[last], run["plant.north"][last], 1)[0]
    v_east = np.polyfit(t[last], run["plant.east"][last], 1)[0]
    return math.degrees(math.atan2(v_east, v_north)), float(v_east)


def _drift(ctx: Context) -> Finding:
    limit, error = converged(ctx, "cur-1", lambda run: _course(run)[1])
    yaw = math.degrees(float(finest(ctx, "cur-1")["plant.yaw"][-1]))
    return Finding(
        values=(limit,),
        errors=(error,),
        shown=f"east drift {limit:.3f} m/s (coupling error {error:.1g}) at heading {yaw:.2f} deg",
        holds=abs(yaw) < 1.0,
    )


def _oscillates(ctx: Context) -> Finding:
    run = finest(ctx, "vert-1")
    t = run["time"]
    swing = math.degrees(float(np.ptp(run["plant.roll"][t >= t[-1] - 2 * LAST])))
    return Finding(
        shown=f"roll swings {swing:.1f} deg peak to peak over the last 20 s", holds=swing > 1.0
    )


def _mean(column: str, scale: float, run: RunData) -> float:
    """``scale`` times the mean of ``column`` over the last 10 s."""
    t = run["time"]
    return scale * float(np.mean(run[column][t >= t[-1] - LAST]))


def _steady(column: str, scale: float, ctx: Context) -> Finding:
    limit, error = converged(ctx, "vert-1", partial(_mean, column, scale))
    return Finding(
        values=(limit,), errors=(error,), shown=f"{limit:.4f} (coupling error {error:.1g})"
    )


def _in_phase(ctx: Context) -> Finding:
    """Fig. 6.45: (m + a33) p w against the tunnel thruster after 20 s."""
    run, params = finest(ctx, "vert-1"), ctx.remus
    late = run["time"] > 20.0
    coupling = (params.m + params.a33) * run["plant.p"][late] * run["plant.w"][late]
    thrust = run["controller.tunnel_force"][late]
    r = float(np.corrcoef(coupling, thrust)[0, 1])
    return Finding(
        shown=f"correlation {r:+.2f} over t > 20 s (amplitudes: (m + a33) p w "
        f"{np.ptp(coupling):.1f} N, thruster {np.ptp(thrust):.1f} N peak to peak)",
        holds=r > IN_PHASE,
    )


def _locked(ctx: Context) -> Finding:
    """Figs. 6.46-6.49: with the mass locked, the roll decays (its peak to peak falls from
    one 5 s window to the next) and both loops settle."""
    run = finest(ctx, "vert-2")
    t = run["time"]
    starts = np.arange(DECAY_FROM, t[-1] - DECAY_WINDOW + 1e-9, DECAY_WINDOW)
    swings = [
        math.degrees(float(np.ptp(run["plant.roll"][(t >= a) & (t < a + DECAY_WINDOW)])))
        for a in starts
    ]
    last = t >= t[-1] - LAST
    yaw = math.degrees(float(np.max(np.abs(run["plant.yaw"][last]))))
    depth = float(np.ptp(run["plant.down"][last]))
    return Finding(
        shown=f"roll peak to peak in 5 s windows from {DECAY_FROM:g} s: "
        f"{', '.join(f'{s:.1f}' for s in swings)} deg; over the last 10 s |psi| <= "
        f"{yaw:.2f} deg, depth within {100 * depth:.1f} cm",
        holds=bool(np.all(np.diff(swings) < 0)) and yaw < 1.0 and depth < 0.05,
    )


def _report_figure(scenario_id: str, name: str, ctx: Context, path: Path) -> None:
    """Copy the run report's ``name`` figure of the FINE run of ``scenario_id``."""
    from cosim.viz.report import write_report

    run = finest(ctx, scenario_id)
    index = ctx.memo(("report", scenario_id), lambda: write_report(run.folder))
    figure = index.parent / f"{name}.png"
    if figure.is_file():
        shutil.copy(figure, path)


def _figures() -> tuple[Figure, ...]:
    return tuple(
        Figure(
            f"{sid}_{name}.png",
            partial(_report_figure, sid, name),
            Cost.SCENARIO,
            alt=f"{sid}, the run at a {1e3 * FINE:g} ms step: {_report_alt(name)}",
        )
        for sid in FIGURE_SCENARIOS
        for name in REPORT_FIGURES
    )


def _report_alt(name: str) -> str:
    """The alt text of the report figure ``name`` of a closed-loop run (no guidance)."""
    from cosim.viz.report import time_history_alt, trajectory_alt

    if name == "trajectory":
        return trajectory_alt()
    return time_history_alt(name, lambda column: not column.startswith("guidance."))


def _numeric(ref: Reference, claim: str, ours: Callable[[Context], Finding], **more) -> Claim:
    """A claim on the printed number(s) ``ref``, with the TOML's tolerance and reason."""
    return Claim(
        claim,
        ref.source,
        printed(ref, more.pop("pick", None)),
        unit_text(ref, more.pop("unit_pick", None)),
        ours,
        tolerance=tolerance_of(ref),
        cost=Cost.SCENARIO,
        reference=ref.key,
        tolerance_reason=ref.tolerance_reason,
        **more,
    )


def _statement(
    claim: str, source: str, printed: str, ours: Callable[[Context], Finding], **more
) -> Claim:
    return Claim(claim, source, printed, "-", ours, cost=Cost.SCENARIO, **more)


def _lqr_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    first, stop, lqr_2 = (
        refs["scenarios.lqr_first_design_settling_time"],
        refs["scenarios.lqr_2_mass_stop"],
        refs["scenarios.lqr_2_settling_time"],
    )
    return (
        _numeric(
            first,
            f"LQR, v0 = -0.01 m/s: all states converge within {first.text} s",
            partial(_settling, "lqr-1", 0.0, BAND),
            note=f"settled: |psi| < 1 deg for good; {FIRST_LQR}",
        ),
        _numeric(stop, "LQR, v0 = -0.05 m/s: the mass saturates at its stop", _lqr_2_stop),
        _numeric(
            lqr_2,
            f"LQR, v0 = -0.05 m/s: heading back to zero within {lqr_2.text} s",
            partial(_settling, "lqr-2", 0.0, BAND),
            explained=LQR_2,
            note="settled: |psi| < 1 deg for good",
        ),
        _statement(
            "LQR, psi0 = 30 deg: the heading rises, then comes back",
            "Sec. 6.3.1, Figs. 6.15-6.16 (lqr-3)",
            "returns (tested: |psi| < 1 deg for good within the run)",
            partial(_back_to_zero, "lqr-3", math.inf),
            note="psi0 = 30 deg and v0 are ours: the text gives this case no initial state; "
            "the first design's Case 3 (Figs. 6.8-6.9) starts from [1.50, -0.01, 0, 0, pi/6, "
            "0, 0], pi/6 in the roll slot though the text calls it the initial heading",
        ),
    )


def _backstepping_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    bs_3 = refs["scenarios.bs_3_settling_time"]
    return (
        _statement(
            "backstepping + thruster, v0 = -0.05 m/s: the state converges quickly",
            "Sec. 6.3.3, Figs. 6.17-6.19 (bs-1)",
            "quickly (tested: |psi| < 1 deg for good by 15 s)",
            partial(_back_to_zero, "bs-1", 15.0),
        ),
        _statement(
            "backstepping, psi0 = 30 deg: back to zero within a short time",
            "Sec. 6.3.3, Figs. 6.20-6.22 (bs-2)",
            "short (tested: |psi| < 1 deg for good by 20 s)",
            partial(_back_to_zero, "bs-2", 20.0),
            note="psi0 = 30 deg is ours, as in lqr-3: the text says only 'nonzero initial yaw "
            "angle' and prints no initial state for this case",
        ),
        _numeric(
            bs_3,
            f"backstepping, v0 = -0.10 m/s: psi converges to zero within {bs_3.text} s",
            partial(_settling, "bs-3", 0.0, BAND),
            note="settled: |psi| < 1 deg for good; the moving mass's reaction kept on the hull "
            "(see the model choices below)",
        ),
    )


def _current_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    drift, cur_2, slow_2 = (
        refs["scenarios.cur_1_drift"],
        refs["scenarios.cur_2_settling_time"],
        refs["scenarios.slow_2_settling_time"],
    )
    h9, h4 = refs["current.heading_9_newton"], refs["current.heading_4_newton"]
    steady = "settled: within 2 % of the set-point step for good"
    return (
        _numeric(drift, "0.2 m/s current east, psi_d = 0: drifts east, v = U_c", _drift),
        _numeric(
            cur_2,
            f"psi_d = {h9.text} deg: steady, course north, after about {cur_2.text} s",
            partial(_step_settling, "cur-2", float(h9.value)),
            note=steady,
        ),
        _statement(
            "T = 4 N, v0 = -0.1 m/s: stabilised",
            "Sec. 6.3.3, Figs. 6.32-6.33 (slow-1)",
            "stabilised (tested: |psi| < 1 deg for good within the run)",
            partial(_back_to_zero, "slow-1", math.inf),
        ),
        _numeric(
            slow_2,
            f"T = 4 N, current, psi_d = {h4.text} deg: psi converges to psi_d in about "
            f"{slow_2.text} s",
            partial(_step_settling, "slow-2", float(h4.value)),
            note=steady,
        ),
    )


def _depth_claims(refs: Mapping[str, Reference]) -> tuple[Claim, ...]:
    """vert-1's steady state, its oscillation, Fig. 6.45, and vert-2."""
    steady = refs["scenarios.depth_steady_state"]
    means = (
        ("w", "plant.w", 1.0),
        ("theta", "plant.pitch", 1.0),
        ("mean delta_s", "controller.fin_angle", math.degrees(1.0)),
    )
    claims = [
        _statement(
            "6-DOF, z_d = 1 m: the vehicle keeps rolling",
            "Sec. 6.3.4, Figs. 6.41-6.42 (vert-1)",
            "keeps rolling (tested: > 1 deg peak to peak over the last 20 s)",
            _oscillates,
        )
    ]
    for k, (name, column, scale) in enumerate(means):
        claims.append(
            _numeric(
                steady,
                f"6-DOF, z_d = 1 m: {name} ~ {steady.text[k]} after convergence",
                partial(_steady, column, scale),
                pick=[k],
                unit_pick=[k],
                note="mean over the last 10 s",
            )
        )
    claims += [
        _statement(
            "after 20 s, (m + a33) p w is in the same phase as the tunnel thrust",
            "Sec. 6.3.4, Fig. 6.45 (vert-1)",
            f"in phase (tested: correlation > {IN_PHASE:g})",
            _in_phase,
            unexplained=IN_PHASE_DIFFERS,
        ),
        _statement(
            "mass locked after 15 s: p and phi decay to zero, both loops work",
            "Sec. 6.3.4, Figs. 6.46-6.49 (vert-2)",
            "decay (tested: roll peak to peak falls in every 5 s window from 20 s; over the "
            "last 10 s |psi| < 1 deg, depth within 5 cm)",
            _locked,
        ),
    ]
    return tuple(claims)


def closed_loop(refs: Mapping[str, Reference]) -> Section:
    """The Chapter 6 scenarios and the figures of five of them."""
    claims = (
        _lqr_claims(refs) + _backstepping_claims(refs) + _current_claims(refs) + _depth_claims(refs)
    )
    title = (
        f"Closed-loop scenarios (Ch. 6), at a converged step (figures: the {1e3 * FINE:g} ms runs)"
    )
    return Section(title, claims, _figures())
