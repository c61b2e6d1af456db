"""Factors against a real scenario (bs-3 and its FMUs), and one run through the adapter."""

from __future__ import annotations

import copy
import json
import math
import os
import subprocess
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import tomli_w

from cosim.outputs.folder import GUARD_SCRIPT
from cosim.runner import run_scenario
from cosim.study import factors as factors_module
from cosim.study.factors import ScenarioFacts, StartValue, resolve_factor
from cosim.study.in_flight import STOPPED_BY, RunsInFlight
from cosim.study.runner import _metrics, _random_text
from cosim.study.spec import StudyError, study_from_dict
from cosim.study.task import Base, check_values, prepare, run_one


@pytest.fixture(scope="module")
def bs3(fmu_paths: dict[str, Path]) -> tuple[Base, ScenarioFacts]:
    return prepare("bs-3", 1.0, fmu_paths["AuvPlant"].parent)


def test_start_values_and_parameters_are_factors(bs3: tuple[Base, ScenarioFacts]) -> None:
    base, facts = bs3
    v0 = resolve_factor("plant.v_0", facts)
    assert v0 == StartValue("plant.v_0", "plant", "v_0", real=True)
    assert v0.normalize(1) == 1.0 and isinstance(v0.normalize(1), float)
    variant = resolve_factor("plant.variant", facts)
    assert variant.normalize(2) == variant.normalize("horizontal") == "horizontal"
    assert variant.normalize(7) == 7  # no such value: the scenario's check names it
    data: dict[str, Any] = {"instances": {"plant": {"fmu": "AuvPlant"}}}
    v0.apply(data, -0.2)
    assert data["instances"]["plant"]["start"] == {"v_0": -0.2}
    assert base.data["instances"]["plant"]["start"]["v_0"] == -0.10  # the base is untouched


def test_unknown_factor_names_it_and_the_known_variables(
    bs3: tuple[Base, ScenarioFacts],
) -> None:
    _, facts = bs3
    with pytest.raises(StudyError) as info:
        resolve_factor("plant.v0", facts)
    message = str(info.value)
    assert message.startswith(
        "factor 'plant.v0': plant has no parameter or input 'v0' (did you mean 'v_0'?)"
    )
    assert "v_0" in message and "max_substep" in message and "yaw," not in message
    with pytest.raises(StudyError, match=r"no instance 'autopilot' \(instances: plant, contr"):
        resolve_factor("autopilot.k0", facts)


def test_outputs_and_connected_inputs_are_refused(bs3: tuple[Base, ScenarioFacts]) -> None:
    _, facts = bs3
    with pytest.raises(StudyError, match=r"plant\.yaw is a continuous output"):
        resolve_factor("plant.yaw", facts)
    with pytest.raises(StudyError, match=r"connected from controller\.thrust"):
        resolve_factor("plant.thrust", facts)


def test_the_dispatch_grows_by_a_kind(
    bs3: tuple[Base, ScenarioFacts], monkeypatch: pytest.MonkeyPatch
) -> None:
    @dataclass(frozen=True)
    class EventTime:  # the shape of an event-time factor
        name: str

        @classmethod
        def recognise(cls, name: str, facts: ScenarioFacts) -> EventTime | None:
            return cls(name) if name.startswith("events.") else None

    _, facts = bs3
    kinds = (StartValue, EventTime)
    monkeypatch.setattr(factors_module, "FACTOR_KINDS", kinds)
    assert resolve_factor("events.turn", facts) == EventTime("events.turn")
    assert isinstance(resolve_factor("plant.v_0", facts), StartValue)


def test_values_the_scenario_refuses_are_errors_before_any_run(
    bs3: tuple[Base, ScenarioFacts],
) -> None:
    base, facts = bs3
    names = ("plant.v_0", "plant.variant", "plant.max_substep")
    found = {n: resolve_factor(n, facts) for n in names}
    with pytest.raises(StudyError, match=r"v_0.*nan is not a finite number"):
        check_values(base, found, {"plant.v_0": math.nan})
    with pytest.raises(StudyError, match=r"0\.5 is not an integer \(variant is Integer\)"):
        check_values(base, found, {"plant.variant": 0.5})
    with pytest.raises(StudyError, match=r"7 is outside \[0, 2\], the range variant takes"):
        check_values(base, found, {"plant.variant": 7})  # the FMU's declared range
    with pytest.raises(StudyError, match=r"-1.0 is outside \[0.0, inf\], the range max_sub"):
        check_values(base, found, {"plant.max_substep": -1.0})  # a Real's declared range too


def test_a_run_the_fmu_refuses_is_a_failed_record(bs3: tuple[Base, ScenarioFacts]) -> None:
    base, facts = bs3
    # a mass beyond its stroke: no declared range says so, the plant refuses it
    found = {"plant.mass_position_0": resolve_factor("plant.mass_position_0", facts)}
    record = run_one(base, base.fmu_paths, found, {"plant.mass_position_0": 0.5}, keep="failed")
    assert record.status == "failed" and record.metrics == {}
    assert "mass_position_0 = 0.5 m: expected |mass_position_0| <= mass_stroke" in record.error
    assert "\n" not in record.error
    good = run_one(base, base.fmu_paths, found, {"plant.mass_position_0": 0.01}, keep="all")
    assert good.status == "complete" and good.error is None
    assert good.metrics["time_reached"] == 1.0 and set(good.metrics) == set(facts.metrics)
    assert set(good.files) == {"results.csv", "summary.json"}
    assert 0.0 < good.loop_s < good.wall_clock_s


def test_a_run_its_study_stopped_ends_before_its_first_step(
    bs3: tuple[Base, ScenarioFacts],
) -> None:
    """The stop request a study's end sets (cosim.study.in_flight) reaches the run: it
    ends as a failed record saying so, not run to its stop time."""
    base, facts = bs3
    found = {"plant.v_0": resolve_factor("plant.v_0", facts)}
    runs = RunsInFlight()
    runs.stop_all()
    with runs.run() as stop:
        record = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05}, stop=stop)
    assert record.status == "failed" and record.metrics == {}, record
    assert record.error == f"stopped by {STOPPED_BY} before the first step", record.error


def test_a_study_task_runs_without_a_tail_guard(
    bs3: tuple[Base, ScenarioFacts], monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    """A study's run starts no tail-guard process (~20 ms a run, a third of a run's fixed
    cost: scripts/bench_sweep.py); a run from the command line still does."""
    started: list[Path] = []
    real_popen = subprocess.Popen

    def popen(args, *more, **kwargs):
        if str(GUARD_SCRIPT) in map(str, args):
            started.append(Path(args[-1]))
        return real_popen(args, *more, **kwargs)

    monkeypatch.setattr(subprocess, "Popen", popen)
    base, facts = bs3
    found = {"plant.v_0": resolve_factor("plant.v_0", facts)}
    record = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05})
    assert record.status == "complete" and started == []
    outcome = run_scenario("bs-3", tmp_path / "run", stop_time=0.1, no_rrd=True,
                           fmu_dir=base.fmu_paths["plant"].parent)  # fmt: skip
    assert outcome.result.complete and started == [outcome.paths["results"]]


def test_a_study_task_that_keeps_no_files_writes_no_results_csv(
    bs3: tuple[Base, ScenarioFacts], monkeypatch: pytest.MonkeyPatch
) -> None:
    """With ``keep = "none"`` (the default) nothing reads a run's results.csv: formatting
    its rows was about a quarter of a run's CPU. The row's metrics are the same as a run
    that writes it."""
    created: list[str] = []
    real_open = os.open

    def watched_open(path, flags, *args, **kwargs):
        if flags & os.O_CREAT and Path(path).name == "results.csv":
            created.append(str(path))
        return real_open(path, flags, *args, **kwargs)

    base, facts = bs3
    found = {"plant.v_0": resolve_factor("plant.v_0", facts)}
    kept = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05}, keep="all")
    monkeypatch.setattr(os, "open", watched_open)
    record = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05})
    assert record.status == "complete" and record.files == {} and created == []
    assert record.metrics == kept.metrics
    failed = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05}, keep="failed")
    assert failed.status == "complete" and len(created) == 1  # written: the run might fail


@pytest.mark.slow
def test_a_study_with_check_step_carries_each_runs_coupling_error(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """``check_step = true``: every key figure and final value gets a coupling_error.<name>
    column, holding the estimate `auv-cosim run --check-step` writes for the same run."""
    base, facts = prepare("bs-3", 1.0, fmu_paths["AuvPlant"].parent, check_step=True)
    errors = [m for m in facts.metrics if m.startswith("coupling_error.")]
    assert "coupling_error.final.plant.yaw" in errors
    assert {e.removeprefix("coupling_error.") for e in errors} <= set(facts.metrics)
    found = {"plant.v_0": resolve_factor("plant.v_0", facts)}
    record = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05}, check_step=True)
    assert record.status == "complete" and set(record.metrics) == set(facts.metrics)
    data = copy.deepcopy(dict(base.data))
    data["instances"]["plant"]["start"]["v_0"] = -0.05
    source = tmp_path / "bs-3-slower.toml"
    source.write_text(tomli_w.dumps(data))
    outcome = run_scenario(source, tmp_path / "run", no_rrd=True, check_step=True)
    check = json.loads(outcome.paths["summary"].read_text())["coupling"]["check_step"]
    assert (
        record.metrics["coupling_error.final.plant.yaw"]
        == (check["final_values"]["plant.yaw"]["error"])
    )
    assert math.isfinite(record.metrics["coupling_error.final.plant.yaw"])
    without = run_one(base, base.fmu_paths, found, {"plant.v_0": -0.05})
    assert not any(name.startswith("coupling_error.") for name in without.metrics)


def test_check_step_on_an_adaptive_scenario_is_refused_in_one_line(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    source = tmp_path / "adaptive.toml"
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    source.write_text(text.replace('algorithm = "gauss-seidel"', 'algorithm = "adaptive"'))
    with pytest.raises(StudyError, match=r"^check_step = true: .* adaptive .*\Z"):
        prepare(source, 1.0, fmu_paths["AuvPlant"].parent, check_step=True)


def test_check_step_with_a_noise_fault_is_refused_in_one_line(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A noise fault makes the runs at h/2 and h/4 other systems: a study with
    ``check_step = true`` ran every run, each checked in vain, and its coupling_error
    columns were empty without a word. Now the study is refused before its first run."""
    source = tmp_path / "noisy.toml"
    text = (Path(__file__).parents[3] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    fault = '\n[[faults]]\nname = "sensor"\nkind = "noise"\ntarget = "controller.yaw"\nstd = 0.01\n'
    source.write_text(text + fault)
    with pytest.raises(StudyError, match=r"^check_step = true: fault 'sensor' \(noise\) draws"):
        prepare(source, 1.0, fmu_paths["AuvPlant"].parent, check_step=True)


def test_check_step_with_collected_metrics_adds_their_coupling_errors() -> None:
    """``check_step = true`` beside ``[metrics] collect`` (as docs/studies.md shows them)
    ran every run three times and wrote no coupling_error column: none was collected."""
    errors = ("coupling_error.final.plant.yaw", "coupling_error.time_reached")
    facts = ScenarioFacts(instances={}, metrics=("final.plant.yaw", "time_reached", *errors))
    study = {"scenario": "bs-3", "grid": {"plant.v_0": [0.1]}, "check_step": True}
    spec = study_from_dict({**study, "metrics": {"collect": ["final.plant.yaw"]}}, "s.toml")
    assert _metrics(spec, facts) == ["final.plant.yaw", "coupling_error.final.plant.yaw"]
    listed = ["coupling_error.time_reached", "final.plant.yaw"]
    spec = study_from_dict({**study, "metrics": {"collect": listed}}, "s.toml")
    assert _metrics(spec, facts) == [*listed, "coupling_error.final.plant.yaw"]


def test_the_page_names_each_random_law_with_its_parameters_and_unit() -> None:
    """index.html showed a random factor as a Python dict, ``controller.k0 ~ {'uniform':
    (0.2, 0.5)}``, without its unit (a normal yaw's std: rad or deg?)."""
    random = {"n": 3, "seed": 11, "controller.k0": {"uniform": [0.2, 0.5]},
              "plant.yaw_0": {"normal": [0.0, 0.1]}, "plant.m": {"normal": [30, 1.25]}}  # fmt: skip
    spec = study_from_dict({"scenario": "bs-3", "random": random}, "s.toml")
    quantities = {"controller.k0": "1/s", "plant.yaw_0": "rad", "plant.m": "1"}
    assert _random_text(spec, quantities) == (
        "controller.k0 ~ uniform on [0.2, 0.5) 1/s; plant.yaw_0 ~ normal, mean 0.0, std 0.1 "
        "rad; plant.m ~ normal, mean 30.0, std 1.25; n = 3, seed = 11, random"
    )


def test_a_study_of_a_plant_parameter_warns_the_autopilot_designs_for_another(
    bs3: tuple[Base, ScenarioFacts],
) -> None:
    """A sweep of plant.m_v over bs-3 ran every run without a word, the autopilot's laws
    designed for remus100's 5.08 kg moving mass whatever the plant's (a run of the same
    scenario warns of it): the study now warns once before its first run, as a run does."""
    import warnings

    from cosim.scenario.design_doubts import DesignWarning
    from cosim.study.runner import _checked_plan

    base, facts = bs3
    spec = study_from_dict({"scenario": "bs-3", "grid": {"plant.m_v": [3.0, 8.0]}}, "m_v")
    factors = {"plant.m_v": resolve_factor("plant.m_v", facts)}
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        runs = _checked_plan(spec, base, factors, facts)
    assert len(runs) == 2
    lines = [str(w.message) for w in caught if issubclass(w.category, DesignWarning)]
    assert [line.split(": the sets differ in ")[1].split(";")[0] for line in lines] == [
        "m_v 3.0 vs 5.083333333333333",
        "m_v 8.0 vs 5.083333333333333",
    ], lines
    assert lines[0].startswith("plant runs vehicle 'remus100' with m_v written over"), lines
