"""[coupling]: the extrapolation default, the adaptive keys, overrides and the resolved
file; the order the connections imply and the loops they close (coupling_graph)."""

from __future__ import annotations

from pathlib import Path

import pytest
from scenario_factory import loop_toml

from cosim.scenario.checks import ScenarioError
from cosim.scenario.coupling_graph import algebraic_loop, connection_order
from cosim.scenario.spec import DEFAULT_EXTRAPOLATION, scenario_from_toml


def loop(test_fmu_dir: Path, text: str):
    return scenario_from_toml(text, base_dir=test_fmu_dir)


def test_a_file_naming_its_algorithm_keeps_held_values_and_one_without_extrapolates(
    test_fmu_dir: Path,
) -> None:
    """Files written before extrapolation existed name jacobi or gauss-seidel and keep
    their results; a file that names no algorithm gets the converging default."""
    named = loop(test_fmu_dir, loop_toml())
    assert named.coupling.extrapolation == "none"
    unnamed = loop(test_fmu_dir, loop_toml().replace('algorithm = "gauss-seidel"\n', ""))
    assert unnamed.coupling.algorithm == "gauss-seidel"
    assert unnamed.coupling.extrapolation == DEFAULT_EXTRAPOLATION == "quadratic"
    chosen = loop_toml().replace("[coupling]", '[coupling]\nextrapolation = "linear"')
    assert loop(test_fmu_dir, chosen).coupling.extrapolation == "linear"
    # an override changes what it names only: the step, or the algorithm (the resolved
    # extrapolation kept; --extrapolation changes that)
    assert unnamed.with_overrides(step=0.05).coupling.extrapolation == "quadratic"
    assert unnamed.with_overrides(algorithm="jacobi").coupling.extrapolation == "quadratic"
    assert named.with_overrides(algorithm="jacobi").coupling.extrapolation == "none"


def test_the_resolved_file_loads_back_to_the_same_coupling(test_fmu_dir: Path) -> None:
    text = loop_toml(algorithm="adaptive").replace("[coupling]", "[coupling]\ntolerance = 1e-4")
    scenario = loop(test_fmu_dir, text)
    assert (scenario.coupling.tolerance, scenario.coupling.max_step) == (1e-4, 64 * 0.1)
    again = scenario_from_toml(scenario.to_toml(), base_dir=test_fmu_dir)
    assert again.coupling == scenario.coupling


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ("tolerance = 1e-3", r"coupling.tolerance.*applies to algorithm = 'adaptive' only"),
        ('extrapolation = "cubic"', r"coupling.extrapolation.*'cubic'"),
        ("tolerance = 2.0", r"coupling.tolerance.*less than 1"),
    ],
)
def test_bad_coupling_keys_are_refused_naming_them(
    test_fmu_dir: Path, change: str, message: str
) -> None:
    with pytest.raises(ScenarioError, match=message):
        loop(test_fmu_dir, loop_toml().replace("[coupling]", f"[coupling]\n{change}"))


def test_a_longest_step_below_the_step_is_refused(test_fmu_dir: Path) -> None:
    text = loop_toml(algorithm="adaptive").replace("[coupling]", "[coupling]\nmax_step = 0.01")
    with pytest.raises(ScenarioError, match=r"max_step.*shorter than coupling.step"):
        loop(test_fmu_dir, text)


def test_the_order_puts_sources_first_and_breaks_a_feedback_loop_where_nothing_feeds_through():
    """A chain in any file order comes out source first; in a plant-controller loop the
    instance that feeds nothing through from it goes first; a declared feedthrough waits
    for its source."""
    names = ["sink", "middle", "source"]
    chain = [("source.y", "middle.u"), ("middle.y", "sink.u")]
    assert connection_order(names, {}, chain) == ("source", "middle", "sink")
    feedback = [("plant.x", "controller.x"), ("controller.u", "plant.u")]
    assert connection_order(["plant", "controller"], {}, feedback) == ("plant", "controller")
    through = {"controller": {"u": {"x"}}}
    assert connection_order(["controller", "plant"], through, feedback) == ("plant", "controller")


def test_a_loop_needs_a_feedthrough_at_every_instance_in_it():
    feedback = [("plant.x", "controller.x"), ("controller.u", "plant.u")]
    assert algebraic_loop({"controller": {"u": {"x"}}}, feedback) is None
    both = {"controller": {"u": {"x"}}, "plant": {"x": {"u"}}}
    loop = algebraic_loop(both, feedback)
    assert loop is not None and loop[0] == loop[-1] and len(loop) == 5
