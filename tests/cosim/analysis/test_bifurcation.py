"""Equilibria, continuation and folds against the dissertation's Sec. 5.1.2-5.1.4.

Expected values are the dissertation's printed numbers (Examples 5.1-5.4, Sec. 5.1.4,
Figs. 5.6-5.7, the T = 4 N case of Sec. 6.3.3), read from docs/dissertation-values.toml.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from reference_values import dissertation

from cosim.analysis.bifurcation import (
    Q_PROP,
    SWEEP_PARAMETERS,
    OperatingConditions,
    cg_offset,
    find_equilibria,
    in_box,
    mass_position_for_cg_offset,
    sweep,
    with_fin_area,
    with_fin_arm,
)
from plant_fmu.model.dynamics import STATE_INDEX, Variant
from plant_fmu.model.parameters import load_vehicle

# A coarser grid than the default keeps the sweeps fast; it still hits every basin.
COARSE_SEEDS = {"u": (1.0, 1.9), "v": (-0.2, 0.0, 0.2), "r": (-0.2, 0.0, 0.2), "roll": (0.0,)}


def _points(equilibria, names):
    return [tuple(e.value(n) for n in names) for e in equilibria]


def _assert_mirrored_pair(equilibria, expected, names, rel=None, abs_=None):
    """Exactly three equilibria: one on the u axis (unstable) and the mirrored pair
    +-expected (stable), compared at the printed precision."""
    assert len(equilibria) == 3, _points(equilibria, names)
    low, axis, high = equilibria  # sorted by v
    assert not axis.stable and low.stable and high.stable
    for eq, sign in ((high, 1.0), (low, -1.0)):
        signed = [expected[0]] + [sign * value for value in expected[1:]]
        got = [eq.value(n) for n in names]
        assert got == pytest.approx(signed, rel=rel, abs=abs_), (names, got, signed)
    return axis


def test_the_roll_torque_unit_is_the_printed_propeller_torque():
    """Example 5.4: Q_prop = -5.43e-1 N m, the unit of every roll-torque sweep."""
    assert dissertation("example_5_4.propeller_roll_torque") == Q_PROP


def test_example_5_1_three_equilibria_two_stable(remus):
    """(5.1.50): x0 = [1.525, 0, 0] unstable, [1.282, +-0.1678, -+0.2291] stable."""
    equilibria = find_equilibria(OperatingConditions(remus, Variant.HORIZONTAL, thrust=9.0))
    turn = dissertation("example_5_1.turn_positive_v")
    axis = _assert_mirrored_pair(equilibria, turn, ("u", "v", "r"), abs_=6e-4)
    assert [axis.value(n) for n in ("u", "v", "r")] == pytest.approx(
        dissertation("example_5_1.straight_line"), abs=5e-4
    )


def test_example_5_1_stable_and_unstable_subspaces(remus):
    """Example 5.1: at x0, E_s = span{[1,0,0], [0,-0.2723,-0.9622]},
    E_u = span{[0,-0.3291,0.9443]} (one positive eigenvalue)."""
    axis = find_equilibria(OperatingConditions(remus))[1]
    values, vectors = np.linalg.eig(axis.jacobian)
    assert np.sum(values.real > 0) == 1
    unstable = vectors[:, np.argmax(values.real)].real
    e_u = dissertation("example_5_1.unstable_subspace")
    assert abs(unstable @ e_u) == pytest.approx(1.0, abs=1e-4)
    stable = vectors[:, values.real < 0].real
    for printed in dissertation("example_5_1.stable_subspace"):
        residual = printed - stable @ np.linalg.lstsq(stable, printed, rcond=None)[0]
        assert np.linalg.norm(residual) < 2e-4


@pytest.mark.slow
def test_example_5_2_long_fins_only_the_straight_line_stable():
    """Example 5.2 (Table 5.3 fins): only [1.525, 0, 0] in D, asymptotically stable."""
    equilibria = find_equilibria(OperatingConditions(load_vehicle("remus100-long-fins")))
    assert len(equilibria) == 1
    (eq,) = equilibria
    assert [eq.value(n) for n in ("u", "v", "r")] == pytest.approx(
        dissertation("example_5_2.straight_line"), abs=5e-4
    )
    assert eq.stable


@pytest.mark.slow
def test_example_5_3_lateral_equilibria_bank_in_turns(remus):
    """(5.1.70): [1.272, +-0.1724, -+0.2316, 0, -+0.0301] stable, x0 unstable."""
    equilibria = find_equilibria(OperatingConditions(remus, Variant.LATERAL))
    names = ("u", "v", "r", "p", "roll")
    turn = dissertation("example_5_3.turn_positive_v")
    _assert_mirrored_pair(equilibria, turn, names, abs_=6e-4)


@pytest.mark.slow
def test_low_speed_equilibria_within_half_a_percent(remus):
    """Sec. 6.3.3, T = 4 N: [1.017, 0, 0] unstable, [0.8467, +-0.1147, -+0.1541] stable."""
    equilibria = find_equilibria(OperatingConditions(remus, Variant.LATERAL, thrust=4.0))
    turn = dissertation("low_speed.turn_positive_v")[:3]
    axis = _assert_mirrored_pair(equilibria, turn, ("u", "v", "r"), rel=5e-3)
    assert axis.value("u") == pytest.approx(dissertation("low_speed.straight_line")[0], rel=5e-3)


@pytest.mark.slow
def test_every_equilibrium_is_a_root_inside_the_box(remus):
    conditions = OperatingConditions(remus, Variant.LATERAL, roll_torque=2 * Q_PROP)
    equilibria = find_equilibria(conditions)
    assert equilibria
    for eq in equilibria:
        xdot = conditions.model.derivative(eq.state, conditions.inputs())
        assert np.max(np.abs(xdot[[STATE_INDEX[n] for n in eq.free_states]])) < 1e-8
        assert in_box(eq.free_states, [eq.value(n) for n in eq.free_states])


@pytest.mark.slow
def test_roll_torque_sign_mirrors_the_equilibria(remus):
    """Sec. 5.1.3: the flow with Q is that with -Q mirrored about the u axis
    (v, r, p, roll change sign)."""
    names = ("u", "v", "r", "p", "roll")
    sign = np.array([1, -1, -1, -1, -1])
    plus = _points(find_equilibria(OperatingConditions(remus, 1, roll_torque=1.0)), names)
    minus = _points(find_equilibria(OperatingConditions(remus, 1, roll_torque=-1.0)), names)
    assert len(plus) == len(minus) == 3
    mirrored = sorted(tuple(np.array(p) * sign) for p in minus)
    np.testing.assert_allclose(sorted(plus), mirrored, atol=1e-7)


@pytest.mark.slow
def test_a_current_shifts_the_ground_velocity_not_the_relative_equilibria(remus):
    """(5.2.10)-(5.2.15): in a uniform current the relative motion has the still-water
    equilibria; heading north in a 0.2 m/s eastward current adds 0.2 m/s to v."""
    still = find_equilibria(OperatingConditions(remus))
    moving = find_equilibria(OperatingConditions(remus, current_east=0.2))
    assert len(still) == len(moving) == 3
    for a, b in zip(still, moving, strict=True):
        assert b.value("u") == pytest.approx(a.value("u"), abs=1e-9)
        assert b.value("v") == pytest.approx(a.value("v") + 0.2, abs=1e-9)
        assert b.stable == a.stable


@pytest.mark.slow
def test_roll_torque_sweep_has_one_fold_between_4_and_5_q_prop(remus):
    """Example 5.4 / Fig. 5.9: the unstable and a stable equilibrium coalesce when |Q| is
    "slightly larger than 4 Q_prop"; beyond it one stable equilibrium remains."""
    result = sweep(
        OperatingConditions(remus, Variant.LATERAL),
        "roll_torque",
        0.0,
        5.5 * Q_PROP,
        steps=40,
        seeds=COARSE_SEEDS,
        search_points=2,
    )
    assert len(result.folds) == 1, [(s.kind, s.parameter) for s in result.special_points]
    fold = result.folds[0]
    printed = dissertation("example_5_4.fold_roll_torque")  # "slightly larger than 4 Q_prop"
    assert printed < fold.parameter / Q_PROP < printed + 1.0
    assert abs(fold.eigenvalues.real).min() < 1e-6  # a zero eigenvalue at the fold
    after = find_equilibria(OperatingConditions(remus, 1, roll_torque=5.5 * Q_PROP))
    assert len(after) == 1 and after[0].stable
    # Along every branch the points are equilibria and the stability at the start agrees
    # with the grid search.
    conditions = OperatingConditions(remus, Variant.LATERAL)
    for branch in result.branches:
        for q, z in zip(branch.parameters[::10], branch.states[::10], strict=True):
            c = OperatingConditions(remus, Variant.LATERAL, roll_torque=float(q))
            x = c.state(dict(zip(branch.free_states, z, strict=True)))
            idx = [STATE_INDEX[n] for n in branch.free_states]
            assert np.max(np.abs(c.model.derivative(x, c.inputs())[idx])) < 1e-8
    start_stability = sorted(
        bool(b.stable[i]) for b in result.branches for i in np.flatnonzero(b.parameters == 0.0)
    )
    assert start_stability == sorted(e.stable for e in find_equilibria(conditions))


@pytest.mark.slow
def test_mass_position_sweep_has_one_fold_at_y_g_between_08_and_09_cm(remus):
    """Sec. 5.1.4 / Fig. 5.12: "when the length of y_g is slightly larger than 0.8 cm,
    the bifurcation occurs"; y_g = m_v g y_v / W for our moving mass."""
    result = sweep(
        OperatingConditions(remus, Variant.LATERAL),
        "mass_position",
        0.0,
        -remus.mass_stroke,
        steps=40,
        seeds=COARSE_SEEDS,
        search_points=2,
    )
    assert len(result.folds) == 1, [(s.kind, s.parameter) for s in result.special_points]
    y_g = 100 * cg_offset(remus, result.folds[0].parameter)  # cm
    printed = dissertation("section_5_1_4.fold_cg_offset")  # "slightly larger than 0.8 cm"
    assert printed < abs(y_g) < printed + 0.1


@pytest.mark.slow
@pytest.mark.parametrize("parameter", ["mu", "eta"])
def test_fin_factor_sweeps_stabilise_the_straight_line_near_2(remus, parameter):
    """Figs. 5.6-5.7: as mu (fin arm) or eta (fin area) grows, the stable turning
    equilibria move onto the u axis, which turns stable at "about 2.0"."""
    result = sweep(
        OperatingConditions(remus),
        parameter,
        1.0,
        3.0,
        steps=40,
        seeds=COARSE_SEEDS,
        search_points=2,
    )
    assert not result.folds
    switches = [s for s in result.special_points if s.kind == "branch point"]
    assert len(switches) == 1
    switch = switches[0]
    printed = dissertation("fin_factors.branch_point")  # "about 2.0"
    assert printed - 0.2 < switch.parameter < printed + 0.2
    assert abs(switch.state["v"]) < 1e-6 and abs(switch.state["r"]) < 1e-6
    below = find_equilibria(OperatingConditions(remus).with_parameter(parameter, printed - 0.2))
    above = find_equilibria(OperatingConditions(remus).with_parameter(parameter, printed + 0.2))
    assert [e.stable for e in below] == [True, False, True]
    assert len(above) == 1 and above[0].stable


def test_fin_factors_scale_the_lift_coefficients_as_5_1_62_and_5_1_63(remus):
    arm = with_fin_arm(remus, 2.0)
    assert (arm.Y_uv, arm.Y_ur, arm.N_uv, arm.N_ur) == pytest.approx(
        (remus.Y_uv, 2 * remus.Y_ur, 2 * remus.N_uv, 4 * remus.N_ur)
    )
    area = with_fin_area(remus, 2.0)
    assert (area.Y_uv, area.Y_ur, area.N_uv, area.N_ur) == pytest.approx(
        (2 * remus.Y_uv, 2 * remus.Y_ur, 2 * remus.N_uv, 2 * remus.N_ur)
    )
    assert with_fin_arm(remus, 1.0) == remus.replace()


def test_mass_at_rest_rolls_the_hull_like_the_cg_offset_it_maps_to(remus):
    """Sec. 5.1.4 replaces Q by W y_g cos(phi): our mass at rest at y_v must give exactly
    that roll moment with y_g = cg_offset(y_v), and nothing in sway or yaw (theta = 0)."""
    y_v = -0.05
    conditions = OperatingConditions(remus, Variant.LATERAL, mass_position=y_v)
    for phi in (0.0, -0.3, 0.4):
        x = conditions.state({"roll": phi, "u": 1.4})
        _, accel, force = conditions.model.moving_mass(x, conditions.inputs())
        assert accel == 0.0
        roll = remus.W * cg_offset(remus, y_v) * math.cos(phi)
        np.testing.assert_allclose(force, [0, 0, 0, roll, 0, 0], atol=1e-12)
    assert mass_position_for_cg_offset(remus, cg_offset(remus, y_v)) == pytest.approx(y_v)


def test_bad_input_is_refused_with_the_value_named(remus):
    with pytest.raises(ValueError, match=r"mass_position = 0\.07 m.*stroke 0\.06"):
        OperatingConditions(remus, Variant.LATERAL, mass_position=0.07)
    with pytest.raises(ValueError, match=r"roll_torque = -0\.5.*horizontal variant"):
        OperatingConditions(remus, Variant.HORIZONTAL, roll_torque=-0.5)
    with pytest.raises(ValueError, match="thrust = nan"):
        OperatingConditions(remus, thrust=float("nan"))
    with pytest.raises(ValueError, match=r"mu = -1\.0"):
        with_fin_arm(remus, -1.0)
    conditions = OperatingConditions(remus, Variant.LATERAL)
    with pytest.raises(ValueError, match="unknown sweep parameter 'speed'"):
        sweep(conditions, "speed", 0.0, 1.0)
    with pytest.raises(ValueError, match="two different finite values"):
        sweep(conditions, "roll_torque", 1.0, 1.0)
    with pytest.raises(ValueError, match=r"mass_position = -0\.1 m"):
        sweep(conditions, "mass_position", 0.0, -0.1)
    assert set(SWEEP_PARAMETERS) == {"roll_torque", "mass_position", "mu", "eta"}


@pytest.mark.parametrize(("parameter", "start", "stop"), [("mu", 1e-3, 1.0), ("eta", 1.0, 1e3)])
def test_a_fin_factor_sweep_near_zero_or_wide_stays_in_its_range(remus, parameter, start, stop):
    """A sweep of a fin factor from just above 0, or over a wide range, runs: the
    continuation's predictor and difference steps reach factors <= 0 beyond the range's
    end, where the factor maps are still defined (only the range itself must be > 0);
    every point it keeps lies within [start, stop]."""
    result = sweep(
        OperatingConditions(remus), parameter, start, stop, steps=8, seeds=COARSE_SEEDS,
        search_points=2,
    )  # fmt: skip
    assert result.branches
    slack = 1e-9 * (stop - start)  # the points' parameters are scaled back by the span
    for branch in result.branches:
        assert branch.parameters.min() >= start - slack
        assert branch.parameters.max() <= stop + slack
