"""The Modelica Association's Reference FMUs (FMI 2.0 co-simulation) through the master,
against their published results ``<Model>_out.csv``, within the references' printed
precision.

The built FMUs and their published results are in ``tests/data/reference-fmus`` (its
README says how they were built, with their licence); ``AUV_REFERENCE_FMUS`` names another
folder of builds to test instead.
"""

from __future__ import annotations

import csv
import math
import os
from decimal import Decimal
from pathlib import Path

import numpy as np
import pytest
from repo_paths import TESTS

from cosim.engine import master
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import scenario_from_toml

FOLDER = Path(os.environ.get("AUV_REFERENCE_FMUS") or TESTS / "data" / "reference-fmus")
# model -> (step s, stop time s, the published columns compared)
MODELS = {
    "VanDerPol": (0.01, 20.0, ("x0", "x1")),
    "Dahlquist": (0.1, 10.0, ("x",)),
    "BouncingBall": (0.01, 3.0, ("h", "v")),
    "Stair": (0.2, 10.0, ("counter",)),
    "Resource": (1.0, 1.0, ("y",)),
    "Feedthrough": (0.1, 2.0, ("Float64_continuous_output", "Float64_discrete_output",
                               "Int32_output", "Boolean_output", "Enumeration_output")),
}  # fmt: skip


def published(model: str) -> tuple[list[str], list[list[str]]]:
    with open(FOLDER / f"{model}_out.csv", newline="") as file:
        rows = list(csv.reader(file))
    return rows[0], rows[1:]


def printed_tolerance(text: str) -> float:
    """Half a unit of the last printed digit (and a few ulps of the value)."""
    if text in ("true", "false"):
        return 0.0
    exponent = Decimal(text).as_tuple().exponent
    assert isinstance(exponent, int)
    return max(0.5 * 10.0**exponent, 4.0 * math.ulp(abs(float(text))))


def assert_published(result: master.RunResult, instance: str, model: str) -> None:
    """Every published row of ``model`` equals ``instance``'s, time and values."""
    header, rows = published(model)
    step = MODELS[model][0]
    times = np.array([float(row[0]) for row in rows])
    ours = result.times[: len(rows)] if step == result.scenario.coupling.step else None
    if ours is None:  # the instance steps k times slower than the scenario: its rows
        k = round(step / result.scenario.coupling.step)
        ours = result.times[::k]
    np.testing.assert_allclose(ours[: len(rows)], times, rtol=0, atol=1e-9)
    pick = np.searchsorted(result.times, times - 1e-9)
    for name in MODELS[model][2]:
        column = result.column(f"{instance}.{name}")[pick]
        j = header.index(name)
        for i, row in enumerate(rows):
            expected = {"true": 1.0, "false": 0.0}.get(row[j], math.nan)
            expected = float(row[j]) if math.isnan(expected) else expected
            assert abs(column[i] - expected) <= printed_tolerance(row[j]), (
                f"{model}.{name} at t = {row[0]} s: {column[i]!r}, published {row[j]}"
            )


def scenario_text(instances: dict[str, str], step: float, stop: float, extra: str = "") -> str:
    text = f"stop_time = {stop}\n[coupling]\nstep = {step}\n{extra}\n"
    for name, model in instances.items():
        fmu = model if model.startswith("Auv") else f"{FOLDER / model}.fmu"
        text += f'[instances.{name}]\nfmu = "{fmu}"\n'
    return text


def run(text: str, **kwargs: object) -> master.RunResult:
    result = master.run(scenario_from_toml(text, **kwargs))  # type: ignore[arg-type]
    assert result.complete, result.error
    return result


@pytest.mark.parametrize("model", list(MODELS))
def test_each_reference_fmu_alone_gives_its_published_results(model: str) -> None:
    """Every type of output recorded (Integer, Boolean, Enumeration as numbers), Stair
    ending the simulation at 9 s with its last row."""
    step, stop, _ = MODELS[model]
    result = run(scenario_text({"m": model}, step, stop))
    assert_published(result, "m", model)
    if model == "Stair":
        assert result.ended == "m ended the simulation at t = 9 s"
        assert result.times[-1] == pytest.approx(9.0)


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_the_row_where_an_fmu_ends_the_simulation_holds_every_instance_there(
    algorithm: str,
) -> None:
    """Stair ends the simulation at 9 s, stepped before VanDerPol: the row of 9 s held
    VanDerPol's values of 8.8 s (it had not stepped yet). VanDerPol now finishes that step
    first, and its last row is the one it has at 9 s alone."""
    coupling = f'algorithm = "{algorithm}"\norder = ["s", "v"]'
    both = run(scenario_text({"s": "Stair", "v": "VanDerPol"}, 0.2, 10.0, coupling))
    alone = run(scenario_text({"v": "VanDerPol"}, 0.2, 10.0))
    assert both.ended == "s ended the simulation at t = 9 s"
    assert both.times[-1] == pytest.approx(9.0)
    at_9 = int(np.searchsorted(alone.times, 9.0 - 1e-9))
    for name in ("v.x0", "v.x1"):
        assert both.column(name)[-1] == alone.column(name)[at_9], name


def test_reference_fmus_together_at_their_own_rates_give_their_results() -> None:
    """VanDerPol every 10 ms beside Dahlquist every 100 ms (step multiple 10)."""
    text = scenario_text({"v": "VanDerPol", "d": "Dahlquist"}, 0.01, 10.0,
                         "step_multiples = { d = 10 }")  # fmt: skip
    result = run(text)
    assert_published(result, "d", "Dahlquist")
    _, rows = published("VanDerPol")
    x0 = result.column("v.x0")
    for i, row in enumerate(rows[: len(x0)]):
        assert abs(x0[i] - float(row[1])) <= printed_tolerance(row[1])


def test_an_integer_output_drives_an_integer_input_and_a_feedthrough_starts_consistent() -> None:
    """Stair -> Feedthrough (Int32) and VanDerPol -> Feedthrough (Real): the feedthrough
    repeats both from row 0 on, in the order the connections imply."""
    text = scenario_text({"f": "Feedthrough", "s": "Stair", "v": "VanDerPol"}, 0.2, 8.0)
    text += """[connections]
same_names = false
add = [{ from = "s.counter", to = "f.Int32_input" },
       { from = "v.x0", to = "f.Float64_continuous_input" }]
"""
    result = run(text)
    assert result.scenario.coupling.order.index("f") == 2
    np.testing.assert_array_equal(result.column("f.Int32_output"), result.column("s.counter"))
    feed = result.column("f.Float64_continuous_output")
    assert feed[0] == 2.0
    np.testing.assert_array_equal(feed, result.column("v.x0"))


def test_two_feedthroughs_in_a_ring_are_refused_as_an_algebraic_loop() -> None:
    text = scenario_text({"a": "Feedthrough", "b": "Feedthrough"}, 0.1, 1.0)
    text += """[connections]
same_names = false
add = [{ from = "a.Float64_continuous_output", to = "b.Float64_continuous_input" },
       { from = "b.Float64_continuous_output", to = "a.Float64_continuous_input" }]
[[faults]]
kind = "bias"
target = "a.Float64_continuous_input"
value = 1.0
"""
    with pytest.raises(ScenarioError, match=r"algebraic loop .*a\.Float64_continuous_output"):
        scenario_from_toml(text)


@pytest.mark.parametrize("table", ["[instances.f.start]\n", "[[events]]\ntime = 0.5\nset = "])
def test_an_enumeration_value_is_checked_against_its_declared_items(table: str) -> None:
    """A start value or an event's value for an Enumeration is one of its type's items,
    refused at load naming them (the FMU refused 3 only at its first set, ending the run
    incomplete), and an item's name stands for its value."""
    text = scenario_text({"f": "Feedthrough"}, 0.1, 1.0)
    value = "{{ 'f.Enumeration_input' = {} }}" if "events" in table else "Enumeration_input = {}"
    with pytest.raises(ScenarioError, match=r"3 is not an item of Enumeration_input: expected "
                       r"one of 'Option 1' \(1\), 'Option 2' \(2\)$"):  # fmt: skip
        scenario_from_toml(f"{text}{table}{value.format(3)}\n")
    result = run(f"{text}{table}{value.format(repr('Option 2'))}\n")
    assert result.column("f.Enumeration_input")[-1] == 2
    assert result.column("f.Enumeration_output")[-1] == 2


@pytest.mark.parametrize(
    ("kind", "variable", "fmi_type"),
    [("bias", "Int32", "Integer"), ("delay", "Enumeration", "Enumeration"),
     ("stuck", "Boolean", "Boolean")],
)  # fmt: skip
def test_a_fault_on_a_connection_that_is_not_real_is_refused_at_load(
    kind: str, variable: str, fmi_type: str
) -> None:
    """Faults act on Real connections only: one on another type was accepted and the run
    ended at its start in ``ValueError: 'b.Int32_input' is not in list``."""
    text = scenario_text({"a": "Feedthrough", "b": "Feedthrough"}, 0.1, 1.0)
    keys = {"bias": "value = 2", "delay": "steps = 2", "stuck": ""}[kind]
    text += f"""[connections]
same_names = false
add = [{{ from = "a.{variable}_output", to = "b.{variable}_input" }},
       {{ from = "a.Float64_continuous_output", to = "b.Float64_continuous_input" }}]
[[faults]]
kind = "{kind}"
target = "b.{variable}_input"
{keys}
"""
    with pytest.raises(ScenarioError, match=(
        rf"key 'faults\[0\]\.target': 'b\.{variable}_input' is {fmi_type}: a connection fault "
        r"acts on Real connections only, expected one of \['b\.Float64_continuous_input'\]$"
    )):  # fmt: skip
        run(text)


def test_a_variable_recorded_twice_is_named_with_both_places() -> None:
    """The refusal said only "lists a variable twice", leaving the user to search a long
    record list for which."""
    text = scenario_text({"v": "VanDerPol"}, 0.01, 1.0)
    text += '[output]\nrecord = ["v.x0", "v.x1", "v.mu", "v.x1"]\n'
    with pytest.raises(ScenarioError, match=(
        r"key 'output.record\[3\]': 'v.x1' is listed twice: at \[1\] and here$"
    )):  # fmt: skip
        scenario_from_toml(text)


@pytest.mark.slow
@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_beside_our_plant_a_feedthrough_is_transparent(
    fmu_paths: dict[str, Path], algorithm: str
) -> None:
    """VanDerPol -> Feedthrough -> AuvPlant's mass command moves the plant exactly as
    VanDerPol -> AuvPlant does, and VanDerPol still gives its published results."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    text = scenario_text({"plant": "AuvPlant", "f": "Feedthrough", "v": "VanDerPol"}, 0.01,
                         2.0, f'algorithm = "{algorithm}"')  # fmt: skip
    wiring = """[instances.plant.start]
variant = "lateral"
u_0 = 1.5
[connections]
same_names = false
add = [{{ from = "v.x0", to = "f.Float64_continuous_input" }},
       {{ from = "{source}", to = "plant.mass_position_cmd" }}]
"""
    through = run(text + wiring.format(source="f.Float64_continuous_output"), fmu_dir=fmu_dir)
    direct = run(text + wiring.format(source="v.x0"), fmu_dir=fmu_dir)
    np.testing.assert_array_equal(through.column("plant.yaw"), direct.column("plant.yaw"))
    _, rows = published("VanDerPol")
    x0 = through.column("v.x0")
    for i, row in enumerate(rows[: len(x0)]):
        assert abs(x0[i] - float(row[1])) <= printed_tolerance(row[1])


def test_an_output_with_an_exact_initial_value_takes_a_start_value() -> None:
    """FMI 2.0 lets a start value be set on any variable whose ``initial`` is "exact" or
    "approx", outputs included (BouncingBall's height h, 1 m in the file): the ball dropped
    from 2 m falls as from 2 m (it was refused, "only parameters and inputs take start
    values"). An output the FMU calculates (``initial="calculated"``) still refuses one."""
    text = scenario_text({"b": "BouncingBall"}, 0.01, 0.4)  # before the 1 m ball bounces
    from_1m = run(text).column("b.h")
    from_2m = run(text + "[instances.b.start]\nh = 2.0\n").column("b.h")
    assert from_1m[0] == 1.0 and from_2m[0] == 2.0
    np.testing.assert_allclose(from_2m - from_1m, 1.0, rtol=0, atol=1e-12)  # the same fall
    with pytest.raises(ScenarioError, match=r"b.der\(h\) is a continuous local .*calculated"):
        scenario_from_toml(text + '[instances.b.start]\n"der(h)" = 1.0\n')


def _faulty_feedthrough(algorithm: str, fault: str) -> master.RunResult:
    """VanDerPol's x0 -> Feedthrough over 2 s at 0.1 s under ``algorithm``, with the fault
    whose keys (besides its target, the feedthrough's input) ``fault`` gives as TOML."""
    coupling = f'algorithm = "{algorithm}"'
    text = scenario_text({"f": "Feedthrough", "v": "VanDerPol"}, 0.1, 2.0, coupling)
    text += """[connections]
same_names = false
add = [{ from = "v.x0", to = "f.Float64_continuous_input" }]
[[faults]]
target = "f.Float64_continuous_input"
"""
    return run(text + fault)


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_a_delay_fault_on_a_feedthrough_delays_by_its_steps(algorithm: str) -> None:
    """VanDerPol -> Feedthrough with a delay of 2 steps on the feedthrough's input: the
    feedthrough (given its inputs again after each step, to pass on the value of that
    point) repeats x0 of two points earlier, from the first value delivered on (x0 at 0 s
    under Jacobi; under Gauss-Seidel, VanDerPol steps first, x0 at the first step). Each
    re-giving counted as a delivery, so the delay was one point, not two."""
    result = _faulty_feedthrough(algorithm, 'kind = "delay"\nsteps = 2\n')
    x0, feed = result.column("v.x0"), result.column("f.Float64_continuous_output")
    first = 0 if algorithm == "jacobi" else 1  # the point of the first value delivered
    rows = np.arange(1, len(feed))
    np.testing.assert_array_equal(feed[1:], x0[np.maximum(rows - 2, first)])


@pytest.mark.parametrize("algorithm", ["jacobi", "gauss-seidel"])
def test_a_noise_fault_on_a_feedthrough_draws_once_per_step(algorithm: str) -> None:
    """VanDerPol -> Feedthrough with noise (seed 7) on the feedthrough's input: the n-th
    row after row 0 carries the n-th draw of default_rng(7) under Gauss-Seidel, where the
    feedthrough passes on what it stepped with (drawn at its step from the point before),
    and the (n+1)-th under Jacobi (drawn at point n, before its step from it). Each
    re-giving drew anew: two draws per step."""
    result = _faulty_feedthrough(algorithm, 'kind = "noise"\nstd = 0.5\nseed = 7\n')
    x0, feed = result.column("v.x0"), result.column("f.Float64_continuous_output")
    draws = np.random.default_rng(7).normal(0.0, 0.5, len(feed))
    first = 1 if algorithm == "jacobi" else 0  # the draw of row 1
    expected = draws[first : first + len(feed) - 1]
    np.testing.assert_allclose(feed[1:] - x0[1:], expected, rtol=0.0, atol=1e-12)


def test_a_run_whose_fmus_take_no_input_derivatives_does_not_claim_to_extrapolate(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``extrapolation = "quadratic"`` reaches only FMUs that declare canInterpolateInputs
    (the Reference FMUs do not: they hold their inputs over the step); the run's report
    says the inputs were held, not that they were extrapolated."""
    from cosim.cli import main

    text = scenario_text(
        {"v": "VanDerPol", "f": "Feedthrough"},
        0.01,
        0.1,
        'algorithm = "jacobi"\nextrapolation = "quadratic"',
    )
    text += '[connections]\nadd = [{ from = "v.x0", to = "f.Float64_continuous_input" }]\n'
    scenario = tmp_path / "held.toml"
    scenario.write_text(f'id = "held"\n{text}')
    assert main(["run", str(scenario), "--no-rrd", "--out", str(tmp_path / "run")]) == 0
    first = capsys.readouterr().out.splitlines()[0]
    assert "10 steps of 0.01 s (jacobi" in first, first
    assert "inputs quadratic" not in first, first
    assert "inputs held: no FMU takes input derivatives" in first, first
