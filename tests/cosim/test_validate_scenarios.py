"""`auv-cosim validate SCENARIO...`: a scenario file or id is checked as a run checks it
before its first step (its keys, its FMUs' variables, its coupling), stepping nothing and
writing nothing; each refused one is named in one line."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cosim.cli import main
from cosim.scenario.spec import scenario_path


def test_a_scenario_is_validated_without_running_it(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch
) -> None:
    """It was taken for an FMU: "s.toml: not a valid FMU: File is not a zip file"."""
    monkeypatch.chdir(tmp_path)
    mine = tmp_path / "mine.toml"
    text = scenario_path("bs-3").read_text("utf-8")
    text = text.replace("stop_time = 60.0", "stop_time = 12.5", 1).replace(
        "step = 0.01", "step = 0.005", 1
    )
    mine.write_text(text, encoding="utf-8")
    assert main(["validate", "mine.toml", "vert-1", "--fmu-dir", str(fmu_dir)]) == 0
    mine_line, builtin_line = capsys.readouterr().out.splitlines()
    assert mine_line == (
        "mine.toml: a valid scenario: plant (AuvPlant), controller (AuvAutopilot); "
        "12.5 s in 2500 steps of 0.005 s (gauss-seidel, inputs quadratic)"
    )
    assert builtin_line.startswith("vert-1: a valid scenario: plant (AuvPlant), controller ")
    assert sorted(os.listdir(tmp_path)) == ["mine.toml"]  # no run folder, no FMU built


def test_each_refused_scenario_is_named_in_one_line(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        scenario_path("bs-3").read_text("utf-8").replace("algorithm =", "method =", 1),
        encoding="utf-8",
    )
    argv = ["validate", str(bad), "bs-9", "bs-3", "--fmu-dir", str(fmu_dir)]
    assert main(argv) == 1
    captured = capsys.readouterr()
    out = captured.out.splitlines()
    assert len(out) == 3
    assert out[0].startswith(f"scenario file {bad}: unknown key 'coupling.method': [coupling] ")
    assert out[1].startswith("unknown scenario 'bs-9': expected a built-in id (bs-1, ")
    assert out[2].startswith("bs-3: a valid scenario: ")
    assert captured.err == "auv-cosim validate: 2 of 3 scenario(s) refused\n"


def test_scenarios_and_fmu_files_are_not_validated_together(
    fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["validate", "bs-3", str(fmu_dir / "AuvPlant.fmu")]) == 1
    assert capsys.readouterr().err == (
        "auv-cosim validate: give scenarios or FMU files, not both "
        f"(FMUs: {fmu_dir / 'AuvPlant.fmu'})\n"
    )
