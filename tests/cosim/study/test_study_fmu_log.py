"""A study's FMU debug log (``auv-cosim sweep --fmu-log``): every run's messages in its
folder's fmu-log.txt, whatever ``keep`` says, never on the workers' stderr; a bad
``--fmu-log`` refused before any run. (A study had no way to turn an FMU's debug log on,
and a base scenario's own debug_logging key sent the messages of every run, interleaved
and unnamed, to the workers' stderr.)"""

from __future__ import annotations

from pathlib import Path

import pytest
from sweep_helpers import sweep, table

from cosim.cli import main

pytestmark = pytest.mark.usefixtures("no_early_cluster")  # refusals wait for no cluster

STUDY = """
scenario = "bs-3"
stop_time = 1.0
[grid]
"controller.yaw_setpoint" = [0.5, 1.0]
"""


@pytest.mark.cluster
@pytest.mark.slow
def test_each_runs_debug_log_lands_in_its_folder(
    tmp_path: Path, fmu_dir: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    sweep(study, out, fmu_dir, "--workers", "1", "--fmu-log", "controller:logAutopilotLimits")
    rows = table(out)
    assert [r["status"] for r in rows] == ["complete", "complete"], rows
    for row in rows:  # keep = "none": the folder holds the run's scenario and its log
        folder = out / "runs" / row["run"]
        assert sorted(p.name for p in folder.iterdir()) == ["fmu-log.txt", "scenario.toml"]
        lines = (folder / "fmu-log.txt").read_text(encoding="utf-8").splitlines()
        assert lines, row
        assert all(line.startswith("controller: [OK] logAutopilotLimits: t = ") for line in lines)
        assert "mass_position_cmd reached its limit" in lines[0], lines
    assert "logAutopilotLimits" not in capfd.readouterr().err
    # the debug log changes no row: the same study resumes without the flag
    sweep(study, out, fmu_dir, "--workers", "1", "--resume")
    assert table(out) == rows


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ("autopilot", "--fmu-log autopilot: bs-3 has no instance 'autopilot'"),
        ("plant:logEvent", "--fmu-log plant:logEvent: 'logEvent' is not a log category of"),
    ],
)
def test_a_bad_fmu_log_is_refused_before_any_run(
    given: str, expected: str, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]
    assert main([*argv, "--fmu-log", given]) == 1
    assert expected in capsys.readouterr().err
    assert not out.exists()
