"""scripts/coupling_study.py's comparison of an adaptive run with the fixed steps: the
doSteps a fixed step takes for a given trajectory error, when the fixed runs' errors
scatter about their trend (vert-1's error is not monotonic in the step)."""

from __future__ import annotations

from types import ModuleType, SimpleNamespace

import numpy as np
import pytest
from repo_paths import script_module


@pytest.fixture(scope="module")
def study() -> ModuleType:
    return script_module("coupling_study")


def trend(n: float) -> float:
    """A fixed step's trajectory error falling as the square of its step: 60 s, doSteps n."""
    return 0.5 * (1000.0 / n) ** 2


def test_one_unlucky_fixed_step_does_not_set_the_comparison(study: ModuleType) -> None:
    """Fixed runs on an error trend, one of them (6000 doSteps) with twice its trend's error:
    an adaptive run with that error is compared with the trend (about 4243 doSteps, within
    10 %), not with the unlucky run (interpolating between neighbours would say 6000)."""
    counts = [1500, 1875, 2000, 2400, 3000, 3750, 4000, 4800, 5000, 6000, 7500, 8000, 12000]
    fixed = [(trend(n) * (2.0 if n == 6000 else 1.0), float(n)) for n in counts]
    error = 2.0 * trend(6000)
    assert study._same_error(fixed, error) == pytest.approx(1000.0 / np.sqrt(error / 0.5), rel=0.1)


def test_the_scatter_is_the_largest_factor_off_the_trend(study: ModuleType) -> None:
    """On the trend exactly the fixed runs scatter by a factor 1; one run with 4 times its
    trend's error is off by about a factor 2 in doSteps (error as the square of the step)."""
    counts = [1500, 1875, 2000, 2400, 3000, 3750, 4000, 4800, 5000, 6000, 7500, 8000, 12000]
    exact = [(trend(n), float(n)) for n in counts]
    assert study._scatter(exact) == pytest.approx(1.0)
    unlucky = [(e * (4.0 if n == 4800 else 1.0), n) for e, n in exact]
    assert study._scatter(unlucky) == pytest.approx(2.0, rel=0.15)


PAGE = """# Coupling

<!-- coupling_study.py shipped -->
| scenario | coupling | key figure | as shipped | limit | error | order |
|---|---|---|---|---|---|---|
| bs-1 | old | yaw settling time | 1 s | 1 s | +0.00 % | 2 |
| bs-2 | old | yaw settling time | 2 s | 2 s | +0.00 % | 2 |
| bs-3 | old | yaw settling time | 3 s | 3 s | +0.00 % | 2 |
<!-- end -->
after
"""


def test_writing_the_shipped_table_of_some_scenarios_keeps_the_others_rows(
    study: ModuleType, tmp_path, monkeypatch
) -> None:
    """``shipped --scenarios zigzag-20 bs-2 --write`` (a contributor measuring the scenario
    they added) replaced the whole table with those scenarios' rows: the other sixteen
    were gone. Now only their rows are replaced, in the order of the built-in ids."""
    page = tmp_path / "coupling.md"
    page.write_text(PAGE, encoding="utf-8")
    monkeypatch.setattr(study, "PAGE", page)

    def measured(ids):  # the table shipped() makes, without the runs
        rows = [f"| {sid} | new | yaw settling time | 9 s | 9 s | +0.00 % | 2 |" for sid in ids]
        return "\n".join(PAGE.splitlines()[3:5] + rows)

    monkeypatch.setattr(study, "shipped", measured)
    assert study.main(["shipped", "--scenarios", "zigzag-20", "bs-2", "--write"]) == 0
    table = page.read_text(encoding="utf-8").split("-->\n", 1)[1].split("\n<!-- end -->")[0]
    assert [line.split(" | ")[:2] for line in table.splitlines()[2:]] == [
        ["| bs-1", "old"], ["| bs-2", "new"], ["| bs-3", "old"], ["| zigzag-20", "new"]
    ]  # fmt: skip
    assert page.read_text(encoding="utf-8").endswith("<!-- end -->\nafter\n")


def run(times: np.ndarray, columns: dict[str, np.ndarray]) -> SimpleNamespace:
    """What the study reads of a master.RunResult: times, columns, values, column()."""
    names = tuple(columns)
    values = np.column_stack([columns[name] for name in names])
    return SimpleNamespace(
        times=times, columns=names, values=values, column=lambda name: columns[name]
    )


def test_the_trajectory_error_names_the_output_and_time_it_is_largest_at(
    study: ModuleType,
) -> None:
    """The scatter table says which plant output carries a run's trajectory error and when
    (vert-1's: the roll rate p, late in the run): the largest |y - y_ref| / (|y_ref| + 1)
    over the plant's outputs at the run's own times, the reference (on a finer grid that
    does not hold them) interpolated there; the controller's outputs do not count."""
    fine = np.linspace(0.0, 6.0, 6001)
    reference = run(
        fine, {"plant.p": np.sin(fine), "plant.v": 0 * fine, "controller.tunnel_force": 0 * fine}
    )
    coarse = np.linspace(0.0, 6.0, 16)  # 0.4 s: not on the reference's grid after 0
    p = np.sin(coarse) + np.where(np.isclose(coarse, 4.4), 0.01, 0.0)
    v = np.full_like(coarse, 0.002)
    force = np.full_like(coarse, 5.0)  # far off, but not the plant's
    measured = run(coarse, {"plant.p": p, "plant.v": v, "controller.tunnel_force": force})
    error, column, at = study._worst(measured, reference)
    assert (column, at) == ("plant.p", pytest.approx(4.4))
    assert error == pytest.approx(0.01 / (abs(np.sin(4.4)) + 1.0), rel=1e-5)
    assert study._error(measured, reference) == error


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["scatter", "--scenarios", "nope"], "--scenarios: unknown scenario 'nope'"),
        (["scatter", "--tolerances", "1e-3"], "--tolerances: only with adaptive"),
        (["adaptive", "--tolerances", "-1"], "--tolerances: -1.0 is not"),
        (["adaptive", "--tolerances", "nan"], "--tolerances: nan is not"),
    ],
)
def test_a_bad_argument_is_refused_in_one_line_before_a_run(
    study: ModuleType, argv: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Guards an unknown scenario id ending the study with a ScenarioError traceback, and
    tolerances the part asked for never reads (or none could meet) being taken silently."""
    with pytest.raises(SystemExit) as ended:
        study.main(argv)
    assert ended.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert said in error and "Traceback" not in error, error


def test_the_envelope_is_the_longest_step_below_which_every_step_reaches_the_error(
    study: ModuleType,
) -> None:
    """The guarantee a user choosing a fixed step can count on: one unlucky fine step
    (7500 doSteps, four times its trend's error) sets it, not the trend; an error no step
    measured misses (or every one misses) has no envelope among the steps measured."""
    counts = [1500, 2000, 3000, 4000, 5000, 6000, 7500, 8000, 10000, 12000]
    fixed = [(trend(n) * (4.0 if n == 7500 else 1.0), float(n)) for n in counts]
    assert study._envelope(fixed, trend(4000)) == 8000  # 5000 and 6000 reach it, 7500 not
    assert study._envelope(fixed, trend(7500) * 4.0) == 4000  # the unlucky one's: 3000 not
    assert study._envelope(fixed, trend(12000) / 2.0) is None  # the finest misses it
    assert study._envelope(fixed, trend(1500) * 2.0) is None  # beyond the coarsest


def test_the_median_line_regresses_the_error_on_the_steps(study: ModuleType) -> None:
    """Errors scattered by a factor 2 either way, alternately, about a second-order trend:
    the line through them is the trend (slope -2 in doSteps), and it gives back the doSteps
    of an error on the trend."""
    counts = np.geomspace(2000, 12000, 40)
    fixed = [(trend(n) * (2.0 if i % 2 else 0.5), float(n)) for i, n in enumerate(counts)]
    slope, _ = study._trend(fixed)
    assert slope == pytest.approx(-2.0, abs=0.1)
    assert study._on_trend(study._trend(fixed), trend(5000)) == pytest.approx(5000, rel=0.1)


def test_a_table_is_written_between_markers_with_nothing_between_them(
    study: ModuleType, tmp_path, monkeypatch
) -> None:
    """A new part's markers in the page, nothing between them yet (how a contributor adds
    a table): ``--write`` said "no marker" after the whole study and printed no table."""
    page = tmp_path / "coupling.md"
    page.write_text("<!-- coupling_study.py scatter -->\n<!-- end -->\nafter\n", encoding="utf-8")
    monkeypatch.setattr(study, "PAGE", page)
    study.write("scatter", "| table |")
    assert page.read_text(encoding="utf-8") == (
        "<!-- coupling_study.py scatter -->\n| table |\n<!-- end -->\nafter\n"
    )


def test_a_page_without_the_markers_is_refused_before_the_first_run(
    study: ModuleType, tmp_path, monkeypatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--write`` into a page without the part's markers failed only once every run of
    the part (up to a quarter of an hour) was done, its table lost."""
    page = tmp_path / "coupling.md"
    page.write_text("# Coupling\n", encoding="utf-8")
    monkeypatch.setattr(study, "PAGE", page)

    def no_run(ids: list[str]) -> str:
        raise AssertionError("the runs started")

    monkeypatch.setattr(study, "scatter", no_run)
    with pytest.raises(SystemExit) as ended:
        study.main(["scatter", "--write"])
    assert ended.value.code == 2
    assert "no marker <!-- coupling_study.py scatter -->" in capsys.readouterr().err


def test_a_scenario_of_two_vehicles_is_refused_in_one_line_before_a_run(
    study: ModuleType, fmu_dir, monkeypatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """The study's tables hold one vehicle's key figures: a scenario of two (plant_a,
    plant_b) was measured as if plant_a were all of it, plant_b's figures silently left
    out of the table. It is refused, naming its plants, before the first run."""
    from two_vehicles import two_vehicles_toml

    from cosim.scenario.spec import scenario_from_toml

    two = scenario_from_toml(two_vehicles_toml(stop_time=0.05), fmu_dir=fmu_dir)
    monkeypatch.setattr(study, "builtin_scenarios", lambda: {"two-vehicles": "two"})
    monkeypatch.setattr(study, "load_scenario", lambda sid, **_: two)
    monkeypatch.setattr(study.master, "run", lambda *a, **k: pytest.fail("a run started"))
    with pytest.raises(SystemExit) as ended:
        study.main(["shipped", "--scenarios", "two-vehicles"])
    assert ended.value.code == 2
    error = capsys.readouterr().err.strip().splitlines()[-1]
    assert (
        "--scenarios: two-vehicles has 2 vehicles (plants plant_a, plant_b); the tables "
        "hold one vehicle's key figures"
    ) in error, error
