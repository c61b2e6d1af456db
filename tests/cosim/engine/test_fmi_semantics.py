"""What FMI 2.0 asks of a master, with FMUs nobody here wrote the master for (tests/fmus:
a feedthrough, a clock with outputs of every type that can end the simulation, a clock
with a fixed step, one allowed once per process): initialisation, Integer and Boolean
values, an FMU that ends the simulation, algebraic loops, the order the connections
imply, fixed steps, String events, when events on a slow instance, and FMUs allowed one
instance per process."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cosim.engine import master
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import scenario_from_toml

SOURCE_X0 = 2.0  # the clock's x at t = 0


TYPED = """
    { from = "src.count", to = "ft.n_in" },
    { from = "src.odd", to = "ft.b_in" },"""


def chain(
    algorithm: str = "gauss-seidel",
    extra: str = "",
    order: str = "",
    src_start: str = "",
    typed: bool = False,
) -> str:
    """clock -> feedthrough -> integrator, the consumer listed first (file order);
    ``typed``: the clock's Integer and Boolean outputs feed the feedthrough's too."""
    return f"""
stop_time = 1.0
{extra}
[coupling]
step = 0.1
algorithm = "{algorithm}"
{order}
[instances.plant]
fmu = "CosimTestIntegrator.fmu"
[instances.plant.start]
x0 = 0.0
[instances.ft]
fmu = "CosimTestFeedthrough.fmu"
[instances.src]
fmu = "CosimTestSource.fmu"
[instances.src.start]
{src_start}
[connections]
same_names = false
add = [
    {{ from = "src.x", to = "ft.u" }},
    {{ from = "ft.y", to = "plant.u" }},{TYPED if typed else ""}
]
"""


def run(test_fmu_dir: Path, text: str) -> master.RunResult:
    return master.run(scenario_from_toml(text, base_dir=test_fmu_dir))


@pytest.mark.parametrize(("algorithm", "first_u"), [("jacobi", 2.0), ("gauss-seidel", 2.1)])
def test_a_feedthrough_starts_from_its_source_value_exchanged_at_initialisation(
    test_fmu_dir: Path, algorithm: str, first_u: float
) -> None:
    """Row 0 of a feedthrough is its source's initial value, and under Jacobi the first
    step of the instance it feeds already uses it (FMI 2.0, 4.2.4: values exchanged in
    initialisation mode); Gauss-Seidel feeds the source's value after its first step."""
    result = run(test_fmu_dir, chain(algorithm))
    assert result.complete, result.error
    assert result.column("ft.y")[0] == result.column("src.x")[0] == SOURCE_X0
    # x' = u from x = 0: the first step integrates the u it was given over 0.1 s
    assert result.column("plant.x")[1] == pytest.approx(0.1 * first_u)


def test_integer_and_boolean_outputs_are_connected_and_recorded(test_fmu_dir: Path) -> None:
    """Integer and Boolean outputs drive inputs of their type and are recorded as numbers
    (Booleans 0 and 1); under Gauss-Seidel a feedthrough repeats its source every row."""
    result = run(test_fmu_dir, chain(typed=True))
    count, odd = result.column("src.count"), result.column("src.odd")
    np.testing.assert_array_equal(count, np.arange(11))
    np.testing.assert_array_equal(odd, np.arange(11) % 2)
    np.testing.assert_array_equal(result.column("ft.n_out"), count)
    np.testing.assert_array_equal(result.column("ft.b_out"), odd)


def test_a_string_output_is_named_when_left_out_and_refused_in_record(
    test_fmu_dir: Path,
) -> None:
    """results.csv holds numbers: a String output is left out of the default record and
    listed as such, and asking to record one is refused naming its type."""
    scenario = scenario_from_toml(chain(), base_dir=test_fmu_dir)
    assert "src.label" not in scenario.record and "src.count" in scenario.record
    assert scenario.unrecorded == ("src.label",)
    asked = chain(extra='[output]\nrecord = ["src.label"]')
    with pytest.raises(ScenarioError, match=r"'src.label' is String: results.csv holds numbers"):
        scenario_from_toml(asked, base_dir=test_fmu_dir)


def test_the_default_gauss_seidel_order_puts_every_source_before_its_consumers(
    test_fmu_dir: Path,
) -> None:
    """Listed consumer first and without an order, the chain still steps source ->
    feedthrough -> integrator: no consumer takes a value one step old."""
    scenario = scenario_from_toml(chain(), base_dir=test_fmu_dir)
    assert scenario.coupling.order == ("src", "ft", "plant")
    result = master.run(scenario)
    np.testing.assert_array_equal(result.column("ft.y"), result.column("src.x"))


def test_an_fmu_that_ends_the_simulation_ends_the_run_complete(test_fmu_dir: Path) -> None:
    """A doStep's Discard with fmi2Terminated is the FMU ending the simulation (FMI 2.0,
    4.2.3): the run ends there, complete, with every row up to the time it reached."""
    result = run(test_fmu_dir, chain(src_start="stop_at = 0.55"))
    assert result.complete and result.error is None
    assert result.ended == "src ended the simulation at t = 0.6 s"
    assert result.times[-1] == pytest.approx(0.6) and result.time_reached == pytest.approx(0.6)
    assert result.column("src.count")[-1] == 6


def test_an_fmu_that_fails_a_step_still_fails_the_run(test_fmu_dir: Path) -> None:
    """A Discard the FMU explains with an Error is a failure, not an end (pythonfmu also
    answers Terminated after a failed step)."""
    failing = chain().replace("x0 = 0.0", "x0 = 0.0\nfail_at = 0.25")
    result = run(test_fmu_dir, failing)
    assert not result.complete and result.ended is None
    assert "injected failure" in (result.error or "")


def ring(bias: float) -> str:
    return f"""
stop_time = 1.0
[coupling]
step = 0.1
[instances.a]
fmu = "CosimTestFeedthrough.fmu"
[instances.a.start]
bias = {bias}
[instances.b]
fmu = "CosimTestFeedthrough.fmu"
[connections]
same_names = false
add = [{{ from = "a.y", to = "b.u" }}, {{ from = "b.y", to = "a.u" }}]
"""


@pytest.mark.parametrize("bias", [0.0, 1.0])
def test_an_algebraic_loop_is_refused_naming_it(test_fmu_dir: Path, bias: float) -> None:
    """Two feedthroughs in a ring (with a bias: no solution) form an algebraic loop: the
    scenario is refused before anything runs, with the loop spelled out."""
    with pytest.raises(ScenarioError) as info:
        scenario_from_toml(ring(bias), base_dir=test_fmu_dir)
    message = str(info.value)
    assert "algebraic loop" in message and "\n" not in message
    for part in ("a.y -> b.u", "b.u -> b.y", "b.y -> a.u", "a.u -> a.y"):
        assert part in message


def fixed_step(stop_time: float, multiple: int = 3) -> str:
    return f"""
stop_time = {stop_time}
[coupling]
step = 0.1
step_multiples = {{ c = {multiple} }}
[instances.c]
fmu = "CosimTestFixedStep.fmu"
"""


def test_an_fmu_that_cannot_change_its_step_is_never_given_a_shorter_one(
    test_fmu_dir: Path,
) -> None:
    """canHandleVariableCommunicationStepSize="false": a stop time its step does not
    divide is refused (the last step would be shorter), one it divides runs."""
    with pytest.raises(ScenarioError, match=r"canHandleVariableCommunicationStepSize"):
        scenario_from_toml(fixed_step(1.0), base_dir=test_fmu_dir)
    result = run(test_fmu_dir, fixed_step(0.9))
    assert result.complete
    assert result.column("c.x")[-1] == pytest.approx(0.9)
    adaptive = fixed_step(0.9, 1).replace("step = 0.1", 'step = 0.1\nalgorithm = "adaptive"')
    with pytest.raises(ScenarioError, match=r"'adaptive' changes every step"):
        scenario_from_toml(adaptive, base_dir=test_fmu_dir)


def test_an_fmu_allowed_once_per_process_gets_one_instance(test_fmu_dir: Path) -> None:
    """canBeInstantiatedOnlyOncePerProcess="true": a second instance of it is refused,
    naming both (a run steps every instance in one process, one library per FMU: they
    would share the global state the flag warns of); one instance runs."""
    one = 'stop_time = 0.5\n[coupling]\nstep = 0.1\n[instances.a]\nfmu = "CosimTestSingleton.fmu"\n'
    two = one + '[instances.b]\nfmu = "CosimTestSingleton.fmu"\n'
    with pytest.raises(
        ScenarioError,
        match=r"instances\.b\.fmu.*a and b are both instances of "
        r"CosimTestSingleton\.fmu, which declares canBeInstantiatedOnlyOnce",
    ):
        scenario_from_toml(two, base_dir=test_fmu_dir)
    result = run(test_fmu_dir, one)
    assert result.complete, result.error
    assert set(result.column("a.live")) == {1}


def test_an_event_sets_a_string_input(test_fmu_dir: Path) -> None:
    """An event's set takes a string for a String variable (the clock's label prefix: its
    Integer label_length shows the change)."""
    text = chain(extra='[[events]]\ntime = 0.3\nset = { "src.prefix" = "lap" }')
    result = run(test_fmu_dir, text)
    assert result.complete, result.error
    length = result.column("src.label_length")
    assert length[3] == len("step 3") and length[4] == len("lap 4")
    assert result.events == [{"name": "event-1", "time": pytest.approx(0.3),
                              "set": {"src.prefix": "lap"}}]  # fmt: skip


def test_a_when_event_on_a_slow_instance_fires_at_its_own_point(test_fmu_dir: Path) -> None:
    """With step multiples, a slow instance's output is known at its own points only: a
    when event on it fires at the point where the value crossed (t = 0.6 s for a clock
    stepping 0.3 s), not when its next step has already produced the value (0.4 s)."""
    text = chain(extra='[[events]]\nwhen = "src.x > 2.35"\nset = { "ft.bias" = 1.0 }',
                 order="step_multiples = { src = 3 }")  # fmt: skip
    result = run(test_fmu_dir, text)
    assert [e["time"] for e in result.events] == [pytest.approx(0.6)]


def test_under_jacobi_a_feedthrough_passes_on_the_value_of_the_same_point(
    test_fmu_dir: Path,
) -> None:
    """clock -> feedthrough -> integrator under Jacobi integrates exactly what clock ->
    integrator does: the feedthrough's output is refreshed at every point."""
    through = run(test_fmu_dir, chain("jacobi"))
    direct_text = chain("jacobi").replace('{ from = "ft.y", to = "plant.u" }',
                                          '{ from = "src.x", to = "plant.u" }')  # fmt: skip
    direct = run(test_fmu_dir, direct_text)
    np.testing.assert_array_equal(through.column("plant.x"), direct.column("plant.x"))


def test_a_when_on_an_integer_output_is_refused_naming_its_type(test_fmu_dir: Path) -> None:
    """`when = "src.count > 3"` on the clock's Integer count, recorded, was refused as
    "neither a recorded Real variable nor a connection's source": it is recorded; its
    type is what a `when` does not take."""
    event = '[[events]]\nwhen = "src.count > 3"\nset = { "plant.x0" = 1.0 }\n'
    with pytest.raises(ScenarioError, match=r"'src.count' is Integer: a `when` compares a Real"):
        scenario_from_toml(chain() + event, base_dir=test_fmu_dir)
