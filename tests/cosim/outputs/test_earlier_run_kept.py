"""An earlier run is removed only once the run replacing it has taken its first step, and
only the files that are still exactly what that run wrote. A run that fails or stops
before its first step -- an FMU binary that will not load, an FMU refusing its
initialisation, a first step that fails, an exception escaping the master, a stop signal,
the process killed -- leaves the folder byte for byte as it was. On the test FMUs of
tests/fmus (and the built plant for a vehicle file it refuses), in process unless a
process must be killed."""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import signal
import subprocess
import sys
import time
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from scenario_factory import write_loop_file

from cosim.cli import main
from cosim.engine import master
from cosim.engine.signals import StopRequest
from cosim.outputs.earlier_run import ASIDE_SUFFIX
from cosim.outputs.folder import MANIFEST_FILE


def tree(folder: Path) -> dict[str, bytes | None]:
    """Every path below ``folder`` (relative, hidden ones too) -> its bytes (None: folder),
    read again while a file listed is gone before it is read (a run putting the earlier
    run back moves files under the listing)."""
    while True:
        try:
            return {
                str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes()
                for p in sorted(folder.rglob("*"))
                if p.name != ".auv-cosim.lock"  # a killed run's lock file: no data, unlocked
            }
        except FileNotFoundError:
            continue


@pytest.fixture
def earlier(test_fmu_dir: Path, tmp_path: Path) -> tuple[Path, dict[str, bytes | None]]:
    """A folder holding a complete earlier run (with its recording), and its tree."""
    out = tmp_path / "d"
    assert main(["run", str(write_loop_file(tmp_path, test_fmu_dir)), "--out", str(out)]) == 0
    return out, tree(out)


def broken_binary(test_fmu_dir: Path, folder: Path) -> Path:
    """``folder`` holding the test FMUs, the integrator's Linux binary replaced by bytes no
    loader takes."""
    shutil.copy(test_fmu_dir / "CosimTestGain.fmu", folder)
    fmu = folder / "CosimTestIntegrator.fmu"
    with zipfile.ZipFile(test_fmu_dir / fmu.name) as src, zipfile.ZipFile(fmu, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename.startswith("binaries/") and item.filename.endswith(".so"):
                data = b"not a shared library\n"
            dst.writestr(item, data)
    return folder


def stop_before_the_first_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """A stop signal arriving while the FMUs load: the loop ends at t = 0."""
    run = master.run

    def signalled(*args: Any, stop: StopRequest, **kwargs: Any) -> Any:
        stop.signum = signal.SIGTERM
        return run(*args, stop=stop, **kwargs)

    monkeypatch.setattr(master, "run", signalled)


LATE_EVENT = '[[events]]\nname = "late"\ntime = 1e308\nset = { "controller.k" = 3.0 }\n'
FAILURES = {  # how the new run fails before its first step -> its exit code
    "a binary that will not load": 1,
    "a first step that fails": 1,
    "a first step giving NaN": 1,
    "a stop signal while loading": 128 + signal.SIGTERM,
    "an event at t = 1e308": 1,
    "a real-time factor of 1e-300": 1,
}


def failing_run(
    failure: str, folder: Path, fmus: Path, monkeypatch: pytest.MonkeyPatch
) -> list[str]:
    """The arguments of a run that fails as ``failure`` says (files written to ``folder``)."""
    if failure == "a binary that will not load":
        return [str(write_loop_file(folder, broken_binary(fmus, folder)))]
    if failure == "a first step that fails":
        return [str(write_loop_file(folder, fmus, "fail_at = 0.0"))]
    if failure == "a first step giving NaN":
        return [str(write_loop_file(folder, fmus, "nan_at = 0.0"))]
    if failure == "a stop signal while loading":
        stop_before_the_first_step(monkeypatch)
    if failure == "an event at t = 1e308":
        return [str(write_loop_file(folder, fmus, extra=LATE_EVENT))]
    if failure == "a real-time factor of 1e-300":
        return [str(write_loop_file(folder, fmus)), "--real-time", "1e-300"]
    return [str(write_loop_file(folder, fmus))]


@pytest.mark.parametrize("failure", list(FAILURES))
def test_a_run_that_never_steps_leaves_the_earlier_run_as_it_was(
    failure: str,
    earlier: tuple[Path, dict[str, bytes | None]],
    test_fmu_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    """--overwrite emptied the folder before the new run was known to work: a binary that
    would not load, an event at t = 1e308 or --real-time 1e-300 left nothing of either
    run."""
    out, before = earlier
    new = tmp_path / "new"
    new.mkdir()
    arguments = failing_run(failure, new, test_fmu_dir, monkeypatch)
    command = ["run", *arguments, "--out", str(out), "--overwrite"]
    capsys.readouterr()
    try:
        returned = main(command)
    except OverflowError:  # a traceback of its own (not this test's concern): still no loss
        returned = 1
    assert returned == FAILURES[failure]
    assert tree(out) == before


def test_a_vehicle_the_plant_refuses_at_initialisation_leaves_the_earlier_run(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    vehicle = tmp_path / "bad-vehicle.toml"
    vehicle.write_text('base = "remus100"\nno_such_key = -5.0\n')
    text = (
        'id = "v"\nstop_time = 0.5\n[coupling]\nstep = 0.01\n[instances.plant]\n'
        f'fmu = "{fmu_paths["AuvPlant"]}"\n[instances.plant.start]\nvariant = "lateral"\n'
    )
    good, bad = tmp_path / "good.toml", tmp_path / "bad.toml"
    good.write_text(text)
    bad.write_text(text + f'vehicle = "{vehicle}"\n')
    out = tmp_path / "d"
    assert main(["run", str(good), "--out", str(out), "--no-rrd"]) == 0
    before = tree(out)
    capsys.readouterr()
    assert main(["run", str(bad), "--out", str(out), "--no-rrd", "--overwrite"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "unknown key 'no_such_key'" in err, err
    assert tree(out) == before


def test_a_binary_that_will_not_load_is_one_line_and_keeps_the_working_directory(
    test_fmu_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    """A broken FMU binary printed fmpy's traceback, left the process in the FMU's binary
    folder, and so (with a relative --out) left a stale lock, a "running" summary and a
    header-only results.csv: a killed run's look."""
    monkeypatch.chdir(tmp_path)
    scenario = write_loop_file(tmp_path, broken_binary(test_fmu_dir, tmp_path))
    assert main(["run", str(scenario), "--out", "fresh", "--no-rrd"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "plant: cannot load the binary of" in err, err
    assert Path.cwd() == tmp_path
    assert not (tmp_path / "fresh").exists()  # a folder the run created goes with it


def test_only_the_first_steps_rows_remove_the_earlier_run(
    earlier: tuple[Path, dict[str, bytes | None]],
    test_fmu_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """While the new run loads and initialises its FMUs, the earlier run's files are all
    still there (set aside, not removed); once it stepped, they are gone."""
    out, before = earlier
    seen: list[dict[str, bytes | None]] = []
    run = master.run

    def watched(*args: Any, **kwargs: Any) -> Any:
        aside = {k: v for k, v in tree(out).items() if k.endswith(ASIDE_SUFFIX)}
        seen.append({k[1:].rsplit(".", 2)[0]: v for k, v in aside.items()})
        return run(*args, **kwargs)

    monkeypatch.setattr(master, "run", watched)
    scenario = write_loop_file(tmp_path, test_fmu_dir)
    assert main(["run", str(scenario), "--out", str(out), "--overwrite"]) == 0
    assert seen == [before]  # every earlier file, byte for byte, while the new run loads
    assert not any(name.endswith(ASIDE_SUFFIX) for name in tree(out))


def run_command(scenario: Path, out: Path, *options: str) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", "run", str(scenario), "--out", str(out), *options],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip


def wait_until(condition: Callable[[], bool], proc: subprocess.Popen[str], what: str) -> None:
    deadline = time.monotonic() + 60.0
    while not condition():
        assert proc.poll() is None or what == "the guard", proc.communicate()
        assert time.monotonic() < deadline, f"no {what} within 60 s"
        time.sleep(0.02)


def rows_in(path: Path) -> int:
    """Lines in a results.csv being written (0 while there is none)."""
    try:
        return path.read_bytes().count(b"\n")
    except OSError:
        return 0


def manifest_pid(out: Path) -> int | None:
    """The pid in the folder's manifest (None while there is none)."""
    try:
        return int(json.loads((out / MANIFEST_FILE).read_text())["pid"])
    except (OSError, ValueError, KeyError):
        return None


@pytest.mark.slow
def test_a_run_killed_before_its_first_step_leaves_the_earlier_run_as_it_was(
    earlier: tuple[Path, dict[str, bytes | None]], test_fmu_dir: Path, tmp_path: Path
) -> None:
    """SIGKILL while the new run waits for its first step (paced at 1/1000 real time, the
    first step is due 100 s after the start): the tail guard puts the earlier run back."""
    out, before = earlier
    scenario = write_loop_file(tmp_path, test_fmu_dir)
    proc = run_command(scenario, out, "--overwrite", "--real-time", "0.001", "--quiet")
    try:
        wait_until(
            lambda: any(n.endswith(ASIDE_SUFFIX) for n in os.listdir(out)), proc, "set-aside"
        )
        wait_until(lambda: manifest_pid(out) == proc.pid, proc, "the new run's manifest")
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        wait_until(lambda: tree(out) == before, proc, "the guard")
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()


@pytest.mark.slow
def test_a_run_killed_before_its_first_step_leaves_its_folder_empty(
    test_fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """SIGKILL (the OOM killer, ``kill -9``) before a new folder's first run has stepped:
    nothing was computed, so its tail guard removes what the run created, and the same
    command runs again without --overwrite. (A run killed while it opened its outputs,
    before its summary.json, left a results.csv header and an empty recording that even
    --overwrite refused: "holds no earlier run".)"""
    out = tmp_path / "d"
    scenario = write_loop_file(tmp_path, test_fmu_dir)
    proc = run_command(scenario, out, "--real-time", "0.001", "--quiet")
    try:
        wait_until(lambda: manifest_pid(out) == proc.pid, proc, "the run's manifest")
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
        wait_until(lambda: tree(out) == {}, proc, "the guard")
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    deadline = time.monotonic() + 30.0
    while main(["run", str(scenario), "--out", str(out), "--no-rrd"]) != 0:
        error = capsys.readouterr().err
        assert "wait for that run to end" in error, error  # the guard, ending, holds the lock
        assert time.monotonic() < deadline, error
        time.sleep(0.2)


@pytest.mark.slow
def test_a_run_killed_while_stepping_is_replaced_with_overwrite(
    test_fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A killed run's files are cut whole by its tail guard, which records them in the
    manifest: --overwrite knows them as that run's."""
    out = tmp_path / "d"
    scenario = write_loop_file(tmp_path, test_fmu_dir)
    proc = run_command(scenario, out, "--real-time", "1", "--quiet", "--stop-time", "60")
    try:
        wait_until(lambda: rows_in(out / "results.csv") > 3, proc, "rows")
        os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGKILL)
        proc.communicate()
    deadline = time.monotonic() + 30.0
    while main(["run", str(scenario), "--out", str(out), "--overwrite", "--no-rrd"]) != 0:
        assert time.monotonic() < deadline, capsys.readouterr().err  # the guard may still run
        time.sleep(0.2)
    assert json.loads((out / "summary.json").read_text())["status"] == "complete"
