"""Chapter 6 without a run: the linearised lateral model with the moving-mass servo
(6.3.19) and the low-speed equilibria of Sec. 6.3.3.

The vehicle is ``remus100`` as shipped, W = m g with g = 9.8, which is how the dissertation
computed (6.3.19).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial

import numpy as np

from cosim.analysis.bifurcation import OperatingConditions
from cosim.analysis.equilibria import Equilibrium
from cosim.analysis.reference_values import Reference
from cosim.reproduction.context import Context, stability, uvr
from cosim.reproduction.record import (
    Claim,
    Finding,
    LastDigit,
    Relative,
    Section,
    printed,
    unit_text,
)
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector

SERVO_STATES = ("v", "r", "p", "roll", "yaw", "mass_position", "mass_velocity")
U0 = 1.525  # m/s: the operating point of (6.3.19)
A22 = (1, 1)  # d(r_dot)/dr: printed with a sign error in J'' of (6.2.33)
B_ROWS = (0, 1, 2, 6)  # v, r, p, y_vel: the other rows of B are 0
LOW_SPEED_TURN = Relative(5e-3)  # the lateral variant banks a little where Sec. 6.3.3 does not


def linearised(ctx: Context) -> tuple[np.ndarray, np.ndarray]:
    """A and B of (6.3.19) for ``remus100`` at U0 = 1.525 m/s, T = 9 N."""

    def compute() -> tuple[np.ndarray, np.ndarray]:
        model = PlantModel(ctx.remus, Variant.LATERAL)
        x0, u0 = state_vector({"u": U0}), input_vector({"thrust": 9.0})
        return linearize(model, x0, u0, list(SERVO_STATES), ["mass_position_cmd"])

    return ctx.memo("(6.3.19)", compute)


def _A_rows(printed_A: list, ctx: Context) -> Finding:
    A, _ = linearised(ctx)
    cells = [(i, j) for i in range(3) for j in range(7) if (i, j) != A22]
    off = [(i, j) for i, j in cells if not LastDigit().accepts(printed_A[i][j], A[i, j])]
    return Finding(
        values=tuple(A[i, j] for i, j in cells),
        against=tuple(printed_A[i][j] for i, j in cells),
        shown="all agree" if not off else f"differ at {off}",
    )


def _A22(ctx: Context) -> Finding:
    return Finding(values=(linearised(ctx)[0][A22],))


def _B(ctx: Context) -> Finding:
    B = linearised(ctx)[1]
    return Finding(values=tuple(B[i, 0] for i in B_ROWS))


def _servo(ctx: Context) -> Finding:
    A = linearised(ctx)[0]
    return Finding(values=(A[6, 5], A[6, 6]))


def equation_6_3_19(refs: Mapping[str, Reference]) -> Section:
    """(6.3.19): A's rows v, r, p, its A(2,2), B and the servo rows."""
    A, B = refs["equation_6_3_19.A"], refs["equation_6_3_19.B"]
    claims = (
        Claim(
            "A of (6.3.19), rows v, r, p (21 entries) except A(2,2)",
            A.source,
            "as printed",
            "SI",
            partial(_A_rows, [list(row) for row in A.text]),
            note=f"at U0 = {U0} m/s with g = 9.8 (W = m g), as the dissertation computed it",
        ),
        Claim(
            "A(2,2) = d(r_dot)/dr",
            A.source,
            printed(A, [7 + 1]),
            "1/s",
            _A22,
            explained="sign error in J'' of (6.2.33): -F - F H'' + gamma4 gives -0.942; "
            "Ex. 5.3's J-bar (-0.9264 at 1.5 m/s = -0.942 x 1.5/1.525) has the right sign",
        ),
        Claim(
            "B of (6.3.19) (rows v, r, p, y_vel)",
            B.source,
            printed(B, B_ROWS),
            "SI",
            _B,
        ),
        Claim(
            "servo rows: y_vel_dot = -k_v/m_v y_v - d_v/m_v y_vel",
            A.source,
            printed(A, [6 * 7 + 5, 6 * 7 + 6]),
            "1/s^2, 1/s",
            _servo,
        ),
    )
    return Section("The linearised lateral model (6.3.19)", claims)


def low_speed_equilibria(ctx: Context) -> tuple[Equilibrium, Equilibrium, Equilibrium]:
    """x0'', x0, x0' at T = 4 N (sorted by v), lateral variant."""
    conditions = OperatingConditions(ctx.remus, Variant.LATERAL, thrust=4.0)
    eqs = ctx.equilibria("low speed", conditions)
    if len(eqs) != 3:
        raise ValueError(f"expected three equilibria, found {len(eqs)}")
    return eqs[0], eqs[1], eqs[2]


def _low_speed(which: int, ctx: Context) -> Finding:
    return Finding(values=uvr(low_speed_equilibria(ctx)[which]))


def _low_speed_stability(ctx: Context) -> Finding:
    low, axis, high = low_speed_equilibria(ctx)
    return Finding(
        shown=f"{stability(axis)} / {stability(high)}, {stability(low)}",
        holds=not axis.stable and high.stable and low.stable,
    )


def low_speed(refs: Mapping[str, Reference]) -> Section:
    """Sec. 6.3.3: the equilibria at T = 4 N."""
    claims = []
    for name, key, which, tolerance in (
        ("x0", "straight_line", 1, LastDigit()),
        ("x0'", "turn_positive_v", 2, LOW_SPEED_TURN),
        ("x0''", "turn_negative_v", 0, LOW_SPEED_TURN),
    ):
        ref = refs[f"low_speed.{key}"]
        claims.append(
            Claim(
                f"T = 4 N: {name} = [u, v, r]",
                ref.source,
                printed(ref, range(3)),
                unit_text(ref, range(3)),
                partial(_low_speed, which),
                tolerance=tolerance,
                note="" if which == 1 else "lateral variant (W != B): a small bank angle",
            )
        )
    claims.append(
        Claim(
            "T = 4 N: x0 unstable, x0', x0'' stable",
            "Sec. 6.3.3",
            "unstable / stable",
            "-",
            _low_speed_stability,
        )
    )
    return Section("Low speed, T = 4 N (Sec. 6.3.3)", tuple(claims))
