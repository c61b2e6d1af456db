"""Property tests are not timed: Hypothesis's per-example deadline (200 ms by default)
failed them on a loaded machine (DeadlineExceeded from a matrix exponential's example
that waited for a core), a timed assertion the suite makes nowhere else."""

from __future__ import annotations

import time

from hypothesis import given, settings
from hypothesis import strategies as st


def test_no_deadline_is_set_for_property_tests() -> None:
    assert settings.default.deadline is None


@settings(max_examples=2)
@given(st.integers())
def test_an_example_that_waits_for_a_core_is_not_failed_for_it(value: int) -> None:
    time.sleep(0.25)  # as an example does when the machine's cores are taken
    assert isinstance(value, int)
