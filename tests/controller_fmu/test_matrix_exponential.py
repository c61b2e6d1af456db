"""The matrix exponential and zero-order hold without scipy: scipy's and python-control's
results, to rounding."""

from __future__ import annotations

import control
import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from controller_fmu.command_filter import CommandFilterBank
from controller_fmu.lateral_model import LateralDesignModel
from controller_fmu.matrix_exponential import expm, zero_order_hold
from plant_fmu.model.parameters import load_vehicle

SQUARE = st.integers(1, 8).flatmap(lambda n: arrays(float, (n, n), elements=st.floats(-1.0, 1.0)))


@settings(max_examples=40)  # the fast tier's minute
@given(matrix=SQUARE, scale=st.sampled_from([1e-4, 1e-2, 0.3, 1.0, 3.0, 30.0]))
def test_expm_agrees_with_scipy_at_every_norm(matrix, scale):
    """Every branch: Pade 3, 5, 7, 9 and 13 with 0 to a few squarings. The tolerance is
    scipy's own error: exp(30 J), J the 8 x 8 matrix of ones, is 2e-11 off there (3e-14
    here), 1e-12 at exp(J); the test below holds ours to 1e-13 of an exact reference."""
    matrix = scale * matrix
    ours, theirs = expm(matrix), scipy.linalg.expm(matrix)
    assert np.abs(ours - theirs).max() <= 1e-10 * max(1.0, float(np.abs(theirs).max()))


@settings(max_examples=40)
@given(matrix=SQUARE, scale=st.sampled_from([1e-4, 0.3, 3.0, 30.0]))
def test_expm_of_a_symmetric_matrix_is_its_eigenvalues_exponential(matrix, scale):
    """An exact reference: exp(S) = V diag(exp(lambda)) V^T for S = V diag(lambda) V^T,
    to 1e-14 ||S||_1 of the largest entry (exp's condition number grows with the norm:
    rounding lambda by eps moves exp(lambda) by eps lambda)."""
    symmetric = scale * 0.5 * (matrix + matrix.T)
    values, vectors = np.linalg.eigh(symmetric)
    exact = (vectors * np.exp(values)) @ vectors.T
    tolerance = 1e-14 * max(1.0, float(np.linalg.norm(symmetric, 1)))
    assert np.abs(expm(symmetric) - exact).max() <= tolerance * float(np.abs(exact).max())


def test_expm_of_the_autopilot_matrices_agrees_with_scipy():
    """The command filters' transition and the design model's discretisation, stiff
    servo included (eigenvalues from about -6000 to 0 1/s)."""
    filters = CommandFilterBank(3, frequency=10.0, damping=1.0)
    w, z = filters.frequency, filters.damping
    augmented = np.array([[0.0, 1.0, 0.0], [-(w**2), -2.0 * z * w, w**2], [0.0, 0.0, 0.0]])
    A, B = LateralDesignModel(load_vehicle("remus100"), 1.525).linearize()
    design = np.zeros((8, 8))
    design[:7, :7], design[:7, 7:] = A, B
    for matrix in (augmented * 0.01, augmented * 0.37, design * 0.001, design * 0.05, A * 2.0):
        theirs = scipy.linalg.expm(matrix)
        assert np.abs(expm(matrix) - theirs).max() <= 1e-13 * np.abs(theirs).max()


@pytest.mark.parametrize("dt", [0.001, 0.01, 0.05])
def test_zero_order_hold_agrees_with_control_c2d(dt):
    A, B = LateralDesignModel(load_vehicle("remus100"), 1.525).linearize()
    theirs = control.c2d(control.ss(A, B, np.eye(7), np.zeros((7, 1))), dt, "zoh")
    Ad, Bd = zero_order_hold(A, B, dt)
    np.testing.assert_allclose(Ad, theirs.A, rtol=0.0, atol=1e-14 * np.abs(theirs.A).max())
    np.testing.assert_allclose(Bd, theirs.B, rtol=0.0, atol=1e-14 * np.abs(theirs.B).max())


@pytest.mark.parametrize(
    ("matrix", "message"),
    [
        (np.ones((2, 3)), r"expected a finite square matrix, got shape \(2, 3\)"),
        (np.array([[np.nan]]), r"expected a finite square matrix, got shape \(1, 1\)"),
    ],
)
def test_expm_refuses_what_is_not_a_finite_square_matrix(matrix, message):
    with pytest.raises(ValueError, match=message):
        expm(matrix)


@pytest.mark.parametrize("dt", [0.0, -0.01, float("nan")])
def test_zero_order_hold_refuses_a_bad_sample_time(dt):
    with pytest.raises(ValueError, match=r"expected a finite time > 0 s"):
        zero_order_hold(np.eye(2), np.ones((2, 1)), dt)
