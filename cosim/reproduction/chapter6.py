"""Chapter 6 without a run: the moving mass and its servo (Sec. 6.2.3, (6.3.16),
Fig. 6.10) and the linearised lateral model with the servo (6.3.19).

The vehicle is ``remus100`` as shipped, W = m g with g = 9.8, which is how the dissertation
computed (6.3.19).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial

import control
import numpy as np

from controller_fmu.lqr import output_matrix
from cosim.analysis.reference_values import Reference
from cosim.reproduction.context import Context
from cosim.reproduction.record import Claim, Finding, LastDigit, Section, printed
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector

SERVO_STATES = ("v", "r", "p", "roll", "yaw", "mass_position", "mass_velocity")
U0 = 1.525  # m/s: the operating point of (6.3.19)
A22 = (1, 1)  # d(r_dot)/dr: printed with a sign error in J'' of (6.2.33)
B_ROWS = (0, 1, 2, 6)  # v, r, p, y_vel: the other rows of B are 0
SERVO = slice(5, 7)  # y_v, y_vel in SERVO_STATES
INERTIA_10_PERCENT = (
    "{increment:.4f} kg m^2 is {share:.1f} % of I_xx + a44 = {total:.4f} kg m^2 "
    "({with_it:.1f} % of the total with it)."
)


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
            reference=A.key,
        ),
        Claim(
            "A(2,2) = d(r_dot)/dr",
            A.source,
            printed(A, [7 + 1]),
            "1/s",
            _A22,
            explained="sign error in J'' of (6.2.33): -F - F H'' + gamma4 gives -0.942; "
            "Ex. 5.3's J-bar (-0.9264 at 1.5 m/s = -0.942 x 1.5/1.525) has the right sign",
            reference=A.key,
        ),
        Claim(
            "B of (6.3.19) (rows v, r, p, y_vel)",
            B.source,
            printed(B, B_ROWS),
            "SI",
            _B,
            reference=B.key,
        ),
        Claim(
            "servo rows: y_vel_dot = -k_v/m_v y_v - d_v/m_v y_vel",
            A.source,
            printed(A, [6 * 7 + 5, 6 * 7 + 6]),
            "1/s^2, 1/s",
            _servo,
            reference=A.key,
        ),
        Claim(
            "(6.3.19) is controllable, and observable from y = [r, p, phi, psi, y_v, y_vel]",
            "(6.3.18)-(6.3.19)",
            "controllable and observable",
            "-",
            _controllable,
        ),
    )
    return Section("The linearised lateral model (6.3.19)", claims)


def _controllable(ctx: Context) -> Finding:
    """Kalman's rank conditions (python-control's ctrb, obsv), and the smallest singular
    value of the PBH matrices [A - lambda I, B] and [A - lambda I; C] over A's eigenvalues
    (how far from losing either)."""
    A, B = linearised(ctx)
    C = output_matrix()
    n = len(A)
    controllable = int(np.linalg.matrix_rank(control.ctrb(A, B)))
    observable = int(np.linalg.matrix_rank(control.obsv(A, C)))
    eye = np.eye(n)
    margins = [
        min(np.linalg.svd(M, compute_uv=False)[-1] for M in blocks)
        for blocks in (
            [np.hstack([A - lam * eye, B]) for lam in np.linalg.eigvals(A)],
            [np.vstack([A - lam * eye, C]) for lam in np.linalg.eigvals(A)],
        )
    ]
    return Finding(
        shown=f"rank {controllable} of {n} (controllability), {observable} of {n} "
        f"(observability); PBH margins {margins[0]:.2f}, {margins[1]:.2f}",
        holds=controllable == n and observable == n,
    )


def _inertia_increment(ctx: Context) -> Finding:
    """Sec. 6.2.3: I_xx' = m_v y_v^2 at the stop (remus100: m_v = m/6, stroke 6 cm)."""
    params = ctx.remus
    return Finding(values=(params.m_v * params.mass_stroke**2,))


def _inertia_fraction(ctx: Context) -> Finding:
    params = ctx.remus
    increment = params.m_v * params.mass_stroke**2
    total = params.I_xx + params.a44
    share = 100 * increment / total
    return Finding(
        values=(share,),
        note=INERTIA_10_PERCENT.format(
            increment=increment,
            share=share,
            total=total,
            with_it=100 * increment / (total + increment),
        ),
    )


def _peak_time(ctx: Context) -> Finding:
    """Fig. 6.10: the servo's step response peaks at pi / omega_d, omega_d the imaginary
    part of the servo rows' eigenvalues in (6.3.19) (the plant's own (6.3.12))."""
    A = linearised(ctx)[0]
    damped = float(np.max(np.abs(np.linalg.eigvals(A[SERVO, SERVO]).imag)))
    return Finding(values=(np.pi / damped,))


def moving_mass_servo(refs: Mapping[str, Reference]) -> Section:
    """Sec. 6.2.3 and Fig. 6.10: what the moving mass adds to the roll inertia, and how
    fast its servo follows a step."""
    increment = refs["section_6_2_3.roll_inertia_increment"]
    fraction = refs["section_6_2_3.roll_inertia_fraction"]
    peak = refs["figure_6_10.peak_time"]
    claims = (
        Claim.of(
            increment,
            "the roll inertia the mass adds at its 6 cm stop, m_v y_v^2 (m_v = m/6)",
            _inertia_increment,
        ),
        Claim.of(
            fraction,
            "that increment is approximately 10 % of I_xx + a44",
            _inertia_fraction,
            explained="the text's 'approximately 10 percent' is loose (the increment itself "
            "agrees, the row above):",
        ),
        Claim.of(
            peak,
            "zeta = 0.9, omega_n = 2.4 rad/s: the servo's step response peaks after about 3 s",
            _peak_time,
        ),
    )
    return Section("The moving mass and its servo (Sec. 6.2.3, (6.3.16), Fig. 6.10)", claims)
