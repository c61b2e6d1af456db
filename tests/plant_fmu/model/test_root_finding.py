"""Brent's method without scipy: the same roots as scipy.optimize.brentq, to its tolerance."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import brentq

from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.moving_mass import MovingMassModel
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.root_finding import brent_root
from plant_fmu.model.state_layout import INPUT_NAMES, MASS_POSITION
from plant_fmu.model.stepping import _rk4, stepping_state

EPS = np.finfo(float).eps


@given(
    root=st.floats(-10.0, 10.0),
    power=st.sampled_from([1, 3, 5]),
    scale=st.floats(1e-3, 1e3),
    offset=st.floats(0.0, 1.0),
)
def test_roots_agree_with_scipy_within_the_tolerance(root, power, scale, offset):
    def f(x: float) -> float:
        return scale * (x - root) ** power + offset * math.tanh(x - root) * abs(x - root)

    a, b, xtol, rtol = root - 3.7, root + 11.0, 1e-12, 4 * EPS
    # a triple root converges slowly (scipy's default of 100 iterations fails on x^3 too)
    ours = brent_root(f, a, b, xtol, rtol, max_iterations=1000)
    theirs = brentq(f, a, b, xtol=xtol, rtol=rtol, maxiter=1000)
    tolerance = xtol + rtol * abs(theirs)
    assert abs(ours - theirs) <= tolerance
    assert abs(ours - root) <= tolerance + 1e-9 * (power > 1)  # flat roots: within f's noise


def test_the_two_body_stop_arrival_agrees_with_scipy():
    """The function the plant solves: the moving mass's position on its rail after an RK4
    step of a given length, minus the stop it runs into."""
    model = PlantModel(
        load_vehicle("remus100"), Variant.FULL, moving_mass_model=MovingMassModel.TWO_BODY
    )
    free = model.without_stops
    stroke = model.params.mass_stroke
    z = stepping_state(np.zeros(14))
    z[MASS_POSITION], z[MASS_POSITION + 1] = 0.059, 0.05  # m, m/s: close to the stop
    inputs = np.zeros(len(INPUT_NAMES))
    inputs[INPUT_NAMES.index("mass_position_cmd")] = 0.1

    def gap(length: float) -> float:
        return float(_rk4(free, z, inputs, length, False)[MASS_POSITION] - stroke)

    dt, xtol, rtol = 0.05, 1e-15, 4 * EPS
    assert gap(0.0) < 0.0 < gap(dt)
    ours = brent_root(gap, 0.0, dt, xtol, rtol)
    theirs = brentq(gap, 0.0, dt, xtol=xtol, rtol=rtol)
    assert 0.0 < ours < dt
    assert abs(ours - theirs) <= xtol + rtol * abs(theirs)


def test_an_end_on_the_root_is_the_root():
    assert brent_root(lambda x: x - 2.0, 2.0, 5.0) == 2.0
    assert brent_root(lambda x: x - 5.0, 2.0, 5.0) == 5.0


@pytest.mark.parametrize(
    ("f", "message"),
    [
        (lambda x: x * x + 1.0, r"f\(-1\.0\) = 2\.0 and f\(2\.0\) = 5\.0 have the same sign"),
        (lambda x: math.nan, r"f\(a\) = nan"),
        (lambda x: x if x < 1.0 else math.inf, r"f\(a\) = -1\.0, f\(b\) = inf"),
    ],
)
def test_no_bracket_or_a_non_finite_value_is_refused(f, message):
    with pytest.raises(ValueError, match=message):
        brent_root(f, -1.0, 2.0)
