"""The depth plane (Sec. 6.3.4): Table 6.1's linear coefficients of (6.3.77) against the
plant, which is built from Table 6.3's nonlinear ones, and what the difference does to the
depth loop of Fig. 6.40 with Table 6.2's gains.

The dissertation's two tables disagree: Table 6.1 (Prestero's linear model, on which
Table 6.2's depth PD was designed) and Table 6.3 (the nonlinear coefficients of its 6-DOF
simulation, which our plant uses, M_uq's sign corrected: docs/model.md). Ours are the
plant's force derivatives at the straight run at U0 = 1.525 m/s, in (6.3.77)'s convention
(its Z_q without the rigid body's m U0).
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import partial

import numpy as np

from controller_fmu.depth_pd import TABLE_6_2_GAMMA, TABLE_6_2_K_P, TABLE_6_2_TAU_D
from cosim.analysis.reference_values import Reference
from cosim.reproduction.context import Context
from cosim.reproduction.record import Claim, Finding, Section
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, linearize, state_vector
from plant_fmu.model.parameters import VehicleParameters

U0 = 1.525  # m/s: Table 6.1's and Table 6.2's design speed
STATES = ["u", "v", "w", "p", "q", "r", "down", "pitch"]
W, Q, DOWN, PITCH = 2, 4, 6, 7  # indices into STATES
HEAVE, PITCH_ROW = 2, 4  # rows of the generalised force [X, Y, Z, K, M, N]
TABLES_DISAGREE = (
    "Table 6.1 and Table 6.3 disagree, and the plant is built from Table 6.3: Z_w = Z_uw U0 "
    "(-66.6 would need Z_uw = -43.7, not -17.9); M_w = (M_uw + a33 - a11) U0, the Munk "
    "moment included; Z_q = (Z_uq + a11) U0. M_theta = -z_g W = -5.86 N m owes nothing to "
    "Table 6.3 (Table 5.4's z_g, either weight): the printed -5.77 would need z_g = 1.93 cm "
    "or W = 294 N, why is not known. The fin coefficients are Table 6.1's own, and M_q "
    "agrees to 1 %."
)


def linear_depth_model(params: VehicleParameters) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, B) of the plant over STATES and the fin angle at the straight run at U0, and the
    force derivatives (M_RB + M_A) [A, B] over its velocity rows."""
    model = PlantModel(params, Variant.FULL)
    A, B = linearize(
        model, state_vector({"u": U0}), input_vector({"thrust": 9.0}), STATES, ["fin_angle"]
    )
    forces = model.mass_matrix @ np.hstack([A, B])[:6]
    return A, B, forces


def coefficients(params: VehicleParameters) -> tuple[float, ...]:
    """Z_w, Z_q, M_w, M_q, M_theta, Z_ds, M_ds of (6.3.77) from the plant."""
    _, _, F = linear_depth_model(params)
    fin = len(STATES)
    return (
        F[HEAVE, W],
        F[HEAVE, Q] - params.m * U0,
        F[PITCH_ROW, W],
        F[PITCH_ROW, Q],
        F[PITCH_ROW, PITCH],
        F[HEAVE, fin],
        F[PITCH_ROW, fin],
    )


def _fin_law() -> np.ndarray:
    """delta_s = K x of Fig. 6.40 with z_d = 0: -K_p [(gamma (0 - z) - theta) - tau_d q]."""
    gain = np.zeros(len(STATES))
    gain[Q] = TABLE_6_2_K_P * TABLE_6_2_TAU_D
    gain[DOWN] = TABLE_6_2_K_P * TABLE_6_2_GAMMA
    gain[PITCH] = TABLE_6_2_K_P
    return gain


def plant_poles(params: VehicleParameters) -> np.ndarray:
    """The depth loop's poles on the plant's linearisation (w, q, z, theta)."""
    A, B, _ = linear_depth_model(params)
    closed = A + B @ _fin_law()[None, :]
    keep = [W, Q, DOWN, PITCH]
    return np.linalg.eigvals(closed[np.ix_(keep, keep)])


def table_poles(params: VehicleParameters, table: list[float], a35: float) -> np.ndarray:
    """The same loop on (6.3.77) with Table 6.1's coefficients and its -a35 coupling (the
    inertias m, I_yy, a33, a55 are the vehicle's, which Table 6.1 repeats)."""
    z_w, z_q, m_w, m_q, m_theta, z_ds, m_ds = table
    mass = np.array([[params.m + params.a33, -a35], [-a35, params.I_yy + params.a55]])
    force = np.array([[z_w, params.m * U0 + z_q, 0.0, 0.0], [m_w, m_q, 0.0, m_theta]])
    gain = _fin_law()[[W, Q, DOWN, PITCH]]
    rates = np.linalg.solve(mass, force + np.outer([z_ds, m_ds], gain))
    kinematics = np.array([[1.0, 0.0, 0.0, -U0], [0.0, 1.0, 0.0, 0.0]])  # z' = w - U0 theta
    return np.linalg.eigvals(np.vstack([rates, kinematics]))


def _pair_text(poles: np.ndarray) -> str:
    upper = sorted((p for p in poles if p.imag >= 0), key=lambda p: abs(p))
    return ", ".join(f"{p.real:.2f} +- {abs(p.imag):.2f}i" for p in upper)


def _coefficients(ctx: Context) -> Finding:
    return Finding(values=coefficients(ctx.remus))


def _loops(table: list[float], a35: float, ctx: Context) -> Finding:
    """Both depth loops stable, the inner (pitch) pair faster than the outer (depth) one."""
    ours, theirs = plant_poles(ctx.remus), table_poles(ctx.remus, table, a35)
    faster = []
    for poles in (ours, theirs):
        slow, fast = sorted((p for p in poles if p.imag >= 0), key=lambda p: abs(p))
        faster.append(abs(fast) / abs(slow))
    pairs = list(zip(sorted(ours, key=abs), sorted(theirs, key=abs), strict=True))
    shift = max(abs(abs(a) / abs(b) - 1) for a, b in pairs)
    decay = max(abs(a.real / b.real - 1) for a, b in pairs)
    return Finding(
        shown=f"plant (Table 6.3): {_pair_text(ours)}; (6.3.77) with Table 6.1: "
        f"{_pair_text(theirs)}; the inner pair {faster[0]:.1f} and {faster[1]:.1f} times "
        f"faster; the poles move by up to {100 * shift:.0f} % in magnitude, "
        f"{100 * decay:.0f} % in decay rate",
        holds=all(p.real < 0 for p in (*ours, *theirs)) and min(faster) > 1.5,
    )


def depth_plane(refs: Mapping[str, Reference]) -> Section:
    """Table 6.1 against the plant, and the depth loop on both."""
    table, a35 = refs["table_6_1.depth_coefficients"], refs["table_6_1.heave_pitch_added_mass"]
    claims = (
        Claim.of(
            table,
            "(6.3.77)'s Z_w, Z_q, M_w, M_q, M_theta, Z_ds, M_ds at U0 = 1.525 m/s",
            _coefficients,
            explained=TABLES_DISAGREE,
        ),
        Claim(
            "Table 6.2's depth PD (Fig. 6.40): the inner pitch loop responds fast compared "
            "with the outer depth loop",
            "Sec. 6.3.4, Table 6.2",
            "inner loop faster (tested: both stable, inner pair > 1.5 times faster)",
            "-",
            partial(_loops, [float(v) for v in np.ravel(table.value)], float(a35.value)),
            note="the shipped depth PD has Table 6.2's gains, designed for Table 6.1's "
            "coefficients, and runs them on the plant built from Table 6.3",
        ),
    )
    return Section("The depth plane (Sec. 6.3.4, Tables 6.1-6.3)", claims)
