"""Chapter 5 in the horizontal plane: Examples 5.1-5.2, the coefficients of (5.1.31), the
phase portraits of Figs. 5.4-5.5 and the fin factors of Figs. 5.6-5.7.

Every vehicle here carries the Chapter 5 weight (:meth:`Context.chapter_5`); the
horizontal variant holds roll and pitch at zero, so the weight does not enter these
numbers, but one convention holds for the whole chapter.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial
from pathlib import Path

import numpy as np

from cosim.analysis.analyze import phase_trajectories
from cosim.analysis.bifurcation import OperatingConditions, Sweep, sweep
from cosim.analysis.equilibria import Equilibrium
from cosim.analysis.plots import PHASE_ALT, plot_phase_portrait, plot_sweep, sweep_alt
from cosim.analysis.reference_values import Reference
from cosim.reproduction.context import Context, stability, uvr
from cosim.reproduction.record import (
    Absolute,
    Claim,
    Cost,
    Figure,
    Finding,
    Section,
    printed,
    unit_text,
)
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

ENDS_AT_EQUILIBRIUM = 1e-3  # distance in (u, v, r) of a trajectory's end from an equilibrium
SUBSPACE_DISTANCE = 2**0.5 * 1e-4  # two 4-decimal entries, each one unit of the last digit


def example_5_1_equilibria(ctx: Context) -> tuple[Equilibrium, Equilibrium, Equilibrium]:
    """x0'', x0, x0' of (5.1.50) (sorted by v): T = 9 N, horizontal variant."""
    conditions = OperatingConditions(ctx.chapter_5(ctx.remus), Variant.HORIZONTAL, thrust=9.0)
    eqs = ctx.equilibria("example 5.1", conditions)
    if len(eqs) != 3:
        raise ValueError(f"expected three equilibria, found {len(eqs)}")
    return eqs[0], eqs[1], eqs[2]


def _count(ctx: Context) -> Finding:
    conditions = OperatingConditions(ctx.chapter_5(ctx.remus), Variant.HORIZONTAL, thrust=9.0)
    count = len(ctx.equilibria("example 5.1", conditions))
    return Finding(values=(count,), shown=str(count))


def _equilibrium(which: int, ctx: Context) -> Finding:
    return Finding(values=uvr(example_5_1_equilibria(ctx)[which]))


def _stability(ctx: Context) -> Finding:
    low, axis, high = example_5_1_equilibria(ctx)
    saddle = int(np.sum(axis.eigenvalues.real > 0)) == 1
    return Finding(
        shown=f"{stability(axis)} / {stability(high)} / {stability(low)}",
        holds=saddle and not axis.stable and high.stable and low.stable,
    )


def _unstable_subspace(ctx: Context) -> Finding:
    axis = example_5_1_equilibria(ctx)[1]
    values, vectors = np.linalg.eig(axis.jacobian)
    direction = vectors[:, np.argmax(values.real)].real
    return Finding(values=tuple(direction * np.sign(direction[2])))


def _stable_subspace(direction: np.ndarray, ctx: Context) -> Finding:
    axis = example_5_1_equilibria(ctx)[1]
    values, vectors = np.linalg.eig(axis.jacobian)
    stable = vectors[:, values.real < 0].real
    fit = stable @ np.linalg.lstsq(stable, direction, rcond=None)[0]
    distance = float(np.linalg.norm(direction - fit))
    return Finding(
        values=(distance,), against=("0",), shown=f"distance from our E_s: {distance:.1e}"
    )


def coefficients(params: VehicleParameters) -> dict[str, float]:
    """The coefficients of (5.1.14) and (5.1.31) from the plant's own equations
    (horizontal variant): A = (m + a22)/(m + a11) from its mass matrix; C (the Munk moment
    per unit yaw inertia) from the ideal-fluid linearisation at u = 1 m/s; beta3, beta4,
    gamma3, gamma4 as the viscous part of (M_RB + M_A) xdot per unit inertia there; beta1,
    beta2, gamma1, gamma2 as the cross-flow drag at v = 1 m/s and r = 1 rad/s per unit
    inertia; alpha as x1_dot = alpha x1|x1| at x1 = 1 with no thrust."""
    real = PlantModel(params, Variant.HORIZONTAL)
    ideal = PlantModel(params, Variant.HORIZONTAL, ideal_fluid=True)
    x0 = state_vector({"u": 1.0})
    inputs = np.zeros(len(INPUT_INDEX))
    names = ["u", "v", "r"]
    M = real.mass_matrix[np.ix_([0, 1, 5], [0, 1, 5])]
    A_real, _ = linearize(real, x0, inputs, names)
    A_ideal, _ = linearize(ideal, x0, inputs, names)
    force = M @ (A_real - A_ideal)  # d(viscous force)/d(u, v, r) at u = 1
    munk = M @ A_ideal  # d(ideal-fluid force)/d(u, v, r) at u = 1
    sway = real.viscous([0.0, 1.0, 0.0, 0.0, 0.0, 0.0])  # cross-flow drag at v = 1 m/s
    yaw = real.viscous([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])  # and at r = 1 rad/s
    return {
        "A": M[1, 1] / M[0, 0],
        "C": munk[2, 1] / M[2, 2],
        "alpha": real.derivative(x0, inputs)[STATE_INDEX["u"]],
        "beta1": sway[1] / M[1, 1],
        "beta2": yaw[1] / M[1, 1],
        "beta3": force[1, 1] / M[1, 1],
        "beta4": force[1, 2] / M[1, 1],
        "gamma1": sway[5] / M[2, 2],
        "gamma2": yaw[5] / M[2, 2],
        "gamma3": force[2, 1] / M[2, 2],
        "gamma4": force[2, 2] / M[2, 2],
    }


def bound_coefficients(params: VehicleParameters) -> tuple[float, float]:
    """The coefficients of U0 y2^2 and U0 y3^2 in (5.1.60)'s bound on V_dot(y) for the
    linear part y_dot = Df(x0) y of (5.1.57): with P = (M_RB + M_A)/(m + a11) (5.1.61),
    the diagonal of P Df(x0) / U0 over (y2, y3) plus half the magnitude of its cross
    coefficient (|y2 y3| <= (y2^2 + y3^2)/2). Df(x0) is the plant's Jacobian at the
    straight run; it is linear in U0."""
    model = PlantModel(params, Variant.HORIZONTAL)
    M = model.mass_matrix[np.ix_([0, 1, 5], [0, 1, 5])]
    jacobian, _ = linearize(
        model, state_vector({"u": 1.0}), np.zeros(len(INPUT_INDEX)), ["u", "v", "r"]
    )
    Q = M @ jacobian / M[0, 0]
    half_cross = abs(Q[1, 2] + Q[2, 1]) / 2
    return Q[1, 1] + half_cross, Q[2, 2] + half_cross


def _coefficients(long: bool, names: tuple[str, ...], ctx: Context) -> Finding:
    ours = coefficients(ctx.chapter_5(ctx.long_fins if long else ctx.remus))
    return Finding(values=tuple(ours[n] for n in names))


def _example_5_2(ctx: Context) -> Finding:
    conditions = OperatingConditions(ctx.chapter_5(ctx.long_fins))
    eqs = ctx.equilibria("example 5.2", conditions)
    shown = "; ".join(f"[{', '.join(f'{x:.4f}' for x in uvr(e))}] {stability(e)}" for e in eqs)
    if len(eqs) != 1:
        return Finding(shown=shown, holds=False)
    return Finding(values=uvr(eqs[0]), shown=shown, holds=eqs[0].stable)


def _phase(long: bool, ctx: Context) -> tuple[list[Equilibrium], list[np.ndarray]]:
    """The equilibria and the open-loop trajectories of Fig. 5.4 (5.5 with the long fins)."""

    def compute() -> tuple[list[Equilibrium], list[np.ndarray]]:
        conditions = OperatingConditions(ctx.chapter_5(ctx.long_fins if long else ctx.remus))
        eqs = ctx.equilibria(("phase portrait", long), conditions)
        return eqs, phase_trajectories(conditions, eqs)

    return ctx.memo(("phase portrait", long), compute)


def _phase_ends(long: bool, off_manifold: int, ctx: Context) -> Finding:
    eqs, trajectories = _phase(long, ctx)
    ends = np.array([x[-1, [STATE_INDEX[n] for n in ("u", "v", "r")]] for x in trajectories])
    stable = np.array([uvr(e) for e in eqs if e.stable])
    distance = np.min(np.linalg.norm(ends[:, None, :] - stable[None], axis=2), axis=1)
    elsewhere = int(np.sum(distance > ENDS_AT_EQUILIBRIUM))
    return Finding(
        shown=f"{len(trajectories) - elsewhere} of {len(trajectories)} within "
        f"{ENDS_AT_EQUILIBRIUM:g} after 30 s",
        holds=elsewhere <= off_manifold,
    )


def _draw_phase(long: bool, caption: str, ctx: Context, path: Path) -> None:
    eqs, trajectories = _phase(long, ctx)
    name = (ctx.long_fins if long else ctx.remus).name
    plot_phase_portrait(
        trajectories, eqs, path, title=f"{caption}: open-loop phase portrait, {name}"
    )


def fin_factor_sweep(name: str, ctx: Context) -> Sweep:
    """The continuation over the fin factor ``name`` ("mu" or "eta") from 1 to 3."""
    conditions = OperatingConditions(ctx.chapter_5(ctx.remus))
    return ctx.memo(("sweep", name), lambda: sweep(conditions, name, 1.0, 3.0))


def _branch_point(name: str, ctx: Context) -> Finding:
    result = fin_factor_sweep(name, ctx)
    switches = [s for s in result.special_points if s.kind == "branch point"]
    shown = ", ".join(f"{s.kind} at {name} = {s.parameter:.3f}" for s in result.special_points)
    values = (switches[0].parameter,) if len(switches) == 1 else ()
    return Finding(values=values, shown=shown or "none", holds=len(switches) == 1)


def _draw_fin_factor(name: str, source: str, ctx: Context, path: Path) -> None:
    title = f"{source}: equilibria over the fin factor {name}"
    plot_sweep(fin_factor_sweep(name, ctx), ctx.remus, path, title=title)


def example_5_1(refs: Mapping[str, Reference]) -> Section:
    """Example 5.1: the three equilibria of (5.1.50), their stability and subspaces."""
    count = refs["example_5_1.equilibrium_count"]
    basis = refs["example_5_1.stable_subspace"]
    spans = [f"[{', '.join(vector)}]" for vector in basis.text]
    turns = [("x0' = [u, v, r]", "turn_positive_v", 2), ("x0'' = [u, v, r]", "turn_negative_v", 0)]
    straight = refs["example_5_1.straight_line"]
    claims = [
        Claim.of(
            count,
            "number of equilibria in D = {0<u<2, |v|,|r|<=0.4}",
            _count,
            tolerance=Absolute(0.0),
        ),
        Claim(
            "x0 = [u, v, r]",
            "(5.1.50)",
            printed(straight),
            unit_text(straight),
            partial(_equilibrium, 1),
            note="T = 9 N",
            reference=straight.key,
        ),
    ]
    for claim, key, which in turns:
        ref = refs[f"example_5_1.{key}"]
        claims.append(
            Claim.of(
                ref,
                claim,
                partial(_equilibrium, which),
            )
        )
    subspace = refs["example_5_1.unstable_subspace"]
    claims += [
        Claim(
            "stability: x0 a saddle (one eigenvalue > 0), x0', x0'' stable",
            "Ex. 5.1",
            "unstable / stable / stable",
            "-",
            _stability,
        ),
        Claim.of(
            subspace,
            "unstable subspace E_u of x0",
            _unstable_subspace,
        ),
        Claim(
            f"stable subspace E_s of x0 = span{{{', '.join(spans)}}}",
            basis.source,
            f"{spans[1]} in E_s",
            unit_text(basis),
            partial(_stable_subspace, np.asarray(basis.value)[1]),
            tolerance=Absolute(SUBSPACE_DISTANCE),
            reference=basis.key,
            tolerance_reason="a distance from a vector printed to 4 decimals, two of its "
            "entries each off by up to one unit of the last digit: sqrt(2) x 1e-4",
        ),
    ]
    return Section("Example 5.1: the REMUS 100 in the horizontal plane", tuple(claims))


def coefficient_claims(refs: Mapping[str, Reference]) -> Section:
    """The coefficients of (5.1.14), (5.1.31) for both fin sets."""
    claims = []
    for key, vehicle, long, names in (
        (
            "example_5_1.coefficients",
            "remus100",
            False,
            ("alpha", "beta3", "beta4", "gamma3", "gamma4"),
        ),
        (
            "example_5_1.other_coefficients",
            "remus100",
            False,
            ("A", "C", "beta1", "beta2", "gamma1", "gamma2"),
        ),
        (
            "example_5_2.coefficients",
            "remus100-long-fins",
            True,
            ("beta3", "beta4", "gamma3", "gamma4"),
        ),
    ):
        ref = refs[key]
        claims.append(
            Claim.of(
                ref,
                f"{', '.join(names)} ({vehicle})",
                partial(_coefficients, long, names),
            )
        )
    return Section("Coefficients of (5.1.14) and (5.1.31)", tuple(claims))


def _bound(ctx: Context) -> Finding:
    return Finding(values=bound_coefficients(ctx.chapter_5(ctx.long_fins)))


def example_5_2(refs: Mapping[str, Reference]) -> Section:
    """Example 5.2: the long fins leave one, stable, equilibrium, which (5.1.60) proves."""
    ref = refs["example_5_2.straight_line"]
    bound = refs["example_5_2.bound_coefficients"]
    claims = (
        Claim.of(
            ref,
            f"only equilibrium in D: [{', '.join(printed(ref))}], asymptotically stable",
            _example_5_2,
        ),
        Claim.of(
            bound,
            "V_dot(y) <= alpha y1^2 (...) + c2 U0 y2^2 + c3 U0 y3^2: [c2, c3], both < 0",
            _bound,
            explained="c2 is the dissertation's arithmetic: A beta3 + (-A + A beta4 + "
            "(1 - A) gamma3 / C)/2 with its own printed A, beta3, beta4, gamma3, C gives "
            "-0.794 too, and c3, from the same cross term, agrees; both stay negative, so "
            "V_dot < 0 and the conclusion holds",
        ),
    )
    return Section("Example 5.2: the modified fins", claims)


def phase_portraits(refs: Mapping[str, Reference]) -> Section:
    """Figs. 5.4-5.5: open-loop trajectories from D end at the stable equilibria."""
    claims, figures = [], []
    for long, caption, name in (
        (False, "Fig. 5.4", "fig5_4_phase_portrait.png"),
        (True, "Fig. 5.5", "fig5_5_phase_portrait_long_fins.png"),
    ):
        off_manifold = 0 if long else 3  # the starts on the u axis lie on W_s of x0
        claims.append(
            Claim(
                f"{caption}: trajectories from D end at the stable equilibria",
                caption,
                "all" if long else "all (except on the stable manifold of x0)",
                "-",
                partial(_phase_ends, long, off_manifold),
                cost=Cost.SWEEP,
                note="" if long else "the 3 starts on the u axis lie on W_s of x0 and stay there",
            )
        )
        fins = ", the long fins" if long else ""
        alt = f"{caption}{fins}: {PHASE_ALT}"
        figures.append(Figure(name, partial(_draw_phase, long, caption), alt=alt))
    return Section("Phase portraits (Figs. 5.4, 5.5)", tuple(claims), tuple(figures))


def fin_factors(refs: Mapping[str, Reference]) -> Section:
    """Figs. 5.6-5.7: the turning pair merges into x0 at mu, eta about 2."""
    branch = refs["fin_factors.branch_point"]
    claims, figures = [], []
    for name, source, file in (
        ("mu", "Fig. 5.6, (5.1.62)", "fig5_6_mu.png"),
        ("eta", "Fig. 5.7, (5.1.63)", "fig5_7_eta.png"),
    ):
        claims.append(
            Claim(
                f"the turning pair merges into x0, which turns stable, at {name} ~ {branch.text}",
                source,
                printed(branch),
                unit_text(branch),
                partial(_branch_point, name),
                cost=Cost.SWEEP,
                reference=branch.key,
                note="a symmetric pitchfork: the fold-free branch point where x0 changes stability",
            )
        )
        source = source.split(",")[0]
        alt = f"{source}: {sweep_alt(name)}"
        figures.append(Figure(file, partial(_draw_fin_factor, name, source), alt=alt))
    return Section("Fin factors mu and eta (Figs. 5.6, 5.7)", tuple(claims), tuple(figures))
