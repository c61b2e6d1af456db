"""Example 5.3: the lateral model's Jacobian, its eigenvalues and the banked turns.

The vehicle carries the Chapter 5 weight, Table 5.4's W = 299 N
(:meth:`Context.chapter_5`), with which the printed Jacobian holds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from decimal import Decimal
from functools import partial

import numpy as np
import scipy.linalg

from cosim.analysis.bifurcation import OperatingConditions
from cosim.analysis.equilibria import Equilibrium
from cosim.analysis.reference_values import Reference
from cosim.reproduction.context import Context, stability
from cosim.reproduction.record import Claim, Finding, Section, printed, unit_text
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

JACOBIAN_STATES = ("v", "r", "p", "roll")
JACOBIAN_SPEED = 1.5  # m/s: where Example 5.3's printed Jacobian holds (not U0 = 1.525)
TURN_STATES = ("u", "v", "r", "p", "roll")


def jacobian(params: VehicleParameters) -> np.ndarray:
    """d(xdot)/dx of the lateral model over [v, r, p, phi] at u = 1.5 m/s, T = 9 N."""
    model = PlantModel(params, Variant.LATERAL)
    x0, u0 = state_vector({"u": JACOBIAN_SPEED}), input_vector({"thrust": 9.0})
    return linearize(model, x0, u0, list(JACOBIAN_STATES))[0]


def printed_jacobian(refs: Mapping[str, Reference]) -> tuple[str, ...]:
    """J-bar + delta-J as printed, row by row (16 entries, with their digits)."""
    bar, delta = (refs[f"example_5_3.{k}"].text for k in ("jacobian_bar", "jacobian_delta"))
    return tuple(
        str(Decimal(a) + Decimal(b))
        for ra, rb in zip(bar, delta, strict=True)
        for a, b in zip(ra, rb, strict=True)
    )


def _jacobian(expected: tuple[str, ...], ctx: Context) -> Finding:
    J = jacobian(ctx.chapter_5(ctx.remus)).ravel()
    shipped = jacobian(ctx.remus).ravel()
    worst = float(np.max(np.abs(np.array(expected, dtype=float) - J)))
    other = float(np.max(np.abs(np.array(expected, dtype=float) - shipped)))
    return Finding(
        values=tuple(J),
        against=expected,
        shown=f"largest difference {worst:.1e}",
        note=f"with remus100's W = m g = {ctx.remus.W:g} N it is {other:.1e}",
    )


def _eigenvalues(coupled: bool, ctx: Context) -> Finding:
    J = jacobian(ctx.chapter_5(ctx.remus))
    if not coupled:
        J[:2, 2:] = 0.0  # J-bar: without the coupling block J12 that delta-J holds
    eig = sorted(np.linalg.eigvals(J), key=lambda z: (-z.real, z.imag))
    return Finding(values=(eig[0].real, eig[3].real, eig[1].real, abs(eig[1].imag)))


def _condition_numbers(ctx: Context) -> Finding:
    """The individual condition numbers of J-bar's eigenvalues, 1/|y^H x| for unit left
    and right eigenvectors y, x, in the printed order: the unstable one, the stable one,
    the roll pair."""
    J = jacobian(ctx.chapter_5(ctx.remus))
    J[:2, 2:] = 0.0
    values, left, right = scipy.linalg.eig(J, left=True, right=True)
    condition = [
        float(
            np.linalg.norm(left[:, k])
            * np.linalg.norm(right[:, k])
            / abs(left[:, k].conj() @ right[:, k])
        )
        for k in range(len(values))
    ]
    order = sorted(range(len(values)), key=lambda k: (abs(values[k].imag) > 0, -values[k].real))
    return Finding(values=tuple(condition[k] for k in order[:3]))


def _eigenvalue_text(ref: Reference) -> tuple[str, ...]:
    """[re, re, re, im] of printed eigenvalues [[re, 0], [re, 0], [re, +im], [re, -im]]."""
    (real_1, _), (real_2, _), (real_3, imag), _ = list(ref.text)
    return real_1, real_2, real_3, imag


def turns(ctx: Context) -> tuple[Equilibrium, Equilibrium, Equilibrium]:
    """x0'', x0, x0' of (5.1.70) (sorted by v): T = 9 N, lateral variant."""
    conditions = OperatingConditions(ctx.chapter_5(ctx.remus), Variant.LATERAL)
    eqs = ctx.equilibria("example 5.3", conditions)
    if len(eqs) != 3:
        raise ValueError(f"expected three equilibria, found {len(eqs)}")
    return eqs[0], eqs[1], eqs[2]


def _turn(which: int, ctx: Context) -> Finding:
    eq = turns(ctx)[which]
    return Finding(values=tuple(eq.value(n) for n in TURN_STATES))


def _turn_stability(printed_bank: str, ctx: Context) -> Finding:
    """The turns stable, x0 not, and the steady bank |phi| (deg) compared with the printed
    'about 2 degrees' (to its printed precision, one degree)."""
    low, axis, high = turns(ctx)
    bank = math.degrees(abs(high.value("roll")))
    return Finding(
        values=(bank,),
        against=(printed_bank,),
        shown=f"{stability(high)}, {stability(low)}, x0 {stability(axis)}; |phi| = {bank:.2f} deg",
        holds=high.stable and low.stable and not axis.stable,
    )


def example_5_3(refs: Mapping[str, Reference]) -> Section:
    """Example 5.3: the Jacobian, its eigenvalues with and without coupling, the turns."""
    weight = refs["table_5_4.weight"]
    bank = refs["example_5_3.bank_angle"]
    claims = [
        Claim(
            "Jacobian J-bar + delta-J over [v, r, p, phi] (16 entries)",
            "Ex. 5.3",
            "as printed",
            "SI",
            partial(_jacobian, printed_jacobian(refs)),
            note=f"holds at u = {JACOBIAN_SPEED} m/s (not U0 = 1.525) with Table 5.4's "
            f"W = {weight.text} N;",
        )
    ]
    for coupled, key, what in (
        (True, "eigenvalues", "J-bar + delta-J"),
        (False, "eigenvalues_bar", "J-bar (coupling J12 removed)"),
    ):
        ref = refs[f"example_5_3.{key}"]
        claims.append(
            Claim(
                f"eigenvalues of {what} (re, re, re +- i im)",
                ref.source,
                _eigenvalue_text(ref),
                unit_text(ref),
                partial(_eigenvalues, coupled),
                reference=ref.key,
            )
        )
    cond = refs["example_5_3.condition_numbers"]
    claims.append(
        Claim.of(
            cond,
            "condition numbers of J-bar's eigenvalues (0.9584, -2.4662, the roll pair)",
            _condition_numbers,
        )
    )
    for name, key, which in (("x0'", "turn_positive_v", 2), ("x0''", "turn_negative_v", 0)):
        ref = refs[f"example_5_3.{key}"]
        claims.append(
            Claim.of(
                ref,
                f"{name} = [u, v, r, p, phi]",
                partial(_turn, which),
            )
        )
    claims.append(
        Claim(
            f"x0', x0'' stable, x0 unstable; steady bank about {bank.text} deg",
            bank.source,
            f"stable; |phi| ~ {bank.text} deg",
            unit_text(bank),
            partial(_turn_stability, printed(bank)[0]),
            reference=bank.key,
        )
    )
    return Section("Example 5.3: lateral-directional motion", tuple(claims))
