"""The reproduction of the dissertation's numbers (cosim/reproduction): every
claim's record evaluates within its tolerance, the page has a row for every claim, the
tolerances and the loop judge as documented, and Chapter 5 uses one weight throughout.

Claims that need a continuation, a phase portrait or a closed-loop run are slow.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from reference_values import DISSERTATION, VALUES_FILE

from cosim.analysis.bifurcation import Q_PROP, OperatingConditions, cg_offset, sweep
from cosim.cli import main
from cosim.reproduction import Claim, Context, Cost, Finding, all_claims, evaluate
from cosim.reproduction.catalogue import catalogue
from cosim.reproduction.context import NotRunError
from cosim.reproduction.lateral import jacobian, printed_jacobian
from cosim.reproduction.page import Evaluated, render
from cosim.reproduction.record import (
    Absolute,
    LastDigit,
    Relative,
    Row,
    SlightlyAbove,
)
from cosim.reproduction.roll_torque import mass_sweep, roll_torque_sweep
from cosim.reproduction.scenarios import runner
from plant_fmu.model.dynamics import Variant

CLAIMS = all_claims(DISSERTATION)
W_TABLE_4_1 = float(DISSERTATION["table_4_1.weight"].value)


def _param(claim: Claim):
    marks = () if claim.cost is Cost.INSTANT else (pytest.mark.slow,)
    label = re.sub(r"\W+", "-", f"{claim.source} {claim.claim}")[:70]
    return pytest.param(claim, marks=marks, id=label)


@pytest.fixture(scope="module")
def ctx() -> Context:
    """The shipped vehicles, no scenario runs."""
    return Context.create(DISSERTATION)


@pytest.fixture(scope="module")
def scenario_ctx(fmu_paths, tmp_path_factory: pytest.TempPathFactory) -> Context:
    """Scenarios run (once each) with the session's freshly built FMUs."""
    fmu_dir = fmu_paths["AuvAutopilot"].parent
    return Context.create(DISSERTATION, runner(tmp_path_factory.mktemp("runs"), fmu_dir=fmu_dir))


def _judged(claim: Claim, ctx: Context) -> None:
    """A known difference (a record with ``explained``) must still differ: if it agrees,
    its explanation is stale."""
    row = evaluate(claim, ctx)
    expected = "differs (explained)" if claim.explained else "agrees"
    assert row.verdict == expected, f"{claim.claim}: ours {row.ours} ({row.note})"


@pytest.mark.parametrize("claim", [_param(c) for c in CLAIMS if c.cost is not Cost.SCENARIO])
def test_every_model_claim_evaluates_within_its_tolerance(claim: Claim, ctx: Context) -> None:
    _judged(claim, ctx)


@pytest.mark.slow
@pytest.mark.parametrize("claim", [_param(c) for c in CLAIMS if c.cost is Cost.SCENARIO])
def test_every_scenario_claim_evaluates_within_its_tolerance(
    claim: Claim, scenario_ctx: Context
) -> None:
    _judged(claim, scenario_ctx)


def test_the_page_has_a_row_for_every_claim_and_states_the_weights() -> None:
    ctx = Context.create(DISSERTATION)
    sections = catalogue(DISSERTATION)
    evaluated = [
        Evaluated(s, tuple(Row(c, f"ours {k}", "agrees") for k, c in enumerate(s.claims)))
        for s in sections
    ]
    page = render(evaluated, ctx)
    rows = [line for line in page.splitlines() if re.match(r"\| \d+ \|", line)]
    assert len(rows) == len(CLAIMS)
    for number, (line, claim) in enumerate(zip(rows, CLAIMS, strict=True), start=1):
        assert line.startswith(f"| {number} | {claim.claim.replace('|', chr(92) + '|')}")
        assert claim.source in line
    assert [f"## {s.title}" for s in sections] == re.findall(r"^## (?!Where).*$", page, re.M)
    assert f"W = {W_TABLE_4_1:g} N" in page and f"W = m g = {ctx.remus.W:g} N" in page
    assert "- Nowhere." in page


def test_the_differences_list_names_every_row_that_does_not_agree() -> None:
    claim = CLAIMS[0]
    rows = (Row(claim, "2", "differs", "why"), Row(claim, "-", "not run", "skipped"))
    page = render([Evaluated(catalogue(DISSERTATION)[0], rows)], Context.create(DISSERTATION))
    assert f"- **#1 {claim.claim}** (differs): why" in page
    assert f"- **#2 {claim.claim}** (not run): skipped" in page


@pytest.mark.parametrize(
    ("tolerance", "printed", "ours", "accepted"),
    [
        (LastDigit(), "1.282", 1.2829, True),
        (LastDigit(), "1.282", 1.2831, False),
        (LastDigit(), "0", 9e-4, True),  # a bare 0 beside figures with decimals
        (LastDigit(), "0", 2e-3, False),
        (Relative(5e-3), "0.8467", 0.8509, True),
        (Relative(5e-3), "0.8467", 0.8510, False),
        (Absolute(0.0), "3", 3, True),
        (Absolute(0.0), "3", 4, False),
        (SlightlyAbove(1.0), "4", -4.27, True),
        (SlightlyAbove(1.0), "4", 3.99, False),
        (SlightlyAbove(0.1), "0.8", 0.91, False),
    ],
)
def test_tolerances(tolerance, printed: str, ours: float, accepted: bool) -> None:
    assert tolerance.accepts(printed, ours) is accepted


def _claim(ours, explained: str = "") -> Claim:
    return Claim("x", "Ex. 0", ("1.5", "2"), "m", ours, explained=explained)


def test_the_loop_judges_numbers_and_facts_and_reports_failures() -> None:
    ctx = Context.create(DISSERTATION)
    assert evaluate(_claim(lambda c: Finding((1.54, 2.0))), ctx).verdict == "agrees"
    row = evaluate(_claim(lambda c: Finding((1.62, 2.0))), ctx)
    assert (row.verdict, row.ours) == ("differs", "[1.62, 2.00]")
    assert evaluate(_claim(lambda c: Finding((1.5,))), ctx).verdict == "differs"  # one short
    assert evaluate(_claim(lambda c: Finding((1.5, 2), holds=False)), ctx).verdict == "differs"
    row = evaluate(_claim(lambda c: Finding((1.7, 2)), explained="known"), ctx)
    assert (row.verdict, row.note) == ("differs (explained)", "known")

    def broken(c: Context) -> Finding:
        raise ValueError("no equilibrium")

    row = evaluate(_claim(broken), ctx)
    assert (row.verdict, row.ours) == ("differs", "ValueError: no equilibrium")

    def skipped(c: Context) -> Finding:
        raise NotRunError("scenarios skipped")

    assert evaluate(_claim(skipped), ctx).verdict == "not run"


def test_a_scenario_claim_without_runner_is_not_run() -> None:
    ctx = Context.create(DISSERTATION)
    claim = next(c for c in CLAIMS if c.cost is Cost.SCENARIO)
    row = evaluate(claim, ctx)
    assert (row.verdict, row.note) == ("not run", "scenarios skipped")


# --- one weight for Chapter 5 ---------------------------------------------------------------


def test_chapter_5_vehicles_carry_the_weight_example_5_3_was_computed_with() -> None:
    """Example 5.3's printed Jacobian holds with Table 4.1's W = 299 N (to its last digit),
    not with W = m g; every Chapter 5 claim gets that weight."""
    ctx = Context.create(DISSERTATION)
    printed = np.array(printed_jacobian(DISSERTATION), dtype=float).reshape(4, 4)
    assert ctx.chapter_5(ctx.remus).W == ctx.chapter_5(ctx.long_fins).W == W_TABLE_4_1 == 299
    assert np.max(np.abs(jacobian(ctx.chapter_5(ctx.remus)) - printed)) < 1e-4
    assert np.max(np.abs(jacobian(ctx.remus) - printed)) > 1e-3


@pytest.mark.slow
def test_the_folds_of_example_5_4_and_sec_5_1_4_use_the_weight_of_example_5_3() -> None:
    """The roll-torque fold and the mass-position fold equal an independent continuation
    with W = 299 N (4.268 Q_prop, y_g = -0.836 cm), not the W = m g values (4.210 Q_prop,
    -0.823 cm)."""
    ctx = Context.create(DISSERTATION)
    vehicle = ctx.remus.replace(W=W_TABLE_4_1)
    lateral = OperatingConditions(vehicle, Variant.LATERAL)
    (fold,) = sweep(lateral, "roll_torque", 0.0, 5.5 * Q_PROP).folds
    (ours,) = roll_torque_sweep(ctx).folds
    assert ours.parameter / Q_PROP == pytest.approx(fold.parameter / Q_PROP, abs=1e-6)
    assert ours.parameter / Q_PROP == pytest.approx(4.268, abs=1e-3)
    (mass_fold,) = mass_sweep(ctx).folds
    assert 100 * cg_offset(vehicle, mass_fold.parameter) == pytest.approx(-0.836, abs=1e-3)


# --- the command ----------------------------------------------------------------------------


def test_reproduce_refuses_a_missing_values_file(tmp_path: Path, capsys) -> None:
    missing = tmp_path / "nothing.toml"
    assert main(["reproduce", "--out", str(tmp_path), "--values", str(missing)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nothing.toml" in err
    assert VALUES_FILE.is_file()
