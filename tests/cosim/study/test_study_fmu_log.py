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


@pytest.mark.cluster
@pytest.mark.slow
def test_cosim_sweep_takes_fmu_log_as_the_command_does(tmp_path: Path, fmu_dir: Path) -> None:
    """``auv-cosim sweep --fmu-log`` had no keyword in ``cosim.sweep``: a notebook's study
    could not turn an FMU's debug log on. ``fmu_log={instance: [categories]}`` writes each
    run's messages to its folder's fmu-log.txt, as the flag does."""
    import cosim

    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    done = cosim.sweep(study, out=out, workers=1, fmu_dir=fmu_dir,
                       fmu_log={"controller": ["logAutopilotLimits"]})  # fmt: skip
    assert list(done.table["status"]) == ["complete", "complete"]
    for run in done.table["run"]:
        lines = (out / "runs" / run / "fmu-log.txt").read_text(encoding="utf-8").splitlines()
        assert lines and all(
            line.startswith("controller: [OK] logAutopilotLimits: t = ") for line in lines
        )


@pytest.mark.parametrize(
    ("given", "expected"),
    [
        ({"autopilot": []}, "fmu_log={'autopilot': []}: bs-3 has no instance 'autopilot'"),
        ({"plant": ["logEvent"]},
         "fmu_log={'plant': ['logEvent']}: 'logEvent' is not a log category of"),
        ("controller", "fmu_log='controller': expected a mapping {instance: [log categories]}"),
        ({"plant": "logAll"},
         "fmu_log={'plant': 'logAll'}: expected a list of log categories for 'plant'"),
    ],
)  # fmt: skip
def test_a_bad_fmu_log_keyword_is_refused_in_one_line_naming_it(
    given: object, expected: str, tmp_path: Path, fmu_dir: Path
) -> None:
    import cosim
    from cosim.errors import CosimError

    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    out = tmp_path / "out"
    with pytest.raises(CosimError) as refused:
        cosim.sweep(study, out=out, workers=1, fmu_dir=fmu_dir, fmu_log=given)
    assert expected in str(refused.value) and "\n" not in str(refused.value), refused.value
    assert not out.exists()


def test_fmu_log_without_out_is_refused_naming_both() -> None:
    """Without ``out`` the study folder is temporary: every run's fmu-log.txt would be
    written and removed unread."""
    import cosim
    from cosim.study.spec import StudyError

    with pytest.raises(StudyError, match=r"^fmu_log=\{'controller': \[\]\} needs out= "):
        cosim.sweep({"scenario": "bs-3", "grid": {"plant.v_0": [0.1]}}, workers=1,
                    fmu_log={"controller": []})  # fmt: skip
