"""A run killed after a checkpoint and resumed writes the results.csv of the run never
interrupted, byte for byte; a checkpoint that cannot be resumed exactly is refused in one
line, leaving the run folder as it was (``--checkpoint-every``, ``--resume``)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from killed_runs import kill_after_checkpoint

from cosim.cli import main
from cosim.errors import CosimError
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.runner import RunOptions, resume_run, run_scenario


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", "run", *args, "--quiet", "--no-rrd"]


def _lines(path: Path) -> int:
    """The lines of a file being written (0 while it is not there: set aside)."""
    try:
        return path.read_bytes().count(b"\n")
    except FileNotFoundError:
        return 0


@pytest.mark.slow
@pytest.mark.parametrize(
    ("scenario", "algorithm"),
    [("bs-3", "gauss-seidel"), ("bs-3", "jacobi"), ("mass-jam", "jacobi")],
)
def test_a_killed_run_resumed_writes_the_uninterrupted_results(
    fmu_dir: Path, tmp_path: Path, scenario: str, algorithm: str
) -> None:
    """bs-3 (extrapolated inputs) under both couplings, and mass-jam with its fault acting
    when the checkpoint is taken."""
    common = ("--fmu-dir", str(fmu_dir), "--stop-time", "120", "--algorithm", algorithm)
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    subprocess.run(_cli(scenario, "--out", str(whole), *common), check=True, timeout=600,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    command = _cli(scenario, "--out", str(killed), *common, "--checkpoint-every", "10")
    assert kill_after_checkpoint(command, killed) == 128 + signal.SIGTERM
    summary = json.loads((killed / "summary.json").read_text())
    assert summary["complete"] is False and summary["time_reached"] < 120
    resumed = subprocess.run(
        _cli("--resume", str(killed), "--fmu-dir", str(fmu_dir)),
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert f"resumed the run in {killed} at t = " in resumed.stderr
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()
    assert json.loads((killed / "summary.json").read_text())["complete"] is True


def _killed_with_guard(fmu_dir: Path, out: Path, *recording: str) -> None:
    """bs-3 to 600 s in ``out``, checkpointing every 20 s, SIGKILLed with its tail guard
    (``recording``: ``--rrd PATH``, or none) once it has checkpointed."""
    command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--out", str(out), "--quiet",
               "--fmu-dir", str(fmu_dir), "--stop-time", "600", "--checkpoint-every", "20",
               *(recording or ("--no-rrd",))]  # fmt: skip
    assert kill_after_checkpoint(command, out, with_guard=True) == -signal.SIGKILL


@pytest.mark.slow
@pytest.mark.parametrize("recording", [False, True])
def test_a_run_killed_with_its_tail_guard_resumes(
    fmu_dir: Path, tmp_path: Path, recording: bool
) -> None:
    """A SIGKILL of the run and its tail guard at once (a job's cgroup killed, a power
    cut) leaves results.csv and the recording longer than the manifest last recorded them,
    perhaps torn: results.csv up to the checkpoint and the recording's head are the run's,
    and the resume writes both again whole."""
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    subprocess.run(_cli("bs-3", "--out", str(whole), "--fmu-dir", str(fmu_dir), "--stop-time",
                        "600"), check=True, timeout=600,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    rrd = killed / "recording.rrd"
    _killed_with_guard(fmu_dir, killed, *(("--rrd", str(rrd)) if recording else ()))
    resumed = subprocess.run(
        [sys.executable, "-m", "cosim.cli", "run", "--resume", str(killed), "--quiet",
         "--fmu-dir", str(fmu_dir)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert resumed.returncode == 0, resumed.stderr
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()
    summary = json.loads((killed / "summary.json").read_text())
    assert summary["complete"] is True
    assert ("recording" in summary["outputs"]) is recording
    assert rrd.exists() is recording


@pytest.mark.slow
def test_a_run_killed_with_its_tail_guard_refuses_rows_edited_before_its_checkpoint(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """The part of results.csv the checkpoint vouches for is checked byte for byte."""
    killed = tmp_path / "killed"
    _killed_with_guard(fmu_dir, killed)
    results = killed / "results.csv"
    data = bytearray(results.read_bytes())
    data[data.index(b"\n") + 1] ^= 1  # the first row's first byte
    results.write_bytes(bytes(data))
    resumed = subprocess.run(
        [sys.executable, "-m", "cosim.cli", "run", "--resume", str(killed), "--quiet",
         "--fmu-dir", str(fmu_dir)],
        capture_output=True, text=True, timeout=600,
    )  # fmt: skip
    assert resumed.returncode == 1
    assert "results.csv is not a file the earlier run wrote" in resumed.stderr
    assert results.read_bytes() == bytes(data)


@pytest.fixture(scope="module")
def checkpointed(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short bs-3 run with checkpoints, made to look killed (its summary says running)."""
    out = tmp_path_factory.mktemp("checkpointed") / "run"
    run_scenario("bs-3", out, stop_time=0.5, checkpoint_every=0.2, no_rrd=True, fmu_dir=fmu_dir)
    summary = json.loads((out / "summary.json").read_text())
    summary.update(status="running", complete=False)
    (out / "summary.json").write_text(json.dumps(summary))
    return out


def _copy(checkpointed: Path, tmp_path: Path) -> Path:
    out = tmp_path / "run"
    shutil.copytree(checkpointed, out)
    return out


def _refused(out: Path, fmu_dir: Path, match: str) -> None:
    """Resuming ``out`` is refused with ``match`` and leaves its files as they were."""
    before = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    with pytest.raises(CosimError, match=match) as refused:
        resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert "\n" not in str(refused.value)
    after = {p.name: p.read_bytes() for p in out.iterdir() if p.is_file()}
    assert after == before


def test_a_checkpoint_of_another_version_is_refused(
    checkpointed: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    out = _copy(checkpointed, tmp_path)
    data = json.loads((out / CHECKPOINT_FILE).read_text())
    data["version"] = "0.0.1"
    (out / CHECKPOINT_FILE).write_text(json.dumps(data))
    _refused(out, fmu_dir, r"written by auv-cosim 0\.0\.1, this is .*: resume it with that")


def test_a_checkpoint_of_another_scenario_is_refused(
    checkpointed: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    out = _copy(checkpointed, tmp_path)
    toml = (out / "scenario.toml").read_text()
    (out / "scenario.toml").write_text(toml.replace("stop_time = 0.5", "stop_time = 0.6"))
    _refused(out, fmu_dir, "the scenario differs from the one checkpointed")


def test_a_checkpoint_of_other_fmus_is_refused(
    checkpointed: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    out = _copy(checkpointed, tmp_path)
    data = json.loads((out / CHECKPOINT_FILE).read_text())
    data["fmus"]["plant"] = "0" * 64
    (out / CHECKPOINT_FILE).write_text(json.dumps(data))
    _refused(out, fmu_dir, "instance 'plant' would load .*AuvPlant.fmu, not the FMU the run")


def test_a_folder_without_a_checkpoint_is_refused(
    checkpointed: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    out = _copy(checkpointed, tmp_path)
    (out / CHECKPOINT_FILE).unlink()
    _refused(out, fmu_dir, f"^--resume {out}: no checkpoint.json there \\(run with "
             "--checkpoint-every SECONDS to write one\\)$")  # fmt: skip


def test_a_complete_run_is_not_resumed(checkpointed: Path, fmu_dir: Path, tmp_path: Path) -> None:
    out = _copy(checkpointed, tmp_path)
    summary = json.loads((out / "summary.json").read_text())
    (out / "summary.json").write_text(json.dumps({**summary, "complete": True}))
    _refused(out, fmu_dir, "the run there is complete: nothing to resume")


def test_an_adaptive_run_refuses_checkpoints(fmu_dir: Path, tmp_path: Path) -> None:
    with pytest.raises(
        CosimError, match=r"--checkpoint-every 1\.0: cannot checkpoint .* 'adaptive'"
    ):
        run_scenario(
            "bs-3", tmp_path / "run", stop_time=1.0, algorithm="adaptive",
            checkpoint_every=1.0, no_rrd=True, fmu_dir=fmu_dir,
        )  # fmt: skip
    assert not (tmp_path / "run").exists()


def test_resume_takes_no_option_that_changes_the_run(checkpointed: Path, tmp_path: Path) -> None:
    with pytest.raises(CosimError, match="--stop-time cannot be given with --resume"):
        resume_run(_copy(checkpointed, tmp_path), RunOptions(stop_time=9.0))


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["bs-3", "--resume", "x"], "give a scenario or --resume OUT, not both"),
        ([], "give a scenario or --resume OUT, not neither"),
        (["--resume", "x", "--out", "y"], "--resume x continues in that folder: --out cannot"),
    ],
)
def test_the_command_line_names_a_resume_it_cannot_do(
    args: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["run", *args]) == 1
    assert said in capsys.readouterr().err


@pytest.mark.slow
def test_a_resumed_run_killed_at_once_can_be_resumed_again(fmu_dir: Path, tmp_path: Path) -> None:
    """Resuming replaces the earlier run's files, its checkpoint.json among them: the
    resumed run writes its own before it steps, so a SIGKILL as soon as it has stepped
    (long before its next periodic checkpoint) still leaves one to resume from."""
    common = ("--fmu-dir", str(fmu_dir), "--stop-time", "600")
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    subprocess.run(_cli("bs-3", "--out", str(whole), *common), check=True, timeout=600,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    command = _cli("bs-3", "--out", str(killed), *common, "--checkpoint-every", "200")
    kill_after_checkpoint(command, killed)
    saved = json.loads((killed / CHECKPOINT_FILE).read_text())["rows"]
    resume = _cli("--resume", str(killed), "--fmu-dir", str(fmu_dir))
    proc = subprocess.Popen(resume, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 300
        while proc.poll() is None and time.monotonic() < deadline:
            if _lines(killed / "results.csv") > saved + 1:  # rows past the checkpoint
                break
            time.sleep(0.01)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait()
    again = subprocess.run(resume, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()


@pytest.mark.slow
def test_a_resumed_run_killed_after_its_next_checkpoint_resumes_from_that_one(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A resumed run checkpoints on after its replay: killed (SIGKILL of it and its tail
    guard) once its first checkpoint past the one it resumed from is saved and recorded,
    it resumes from that later one (not the replayed one), and the twice-resumed run
    writes the uninterrupted results, byte for byte."""
    common = ("--fmu-dir", str(fmu_dir), "--stop-time", "600")
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    subprocess.run(_cli("bs-3", "--out", str(whole), *common), check=True, timeout=600,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    command = _cli("bs-3", "--out", str(killed), *common, "--checkpoint-every", "200")
    assert kill_after_checkpoint(command, killed, with_guard=True) == -signal.SIGKILL
    first = json.loads((killed / CHECKPOINT_FILE).read_text())["time"]
    assert first == 200.0
    resume = _cli("--resume", str(killed), "--fmu-dir", str(fmu_dir))
    assert kill_after_checkpoint(resume, killed, with_guard=True, past=first) == -signal.SIGKILL
    assert json.loads((killed / CHECKPOINT_FILE).read_text())["time"] == 400.0
    again = subprocess.run(resume, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert f"resumed the run in {killed} at t = 400 s" in again.stderr
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()


# ``auv-cosim run --resume`` SIGKILLed (the process alone: its tail guard lives on) as it
# hands the third chunk of the replayed rows on, chunks of 100 rows
KILLED_IN_THE_REPLAY = """
import os, signal, sys
import cosim.outputs.results as results

results.READ_CHUNK_ROWS = 100
chunks = results.CsvRows.chunks


def chunks_then_killed(self):
    for n, chunk in enumerate(chunks(self)):
        if n == 2:
            os.kill(os.getpid(), signal.SIGKILL)
        yield chunk


results.CsvRows.chunks = chunks_then_killed
from cosim.cli import main

sys.exit(main(sys.argv[1:]))
"""


def _settled(out: Path, within: float = 60.0) -> None:
    """Wait until the run folder holds no file set aside (``.<name>.<pid>.auv-cosim-
    earlier``): the tail guard of a killed run puts them back. A guard against a hang,
    not a measure."""
    deadline = time.monotonic() + within
    while any(p.name.endswith(".auv-cosim-earlier") for p in out.iterdir()):
        assert time.monotonic() < deadline, sorted(p.name for p in out.iterdir())
        time.sleep(0.05)


@pytest.mark.slow
def test_a_resume_killed_in_its_replay_resumes_from_the_same_checkpoint(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A SIGKILL while a resume replayed the rows up to its checkpoint left a folder the
    next ``--resume`` refused ("results.csv: holds 200 rows, the checkpoint needs the
    first 806"; docs/runs.md said "is not a file the earlier run wrote"): the
    earlier results.csv was removed as the first replayed row past t = 0 arrived, and the
    new one held a part of the replay. The earlier run's files are now replaced only once
    the resumed run steps past its checkpoint, so the tail guard puts them back and the
    next resume writes the uninterrupted results, byte for byte."""
    common = ("--fmu-dir", str(fmu_dir), "--stop-time", "20")
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    subprocess.run(_cli("bs-3", "--out", str(whole), *common), check=True, timeout=600,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    command = _cli("bs-3", "--out", str(killed), *common, "--checkpoint-every", "5")
    assert kill_after_checkpoint(command, killed) == 128 + signal.SIGTERM
    rows = json.loads((killed / CHECKPOINT_FILE).read_text())["rows"]
    assert rows > 300, rows  # more than the three chunks the replay is killed in
    resume = [*_cli("--resume", str(killed), "--fmu-dir", str(fmu_dir))]
    replay = [sys.executable, "-c", KILLED_IN_THE_REPLAY, *resume[3:]]
    killed_in_replay = subprocess.run(replay, capture_output=True, text=True, timeout=600)
    assert killed_in_replay.returncode == -signal.SIGKILL, killed_in_replay.stderr
    _settled(killed)
    again = subprocess.run(resume, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()
