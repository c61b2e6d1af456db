"""scripts/lqr_rounding.py: where two installs' LQR designs part, and how far rounding
alone moves the gain (docs/performance.md#other-pythons quotes it)."""

from __future__ import annotations

from repo_paths import script_module

lqr_rounding = script_module("lqr_rounding")


def test_a_design_saved_and_compared_is_bit_for_bit_and_a_moved_gain_is_measured() -> None:
    mine = lqr_rounding.design()
    saved = {name: [v.hex() for v in m.ravel().tolist()] for name, m in mine.items()}
    assert all(line.endswith("bit for bit") for line in lqr_rounding.compare(mine, saved))
    K = mine["K"]
    saved["K"] = [v.hex() for v in (K * (1.0 + 1e-12)).ravel().tolist()]
    assert (
        lqr_rounding.compare(mine, saved)[-1] == "  K: 1e-12 apart (relative to the largest entry)"
    )


def test_one_ulp_in_each_solve_moves_the_gain_far_less_than_the_tolerance_quoted() -> None:
    """The design's 1e-11 tolerance across installs: one ulp in each solve moves K by
    well under it (docs/performance.md)."""
    line = lqr_rounding.sensitivity(trials=3)
    largest = float(line.split("(median), ")[1].split(" (largest)")[0])
    assert 0.0 < largest < 1e-11, line
