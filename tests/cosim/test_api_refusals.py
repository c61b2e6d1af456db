"""The Python API's refusals that must agree with each other: a study given as a dict
refuses the values ``cosim.run`` refuses, ``cosim.sweep`` raises the StudyError its
docstring and docs/api.md name (a bad scenario included), and ``Scenario.with_overrides``
refuses a ``names`` that is not an :class:`~cosim.errors.OptionNames`."""

from __future__ import annotations

from decimal import Decimal
from fractions import Fraction
from pathlib import Path

import pytest

import cosim
from cosim.errors import KEYWORDS, CosimError
from cosim.scenario.checks import ScenarioError
from cosim.study.spec import StudyError

GRID = {"plant.v_0": [0.1]}


@pytest.mark.parametrize(
    ("study", "named"),
    [
        ({"scenario": "bs-3", "grid": {"plant.v_0": [Decimal("0.1")]}}, "'grid.plant.v_0[0]'"),
        ({"scenario": "bs-3", "stop_time": Decimal("1"), "grid": GRID}, "'stop_time'"),
        ({"scenario": "bs-3", "grid": {"plant.v_0": [Fraction(1, 10)]}}, "'grid.plant.v_0[0]'"),
    ],
    ids=["decimal-grid", "decimal-stop-time", "fraction-grid"],
)
def test_a_study_dict_refuses_the_numbers_cosim_run_refuses(
    study: dict, named: str, fmu_dir: Path
) -> None:
    """A Decimal grid value was written to the study's TOML as a float and run, where
    ``cosim.run`` refuses a Decimal (its value is not the float's): refused as cosim.run
    refuses it, naming the key and what was expected, before any run."""
    with pytest.raises(StudyError) as refused:
        cosim.sweep(study, workers=1, fmu_dir=fmu_dir)
    message = str(refused.value)
    assert message.startswith(f"study (given as a dict): key {named} = "), message
    assert message.endswith("expected a bool, int, float or str (or a numpy scalar of one)")


@pytest.mark.parametrize("scenario", [Path("nope.toml"), "no-such-scenario"])
def test_a_sweep_of_a_bad_scenario_raises_study_error(
    scenario: object, fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``cosim.sweep`` documents StudyError for a study that cannot run: a study whose
    scenario is no file raised ScenarioError, past a caller's ``except StudyError``. The
    message is the scenario's own."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(StudyError) as refused:
        cosim.sweep({"scenario": scenario, "grid": GRID}, workers=1, fmu_dir=fmu_dir)
    assert "no-such-scenario" in str(refused.value) or "nope.toml" in str(refused.value)


@pytest.mark.parametrize("names", ["keywords", True, object()], ids=["str", "bool", "object"])
def test_with_overrides_refuses_names_that_are_no_option_names(
    names: object, fmu_dir: Path
) -> None:
    """``with_overrides(names=...)`` raised AttributeError from inside for anything but an
    OptionNames: refused as a ScenarioError naming it and what was expected."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError) as refused:
        scenario.with_overrides(stop_time=1.0, names=names)  # type: ignore[arg-type]
    assert str(refused.value).startswith(f"names={names!r}: expected "), refused.value


def test_with_overrides_names_the_overrides_as_option_names_say(fmu_dir: Path) -> None:
    """An OptionNames still names an override the scenario refuses as it says."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(CosimError, match=r"^step=1e-09: "):
        scenario.with_overrides(step=1e-9, names=KEYWORDS)


@pytest.mark.parametrize(
    ("overrides", "named"),
    [
        ({"step": 1e-9}, "step=1e-09: scenario file "),
        ({"stop_time": 1e12}, "stop_time=1000000000000.0: 1000000000000.0 s is 1e+14 "),
        ({"tolerance": 0.01}, "tolerance=0.01: applies to algorithm = 'adaptive' only"),
    ],
)
def test_with_overrides_called_directly_names_the_keyword(
    overrides: dict, named: str, fmu_dir: Path
) -> None:
    """``scenario.with_overrides(step=1e-9)`` without ``names`` was refused as "scenario
    file ... (with the override coupling.step = 1e-09): key 'stop_time': ...", naming a
    scenario key where docs/api.md promises the keyword given; it names the keyword first,
    as ``cosim.run`` does."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(ScenarioError) as refused:
        scenario.with_overrides(**overrides)
    assert str(refused.value).startswith(named), refused.value
