"""A run's start-up (scenario, outputs, loading and initialising the FMUs) is timed apart
from its stepping loop, in summary.json and the report's last line; the progress bar says
what the run does before it steps."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from scenario_factory import loop_toml

from cosim.outputs.sinks import ProgressSink
from cosim.runner import report, run_scenario
from cosim.scenario.spec import scenario_from_toml

PHASES = ["prepare", "outputs", "load_fmus", "initialise"]


def test_summary_separates_start_up_from_the_loop(test_fmu_dir: Path, tmp_path: Path) -> None:
    scenario = scenario_from_toml(loop_toml(), base_dir=test_fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert list(summary["startup_s"]) == PHASES
    assert all(v >= 0.0 for v in summary["startup_s"].values())
    assert summary["startup_total_s"] == pytest.approx(sum(summary["startup_s"].values()))
    assert summary["wall_clock_s"] == outcome.result.wall_clock_s
    assert summary["real_time_factor"] == pytest.approx(
        summary["time_reached"] / summary["wall_clock_s"]
    )
    last = report(outcome).splitlines()[-1]
    assert "start-up" in last and "loading FMUs" in last and "initialising" in last
    assert last.rstrip().endswith("x real time)") and "stepping loop" in last


def test_progress_bar_says_what_it_does_before_stepping(capsys: pytest.CaptureFixture) -> None:
    bar = ProgressSink(None, "bs-3")
    bar.phase("building FMUs (AuvPlant)")
    bar.phase("initialising")
    bar.total_rows = 3
    bar.add_rows(np.zeros(3), np.zeros((3, 1)))
    bar.close()
    err = capsys.readouterr().err
    assert "bs-3: building FMUs (AuvPlant)" in err
    assert err.index("building FMUs") < err.index("bs-3: initialising") < err.index("/3 ")


def test_the_bar_names_only_the_fmus_the_scenario_builds(tmp_path: Path) -> None:
    from cosim.runner import _fmus_to_build

    assert sorted(_fmus_to_build("bs-3", tmp_path)) == ["AuvAutopilot", "AuvPlant"]
    assert "AuvGuidance" in _fmus_to_build("survey", tmp_path)
    assert _fmus_to_build(tmp_path / "missing.toml", tmp_path) == []


def test_an_adaptive_run_s_bar_counts_simulated_time_to_its_stop_time(
    test_fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """The bar's total was the fixed step's count of rows (11 for 1 s at 0.1 s) while an
    adaptive run counted its own steps against it, thousands at a tolerance of 1e-6: past
    its total the bar became a bare count of steps, with no share done and no time left,
    for the rest of the run. Now an adaptive run's bar counts simulated seconds (s) up to
    its stop time."""
    import re

    text = loop_toml(algorithm="adaptive").replace("[coupling]", "[coupling]\ntolerance = 1e-6")
    scenario = scenario_from_toml(text, base_dir=test_fmu_dir)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True, progress=True)
    assert outcome.result.rows > 2 * scenario.n_steps  # more steps than the fixed step's
    err = capsys.readouterr().err
    counts = [(float(a), float(b)) for a, b in re.findall(r"\| *([0-9.]+)/([0-9.]+) \[", err)]
    assert counts, f"no progress shown: {err!r}"
    assert all(total == scenario.stop_time and done <= total for done, total in counts), counts
    assert "step/s" not in err  # no bare count of steps
