"""The reproduction of the dissertation's numbers (cosim/reproduction): every
claim's record evaluates within its tolerance (a known difference still differs), no
tolerance is wider than the printed precision without a reason, the page has a row for
every claim, the tolerances and the loop judge as documented, closed-loop figures are
taken at a converged step, and Chapter 5 uses one weight throughout.

Claims that need a continuation, a phase portrait or a closed-loop run are slow.
"""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path

import numpy as np
import pytest
from reference_values import DISSERTATION, VALUES_FILE

from cosim.analysis.bifurcation import Q_PROP, OperatingConditions, cg_offset, sweep
from cosim.analysis.equilibria import find_equilibrium
from cosim.analysis.reference_values import load_reference_values
from cosim.cli import main
from cosim.metrics.key_figures import settling_time
from cosim.reproduction import Claim, Context, Cost, Finding, all_claims, evaluate
from cosim.reproduction.catalogue import catalogue
from cosim.reproduction.context import NotRunError, RunData
from cosim.reproduction.depth_plane import TABLES_DISAGREE
from cosim.reproduction.generate import figures_of
from cosim.reproduction.lateral import jacobian, printed_jacobian
from cosim.reproduction.low_speed import LOW_SPEED_TURNS, LOW_THRUST
from cosim.reproduction.model_choices import WithoutReaction, momentum_drift
from cosim.reproduction.page import Evaluated, render
from cosim.reproduction.record import (
    Absolute,
    AtMost,
    LastDigit,
    Relative,
    Row,
    SlightlyAbove,
    effect_of,
    resolution,
    tolerance_of,
)
from cosim.reproduction.roll_torque import mass_sweep, roll_torque_sweep
from cosim.reproduction.runs import COARSE, FINE, converged, runner
from cosim.reproduction.scenarios import BAND, LQR_2
from plant_fmu.model import compiled
from plant_fmu.model.dynamics import INPUT_INDEX, STATE_INDEX, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.moving_mass import MovingMassModel, rail_direction
from plant_fmu.model.parameters import VehicleParameters, load_vehicle
from plant_fmu.model.stepping import advance

CLAIMS = all_claims(DISSERTATION)
CHOICES = [c for section in catalogue(DISSERTATION) for c in section.choices]
W_TABLE_5_4 = float(DISSERTATION["table_5_4.weight"].value)


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
    """A known difference (a record with ``explained`` or ``unexplained``) must still
    differ: if it agrees, what the page says of it is stale."""
    row = evaluate(claim, ctx)
    expected = "agrees"
    if claim.known_difference:
        expected = "differs (explained)" if claim.explained else "differs"
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


def _page(rows=None) -> str:
    """The page rendered from placeholder rows (and effects) for every claim (choice)."""
    evaluated = [
        Evaluated(
            s,
            tuple(Row(c, f"ours {k}", "agrees", compared=True) for k, c in enumerate(s.claims)),
            effects=tuple(f"effect {k}" for k in range(len(s.choices))),
        )
        for s in catalogue(DISSERTATION)
    ]
    return render(evaluated, Context.create(DISSERTATION))


def test_the_page_has_a_row_for_every_claim_and_states_the_weights() -> None:
    ctx = Context.create(DISSERTATION)
    sections = catalogue(DISSERTATION)
    page = _page()
    rows = [line for line in page.splitlines() if re.match(r"\| \d+ \|", line)]
    assert len(rows) == len(CLAIMS)
    for number, (line, claim) in enumerate(zip(rows, CLAIMS, strict=True), start=1):
        assert line.startswith(f"| {number} | {claim.claim.replace('|', chr(92) + '|')}")
        assert claim.source in line
    assert [f"## {s.title}" for s in sections] == re.findall(r"^## (?!Where).*$", page, re.M)
    assert f"W = {W_TABLE_5_4:g} N" in page and f"W = m g = {ctx.remus.W:g} N" in page
    assert "Table 5.4's printed W" in page
    assert "- Nowhere." in page
    for choice in CHOICES:
        assert f"| {choice.choice} | {choice.dissertation} |" in page


def test_no_tolerance_is_wider_than_the_printed_precision_without_a_reason() -> None:
    """Every claim that compares numbers: its tolerance is no wider than the printed
    precision of its numbers, read from docs/dissertation-values.toml itself (one unit of
    the last digit), unless the claim states why; and every number it calls printed is
    printed there."""
    values = load_reference_values(VALUES_FILE)
    for claim in CLAIMS:
        if claim.tolerance_reason or isinstance(claim.printed, str):
            continue
        assert claim.reference in values, f"{claim.claim}: no printed value to compare with"
        entry = values[claim.reference]
        texts = entry.text if isinstance(entry.text, list) else [entry.text]
        flat = list(np.ravel(np.array(texts, dtype=object)))
        for text in claim.printed:
            assert text in flat, f"{claim.claim}: {text} is not printed in {claim.reference}"
            width = claim.tolerance.width(text)
            assert width <= resolution(text) * (1 + 1e-9), (
                f"{claim.claim}: tolerance {claim.tolerance} of {text} is wider than its "
                f"printed precision {resolution(text):g} and no reason is given"
            )


def test_the_values_file_gives_a_reason_for_every_tolerance_wider_than_its_digits() -> None:
    for key, entry in load_reference_values(VALUES_FILE).items():
        tolerance = tolerance_of(entry)
        texts = list(np.ravel(np.array(entry.text, dtype=object)))
        if any(tolerance.width(t) > resolution(t) * (1 + 1e-9) for t in texts):
            assert entry.tolerance_reason.strip(), f"{key}: tolerance {tolerance} without a reason"


def test_a_tolerance_wider_than_the_printed_precision_is_shown_with_its_reason() -> None:
    page = _page()
    widened = [c for c in CLAIMS if c.tolerance_reason]
    assert widened, "the check must see rows with a reason"
    for claim in widened:
        row = next(
            line
            for line in page.splitlines()
            if claim.source in line and claim.claim.replace("|", chr(92) + "|")[:40] in line
        )
        assert f"{claim.tolerance}: {claim.tolerance_reason}" in row


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
        (AtMost(), "10", 9.99, True),
        (AtMost(), "10", 10.01, False),
    ],
)
def test_tolerances(tolerance, printed: str, ours: float, accepted: bool) -> None:
    assert tolerance.accepts(printed, ours) is accepted


@pytest.mark.parametrize(
    ("tolerance", "printed", "width"),
    [
        (LastDigit(), "1.282", 1e-3),
        (LastDigit(), "20", 1.0),
        (LastDigit(), "0", 1e-3),
        (Relative(5e-3), "0.8467", 5e-3 * 0.8467),
        (Absolute(5.0), "20", 5.0),
        (SlightlyAbove(1.0), "4", 1.0),
        (AtMost(), "10", 0.0),
    ],
)
def test_a_tolerance_says_how_far_beyond_the_printed_value_ours_may_lie(
    tolerance, printed: str, width: float
) -> None:
    assert tolerance.width(printed) == pytest.approx(width)


def _claim(ours, explained: str = "", unexplained: str = "") -> Claim:
    return Claim(
        "x", "Ex. 0", ("1.5", "2"), "m", ours, explained=explained, unexplained=unexplained
    )


def test_a_figure_whose_numerical_error_reaches_the_printed_precision_differs() -> None:
    """A closed-loop figure is judged only where its coupling error is below the printed
    precision; at or above it the row differs and says why."""
    ctx = Context.create(DISSERTATION)
    converged_row = evaluate(_claim(lambda c: Finding((1.5, 2.0), errors=(0.05, 0.5))), ctx)
    assert converged_row.verdict == "agrees"
    row = evaluate(_claim(lambda c: Finding((1.5, 2.0), errors=(0.1, 0.5))), ctx)
    assert row.verdict == "differs" and "Not converged" in row.note and "0.1" in row.note


def test_a_row_that_differs_says_by_how_much() -> None:
    ctx = Context.create(DISSERTATION)
    one = Claim("x", "Ex. 0", ("-7.55",), "deg", lambda c: Finding((-7.536,)))
    assert evaluate(one, ctx).size == "by 0.014 (0.19 %)"
    row = evaluate(_claim(lambda c: Finding((1.5, 3.5))), ctx)
    assert (row.verdict, row.size) == ("differs", "by up to 75 %")


def test_the_loop_judges_numbers_and_facts_and_reports_failures() -> None:
    ctx = Context.create(DISSERTATION)
    assert evaluate(_claim(lambda c: Finding((1.54, 2.0))), ctx).verdict == "agrees"
    row = evaluate(_claim(lambda c: Finding((1.62, 2.0))), ctx)
    assert (row.verdict, row.ours) == ("differs", "[1.62, 2.00]")
    assert evaluate(_claim(lambda c: Finding((1.5,))), ctx).verdict == "differs"  # one short
    assert evaluate(_claim(lambda c: Finding((1.5, 2), holds=False)), ctx).verdict == "differs"
    row = evaluate(_claim(lambda c: Finding((1.7, 2)), explained="known"), ctx)
    assert (row.verdict, row.note) == ("differs (explained)", "known")
    row = evaluate(_claim(lambda c: Finding((1.7, 2)), unexplained="why unknown"), ctx)
    assert (row.verdict, row.note) == ("differs", "why unknown")

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


def test_example_5_3s_bank_angle_is_judged_against_the_printed_2_degrees(ctx: Context) -> None:
    """'The absolute value of the steady-state roll angle is about 2 degrees': the row
    compares our bank with the printed 2 deg (it used to show ours and judge only the
    stability), so a bank outside 1-3 deg makes it differ."""
    bank = DISSERTATION["example_5_3.bank_angle"]
    (claim,) = [c for c in CLAIMS if c.reference == bank.key]
    finding = claim.ours(ctx)
    assert finding.against == (bank.text,) and len(finding.values) == 1
    assert evaluate(claim, ctx).verdict == "agrees"
    for off in (0.9, 3.1):  # deg: beyond one unit of the printed digit
        wrong = dataclasses.replace(
            claim, ours=lambda c, b=off: dataclasses.replace(finding, values=(b,))
        )
        assert evaluate(wrong, ctx).verdict == "differs"


def test_the_low_speed_equilibria_are_compared_in_every_printed_entry(ctx: Context) -> None:
    """Sec. 6.3.3 prints the T = 4 N equilibria as [u, v, r, p, phi], the turns with phi = 0:
    the rows compare all five (they compared u, v, r only, hiding that ours banks by
    0.77 deg there)."""
    for key in ("straight_line", "turn_positive_v", "turn_negative_v"):
        ref = DISSERTATION[f"low_speed.{key}"]
        (claim,) = [c for c in CLAIMS if c.reference == ref.key]
        assert claim.printed == tuple(ref.text)
        assert len(claim.ours(ctx).values) == len(ref.text) == 5


def _low_speed_turn(
    params: VehicleParameters, variant: Variant, printed: dict[str, float]
) -> tuple[list[float], float]:
    """The T = 4 N turn x0' of ``params`` in ``variant``, found from the printed one: the
    relative distance (%) of its u, v, r from the printed ones, and its bank |phi| (deg)."""
    model = PlantModel(params, variant)
    eq = find_equilibrium(model, printed, {"thrust": LOW_THRUST})
    off = [100 * abs(eq.value(name) / value - 1) for name, value in printed.items()]
    return off, float(np.degrees(abs(eq.value("roll"))))


def test_the_low_speed_explanation_states_what_each_variant_of_the_model_gives() -> None:
    """Why ours differs from the printed T = 4 N turns is argued from four variants of the
    model: every figure the argument states is the one the model gives (it called the
    W = B vehicle bank-free, which banks by 0.75 deg), so it cannot go stale unnoticed."""
    remus = load_vehicle("remus100")
    ref = DISSERTATION["low_speed.turn_positive_v"]
    printed = dict(zip(("u", "v", "r"), (float(t) for t in ref.text[:3]), strict=True))
    near = [
        _low_speed_turn(remus, Variant.LATERAL, printed),
        _low_speed_turn(remus.replace(W=W_TABLE_5_4), Variant.LATERAL, printed),
    ]
    horizontal = _low_speed_turn(remus, Variant.HORIZONTAL, printed)
    neutral = _low_speed_turn(remus.replace(W=remus.B), Variant.LATERAL, printed)
    near_off = [x for off, _ in near for x in off]
    far_off = horizontal[0] + neutral[0]
    ratios = [far / close for far, close in zip(horizontal[0], near[0][0], strict=True)]
    assert neutral[0] == pytest.approx(horizontal[0], abs=1e-6)  # W = B: the same u, v, r
    assert horizontal[1] == 0.0
    stated = [
        f"by {min(near_off):.2f}-{max(near_off):.2f} %",
        *(f"banks by {bank:.2f} deg" for _, bank in near),
        f"by {min(far_off):.1f}-{max(far_off):.1f} %",
        f"{math.floor(min(ratios))}-{math.ceil(max(ratios))} times further",
        f"banks, by {neutral[1]:.2f} deg",
    ]
    missing = [text for text in stated if text not in LOW_SPEED_TURNS]
    assert not missing, f"{missing} are not in the explanation: {LOW_SPEED_TURNS}"


def test_the_depth_plane_explanation_accounts_for_m_theta() -> None:
    """Table 6.1's M_theta is not Table 6.3's business: it is -z_g W, -5.86 N m with Table
    5.4's z_g and either weight, where the table prints -5.77. The explanation of the depth
    row (the two tables disagree) said only "M_theta = -z_g W"; it must give ours and what
    the printed value would need."""
    remus = load_vehicle("remus100")
    printed = float(DISSERTATION["table_6_1.depth_coefficients"].text[4])
    ours = {round(-remus.z_g * w, 2) for w in (remus.W, W_TABLE_5_4)}
    assert len(ours) == 1, ours  # the same to the printed digits with either weight
    stated = [
        f"M_theta = -z_g W = {ours.pop():.2f} N m",
        f"would need z_g = {100 * printed / -W_TABLE_5_4:.2f} cm",
        f"or W = {printed / -remus.z_g:.0f} N",
    ]
    missing = [text for text in stated if text not in TABLES_DISAGREE]
    assert not missing, f"{missing} are not in the explanation: {TABLES_DISAGREE}"


# --- the converged step and the model choices -------------------------------------------------


def test_a_closed_loop_figure_is_its_richardson_limit_with_the_fine_runs_error() -> None:
    """A figure first order in the step, f(h) = 3 + 40 h: ours is its limit 3, and the
    coupling error of the finer run is 40 (COARSE - FINE)."""
    runs = []

    def fake(scenario_id: str, step: float, start, held: bool) -> RunData:
        runs.append((scenario_id, step, dict(start), held))
        return RunData({"f": np.array([3.0 + 40.0 * step])}, Path("."))

    ctx = Context.create(DISSERTATION, fake)
    limit, error = converged(ctx, "bs-3", lambda run: float(run["f"][0]), {"plant.a35": 1.0})
    assert limit == pytest.approx(3.0) and error == pytest.approx(40.0 * (COARSE - FINE))
    assert runs == [  # as the scenario ships (its extrapolation), not held
        ("bs-3", COARSE, {"plant.a35": 1.0}, False),
        ("bs-3", FINE, {"plant.a35": 1.0}, False),
    ]
    assert FINE < COARSE <= 0.00125  # below the scenarios' 10 ms, where the errors are


def test_the_dissertations_plant_without_the_reaction_drops_exactly_the_servo_reaction() -> None:
    """WithoutReaction (the plant of (6.3.79)) differs from ours by the servo's reaction
    -m_v y'' J on the hull and nothing else; a stop's impact leaves its hull alone."""
    params = load_vehicle()
    ours, theirs = PlantModel(params, Variant.LATERAL), WithoutReaction(params, Variant.LATERAL)
    x = state_vector(dict(u=1.5, v=-0.1, r=0.05, p=0.2, roll=0.1, mass_position=0.02))
    inputs = input_vector(dict(mass_position_cmd=-0.05), thrust=9.0)
    _, accel, force = ours.moving_mass(x.tolist(), inputs.tolist())
    _, same_accel, dropped = theirs.moving_mass(x.tolist(), inputs.tolist())
    assert accel == same_accel != 0.0
    np.testing.assert_allclose(force - dropped, -params.m_v * accel * rail_direction(params))
    assert dropped[3] == pytest.approx(params.m_v * params.g * 0.02 * np.cos(0.1))  # weight stays
    nu = x[6:12]
    np.testing.assert_array_equal(theirs._velocity_after_impact(nu, 0.06, 0.3), nu)
    assert not np.array_equal(ours._velocity_after_impact(nu, 0.06, 0.3), nu)


@pytest.mark.skipif(not compiled.AVAILABLE, reason=compiled.NO_JIT_REASON)
def test_the_plant_without_the_reaction_is_stepped_compiled_and_drops_it_there_too() -> None:
    """The in-process runs without the reaction step the compiled path (the reference is
    minutes slower), which must leave out what the reference leaves out: the reaction in
    the derivative and the impact at a stop."""
    params = load_vehicle()
    theirs = WithoutReaction(params, Variant.LATERAL)
    assert compiled.supports(theirs) == ""
    fast = compiled.CompiledPlant(theirs)
    x = state_vector(dict(u=1.5, v=-0.1, r=0.05, p=0.2, roll=0.1, mass_position=0.02))
    inputs = input_vector(dict(mass_position_cmd=-0.05), thrust=9.0)
    np.testing.assert_allclose(
        fast.derivative(x, inputs), theirs.derivative(x, inputs), rtol=1e-13, atol=1e-13
    )
    ours = PlantModel(params, Variant.LATERAL).derivative(x, inputs)
    assert np.max(np.abs(fast.derivative(x, inputs) - ours)) > 1e-3
    x[STATE_INDEX["mass_position"]], x[STATE_INDEX["mass_velocity"]] = 0.0199, 0.5
    inputs[INPUT_INDEX["mass_position_cmd"]] = 0.05
    reference, stepped = x, x
    for _ in range(20):  # into the stop, fast
        reference = advance(theirs, reference, inputs, 0.01)
        stepped = advance(theirs, stepped, inputs, 0.01, compiled=fast)
    np.testing.assert_allclose(stepped, reference, rtol=0.0, atol=1e-12)


@pytest.mark.slow
def test_the_shipped_rk4_keeps_the_two_body_momentum_to_the_page_s_figure() -> None:
    """The page's figure for model 1 stepped by the shipped RK4 (10 ms): the 60 s tumble's
    linear momentum drifts by about 1e-6, far below model 0's few per cent, and shrinks
    as RK4's h^4 when the step is halved."""
    ten, five = (momentum_drift(MovingMassModel.TWO_BODY, h) for h in (0.01, 0.005))
    assert 1e-8 < ten < 1e-5
    assert five < ten / 8
    assert momentum_drift(MovingMassModel.DISSERTATION) > 1e-2


@pytest.mark.slow
@pytest.mark.parametrize("choice", CHOICES, ids=lambda c: c.choice[:40])
def test_every_model_choice_says_what_it_changes(choice, scenario_ctx: Context) -> None:
    effect = effect_of(choice, scenario_ctx)
    assert not effect.startswith(("not run", "not computed")), effect
    assert re.search(r"\d", effect), effect
    # an in-process loop checked against the FMUs run with the same (held) coupling agrees
    assert "loop giving" not in effect or "the loop giving the same" in effect, effect


@pytest.mark.slow
def test_lqr_2_s_explanation_states_what_a_saturated_command_gives(scenario_ctx: Context) -> None:
    """Why lqr-2 misses the text's 20 s says what limiting the servo command to the 6 cm
    stroke does: the rail speed and the settling time (|psi| < 1 deg for good) it states
    are those of lqr-2 run so (it said 43 s where the model gives 41.7 s)."""
    assert scenario_ctx.runner is not None
    stroke = load_vehicle("remus100").mass_stroke
    run = scenario_ctx.runner("lqr-2", 0.01, {"controller.mass_position_cmd_limit": stroke}, False)
    settled = settling_time(run["time"], run["plant.yaw"], BAND, angle=True)
    rail = 100 * float(np.max(np.abs(run["plant.mass_velocity"])))
    assert settled is not None
    stated = [f"slows the mass to ~{rail:.0f} cm/s", f"the settling to {settled:.0f} s"]
    missing = [text for text in stated if text not in LQR_2]
    assert not missing, f"{missing} are not in the explanation: {LQR_2}"


# --- one weight for Chapter 5 ---------------------------------------------------------------


def test_chapter_5_vehicles_carry_the_weight_example_5_3_was_computed_with() -> None:
    """Example 5.3's printed Jacobian holds with Table 5.4's W = 299 N (to its last digit),
    not with W = m g; every Chapter 5 claim gets that weight."""
    ctx = Context.create(DISSERTATION)
    printed = np.array(printed_jacobian(DISSERTATION), dtype=float).reshape(4, 4)
    assert DISSERTATION["table_5_4.weight"].source == "Table 5.4"
    assert ctx.chapter_5(ctx.remus).W == ctx.chapter_5(ctx.long_fins).W == W_TABLE_5_4 == 299
    assert np.max(np.abs(jacobian(ctx.chapter_5(ctx.remus)) - printed)) < 1e-4
    assert np.max(np.abs(jacobian(ctx.remus) - printed)) > 1e-3


@pytest.mark.slow
def test_the_folds_of_example_5_4_and_sec_5_1_4_use_the_weight_of_example_5_3(
    ctx: Context,
) -> None:
    """The roll-torque fold and the mass-position fold equal an independent continuation
    with W = 299 N (4.268 Q_prop, y_g = -0.836 cm), not the W = m g values (4.210 Q_prop,
    -0.823 cm). On the module's context: its two sweeps are the claims' (memoised)."""
    vehicle = ctx.remus.replace(W=W_TABLE_5_4)
    lateral = OperatingConditions(vehicle, Variant.LATERAL)
    (fold,) = sweep(lateral, "roll_torque", 0.0, 5.5 * Q_PROP).folds
    (ours,) = roll_torque_sweep(ctx).folds
    assert ours.parameter / Q_PROP == pytest.approx(fold.parameter / Q_PROP, abs=1e-6)
    assert ours.parameter / Q_PROP == pytest.approx(4.268, abs=1e-3)
    (mass_fold,) = mass_sweep(ctx).folds
    assert 100 * cg_offset(vehicle, mass_fold.parameter) == pytest.approx(-0.836, abs=1e-3)


# --- the command ----------------------------------------------------------------------------


def test_the_figures_a_page_shows_are_the_ones_a_rerun_may_remove(tmp_path: Path) -> None:
    """docs/figures holds other pages' figures too (the README's screenshots): a rerun
    of reproduce removes only what its earlier page showed and the new one does not."""
    page = tmp_path / "reproduction.md"
    page.write_text(
        "![a](figures/fig5_4_phase_portrait.png)\n\n![b](figures/gone-since.png)\n",
        encoding="utf-8",
    )
    assert figures_of(page) == {"fig5_4_phase_portrait.png", "gone-since.png"}
    assert figures_of(tmp_path / "no-page-yet.md") == set()  # a first run removes nothing


def test_a_values_file_lacking_an_entry_is_named_and_changes_nothing(
    tmp_path: Path, capsys
) -> None:
    """A values file without an entry a claim reads ended in a KeyError traceback, after
    the earlier page's figures had been removed and an empty figures/ made."""
    lacking = tmp_path / "lacking.toml"
    lacking.write_text("[nothing]\n", encoding="utf-8")
    out = tmp_path / "docs"
    out.mkdir()
    (out / "reproduction.md").write_text("![a](figures/kept.png)\n", encoding="utf-8")
    (out / "figures").mkdir()
    (out / "figures" / "kept.png").write_bytes(b"png")
    assert main(["reproduce", "--out", str(out), "--values", str(lacking)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "lacking.toml" in err and "no entry '" in err, err
    assert sorted(p.name for p in (out / "figures").iterdir()) == ["kept.png"]


def test_reproduce_refuses_a_missing_values_file(tmp_path: Path, capsys) -> None:
    missing = tmp_path / "nothing.toml"
    assert main(["reproduce", "--out", str(tmp_path), "--values", str(missing)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nothing.toml: no such file" in err
    assert "run it from the checkout's root" in err  # the default is relative to it
    assert VALUES_FILE.is_file()


def _scenario_sections(full_run: bool) -> list:
    """The catalogue's closed-loop claims and model choices, and one figure, as a full run
    finds them (``full_run``: findings of every verdict, '|' in their text, a figure
    drawn) or as ``--skip-scenarios`` does (each raises NotRunError)."""
    from cosim.reproduction.record import Figure, Section

    def ours(i: int):
        def found(c: Context) -> Finding:
            if not full_run:
                raise NotRunError("scenarios skipped")
            return Finding(shown=f"peak |psi| {i}", holds=i % 2 == 1, note=f"note {i} |x|")

        return found

    def effect(c: Context) -> str:
        if not full_run:
            raise NotRunError("scenarios skipped")
        return "bs-3 settles | after 3 s"

    def draw(c: Context, path: Path) -> None:
        if not full_run:
            raise NotRunError("scenarios skipped")
        path.write_bytes(b"\x89PNG")

    claims = [c for c in CLAIMS if c.cost is Cost.SCENARIO]
    choices = [c for c in CHOICES if c.cost is Cost.SCENARIO]
    return [
        Section(
            "Closed loop",
            tuple(dataclasses.replace(c, ours=ours(i)) for i, c in enumerate(claims)),
            (Figure("bs-3_velocities.png", draw, Cost.SCENARIO),),
            tuple(dataclasses.replace(c, effect=effect) for c in choices),
        )
    ]


def test_skip_scenarios_keeps_the_closed_loop_rows_figures_and_effects(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`auv-cosim reproduce --skip-scenarios` rewrote docs/reproduction.md with every
    closed-loop row, model-choice effect and difference reading 'not run' and deleted the
    closed-loop figures the page showed: regenerating the page after a change to Chapter 5
    alone wiped Chapter 6's results. Unchanged, the page must come back byte-identical."""
    import cosim.reproduction.generate as generate

    monkeypatch.setattr(generate, "catalogue", lambda refs: _scenario_sections(True))
    generate.reproduce(tmp_path, VALUES_FILE, scenarios=False, log=lambda m: None)
    earlier = (tmp_path / "reproduction.md").read_bytes()
    assert b"not run" not in earlier and b"](figures/bs-3_velocities.png)" in earlier
    assert b"| differs (explained) |" in earlier and b"bs-3 settles \\| after 3 s" in earlier
    monkeypatch.setattr(generate, "catalogue", lambda refs: _scenario_sections(False))
    logged: list[str] = []
    generate.reproduce(tmp_path, VALUES_FILE, scenarios=False, log=logged.append)
    assert (tmp_path / "reproduction.md").read_bytes() == earlier
    assert (tmp_path / "figures" / "bs-3_velocities.png").is_file()
    assert any("kept from the earlier page" in m for m in logged), logged


def test_skip_scenarios_names_a_kept_row_whose_explanation_has_changed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A closed-loop row kept by `--skip-scenarios` keeps the earlier page's text, its
    explanation included: lqr-2's was corrected (43 s -> 42 s) and the regenerated page
    still said 43 s, silently. The rows whose explanation changed since the full run must
    be named, so the page is not taken for current."""
    import cosim.reproduction.generate as generate

    monkeypatch.setattr(generate, "catalogue", lambda refs: _scenario_sections(True))
    generate.reproduce(tmp_path, VALUES_FILE, scenarios=False, log=lambda m: None)
    sections = _scenario_sections(False)
    claims = tuple(
        dataclasses.replace(c, explained=f"{c.explained} (corrected)") if c.explained else c
        for c in sections[0].claims
    )
    monkeypatch.setattr(
        generate, "catalogue", lambda refs: [dataclasses.replace(sections[0], claims=claims)]
    )
    logged: list[str] = []
    generate.reproduce(tmp_path, VALUES_FILE, scenarios=False, log=logged.append)
    page = (tmp_path / "reproduction.md").read_text(encoding="utf-8")
    explained = [c for c in claims if c.explained]
    differing = [c for c in explained if f"**#{claims.index(c) + 1} {c.claim}** (differs" in page]
    assert differing, "the check must see a kept row that differs with an explanation"
    for claim in differing:
        assert any(claim.claim in m and "explanation" in m for m in logged), (claim, logged)
    assert not any(c.claim in m for c in claims if not c.explained for m in logged)


def test_skip_scenarios_keeps_a_choice_s_effect_when_only_its_reasoning_changed(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A model choice's effect is a run's; its 'why ours' is prose. Rewording the why of
    M_uq's choice and regenerating with `--skip-scenarios` turned its effect into 'not run
    (scenarios skipped)': the earlier page's effects were looked up by the why as well.
    The effect must be kept, and the page must show the new why."""
    import cosim.reproduction.generate as generate

    monkeypatch.setattr(generate, "catalogue", lambda refs: _scenario_sections(True))
    generate.reproduce(tmp_path, VALUES_FILE, scenarios=False, log=lambda m: None)

    def reworded(full_run: bool) -> list:
        sections = _scenario_sections(full_run)
        choices = tuple(
            dataclasses.replace(c, why=f"{c.why}; reworded") for c in sections[0].choices
        )
        return [dataclasses.replace(sections[0], choices=choices)]

    monkeypatch.setattr(generate, "catalogue", lambda refs: reworded(False))
    generate.reproduce(tmp_path, VALUES_FILE, scenarios=False, log=lambda m: None)
    page = (tmp_path / "reproduction.md").read_text(encoding="utf-8")
    assert "not run" not in page
    assert page.count("; reworded | bs-3 settles \\| after 3 s |") == len(
        reworded(False)[0].choices
    )


def test_every_figure_on_the_page_has_an_alt_text_saying_what_it_shows() -> None:
    """docs/reproduction.md showed each figure as ``![fig5_4_phase_portrait](...)``: a
    screen reader (and a page whose image did not load) gave the file's name, nothing of
    what the figure plots."""
    sections = catalogue(DISSERTATION)
    evaluated = [
        Evaluated(s, (), tuple(f.name for f in s.figures), tuple("-" for _ in s.choices))
        for s in sections
    ]
    page = render(evaluated, Context.create(DISSERTATION))
    shown = re.findall(r"!\[([^\]]*)\]\(figures/([\w.-]+)\.png\)", page)
    assert len(shown) == sum(len(s.figures) for s in sections) > 0
    named = [(alt, name) for alt, name in shown if alt.strip().lower() in ("", name.lower())]
    assert named == []
    assert all(re.search(r"\((m/s|rad/s|deg|s|m|N m|cm)\)", alt) for alt, _ in shown), shown
