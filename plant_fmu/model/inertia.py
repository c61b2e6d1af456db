"""Inertia of hull and fluid: rigid-body and added-mass matrices (2.3.11, Tables 5.1, 5.4).

Kept apart from :mod:`plant_fmu.model.dynamics` so that :mod:`plant_fmu.model.parameters`
can check a parameter set's mass matrix without importing the dynamics (which imports the
parameters); the functions take any object with the fields of :class:`InertiaParameters`
(a ``VehicleParameters`` has them), so this module imports no parameter module.
Units: kg, kg m, kg m^2.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

import numpy as np

from plant_fmu.model.kinematics import skew


class InertiaParameters(Protocol):
    """The fields of a parameter set the mass matrices use (SI, body origin at the CB),
    read-only (a parameter set is frozen)."""

    @property
    def m(self) -> float: ...

    @property
    def x_g(self) -> float: ...

    @property
    def z_g(self) -> float: ...

    @property
    def I_xx(self) -> float: ...

    @property
    def I_yy(self) -> float: ...

    @property
    def I_zz(self) -> float: ...

    @property
    def a11(self) -> float: ...

    @property
    def a22(self) -> float: ...

    @property
    def a33(self) -> float: ...

    @property
    def a44(self) -> float: ...

    @property
    def a55(self) -> float: ...

    @property
    def a66(self) -> float: ...

    @property
    def a26(self) -> float: ...

    @property
    def a35(self) -> float: ...


def rigid_body_mass_matrix(params: InertiaParameters) -> np.ndarray:
    """M_RB (2.3.11) about the CB, with r_g = [x_g, 0, z_g] and I_o = diag(I_xx, I_yy, I_zz)."""
    r_g = np.array([params.x_g, 0.0, params.z_g])
    M = np.zeros((6, 6))
    M[:3, :3] = params.m * np.eye(3)
    M[:3, 3:] = -params.m * skew(r_g)
    M[3:, :3] = params.m * skew(r_g)
    M[3:, 3:] = np.diag([params.I_xx, params.I_yy, params.I_zz])
    return M


def added_mass_matrix(params: InertiaParameters) -> np.ndarray:
    """M_A: diag(a11..a66) with the sway-yaw (a26 = a62) and heave-pitch (a35 = a53) pairs
    (Tables 5.1, 5.4, 6.1)."""
    M = np.diag([params.a11, params.a22, params.a33, params.a44, params.a55, params.a66])
    M[1, 5] = M[5, 1] = params.a26
    M[2, 4] = M[4, 2] = params.a35
    return M


def added_mass_matrix_times(
    params: InertiaParameters, nu: Sequence[float] | np.ndarray
) -> list[float]:
    """M_A nu without building the matrix: the added-mass impulse of nu = [u, v, w, p, q,
    r] (m/s, rad/s), kg m/s in the force rows and kg m^2/s in the moment rows."""
    u, v, w, roll_rate, q, r = nu
    return [
        params.a11 * u,
        params.a22 * v + params.a26 * r,
        params.a33 * w + params.a35 * q,
        params.a44 * roll_rate,
        params.a55 * q + params.a35 * w,
        params.a66 * r + params.a26 * v,
    ]
