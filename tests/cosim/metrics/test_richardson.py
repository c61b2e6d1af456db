"""Richardson extrapolation of a figure from runs at h, h / 2, h / 4."""

from __future__ import annotations

import math

import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from cosim.metrics.richardson import estimate, observed_order


@given(
    limit=st.floats(-100.0, 100.0),
    c=st.floats(0.01, 100.0) | st.floats(-100.0, -0.01),
    p=st.floats(0.6, 5.0),
    h=st.floats(1e-3, 0.1),
)
def test_a_figure_converging_at_order_p_gives_p_its_limit_and_its_error(limit, c, p, h):
    """f(h) = f0 + C h^p: the observed order is p, the limit f0 and the error C h^p."""
    assume(abs(c) * (h / 4) ** p > 1e-7 * (1.0 + abs(limit)))  # above the rounding
    f1, f2, f4 = (limit + c * (h / k) ** p for k in (1, 2, 4))
    estimates, _ = estimate([{"f": f1}, {"f": f2}, {"f": f4}], fallback=1.0)
    e = estimates["f"]
    assert e.observed and e.order == pytest.approx(p, rel=1e-4)
    assert e.limit == pytest.approx(limit, abs=1e-4 * abs(c) * h**p + 1e-12)
    assert e.error == pytest.approx(c * h**p, rel=1e-4)


def test_a_figure_that_does_not_converge_monotonically_takes_the_runs_order():
    """Differences of opposite signs have no order: the one observed on all the figures
    together is used (else the fallback), and the estimate says it was not observed."""
    values = [{"a": 1.0, "b": 10.0}, {"a": 0.5, "b": 10.3}, {"a": 0.25, "b": 10.2}]
    estimates, order = estimate(values, fallback=2.0)
    assert observed_order(10.0, 10.3, 10.2) is None
    assert estimates["a"].observed and not estimates["b"].observed
    assert estimates["b"].order == order
    assert math.isfinite(estimates["b"].error)


def test_figures_missing_from_a_run_are_left_out():
    values = [{"a": 1.0, "b": None}, {"a": 0.5, "b": 2.0}, {"a": 0.25, "b": 2.0}]
    estimates, _ = estimate(values, fallback=1.0)
    assert set(estimates) == {"a"}


def test_the_runs_order_is_observed_from_the_largest_differences_of_all_figures() -> None:
    """Two figures converging at order 2 (f = f0 + C h^2, different C) and one wobbling
    by less: the largest differences between the runs fall by 2^2 per halving, so the
    run's order is 2 and not the fallback, and the figure without an order of its own
    takes it."""
    h = (1.0, 0.5, 0.25)
    values = [
        {"a": 1.0 + 3.0 * step**2, "b": -2.0 + 0.5 * step**2, "c": wobble}
        for step, wobble in zip(h, (5.0, 5.01, 5.0), strict=True)
    ]
    estimates, order = estimate(values, fallback=1.0)
    assert order == pytest.approx(2.0, rel=1e-12)
    assert not estimates["c"].observed and estimates["c"].order == order
    assert estimates["a"].limit == pytest.approx(1.0) and estimates["b"].limit == pytest.approx(
        -2.0
    )
