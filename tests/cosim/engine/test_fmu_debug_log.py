"""An FMU's debug log in a run (FMI 2.0, 2.1.5): a scenario's ``debug_logging`` and
``log_categories`` keys and ``auv-cosim run --fmu-log`` call fmi2SetDebugLogging before
initialisation and show the instance's messages of every status on stderr; a category the
FMU does not declare, or any for an FMU declaring none, is refused in one line before
anything runs. Foreign FMUs: tests/fmus/cosim_test_foreign.py (pythonfmu's own binary) and
the Reference FMUs (tests/data/reference-fmus)."""

from __future__ import annotations

import os
import re
import sys
import zipfile
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import TESTS

from cosim.cli import main
from cosim.engine import master
from cosim.scenario.checks import ScenarioError
from cosim.scenario.spec import scenario_from_toml

BALL = TESTS / "data" / "reference-fmus" / "BouncingBall.fmu"
BALL_SCENARIO = f'stop_time = 0.1\n[coupling]\nstep = 0.01\n[instances.ball]\nfmu = "{BALL}"\n'
DEBUG_LINE = re.compile(r"^(\w+): \[(OK|Warning|Discard|Error|Fatal)\] (\S*): (.*)$")


def foreign_run(folder: Path, keys: str, start: str = "chatter = 1") -> master.RunResult:
    """One CosimTestForeign instance ``f`` for 0.3 s in steps of 0.1 s, with the instance
    keys ``keys`` and the start values ``start`` (TOML lines); its chatter logs one OK
    line a step."""
    text = f"""
stop_time = 0.3
[coupling]
step = 0.1
[instances.f]
fmu = "CosimTestForeign.fmu"
{keys}
[instances.f.start]
{start}
"""
    return master.run(scenario_from_toml(text, base_dir=folder))


def debug_lines(err: str) -> list[tuple[str, ...]]:
    """(instance, status, category, text) of each debug-log line of ``err``."""
    return [m.groups() for m in map(DEBUG_LINE.match, err.splitlines()) if m]


def test_debug_logging_shows_every_message_with_instance_status_and_category(
    test_fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An integrator debugging an FMU sees its debug (OK) messages, which a run otherwise
    drops, as they are logged, with the instance and status; Warnings too."""
    result = foreign_run(test_fmu_dir, "debug_logging = true", "chatter = 1\nwarn_at = 0.1")
    assert result.complete, result.error
    lines = debug_lines(capsys.readouterr().err)
    assert ("f", "OK", "logAll", "constructed") in lines, lines  # logged as it instantiated
    assert ("f", "OK", "logAll", "step at 0.000: line 0") in lines, lines
    assert ("f", "OK", "logAll", "step at 0.200: line 0") in lines, lines
    assert ("f", "Warning", "logStatusWarning", "warned at 0.100") in lines, lines
    assert result.messages["f"] == ["[Warning] warned at 0.100"]  # kept as before


def test_without_debug_logging_no_message_is_shown_live(
    test_fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The default stays as it was: debug messages dropped, warnings kept for the report."""
    result = foreign_run(test_fmu_dir, "", "chatter = 1\nwarn_at = 0.1")
    assert result.complete, result.error
    assert debug_lines(capsys.readouterr().err) == []
    assert result.messages["f"] == ["[Warning] warned at 0.100"]


def test_log_categories_show_only_those_messages(
    test_fmu_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Categories narrow the messages shown to theirs (the FMU passes only those): the
    warnings, not the debug lines."""
    keys = 'log_categories = ["logStatusWarning"]'
    result = foreign_run(test_fmu_dir, keys, "chatter = 1\nwarn_at = 0.1")
    assert result.complete, result.error
    lines = debug_lines(capsys.readouterr().err)
    assert lines == [("f", "Warning", "logStatusWarning", "warned at 0.100")], lines


def test_the_categories_reach_an_fmu_that_narrows_its_messages_itself(
    test_fmu_dir: Path,
) -> None:
    """pythonfmu's own binary passes the host only messages of the categories asked for,
    warnings too: asked for its errors alone, its warning never reaches the run. (Shown
    here, a warning would mean fmi2SetDebugLogging was not called with the categories.)"""
    keys = 'log_categories = ["logStatusError"]'
    result = foreign_run(test_fmu_dir, keys, "chatter = 1\nwarn_at = 0.1")
    assert result.complete, result.error
    assert result.messages["f"] == []


def test_a_category_the_fmu_does_not_declare_is_refused_naming_those_it_does() -> None:
    text = BALL_SCENARIO + 'log_categories = ["logEvent"]\n'
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text)
    message = str(refused.value)
    assert "\n" not in message
    assert "key 'instances.ball.log_categories': 'logEvent' is not a log category of " in message
    assert "BouncingBall (did you mean 'logEvents'?)" in message
    assert message.endswith("expected one of logEvents, logStatusError"), message


def test_a_reference_fmu_runs_with_its_categories_and_the_run_replays_them(
    tmp_path: Path,
) -> None:
    """fmi2SetDebugLogging with the Reference FMU's own categories is taken (it refuses any
    other with fmi2Error), and the resolved scenario.toml keeps them."""
    text = (
        f'stop_time = 0.5\n[coupling]\nstep = 0.01\n[instances.ball]\nfmu = "{BALL}"\n'
        'log_categories = ["logEvents", "logStatusError"]\n'
    )
    scenario = scenario_from_toml(text)
    assert scenario.instances["ball"].debug_logging == ("logEvents", "logStatusError")
    result = master.run(scenario)
    assert result.complete, result.error
    again = scenario_from_toml(scenario.to_toml())
    assert again.instances["ball"].debug_logging == ("logEvents", "logStatusError")


def without_log_categories(fmu: Path, folder: Path) -> Path:
    """A copy of ``fmu`` whose modelDescription.xml declares no LogCategories."""
    copy = folder / fmu.name
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(copy, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                data = re.sub(rb"<LogCategories>.*?</LogCategories>", b"", data, flags=re.S)
            target.writestr(item, data)
    return copy


def test_an_fmu_declaring_no_categories_takes_debug_logging_but_no_category(
    tmp_path: Path,
) -> None:
    bare = without_log_categories(BALL, tmp_path)
    head = f'stop_time = 0.1\n[coupling]\nstep = 0.01\n[instances.ball]\nfmu = "{bare}"\n'
    with pytest.raises(ScenarioError, match="BouncingBall declares no LogCategories"):
        scenario_from_toml(head + 'log_categories = ["logEvents"]\n')
    result = master.run(scenario_from_toml(head + "debug_logging = true\n"))
    assert result.complete, result.error


def test_debug_logging_off_with_categories_is_refused() -> None:
    text = BALL_SCENARIO + 'debug_logging = false\nlog_categories = ["logEvents"]\n'
    with pytest.raises(ScenarioError, match="debug_logging is false"):
        scenario_from_toml(text)


@pytest.mark.parametrize(
    ("flag", "expected"),
    [
        ("bal", "--fmu-log bal: "),
        ("ball:logEvent", "--fmu-log ball:logEvent: 'logEvent' is not a log category of "),
    ],
)
def test_fmu_log_refuses_an_unknown_instance_or_category_in_one_line(
    flag: str, expected: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "ball.toml"
    scenario.write_text(BALL_SCENARIO)
    argv = ["run", str(scenario), "--out", str(tmp_path / "run"), "--no-rrd", "--quiet"]
    assert main([*argv, "--fmu-log", flag]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"auv-cosim run: {expected}"), err
    assert not (tmp_path / "run" / "results.csv").exists()


def test_fmu_log_turns_an_instances_debug_log_on(
    test_fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "foreign.toml"
    fmu = test_fmu_dir / "CosimTestForeign.fmu"
    scenario.write_text(
        f'stop_time = 0.2\n[coupling]\nstep = 0.1\n[instances.f]\nfmu = "{fmu}"\n'
        "[instances.f.start]\nchatter = 1\n"
    )
    argv = ["run", str(scenario), "--out", str(tmp_path / "run"), "--no-rrd", "--quiet"]
    assert main([*argv, "--fmu-log", "f"]) == 0
    assert ("f", "OK", "logAll", "step at 0.100: line 0") in debug_lines(capsys.readouterr().err)
    resolved = (tmp_path / "run" / "scenario.toml").read_text()
    assert "debug_logging = true" in resolved


def test_validate_says_which_instances_log_for_debugging(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    scenario = tmp_path / "ball.toml"
    scenario.write_text(BALL_SCENARIO + 'log_categories = ["logEvents"]\n')
    assert main(["validate", str(scenario)]) == 0
    assert "ball (BouncingBall, debug log: logEvents)" in capsys.readouterr().out


@pytest.mark.slow
def test_both_runtimes_show_the_same_debug_log(fmu_paths: dict[str, Path], tmp_path: Path) -> None:
    """Our FMUs on their runtime and on pythonfmu's binary (AUV_FMU_RUNTIME=pythonfmu)
    show the same lines: the plant's warning that its compiled step is off; on pythonfmu's
    binary each instance whose debug log has "logAll" also says that binary runs it, and
    one asking for other categories is not told (the line came at instantiation, before
    the categories were set, and showed whatever ``--fmu-log`` chose)."""
    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    shown = {}
    for runtime in ("", "pythonfmu"):
        env = {**os.environ, "AUV_FMU_RUNTIME": runtime, "AUV_COSIM_NO_JIT": "1"}
        out = tmp_path / (runtime or "runtime")
        argv = [sys.executable, "-m", "cosim", "run", "bs-3", "--stop-time", "0.05", "--out",
                str(out), "--no-rrd", "--quiet", "--fmu-dir", fmu_dir, "--fmu-log", "plant",
                "--fmu-log", "controller:logStatusError"]  # fmt: skip
        done = run_in_group(argv, env=env, timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        shown[runtime] = debug_lines(done.stderr)
    told = [line for line in shown["pythonfmu"] if "runs on pythonfmu's own binary" in line[3]]
    assert [line[:3] for line in told] == [("plant", "OK", "logAll")], shown
    assert shown[""] == [line for line in shown["pythonfmu"] if line not in told], shown
    assert any(
        line[:3] == ("plant", "Warning", "logStatusWarning") and "compiled plant is off" in line[3]
        for line in shown[""]
    ), shown


def test_a_run_asking_no_debug_log_gets_no_debug_message_from_our_fmus(
    fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The master instantiated every FMU with logging on (pythonfmu's own binary drops even
    its errors otherwise) and dropped their debug messages itself: our FMUs, whose runtime
    passes warnings and errors whatever loggingOn says, did their debug work for nothing
    (the autopilot checked its commands against their limits at every step: a 120 s bs-3
    run's loop ~10 % slower). Unless a debug log is asked for, they are instantiated with
    logging off and send no message at all on a quiet run."""
    from cosim.engine import slave as slave_module
    from cosim.scenario.spec import load_scenario

    class Counting(dict):  # the logger looks each message's instance up here
        messages = 0

        def get(self, key: object, default: object = None) -> object:
            Counting.messages += 1
            return super().get(key, default)

    monkeypatch.setattr(slave_module, "_log_sinks", Counting())
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir).with_overrides(stop_time=0.5)
    result = master.run(scenario)
    assert result.complete, result.error
    assert Counting.messages == 0
