"""Regenerate ``docs/reproduction.md``: every numeric claim of the dissertation we check,
the printed value, ours, and the verdict, with the figures beside it.

    python scripts/reproduce_dissertation.py [--out docs] [--skip-scenarios]

Sources (B. Li, FAU 2016): Examples 5.1-5.6 and Sec. 5.1.2-5.1.4 (open-loop equilibria,
Jacobians, folds and the fin factors mu, eta), (6.3.19) (the linearised lateral model
with the moving mass), the low-speed equilibria of Sec. 6.3.3 and the Ch. 6 closed-loop
scenarios (run through the co-simulation master, ``cosim.runner.run_scenario``).

Every "ours" number is computed here from the shipped model (``plant_fmu``) or from a
run of the two FMUs; the dissertation's numbers come from ``docs/dissertation-values.toml``
(the same file the tests read), with the digits they were printed with. A printed value
"agrees" when ours is within one unit of its last printed digit (or the stated tolerance),
because the dissertation rounds and integrates numerically.
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
import time
import traceback
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from decimal import Decimal
from pathlib import Path
from typing import cast

import numpy as np

from cosim.analysis.analyze import phase_trajectories
from cosim.analysis.bifurcation import (
    Q_PROP,
    OperatingConditions,
    cg_offset,
    find_equilibria,
    mass_position_for_cg_offset,
    sweep,
)
from cosim.analysis.plots import plot_phase_portrait, plot_sweep
from cosim.analysis.reference_values import Reference, load_reference_values
from cosim.metrics.key_figures import settling_time
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters, load_vehicle

ROOT = Path(__file__).resolve().parents[1]
ZERO_TOLERANCE = 1e-3
DISSERTATION = load_reference_values(ROOT / "docs" / "dissertation-values.toml")


def printed(key: str) -> list[str]:
    """The dissertation's value ``key`` as printed, a list of strings (a number: one)."""
    text = DISSERTATION[key].text
    return text if isinstance(text, list) else [text]


def reference(key: str) -> Reference:
    """The dissertation's value ``key`` (docs/dissertation-values.toml)."""
    return DISSERTATION[key]


@dataclass
class Row:
    """One checked claim."""

    claim: str
    source: str
    printed: str
    ours: str
    verdict: str  # "agrees", "differs (explained)", "differs", "not run"
    note: str = ""


def decimals(text: str) -> int:
    """Digits after the decimal point of a printed number ("1.282" -> 3)."""
    mantissa = text.lower().split("e")[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


def agrees(printed: str, ours: float, rel: float | None = None) -> bool:
    """Within one unit of the last printed digit (or ``rel`` relative)."""
    value = float(printed)
    if rel is not None and value != 0.0:
        return abs(ours - value) <= rel * abs(value)
    if value == 0.0 and decimals(printed) == 0:
        return abs(ours) <= ZERO_TOLERANCE  # a bare "0" next to 3-4 decimal figures
    return abs(ours - value) <= 10.0 ** (-decimals(printed)) * (1 + 1e-9)


def vector_row(
    claim: str,
    source: str,
    printed: Sequence[str],
    ours: Sequence[float],
    rel: float | None = None,
    note: str = "",
) -> Row:
    ok = all(agrees(p, o, rel) for p, o in zip(printed, ours, strict=True))
    shown = ", ".join(
        f"{o:.{max(decimals(p), 1) + 1}f}" for p, o in zip(printed, ours, strict=True)
    )
    return Row(
        claim,
        source,
        "[" + ", ".join(printed) + "]",
        f"[{shown}]",
        "agrees" if ok else "differs",
        note,
    )


def fact_row(claim: str, source: str, printed: str, ours: str, ok: bool, note: str = "") -> Row:
    return Row(claim, source, printed, ours, "agrees" if ok else "differs", note)


# --- Ch. 5: open-loop equilibria ------------------------------------------------------------


def _by_v(equilibria):
    return sorted(equilibria, key=lambda e: e.value("v"))


def example_5_1(remus: VehicleParameters) -> list[Row]:
    eqs = _by_v(find_equilibria(OperatingConditions(remus, Variant.HORIZONTAL, thrust=9.0)))
    rows = [
        fact_row(
            "number of equilibria in D = {0<u<2, |v|,|r|<=0.4}",
            "Ex. 5.1, (5.1.50)",
            printed("example_5_1.equilibrium_count")[0],
            str(len(eqs)),
            len(eqs) == reference("example_5_1.equilibrium_count").value,
        )
    ]
    if len(eqs) != 3:
        return rows
    low, axis, high = eqs
    rows.append(
        vector_row(
            "x0 = [u, v, r]",
            "(5.1.50)",
            printed("example_5_1.straight_line"),
            _uvr(axis),
            note="T = 9 N",
        )
    )
    rows.append(
        vector_row(
            "x0' = [u, v, r]", "(5.1.50)", printed("example_5_1.turn_positive_v"), _uvr(high)
        )
    )
    rows.append(
        vector_row(
            "x0'' = [u, v, r]", "(5.1.50)", printed("example_5_1.turn_negative_v"), _uvr(low)
        )
    )
    rows.append(
        fact_row(
            "stability: x0 saddle (one eigenvalue > 0), x0', x0'' stable",
            "Ex. 5.1",
            "unstable / stable / stable",
            f"{_stability(axis)} / {_stability(high)} / {_stability(low)}",
            (not axis.stable)
            and high.stable
            and low.stable
            and int(np.sum(axis.eigenvalues.real > 0)) == 1,
        )
    )
    values, vectors = np.linalg.eig(axis.jacobian)
    unstable = vectors[:, np.argmax(values.real)].real
    unstable *= np.sign(unstable[2])
    rows.append(
        vector_row(
            "unstable subspace E_u of x0",
            "Ex. 5.1",
            printed("example_5_1.unstable_subspace"),
            list(unstable),
        )
    )
    stable = vectors[:, values.real < 0].real
    basis = reference("example_5_1.stable_subspace")
    direction = np.asarray(basis.value)[1]
    residual = float(
        np.linalg.norm(direction - stable @ np.linalg.lstsq(stable, direction, rcond=None)[0])
    )
    shown = [f"[{', '.join(vector)}]" for vector in basis.text]
    rows.append(
        fact_row(
            f"stable subspace E_s of x0 = span{{{', '.join(shown)}}}",
            "Ex. 5.1",
            f"{shown[1]} in E_s",
            f"distance of it from our E_s: {residual:.1e}",
            residual < 2e-4,
        )
    )
    return rows


def _uvr(eq) -> list[float]:
    return [eq.value("u"), eq.value("v"), eq.value("r")]


def _stability(eq) -> str:
    return "stable" if eq.stable else "unstable"


def lift_coefficients(remus: VehicleParameters, long_fins: VehicleParameters) -> list[Row]:
    """beta3, beta4, gamma3, gamma4 of (5.1.31), alpha: evaluated on the model as the
    viscous part of (M_RB + M_A) xdot per unit inertia at u = 1 m/s (horizontal variant)."""
    rows = []
    for params, source, key, names in (
        (remus, "Ex. 5.1", "example_5_1", ["alpha", "beta3", "beta4", "gamma3", "gamma4"]),
        (long_fins, "Ex. 5.2", "example_5_2", ["beta3", "beta4", "gamma3", "gamma4"]),
    ):
        ours = _coefficients(params)
        rows.append(
            vector_row(
                f"{', '.join(names)} ({params.name})",
                source,
                printed(f"{key}.coefficients"),
                [ours[n] for n in names],
            )
        )
    return rows


def _coefficients(params: VehicleParameters) -> dict[str, float]:
    real = PlantModel(params, Variant.HORIZONTAL)
    ideal = PlantModel(params, Variant.HORIZONTAL, ideal_fluid=True)
    x0 = state_vector({"u": 1.0})
    inputs = np.zeros(len(INPUT_INDEX))
    names = ["u", "v", "r"]
    # (M_RB + M_A) xdot = generalised force: its viscous part, differentiated at u = 1.
    M = real.mass_matrix[np.ix_([0, 1, 5], [0, 1, 5])]
    A_real, _ = linearize(real, x0, inputs, names)
    A_ideal, _ = linearize(ideal, x0, inputs, names)
    force = M @ (A_real - A_ideal)  # d(viscous force)/d(u, v, r) at u = 1
    surge = real.derivative(x0, inputs)[STATE_INDEX["u"]]
    return {
        "alpha": surge,  # x1_dot = alpha x1|x1| at x1 = 1 with no thrust
        "beta3": force[1, 1] / M[1, 1],
        "beta4": force[1, 2] / M[1, 1],
        "gamma3": force[2, 1] / M[2, 2],
        "gamma4": force[2, 2] / M[2, 2],
    }


def example_5_2(long_fins: VehicleParameters) -> list[Row]:
    eqs = find_equilibria(OperatingConditions(long_fins))
    ok = len(eqs) == 1 and eqs[0].stable
    shown = "; ".join(f"[{', '.join(f'{x:.4f}' for x in _uvr(e))}] {_stability(e)}" for e in eqs)
    expected = printed("example_5_2.straight_line")
    return [
        fact_row(
            f"only equilibrium in D: [{', '.join(expected)}], asymptotically stable",
            "Ex. 5.2",
            f"[{', '.join(expected)}] stable",
            shown,
            ok and all(agrees(p, o) for p, o in zip(expected, _uvr(eqs[0]), strict=True)),
        )
    ]


def _example_5_3_jacobian(remus: VehicleParameters) -> tuple[Row, np.ndarray]:
    """The Jacobian row of Example 5.3 and J itself, with Table 4.1's W as it was computed."""
    names = ["v", "r", "p", "roll"]
    at_speed = state_vector({"u": 1.5}), input_vector({"thrust": 9.0})
    ours_J, _ = linearize(PlantModel(remus, Variant.LATERAL), *at_speed, names)
    weight = float(reference("table_4_1.weight").value)
    J, _ = linearize(PlantModel(remus.replace(W=weight), Variant.LATERAL), *at_speed, names)
    bar, delta = (
        cast(list[list[Decimal]], reference(f"example_5_3.{k}").printed)  # 4 x 4 as printed
        for k in ("jacobian_bar", "jacobian_delta")
    )
    printed_J = [
        [str(a + b) for a, b in zip(row_bar, row_delta, strict=True)]
        for row_bar, row_delta in zip(bar, delta, strict=True)
    ]  # J-bar + delta-J as printed
    flat_ok = all(agrees(printed_J[i][j], J[i, j]) for i in range(4) for j in range(4))
    worst = max(abs(float(printed_J[i][j]) - J[i, j]) for i in range(4) for j in range(4))
    ours = max(abs(float(printed_J[i][j]) - ours_J[i, j]) for i in range(4) for j in range(4))
    row = fact_row(
        "Jacobian J-bar + delta-J over [v, r, p, phi] (16 entries)",
        "Ex. 5.3",
        "as printed",
        f"largest difference {worst:.1e}",
        flat_ok,
        f"holds at u = 1.5 m/s (not U0 = 1.525) with Table 4.1's W = {weight:g} N; with "
        f"remus100's W = m g = {remus.m * remus.g:.1f} N it is {ours:.1e}",
    )
    return row, J


def example_5_3(remus: VehicleParameters) -> list[Row]:
    """Example 5.3 with Table 4.1's W = 299 N, as the dissertation computed it."""
    row, J = _example_5_3_jacobian(remus)
    rows = [row]
    remus = remus.replace(W=float(reference("table_4_1.weight").value))
    eig = sorted(np.linalg.eigvals(J), key=lambda z: (-z.real, z.imag))
    rows.append(
        vector_row(
            "eigenvalues of J-bar + delta-J (re, re, re +- i im)",
            "Ex. 5.3",
            _eigenvalue_text("example_5_3.eigenvalues"),
            [eig[0].real, eig[3].real, eig[1].real, abs(eig[1].imag)],
        )
    )
    J_bar = J.copy()
    J_bar[:2, 2:] = 0.0  # the coupling block J12 that delta-J holds
    eig = sorted(np.linalg.eigvals(J_bar), key=lambda z: (-z.real, z.imag))
    rows.append(
        vector_row(
            "eigenvalues of J-bar (coupling J12 removed)",
            "Ex. 5.3",
            _eigenvalue_text("example_5_3.eigenvalues_bar"),
            [eig[0].real, eig[3].real, eig[1].real, abs(eig[1].imag)],
        )
    )
    eqs = _by_v(find_equilibria(OperatingConditions(remus, Variant.LATERAL)))
    bank = printed("example_5_3.bank_angle")[0]
    if len(eqs) == 3:
        low, axis, high = eqs
        f = ("u", "v", "r", "p", "roll")
        rows.append(
            vector_row(
                "x0' = [u, v, r, p, phi]",
                "(5.1.70)",
                printed("example_5_3.turn_positive_v"),
                [high.value(n) for n in f],
            )
        )
        rows.append(
            vector_row(
                "x0'' = [u, v, r, p, phi]",
                "(5.1.70)",
                printed("example_5_3.turn_negative_v"),
                [low.value(n) for n in f],
            )
        )
        rows.append(
            fact_row(
                f"x0', x0'' stable, x0 unstable; steady bank about {bank} deg",
                "Ex. 5.3",
                f"stable; |phi| ~ {bank} deg",
                f"{_stability(high)}, {_stability(low)}, x0 {_stability(axis)}; "
                f"|phi| = {math.degrees(abs(high.value('roll'))):.2f} deg",
                high.stable and low.stable and not axis.stable,
            )
        )
    else:
        rows.append(fact_row("three equilibria", "(5.1.70)", "3", str(len(eqs)), False))
    return rows


def _eigenvalue_text(key: str) -> list[str]:
    """[re, re, re, im] of printed eigenvalues [[re, 0], [re, 0], [re, +im], [re, -im]]."""
    (real_1, _), (real_2, _), (real_3, imag), _ = cast(list[list[str]], reference(key).text)
    return [real_1, real_2, real_3, imag]


def roll_torque_claims(remus, long_fins, figures: Path) -> list[Row]:
    rows = []
    result = sweep(OperatingConditions(remus, Variant.LATERAL), "roll_torque", 0.0, 5.5 * Q_PROP)
    plot_sweep(
        result,
        remus,
        figures / "fig5_9_roll_torque.png",
        title="Figs. 5.9-5.10: equilibria of the REMUS 100 over the roll torque Q",
    )
    folds = result.folds
    ours = ", ".join(f"{f.parameter / Q_PROP:.3f} Q_prop" for f in folds) or "none"
    fold = reference("example_5_4.fold_roll_torque")
    rows.append(
        fact_row(
            f"one fold (saddle-node) as |Q| grows, 'slightly larger than {fold.text} Q_prop'",
            "Ex. 5.4, Fig. 5.9",
            f"> {fold.text} Q_prop (Q_prop = {Q_PROP} N m)",
            f"{len(folds)} fold at {ours} (Q = {folds[0].parameter:.4f} N m)" if folds else ours,
            # "slightly larger": within one Q_prop
            len(folds) == 1
            and float(fold.value) < folds[0].parameter / Q_PROP < float(fold.value) + 1.0,
        )
    )
    after = find_equilibria(OperatingConditions(remus, Variant.LATERAL, roll_torque=5 * Q_PROP))
    rows.append(
        fact_row(
            "beyond the fold one equilibrium remains, stable, banked to port (phi < 0)",
            "Ex. 5.4, Figs. 5.9-5.10",
            "1, stable",
            f"{len(after)}, "
            + ", ".join(
                f"{_stability(e)} at phi = {math.degrees(e.value('roll')):.1f} deg" for e in after
            ),
            len(after) == 1 and after[0].stable and after[0].value("roll") < 0,
        )
    )
    ok, shown = True, []
    for k in (1, 2, 3, 4):
        eqs = find_equilibria(
            OperatingConditions(long_fins, Variant.LATERAL, roll_torque=k * Q_PROP)
        )
        ok &= len(eqs) == 1 and eqs[0].stable
        ok &= bool(eqs) and eqs[0].value("v") > 0 and eqs[0].value("r") > 0
        ok &= bool(eqs) and eqs[0].value("roll") < 0
        shown += [
            f"{k}Q: phi {math.degrees(eqs[0].value('roll')):.1f} deg" if eqs else f"{k}Q: none"
        ]
    result = sweep(OperatingConditions(long_fins, Variant.LATERAL), "roll_torque", 0.0, 4 * Q_PROP)
    plot_sweep(
        result,
        long_fins,
        figures / "fig5_11_roll_torque_long_fins.png",
        title="Fig. 5.11: the straight-line stable vehicle over Q",
    )
    rows.append(
        fact_row(
            "long fins, Q = 1..4 Q_prop: one stable equilibrium, phi < 0, v > 0, r > 0",
            "Ex. 5.5, Fig. 5.11",
            "structurally stable",
            "; ".join(shown) + f"; {len(result.special_points)} special points on the way",
            ok and not result.special_points,
        )
    )
    rows.append(_neutral_buoyancy_claim(long_fins))
    return rows


def _neutral_buoyancy_claim(long_fins: VehicleParameters) -> Row:
    """Example 5.6: with W = B the roll torque only banks the vehicle, by (5.1.74)."""
    neutral = long_fins.replace(W=long_fins.B)
    eqs = find_equilibria(OperatingConditions(neutral, Variant.LATERAL, roll_torque=Q_PROP))
    expected = math.degrees(math.asin(Q_PROP / (neutral.W * neutral.z_g)))
    return fact_row(
        "W = B, x_g = 0: equilibrium [U0, 0, 0, 0, phi0], sin phi0 = Q / (W z_g), stable",
        "Ex. 5.6, (5.1.74)",
        f"phi0 = {expected:.3f} deg at Q = Q_prop",
        ", ".join(
            f"v = {e.value('v'):.1e}, r = {e.value('r'):.1e}, "
            f"phi = {math.degrees(e.value('roll')):.3f} deg, {_stability(e)}"
            for e in eqs
        ),
        len(eqs) == 1
        and eqs[0].stable
        and abs(math.degrees(eqs[0].value("roll")) - expected) < 1e-3
        and abs(eqs[0].value("v")) < 1e-9,
        "(5.1.74) is exact here, so 1e-3 deg is the tolerance",
    )


def mass_claims(remus: VehicleParameters, figures: Path) -> list[Row]:
    rows = []
    result = sweep(
        OperatingConditions(remus, Variant.LATERAL), "mass_position", 0.0, -remus.mass_stroke
    )
    plot_sweep(
        result,
        remus,
        figures / "fig5_12_mass_position.png",
        title="Figs. 5.12-5.13: equilibria over the moving-mass position",
    )
    folds = result.folds
    y_g = [100 * cg_offset(remus, f.parameter) for f in folds]
    fold = reference("section_5_1_4.fold_cg_offset")
    rows.append(
        fact_row(
            f"one fold when |y_g| is 'slightly larger than {fold.text} cm'",
            "Sec. 5.1.4, Fig. 5.12",
            f"|y_g| > {fold.text} cm",
            ", ".join(
                f"y_g = {g:.3f} cm (y_v = {100 * f.parameter:.2f} cm)"
                for g, f in zip(y_g, folds, strict=True)
            )
            or "none",
            # "slightly larger": within one unit of the printed digit
            len(folds) == 1
            and float(fold.value) < abs(y_g[0]) < float(fold.value) + float(fold.resolution),
            "y_g = m_v g y_v / W: the roll torque of our mass at rest equals W y_g cos(phi)",
        )
    )
    beyond = reference("section_5_1_4.single_equilibrium_cg_offset")
    y_v = mass_position_for_cg_offset(remus, float(beyond.value) / 100)
    eqs = find_equilibria(OperatingConditions(remus, Variant.LATERAL, mass_position=y_v))
    estimate = math.degrees(math.atan(beyond.value / 100 / remus.z_g))
    rows.append(
        fact_row(
            f"y_g = {beyond.text} cm: one equilibrium, phi0 ~ arctan(y_g / z_g) "
            "'with a slight difference'",
            "(5.1.77), Fig. 5.12",
            f"arctan estimate {estimate:.1f} deg",
            ", ".join(
                f"phi = {math.degrees(e.value('roll')):.1f} deg, {_stability(e)}" for e in eqs
            ),
            len(eqs) == 1
            and eqs[0].stable
            and abs(math.degrees(eqs[0].value("roll")) - estimate) < 3,
            "the estimate ignores the coupling terms, as the text says",
        )
    )
    return rows


def fin_factor_claims(remus: VehicleParameters, figures: Path) -> list[Row]:
    rows = []
    branch = reference("fin_factors.branch_point")
    for name, fig, source in (
        ("mu", "fig5_6_mu", "Fig. 5.6, (5.1.62)"),
        ("eta", "fig5_7_eta", "Fig. 5.7, (5.1.63)"),
    ):
        result = sweep(OperatingConditions(remus), name, 1.0, 3.0)
        plot_sweep(
            result,
            remus,
            figures / f"{fig}.png",
            title=f"{source.split(',')[0]}: equilibria over the fin factor {name}",
        )
        switches = [s for s in result.special_points if s.kind == "branch point"]
        rows.append(
            fact_row(
                f"the turning pair merges into x0, which turns stable, at {name} ~ {branch.text}",
                source,
                f"about {branch.text}",
                ", ".join(f"{s.kind} at {name} = {s.parameter:.3f}" for s in result.special_points)
                or "none",
                len(switches) == 1 and abs(switches[0].parameter - float(branch.value)) < 0.15,
                "a symmetric pitchfork: the fold-free branch point where x0 changes stability",
            )
        )
    return rows


def phase_portraits(remus, long_fins, figures: Path) -> list[Row]:
    rows = []
    for params, name, caption in (
        (remus, "fig5_4_phase_portrait", "Fig. 5.4"),
        (long_fins, "fig5_5_phase_portrait_long_fins", "Fig. 5.5"),
    ):
        conditions = OperatingConditions(params)
        eqs = find_equilibria(conditions)
        trajectories = phase_trajectories(conditions, eqs)
        plot_phase_portrait(
            trajectories,
            eqs,
            figures / f"{name}.png",
            title=f"{caption}: open-loop phase portrait, {params.name}",
        )
        ends = np.array([x[-1, [STATE_INDEX[n] for n in ("u", "v", "r")]] for x in trajectories])
        stable = np.array([_uvr(e) for e in eqs if e.stable])
        distance = np.min(np.linalg.norm(ends[:, None, :] - stable[None], axis=2), axis=1)
        on_manifold = int(np.sum(distance > 1e-3))
        rows.append(
            fact_row(
                f"{caption}: trajectories from D end at the stable equilibria",
                caption,
                "all (except on the stable manifold of x0)" if len(stable) > 1 else "all",
                f"{len(trajectories) - on_manifold} of {len(trajectories)} within 1e-3 after 30 s",
                on_manifold <= (3 if len(stable) > 1 else 0),
                "the 3 starts on the u axis lie on W_s of x0 and stay there"
                if len(stable) > 1
                else "",
            )
        )
    return rows


# --- Ch. 6: the linearised model and the low-speed equilibria --------------------------------


def linearised_6_3_19(remus: VehicleParameters) -> list[Row]:
    """(6.3.19) at U0 = 1.525 m/s with W = m g, g = 9.8 (the dissertation's values)."""
    params = remus.replace(g=9.8, W=remus.m * 9.8)
    model = PlantModel(params, Variant.LATERAL)
    states = ["v", "r", "p", "roll", "yaw", "mass_position", "mass_velocity"]
    A, B = linearize(
        model,
        state_vector({"u": 1.525}),
        input_vector({"thrust": 9.0}),
        states,
        ["mass_position_cmd"],
    )
    printed_A = reference("equation_6_3_19.A").text
    printed_B = printed("equation_6_3_19.B")
    rows = []
    mismatches = [
        (i, j) for i in range(3) for j in range(7) if not agrees(printed_A[i][j], A[i, j])
    ]
    others = [m for m in mismatches if m != (1, 1)]
    rows.append(
        fact_row(
            "A of (6.3.19), rows v, r, p (21 entries) except A(2,2)",
            "(6.3.19)",
            "as printed",
            "all agree" if not others else f"differ at {others}",
            not others,
            "at U0 = 1.525 m/s with g = 9.8 (W = m g), as the dissertation computed it",
        )
    )
    rows.append(
        Row(
            "A(2,2) = d(r_dot)/dr",
            "(6.3.19)",
            printed_A[1][1],
            f"{A[1, 1]:.3f}",
            "differs (explained)" if not agrees(printed_A[1][1], A[1, 1]) else "agrees",
            "sign error in J'' of (6.2.33): -F - F H'' + gamma4 gives -0.942; Ex. 5.3's J-bar "
            "(-0.9264 at 1.5 m/s = -0.942 x 1.5/1.525) has the right sign",
        )
    )
    rows_B = [0, 1, 2, 6]  # v, r, p, y_vel: the others are 0
    rows.append(
        vector_row(
            "B of (6.3.19) (rows v, r, p, y_vel)",
            "(6.3.19)",
            [printed_B[i] for i in rows_B],
            [B[i, 0] for i in rows_B],
        )
    )
    rows.append(
        vector_row(
            "servo rows: y_vel_dot = -k_v/m_v y_v - d_v/m_v y_vel",
            "(6.3.19)",
            printed_A[6][5:],
            [A[6, 5], A[6, 6]],
        )
    )
    return rows


def low_speed(remus: VehicleParameters) -> list[Row]:
    eqs = _by_v(find_equilibria(OperatingConditions(remus, Variant.LATERAL, thrust=4.0)))
    if len(eqs) != 3:
        return [fact_row("T = 4 N: three equilibria", "Sec. 6.3.3", "3", str(len(eqs)), False)]
    low, axis, high = eqs
    note = "lateral variant (W != B): a small bank angle; within 0.5 %"
    return [
        vector_row(
            "T = 4 N: x0 = [u, v, r]",
            "Sec. 6.3.3",
            printed("low_speed.straight_line")[:3],
            _uvr(axis),
        ),
        vector_row(
            "T = 4 N: x0' = [u, v, r]",
            "Sec. 6.3.3",
            printed("low_speed.turn_positive_v")[:3],
            _uvr(high),
            rel=5e-3,
            note=note,
        ),
        vector_row(
            "T = 4 N: x0'' = [u, v, r]",
            "Sec. 6.3.3",
            printed("low_speed.turn_negative_v")[:3],
            _uvr(low),
            rel=5e-3,
            note=note,
        ),
        fact_row(
            "T = 4 N: x0 unstable, x0', x0'' stable",
            "Sec. 6.3.3",
            "unstable / stable",
            f"{_stability(axis)} / {_stability(high)}, {_stability(low)}",
            not axis.stable and high.stable and low.stable,
        ),
    ]


# --- Ch. 6: closed-loop scenarios through the master ----------------------------------------


@dataclass
class RunData:
    """A scenario's results: columns by name."""

    table: dict[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.table[name]

    def has(self, *names: str) -> bool:
        return all(n in self.table for n in names)


def heading_summary(t: np.ndarray, yaw: np.ndarray, band: float) -> tuple[str, float | None]:
    """'peak |psi| ... at ...; |psi| < band first at ... after the peak, for good from ...'
    and the settling time (for good)."""
    k0 = int(np.argmax(np.abs(yaw)))
    inside = np.flatnonzero(np.abs(yaw[k0:]) < band)
    first = float(t[k0 + inside[0]]) if inside.size else None
    s = settling_time(t, yaw, band, angle=True)
    text = (
        f"peak |psi| {math.degrees(abs(yaw[k0])):.1f} deg at {t[k0]:.1f} s; "
        f"|psi| < {math.degrees(band):.0f} deg first at {_fmt_time(first)}, "
        f"for good from {_fmt_time(s)}"
    )
    return text, s


def _fmt_time(value: float | None) -> str:
    return "never" if value is None else f"{value:.1f} s"


DEG = math.radians(1.0)
ABOUT = 5.0  # s: the slack we test an "about N seconds" of the text with
LQR_1_TIME = reference("scenarios.lqr_1_settling_time")
LQR_2_STOP = reference("scenarios.lqr_2_mass_stop")
LQR_2_TIME = reference("scenarios.lqr_2_settling_time")
BS_3_TIME = reference("scenarios.bs_3_settling_time")
CUR_2_TIME = reference("scenarios.cur_2_settling_time")
SLOW_2_TIME = reference("scenarios.slow_2_settling_time")
HEADING_9_N = reference("current.heading_9_newton")
HEADING_4_N = reference("current.heading_4_newton")
DEPTH_STEADY = reference("scenarios.depth_steady_state")

# id -> (claim, source, printed, check(run) -> (ours text, ok, note))
ScenarioCheck = Callable[[RunData], tuple[str, bool, str]]


def _heading_back(within: float) -> ScenarioCheck:
    def check(run: RunData) -> tuple[str, bool, str]:
        text, s = heading_summary(run["time"], run["plant.yaw"], DEG)
        return text, s is not None and s <= within, ""

    return check


def _lqr2(run: RunData) -> tuple[str, bool, str]:
    text, s = heading_summary(run["time"], run["plant.yaw"], DEG)
    saturated = float(np.min(run["plant.mass_position"]))
    text = f"min y_v = {100 * saturated:.2f} cm; {text}"
    peak = math.degrees(float(np.max(np.abs(run["plant.yaw"]))))
    rail_speed = 100 * float(np.max(np.abs(run["plant.mass_velocity"])))
    note = (
        f" Ours peaks at {peak:.1f} deg of yaw where Fig. 6.14's axis ends at 10 deg, with rail "
        f"speeds up to {rail_speed:.0f} cm/s (its axis: +-50 cm/s)."
    )
    stop = float(LQR_2_STOP.value) / 100  # cm -> m
    settled = s is not None and s <= float(LQR_2_TIME.value)
    return text, abs(saturated - stop) < 1e-3 and settled, note


def _current_drift(run: RunData) -> tuple[str, bool, str]:
    t, north, east = run["time"], run["plant.north"], run["plant.east"]
    k = t >= t[-1] - 10.0
    v_north = np.polyfit(t[k], north[k], 1)[0]
    v_east = np.polyfit(t[k], east[k], 1)[0]
    course = math.degrees(math.atan2(v_east, v_north))
    yaw = math.degrees(run["plant.yaw"][-1])
    return (
        f"heading {yaw:.2f} deg, course over ground {course:.2f} deg, east drift {v_east:.3f} m/s",
        abs(yaw) < 1.0 and v_east > 0.15,
        "",
    )


def _current_track(target_deg: float, within: float) -> ScenarioCheck:
    def check(run: RunData) -> tuple[str, bool, str]:
        t, north, east = run["time"], run["plant.north"], run["plant.east"]
        k = t >= t[-1] - 10.0
        v_north = np.polyfit(t[k], north[k], 1)[0]
        v_east = np.polyfit(t[k], east[k], 1)[0]
        course = math.degrees(math.atan2(v_east, v_north))
        yaw = run["plant.yaw"]
        final = math.degrees(float(np.mean(yaw[k])))
        s = settling_time(t, yaw - math.radians(target_deg), 0.5 * DEG, angle=True)
        return (
            f"heading {final:.2f} deg (within 0.5 deg of psi_d from {_fmt_time(s)}), "
            f"course over ground {course:.2f} deg",
            s is not None and s <= within and abs(course) < 1.0,
            "",
        )

    return check


def _roll_keeps_oscillating(run: RunData) -> tuple[str, bool, str]:
    t, roll = run["time"], run["plant.roll"]
    k = t >= t[-1] - 20.0
    swing = math.degrees(float(np.ptp(roll[k])))
    return f"roll swings {swing:.2f} deg peak to peak over the last 20 s", swing > 1.0, ""


def _vert2(run: RunData) -> tuple[str, bool, str]:
    t = run["time"]
    k = t >= t[-1] - 10.0
    w = float(np.mean(run["plant.w"][k]))
    theta = float(np.mean(run["plant.pitch"][k]))
    fin = math.degrees(float(np.mean(run["controller.fin_angle"][k])))
    w_text, theta_text, fin_text = cast(list[str], DEPTH_STEADY.text)
    ok = (
        agrees(w_text, w)
        and agrees(theta_text, theta, rel=0.25)
        and abs(fin - float(fin_text)) < 1.5
    )
    return f"w = {w:.3f} m/s, theta = {theta:.3f} rad, mean delta_s = {fin:.2f} deg", ok, ""


SCENARIO_CLAIMS: dict[str, tuple[str, str, str, ScenarioCheck]] = {
    "lqr-1": (
        f"LQR, v0 = -0.01: converges within ~{LQR_1_TIME.text} s",
        "Figs. 6.11-6.12",
        f"~{LQR_1_TIME.text} s (tested: |psi| < 1 deg for good by "
        f"{LQR_1_TIME.value + ABOUT:.0f} s)",
        _heading_back(float(LQR_1_TIME.value) + ABOUT),
    ),
    "lqr-2": (
        f"LQR, v0 = -0.05: y_v saturates at {LQR_2_STOP.text} cm, heading back within "
        f"{LQR_2_TIME.text} s",
        "Figs. 6.13-6.14",
        f"{LQR_2_STOP.text} cm; {LQR_2_TIME.text} s (tested: |psi| < 1 deg for good by "
        f"{LQR_2_TIME.text} s)",
        _lqr2,
    ),
    "lqr-3": (
        "LQR, psi0 = 30 deg: heading returns",
        "Figs. 6.15-6.16",
        "returns (tested: |psi| < 1 deg for good within the run)",
        _heading_back(math.inf),
    ),
    "bs-1": (
        "backstepping + thruster, v0 = -0.05: fast convergence",
        "Figs. 6.17-6.19",
        "fast (tested: |psi| < 1 deg for good by 15 s)",
        _heading_back(15.0),
    ),
    "bs-2": (
        "backstepping, psi0 = 30 deg: back within a short time",
        "Figs. 6.20-6.22",
        "short (tested: |psi| < 1 deg for good by 20 s)",
        _heading_back(20.0),
    ),
    "bs-3": (
        f"backstepping, v0 = -0.10: psi back to 0 within {BS_3_TIME.text} s",
        "Figs. 6.23-6.25",
        f"{BS_3_TIME.text} s (tested: |psi| < 1 deg for good by {BS_3_TIME.text} s)",
        _heading_back(float(BS_3_TIME.value)),
    ),
    "cur-1": (
        f"{reference('current.speed').text} m/s current east, psi_d = 0: drifts east with sideslip",
        "Figs. 6.26-6.28",
        "drifts east",
        _current_drift,
    ),
    "cur-2": (
        f"psi_d = -beta = {HEADING_9_N.text} deg: tracks along north, steady after about "
        f"{CUR_2_TIME.text} s",
        "Figs. 6.29-6.31",
        f"course 0; ~{CUR_2_TIME.text} s (tested: within 0.5 deg of psi_d, course within 1 deg, "
        f"by {CUR_2_TIME.value + ABOUT:.0f} s)",
        _current_track(float(HEADING_9_N.value), float(CUR_2_TIME.value) + ABOUT),
    ),
    "slow-1": (
        "T = 4 N, v0 = -0.1: stabilised",
        "Figs. 6.32-6.33",
        "stabilised (tested: |psi| < 1 deg for good within the run)",
        _heading_back(math.inf),
    ),
    "slow-2": (
        f"T = 4 N, current, psi_d = {HEADING_4_N.text} deg: converges in ~{SLOW_2_TIME.text} s",
        "Figs. 6.34-6.39",
        f"~{SLOW_2_TIME.text} s (tested as cur-2)",
        _current_track(float(HEADING_4_N.value), float(SLOW_2_TIME.value) + ABOUT),
    ),
    "vert-1": (
        "6-DOF, z_d = 1 m: roll keeps oscillating",
        "Figs. 6.41-6.45",
        "oscillates (tested: > 1 deg peak to peak over the last 20 s)",
        _roll_keeps_oscillating,
    ),
    "vert-2": (
        "6-DOF, mass locked after 15 s: w ~ {}, theta ~ {}, delta_s ~ {} deg".format(
            *DEPTH_STEADY.text
        ),
        "Figs. 6.46-6.49; Sec. 6.3.4",
        "{} m/s, {} rad, {} deg (tested: last 10 s means)".format(*DEPTH_STEADY.text),
        _vert2,
    ),
}

SCENARIO_NOTES = {
    "lqr-2": "with the mass on its stop (y_v = -6 cm) the yaw moment it can make is capped "
    "and the heading comes back on the slow closed-loop mode. An independent reproduction of "
    "this case (continuous LQR gains, RK4 at 0.2 ms) also needs 28-34 s to stay "
    "within 1 deg, so the 20 s claim does not hold for this model. Like the dissertation "
    "(Sec. 6.3.1 bounds y_v and y_vel only), the scenario leaves the servo command "
    "unsaturated; saturating it at the 6 cm stroke slows the mass to ~6 cm/s and the "
    "settling to 43 s.",
}

# Figures of the report copied next to the table for these scenarios.
SCENARIO_FIGURES = ("lqr-2", "bs-3", "cur-2", "vert-2")


def scenario_claims(figures: Path, work: Path) -> list[Row]:
    try:
        from cosim.outputs.results import read_csv
        from cosim.runner import run_scenario
        from cosim.scenario.spec import builtin_scenarios
        from cosim.viz.report import write_report
    except ImportError as exc:
        return [_not_run(sid, f"the master is not available ({exc})") for sid in SCENARIO_CLAIMS]
    try:
        available = builtin_scenarios()
    except Exception as exc:  # any failure here means: cannot run scenarios
        return [_not_run(sid, f"no built-in scenarios ({exc})") for sid in SCENARIO_CLAIMS]
    rows = []
    for sid, (claim, source, printed, check) in SCENARIO_CLAIMS.items():
        if sid not in available:
            rows.append(_not_run(sid, "no such built-in scenario yet"))
            continue
        started = time.perf_counter()
        try:
            outcome = run_scenario(sid, work / sid, no_rrd=True)
        except Exception as exc:  # reported in the table, not fatal
            rows.append(_not_run(sid, f"run failed: {type(exc).__name__}: {exc}"))
            continue
        print(f"  {sid}: ran in {time.perf_counter() - started:.0f} s", file=sys.stderr)
        if not outcome.result.complete:
            rows.append(
                Row(
                    claim,
                    f"{source} ({sid})",
                    printed,
                    outcome.result.error or "",
                    "differs",
                    "the run did not complete",
                )
            )
            continue
        columns, values = read_csv(outcome.paths["results"])
        run = RunData({name: values[:, k] for k, name in enumerate(columns)})
        try:
            ours, ok, note = check(run)
        except KeyError as exc:
            rows.append(_not_run(sid, f"column {exc} not recorded"))
            continue
        note = SCENARIO_NOTES.get(sid, "") + note
        verdict = (
            "agrees" if ok else ("differs (explained)" if sid in SCENARIO_NOTES else "differs")
        )
        rows.append(Row(claim, f"{source} ({sid})", printed, ours, verdict, note))
        if sid in SCENARIO_FIGURES:
            index = write_report(work / sid)
            for png in sorted(index.parent.glob("*.png")):
                shutil.copy(png, figures / f"{sid}_{png.name}")
    return rows


def _not_run(sid: str, reason: str) -> Row:
    claim, source, printed, _ = SCENARIO_CLAIMS[sid]
    return Row(claim, f"{source} ({sid})", printed, "-", "not run", reason)


# --- the page -------------------------------------------------------------------------------


@dataclass
class Section:
    """A table of rows and the figures shown under it (file names in docs/figures)."""

    title: str
    rows: list[Row]
    figures: tuple[str, ...] = ()


def markdown(sections: list[Section], figures: Path, out: Path) -> str:
    counts: dict[str, int] = {}
    for section in sections:
        rows = section.rows
        for row in rows:
            counts[row.verdict] = counts.get(row.verdict, 0) + 1
    lines = [
        "# Reproduction of the dissertation's numbers",
        "",
        "Generated by `python scripts/reproduce_dissertation.py`; do not edit by hand. Source: "
        "B. Li, *Dynamics and Control of Autonomous Underwater Vehicles with Internal "
        "Actuators*, FAU 2016 (equation, example and figure numbers are the dissertation's).",
        "Every 'ours' value is computed from the shipped model (`plant_fmu`) or a run of the "
        "two FMUs through our master; a printed value agrees when ours is within one unit "
        "of its last printed digit, or the stated tolerance.",
        "",
        "Beyond the dissertation: [the moving mass as a second body](moving-mass-model.md) "
        "(plant parameter `moving_mass_model = 1`; what it changes in lqr-2, bs-3, vert-1 and "
        "vert-2, from `python scripts/moving_mass_models.py`). One gravity, g = 9.8 m/s^2 and "
        "W = m g, and the claims it moved: [model.md](model.md#gravity-and-the-moving-mass).",
        "",
        "Verdicts: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())) + ".",
        "",
    ]
    number = 0
    explained = []
    for section in sections:
        title, rows = section.title, section.rows
        lines += [
            f"## {title}",
            "",
            "| # | claim | source | dissertation | ours | verdict |",
            "|---|---|---|---|---|---|",
        ]
        for row in rows:
            number += 1
            note = f" ({row.note})" if row.note and row.verdict == "agrees" else ""
            lines.append(
                f"| {number} | {_cell(row.claim)}{_cell(note)} | {_cell(row.source)} | "
                f"{_cell(row.printed)} | {_cell(row.ours)} | {row.verdict} |"
            )
            if row.verdict != "agrees":
                explained.append((number, row))
        lines.append("")
        for name in section.figures:
            png = figures / name
            if png.is_file():
                lines += [f"![{png.stem}]({png.relative_to(out).as_posix()})", ""]
    lines += ["## Where we differ, and why", ""]
    for n, row in explained:
        lines.append(f"- **#{n} {row.claim}** ({row.verdict}): {row.note or 'no explanation yet'}")
    if not explained:
        lines.append("- Nowhere.")
    return "\n".join(lines)


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=ROOT / "docs", help="[docs]")
    parser.add_argument("--skip-scenarios", action="store_true", help="Ch. 5 and (6.3.19) only")
    args = parser.parse_args(argv)
    figures = args.out / "figures"
    figures.mkdir(parents=True, exist_ok=True)
    for old in figures.glob("*.png"):
        old.unlink()
    remus, long_fins = load_vehicle("remus100"), load_vehicle("remus100-long-fins")
    sections: list[Section] = []

    def section(title: str, build: Callable[[], list[Row]], *shown: str) -> None:
        started = time.perf_counter()
        try:
            rows = build()
        except Exception as exc:  # a broken check is a row, not a crash
            traceback.print_exc()
            rows = [Row(title, "-", "-", f"{type(exc).__name__}: {exc}", "differs", "check failed")]
        sections.append(Section(title, rows, shown))
        print(f"{title}: {time.perf_counter() - started:.1f} s", file=sys.stderr)

    section("Example 5.1: the REMUS 100 in the horizontal plane", lambda: example_5_1(remus))
    section("Coefficients of (5.1.31)", lambda: lift_coefficients(remus, long_fins))
    section("Example 5.2: the modified fins", lambda: example_5_2(long_fins))
    section(
        "Phase portraits (Figs. 5.4, 5.5)",
        lambda: phase_portraits(remus, long_fins, figures),
        "fig5_4_phase_portrait.png",
        "fig5_5_phase_portrait_long_fins.png",
    )
    section(
        "Fin factors mu and eta (Figs. 5.6, 5.7)",
        lambda: fin_factor_claims(remus, figures),
        "fig5_6_mu.png",
        "fig5_7_eta.png",
    )
    section("Example 5.3: lateral-directional motion", lambda: example_5_3(remus))
    section(
        "Roll torque (Sec. 5.1.3, Examples 5.4-5.6)",
        lambda: roll_torque_claims(remus, long_fins, figures),
        "fig5_9_roll_torque.png",
        "fig5_11_roll_torque_long_fins.png",
    )
    section(
        "Moving mass (Sec. 5.1.4)",
        lambda: mass_claims(remus, figures),
        "fig5_12_mass_position.png",
    )
    section("The linearised lateral model (6.3.19)", lambda: linearised_6_3_19(remus))
    section("Low speed, T = 4 N (Sec. 6.3.3)", lambda: low_speed(remus))
    if not args.skip_scenarios:
        shown = [
            f"{sid}_{name}.png"
            for sid in SCENARIO_FIGURES
            for name in ("velocities", "attitude_actuators", "trajectory", "depth")
        ]
        with tempfile.TemporaryDirectory() as work:
            section(
                "Closed-loop scenarios (Ch. 6)",
                lambda: scenario_claims(figures, Path(work)),
                *shown,
            )
    page = args.out / "reproduction.md"
    page.write_text(markdown(sections, figures, args.out) + "\n", encoding="utf-8")
    print(f"wrote {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
