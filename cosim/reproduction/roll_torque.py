"""Chapter 5 under a roll torque: the fold over Q (Example 5.4, Figs. 5.9-5.10), the
straight-line stable vehicle (Example 5.5, Fig. 5.11), the neutrally buoyant one
(Example 5.6, (5.1.74)) and the moving mass as a centre-of-gravity offset y_g
(Sec. 5.1.4, Figs. 5.12-5.13, (5.1.77)).

Every vehicle carries the Chapter 5 weight, Table 5.4's W = 299 N, as Example 5.3
(:meth:`Context.chapter_5`); Example 5.6 sets W = B itself. The offset y_g = m_v g y_v / W
uses the same W.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import partial
from pathlib import Path

from cosim.analysis.bifurcation import (
    Q_PROP,
    OperatingConditions,
    Sweep,
    cg_offset,
    find_equilibria,
    mass_position_for_cg_offset,
    sweep,
)
from cosim.analysis.plots import plot_sweep, sweep_alt
from cosim.analysis.reference_values import Reference
from cosim.reproduction.context import Context, stability
from cosim.reproduction.record import (
    Absolute,
    Claim,
    Cost,
    Figure,
    Finding,
    Section,
    SlightlyAbove,
    printed,
)
from plant_fmu.model.dynamics import Variant

FOLD_ABOVE = 1.0  # Q_prop: "slightly larger than 4 Q_prop" read as within one Q_prop above
EXACT_BANK = 1e-3  # deg: (5.1.74) is exact for a neutrally buoyant vehicle
ESTIMATE_BANK = 3.0  # deg: (5.1.77)'s arctan estimate holds "with a slight difference"
LONG_FIN_TORQUES = (1, 2, 3, 4)  # Q_prop, Fig. 5.11


def roll_torque_sweep(ctx: Context, long: bool = False) -> Sweep:
    """Equilibria over Q: 0 to 5.5 Q_prop (remus100), 0 to 4 Q_prop (the long fins)."""
    vehicle = ctx.chapter_5(ctx.long_fins if long else ctx.remus)
    end = (4.0 if long else 5.5) * Q_PROP
    conditions = OperatingConditions(vehicle, Variant.LATERAL)
    return ctx.memo(("sweep roll_torque", long), lambda: sweep(conditions, "roll_torque", 0, end))


def mass_sweep(ctx: Context) -> Sweep:
    """Equilibria over the moving-mass position y_v, 0 to the stop at -6 cm."""
    vehicle = ctx.chapter_5(ctx.remus)
    conditions = OperatingConditions(vehicle, Variant.LATERAL)
    return ctx.memo(
        "sweep mass_position",
        lambda: sweep(conditions, "mass_position", 0.0, -vehicle.mass_stroke),
    )


def _roll_torque_fold(ctx: Context) -> Finding:
    folds = roll_torque_sweep(ctx).folds
    shown = ", ".join(
        f"{f.parameter / Q_PROP:.3f} Q_prop (Q = {f.parameter:.4f} N m)" for f in folds
    )
    values = (folds[0].parameter / Q_PROP,) if len(folds) == 1 else ()
    return Finding(values=values, shown=f"{len(folds)} fold: {shown or 'none'}", holds=bool(values))


def _beyond_the_fold(ctx: Context) -> Finding:
    vehicle = ctx.chapter_5(ctx.remus)
    eqs = find_equilibria(OperatingConditions(vehicle, Variant.LATERAL, roll_torque=5 * Q_PROP))
    where = ", ".join(
        f"{stability(e)} at phi = {math.degrees(e.value('roll')):.1f} deg" for e in eqs
    )
    return Finding(
        shown=f"{len(eqs)}, {where}",
        holds=len(eqs) == 1 and eqs[0].stable and eqs[0].value("roll") < 0,
    )


def _long_fins(ctx: Context) -> Finding:
    vehicle = ctx.chapter_5(ctx.long_fins)
    holds, shown = True, list[str]()
    for k in LONG_FIN_TORQUES:
        conditions = OperatingConditions(vehicle, Variant.LATERAL, roll_torque=k * Q_PROP)
        eqs = find_equilibria(conditions)
        if len(eqs) != 1:
            holds, shown = False, [*shown, f"{k}Q: {len(eqs)} equilibria"]
            continue
        eq = eqs[0]
        holds &= eq.stable and eq.value("v") > 0 and eq.value("r") > 0 and eq.value("roll") < 0
        shown.append(f"{k}Q: phi {math.degrees(eq.value('roll')):.1f} deg")
    special = roll_torque_sweep(ctx, long=True).special_points
    return Finding(
        shown="; ".join(shown) + f"; {len(special)} special points on the way",
        holds=holds and not special,
    )


def _neutral_buoyancy(ctx: Context) -> Finding:
    """Example 5.6: with W = B the roll torque only banks the vehicle, by (5.1.74); the
    stability it claims is for a vehicle inherently stable in the horizontal plane, the
    long fins. With the original fins that equilibrium exists but is unstable."""
    expected, found = {}, {}
    for name, vehicle in (("long fins", ctx.long_fins), ("original fins", ctx.remus)):
        neutral = vehicle.replace(W=vehicle.B)
        eqs = find_equilibria(OperatingConditions(neutral, Variant.LATERAL, roll_torque=Q_PROP))
        expected[name] = math.degrees(math.asin(Q_PROP / (neutral.W * neutral.z_g)))
        found[name] = [e for e in eqs if abs(e.value("v")) < 1e-9 and abs(e.value("r")) < 1e-9]
    if len(found["long fins"]) != 1 or len(found["original fins"]) != 1:
        return Finding(shown=f"banked straight runs found: {found}", holds=False)
    (eq,), (original,) = found["long fins"], found["original fins"]
    bank = math.degrees(eq.value("roll"))
    return Finding(
        values=(bank,),
        against=(repr(expected["long fins"]),),
        shown=f"long fins: v = {eq.value('v'):.1e}, r = {eq.value('r'):.1e}, phi = "
        f"{bank:.3f} deg, {stability(eq)} (sin phi0 = Q / (W z_g): {expected['long fins']:.3f} "
        f"deg); original fins: phi = {math.degrees(original.value('roll')):.3f} deg, "
        f"{stability(original)}",
        holds=eq.stable and not original.stable,
    )


def _mass_fold(ctx: Context) -> Finding:
    vehicle = ctx.chapter_5(ctx.remus)
    folds = mass_sweep(ctx).folds
    y_g = [100 * cg_offset(vehicle, f.parameter) for f in folds]  # cm
    shown = ", ".join(
        f"y_g = {g:.3f} cm (y_v = {100 * f.parameter:.2f} cm)"
        for g, f in zip(y_g, folds, strict=True)
    )
    return Finding(values=tuple(y_g[:1]), shown=shown or "none", holds=len(folds) == 1)


def _single_equilibrium(y_g_cm: float, ctx: Context) -> Finding:
    vehicle = ctx.chapter_5(ctx.remus)
    y_v = mass_position_for_cg_offset(vehicle, y_g_cm / 100)
    stop = ""
    if abs(y_v) > vehicle.mass_stroke:  # Sec. 5.1.4's offset has no stop: lift ours to reach it
        stop = f"; y_v = {100 * y_v:.3f} cm, our stop moved out to it"
        vehicle = vehicle.with_stroke(abs(y_v))
    eqs = find_equilibria(OperatingConditions(vehicle, Variant.LATERAL, mass_position=y_v))
    estimate = math.degrees(math.atan(y_g_cm / 100 / vehicle.z_g))
    shown = ", ".join(f"phi = {math.degrees(e.value('roll')):.1f} deg, {stability(e)}" for e in eqs)
    if len(eqs) != 1:
        return Finding(shown=shown or "none", holds=False)
    return Finding(
        values=(math.degrees(eqs[0].value("roll")),),
        against=(repr(estimate),),
        shown=f"{shown} (arctan estimate {estimate:.1f} deg{stop})",
        holds=eqs[0].stable,
    )


def _draw_sweep(which: str, title: str, ctx: Context, path: Path) -> None:
    if which == "mass":
        result, vehicle = mass_sweep(ctx), ctx.remus
    else:
        long = which == "long fins"
        result, vehicle = roll_torque_sweep(ctx, long), ctx.long_fins if long else ctx.remus
    plot_sweep(result, ctx.chapter_5(vehicle), path, title=title)


def roll_torque(refs: Mapping[str, Reference]) -> Section:
    """Sec. 5.1.3, Examples 5.4-5.6."""
    fold = refs["example_5_4.fold_roll_torque"]
    claims = (
        Claim(
            f"one fold (saddle-node) as |Q| grows, 'slightly larger than {fold.text} Q_prop'",
            fold.source,
            printed(fold),
            f"Q_prop = {Q_PROP} N m",
            _roll_torque_fold,
            tolerance=SlightlyAbove(FOLD_ABOVE),
            cost=Cost.SWEEP,
            reference=fold.key,
        ),
        Claim(
            "beyond the fold one equilibrium remains, stable, banked to port (phi < 0)",
            "Ex. 5.4, Figs. 5.9-5.10",
            "1, stable",
            "-",
            _beyond_the_fold,
        ),
        Claim(
            "long fins, Q = 1..4 Q_prop: one stable equilibrium, phi < 0, v > 0, r > 0",
            "Ex. 5.5, Fig. 5.11",
            "structurally stable",
            "-",
            _long_fins,
            cost=Cost.SWEEP,
        ),
        Claim(
            "W = B, x_g = 0, a vehicle stable in the horizontal plane (remus100-long-fins): "
            "equilibrium [U0, 0, 0, 0, phi0], sin phi0 = Q / (W z_g), stable",
            "Ex. 5.6, (5.1.74)",
            "phi0 from (5.1.74) at Q = Q_prop",
            "deg",
            _neutral_buoyancy,
            tolerance=Absolute(EXACT_BANK),
            cost=Cost.SWEEP,
            note="(5.1.74) is exact here; with the original fins the same equilibrium is "
            "unstable, as the example's condition implies",
            tolerance_reason="a formula, not a printed number: (5.1.74) is exact for W = B, "
            "so ours must equal it to within the continuation's accuracy",
        ),
    )
    figures = (
        Figure(
            "fig5_9_roll_torque.png",
            partial(_draw_sweep, "remus", "Figs. 5.9-5.10: equilibria of the REMUS 100 over Q"),
            alt=f"Figs. 5.9-5.10, the REMUS 100: {sweep_alt('roll_torque')}",
        ),
        Figure(
            "fig5_11_roll_torque_long_fins.png",
            partial(_draw_sweep, "long fins", "Fig. 5.11: the straight-line stable vehicle over Q"),
            alt=f"Fig. 5.11, the long fins: {sweep_alt('roll_torque')}",
        ),
    )
    return Section("Roll torque (Sec. 5.1.3, Examples 5.4-5.6)", claims, figures)


def moving_mass(refs: Mapping[str, Reference]) -> Section:
    """Sec. 5.1.4: the fold over y_g and the one equilibrium beyond it."""
    fold = refs["section_5_1_4.fold_cg_offset"]
    beyond = refs["section_5_1_4.single_equilibrium_cg_offset"]
    claims = (
        Claim.of(
            fold,
            f"one fold when |y_g| is 'slightly larger than {fold.text} cm'",
            _mass_fold,
            tolerance=SlightlyAbove(float(fold.resolution)),
            cost=Cost.SWEEP,
            note="y_g = m_v g y_v / W: the roll torque of our mass at rest equals W y_g cos(phi)",
        ),
        Claim(
            f"y_g = {beyond.text} cm: one equilibrium, phi0 ~ arctan(y_g / z_g) "
            "'with a slight difference'",
            beyond.source,
            "phi0 ~ arctan(y_g / z_g)",
            "deg",
            partial(_single_equilibrium, float(beyond.value)),
            tolerance=Absolute(ESTIMATE_BANK),
            note="the estimate ignores the coupling terms, as the text says",
            tolerance_reason="a formula the text says differs 'slightly' from the true angle "
            "(it ignores the coupling terms): up to 3 deg, a tenth of the angle",
        ),
    )
    figure = Figure(
        "fig5_12_mass_position.png",
        partial(_draw_sweep, "mass", "Figs. 5.12-5.13: equilibria over the moving-mass position"),
        alt=f"Figs. 5.12-5.13: {sweep_alt('mass_position')}",
    )
    return Section("Moving mass (Sec. 5.1.4)", claims, (figure,))
