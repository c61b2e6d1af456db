"""``cosim.run(fmu_log=...)``: an instance's debug log for one run, as ``auv-cosim run
--fmu-log`` and ``cosim.sweep(fmu_log=...)`` give it."""

from __future__ import annotations

from pathlib import Path

import pytest

import cosim
from cosim.errors import CosimError


def test_fmu_log_turns_an_instances_debug_log_on_as_the_command_line_does(
    tmp_path: Path, fmu_dir: Path, capfd: pytest.CaptureFixture[str]
) -> None:
    """cosim.run had no fmu_log= (a TypeError), though the command line's run and
    cosim.sweep have it. It logs what --fmu-log does, and the run's scenario.toml keeps
    the keys as with_debug_logging's does."""
    logs = {"controller": ["logAutopilotLimits"]}
    cosim.run("bs-3", stop_time=0.5, fmu_dir=fmu_dir, out=tmp_path / "by-keyword",
              recording=False, fmu_log=logs)  # fmt: skip
    said = capfd.readouterr().err.splitlines()
    assert any(line.startswith("controller: ") for line in said), said
    loaded = cosim.load_scenario("bs-3", fmu_dir=fmu_dir).with_debug_logging(logs)
    cosim.run(loaded, stop_time=0.5, fmu_dir=fmu_dir, out=tmp_path / "by-method", recording=False)
    written = [(tmp_path / f / "scenario.toml").read_text() for f in ("by-keyword", "by-method")]
    assert written[0] == written[1]
    assert "debug_logging = true" in written[0] and '"logAutopilotLimits"' in written[0]


@pytest.mark.parametrize(
    ("value", "said"),
    [
        ("controller", "fmu_log='controller': expected a mapping {instance: [log categories]}"),
        ({"controller": "logAll"}, "expected a list of log categories for 'controller'"),
        ({"nosuch": []}, "bs-3 has no instance 'nosuch'"),
        ({"plant": ["logEvent"]}, "'logEvent' is not a log category of AuvPlant"),
    ],
)
def test_a_bad_fmu_log_is_refused_in_one_line_naming_the_keyword(
    value: object, said: str, fmu_dir: Path
) -> None:
    with pytest.raises(CosimError) as refused:
        cosim.run("bs-3", stop_time=0.1, fmu_dir=fmu_dir, fmu_log=value)  # type: ignore[arg-type]
    message = str(refused.value)
    assert message.startswith("fmu_log=") and said in message and "\n" not in message, message


@pytest.mark.parametrize(
    ("logs", "said"),
    [
        (["plant"], "logs=['plant']: expected a mapping {instance: [log categories]}"),
        ({"plant": "logAll"}, "expected a list of log categories for 'plant'"),
        ({3: []}, "expected instance names as keys, not 3"),
    ],
)
def test_with_debug_logging_refuses_what_is_no_mapping_of_lists_in_one_line(
    fmu_dir: Path, logs: object, said: str
) -> None:
    """with_debug_logging(["plant"]) failed with "AttributeError: 'list' object has no
    attribute 'items'", and a bare string of categories was split into its letters: the
    method checks what it is given as cosim.run's fmu_log= is checked, naming `logs=`."""
    scenario = cosim.load_scenario("bs-3", fmu_dir=fmu_dir)
    with pytest.raises(cosim.ScenarioError) as refused:
        scenario.with_debug_logging(logs)  # type: ignore[arg-type]
    assert said in str(refused.value) and "\n" not in str(refused.value)
