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
