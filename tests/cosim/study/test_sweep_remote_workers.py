"""A study on a cluster of one's own whose workers cannot run it: a scheduler with no
worker, a worker whose Python lacks auv-cosim, a worker of another auv-cosim (an older
checkout on its PYTHONPATH), a worker that cannot write the study's FMUs. Each is refused
in one line naming the scheduler or the worker and what to do, before any run, leaving no
study folder behind and nothing of the study on the cluster. And a vehicle file that only
the client has reaches the workers."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from contextlib import nullcontext
from pathlib import Path

import pytest
from distributed import Client
from sweep_helpers import (
    PLANT_WITH_VEHICLE_FILE,
    VEHICLE_FILE,
    dask_processes,
    end_group,
    sweep,
    table,
    wait_for,
)
from test_sweep_lost_worker import rows_written

import cosim
from cosim.cli import main
from cosim.errors import CosimError
from cosim.scenario.design_doubts import DesignWarning
from cosim.study import execution, runner
from cosim.study.execution import FMU_FOLDER

pytestmark = [pytest.mark.cluster, pytest.mark.slow]  # each starts a Dask scheduler

NO_COSIM = 'raise ModuleNotFoundError("No module named \'cosim\'", name="cosim")\n'


def refused(study: Path, out: Path, fmu_dir: Path, options: list[str], capsys) -> str:
    """The one line ``auv-cosim sweep`` refuses the study with (exit 1, no traceback, no
    study folder left)."""
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet"]
    assert main([*argv, *options]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert not out.exists()
    return err


@pytest.mark.timeout(120)
def test_a_scheduler_without_workers_is_refused_naming_it(
    small_study: Path, fmu_dir: Path, tmp_path: Path, monkeypatch, capsys
) -> None:
    """A study sent to a scheduler no worker had joined waited forever, saying nothing."""
    monkeypatch.setattr(execution, "WORKER_WAIT_S", 2.0, raising=False)
    with dask_processes(tmp_path / "elsewhere", worker_envs=()) as cluster:
        err = refused(small_study, tmp_path / "out", fmu_dir, cluster.options, capsys)
    assert f"the Dask scheduler at {cluster.address} has no workers" in err, err
    assert f"dask worker {cluster.address} --nthreads 1" in err, err


def test_a_worker_without_auv_cosim_is_refused_naming_it(
    small_study: Path, fmu_dir: Path, tmp_path: Path, capsys
) -> None:
    """A worker started from a Python without auv-cosim ended the study in a traceback
    ending "Exception: ModuleNotFoundError("No module named 'cosim'")"."""
    hidden = tmp_path / "hidden" / "cosim"
    hidden.mkdir(parents=True)
    (hidden / "__init__.py").write_text(NO_COSIM)
    envs = [{"PYTHONPATH": str(hidden.parent)}]
    with dask_processes(tmp_path / "elsewhere", worker_envs=envs) as cluster:
        err = refused(small_study, tmp_path / "out", fmu_dir, cluster.options, capsys)
    assert "cannot import auv-cosim" in err and "No module named 'cosim'" in err, err
    assert "tcp://127.0.0.1:" in err and "install" in err, err


def test_a_worker_of_another_auv_cosim_is_refused_naming_it(
    small_study: Path, fmu_dir: Path, tmp_path: Path, capsys
) -> None:
    """A worker running another auv-cosim (an older checkout on its PYTHONPATH) ran the
    study's runs with its own code, silently: the table then depended on which worker
    ran a run."""
    other = tmp_path / "other"
    source = Path(cosim.__file__).parent
    shutil.copytree(source, other / "cosim", ignore=shutil.ignore_patterns("__pycache__"))
    with (other / "cosim" / "study" / "task.py").open("a", encoding="utf-8") as f:
        f.write("# another version\n")
    envs = [{}, {"PYTHONPATH": str(other)}]
    with dask_processes(tmp_path / "elsewhere", worker_envs=envs) as cluster:
        err = refused(small_study, tmp_path / "out", fmu_dir, cluster.options, capsys)
    assert "runs another auv-cosim" in err and str(other / "cosim") in err, err
    assert err.count("tcp://127.0.0.1:") == 2, err  # the scheduler, and the one odd worker


def studies_on(address: str) -> list[str]:
    """The study plugins the scheduler at ``address`` still hands to a worker that joins."""
    with Client(address, timeout=60) as client:
        names = client.run_on_scheduler(lambda dask_scheduler: list(dask_scheduler.worker_plugins))
    return [name for name in names if name.startswith("auv-cosim-study-")]


def test_a_worker_that_cannot_write_the_fmus_is_named_and_leaves_the_cluster_clean(
    small_study: Path, fmu_dir: Path, tmp_path: Path, capsys
) -> None:
    """A worker that cannot write the study's FMUs into its local directory (a full or
    read-only disk; here a file where their folder goes) ended the study in a traceback,
    and left the study's plugin on the scheduler: every worker joining later was handed
    it, and one without auv-cosim then failed to start."""
    with dask_processes(tmp_path / "elsewhere", worker_envs=[{}]) as cluster:
        with Client(cluster.address, timeout=60) as client:
            (folder,) = client.run(lambda dask_worker: dask_worker.local_directory).values()
        (Path(folder) / FMU_FOLDER).write_text("in the way")
        err = refused(small_study, tmp_path / "out", fmu_dir, cluster.options, capsys)
        assert studies_on(cluster.address) == []
    assert "cannot write the study's FMUs" in err and str(Path(folder) / FMU_FOLDER) in err, err
    assert "tcp://127.0.0.1:" in err, err


BY_FACTOR = (
    'scenario = "bs-3"\nstop_time = 0.5\n[grid]\n"plant.vehicle" = ["remus100", "myveh.toml"]\n'
)
BY_SCENARIO = 'scenario = "plant.toml"\n[grid]\n"plant.v_0" = [0.0, 0.05]\n'


@pytest.mark.parametrize("study_text", [BY_FACTOR, BY_SCENARIO], ids=["factor", "scenario"])
def test_a_vehicle_file_only_the_client_has_reaches_the_workers(
    study_text: str,
    fmu_dir: Path,
    fmu_paths: dict[str, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys,
) -> None:
    """A vehicle set named by a factor or by the scenario, on the client's disk only (here
    removed once the study has sent its runs' data), failed every run that read it, with
    "names no file (looked for <the worker's working folder>/myveh.toml)". (The factor
    gives the plant a vehicle its autopilot was not designed for: the study says so.)"""
    vehicle = tmp_path / "client" / "myveh.toml"
    vehicle.parent.mkdir()
    vehicle.write_text(VEHICLE_FILE)
    (vehicle.parent / "plant.toml").write_text(
        PLANT_WITH_VEHICLE_FILE.format(fmu=fmu_paths["AuvPlant"])
    )
    study = vehicle.parent / "study.toml"
    study.write_text(study_text)
    make_job = runner.make_job

    def then_gone(*args, **kwargs):  # the workers cannot read the client's disk
        made = make_job(*args, **kwargs)
        vehicle.unlink(missing_ok=True)
        return made

    monkeypatch.setattr(runner, "make_job", then_gone)
    mismatch = study_text == BY_FACTOR
    said = pytest.warns(DesignWarning, match="myveh.toml") if mismatch else nullcontext()
    with dask_processes(tmp_path / "elsewhere", worker_envs=[{}]) as cluster, said:
        sweep(study, tmp_path / "out", fmu_dir, *cluster.options)
    rows = table(tmp_path / "out")
    assert not vehicle.exists() and len(rows) == 2
    assert [row["error"] for row in rows] == ["", ""]
    assert all(row["status"] == "complete" for row in rows)


LONG = 'scenario = "bs-3"\nstop_time = 1500.0\n[grid]\n"plant.v_0" = [-0.1, -0.05, 0.05, 0.1]\n'
SWEEP_WAITING = """
import sys
from cosim.study import execution
execution.WORKER_WAIT_S = 2.0
from cosim.cli import main
from cosim.errors import CosimError
sys.exit(main(["sweep", *sys.argv[1:]]))
"""


def test_a_cluster_that_loses_every_worker_ends_the_study_keeping_its_rows(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A study whose cluster lost its last worker (killed with SIGKILL after the first
    row) waited forever without a word; it ends in one line naming the scheduler and how
    to go on, the finished rows kept for --resume."""
    study, out = tmp_path / "long.toml", tmp_path / "out"
    study.write_text(LONG)
    with dask_processes(tmp_path / "elsewhere", worker_envs=[{}]) as cluster:
        argv = [sys.executable, "-c", SWEEP_WAITING, str(study), "--out", str(out)]
        argv += ["--fmu-dir", str(fmu_dir), "--quiet", *cluster.options]
        proc = subprocess.Popen(argv, start_new_session=True, stderr=subprocess.PIPE, text=True)
        try:
            wait_for(lambda: rows_written(out / "runs.csv") >= 1 or proc.poll() is not None,
                     "the first row")  # fmt: skip
            (worker,) = cluster.workers
            os.killpg(worker.pid, signal.SIGKILL)
            _, err = proc.communicate(timeout=120)
        finally:
            end_group(proc, signal.SIGKILL)
    assert proc.returncode == 1 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"the Dask scheduler at {cluster.address} has no workers" in err, err
    kept = rows_written(out / "runs.csv")
    finished = f"{kept} finished run{'s' * (kept != 1)} kept"  # 1 run in the singular
    assert 1 <= kept < 4 and finished in err and "--resume" in err, err


def test_a_killed_study_s_plugin_is_removed_by_the_next_study(
    small_study: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """A study killed with SIGKILL (or whose machine went down) left its plugin, with
    every FMU it carried, on the scheduler and every worker for good: each later worker
    was handed it, one more for each killed study. The next study removes it."""
    study, out = tmp_path / "long.toml", tmp_path / "out"
    study.write_text(LONG)
    with dask_processes(tmp_path / "elsewhere") as cluster:
        argv = [sys.executable, "-m", "cosim.cli", "sweep", str(study), "--out", str(out)]
        argv += ["--fmu-dir", str(fmu_dir), "--quiet", *cluster.options]
        proc = subprocess.Popen(argv, start_new_session=True, stderr=subprocess.DEVNULL)
        try:
            wait_for(lambda: rows_written(out / "runs.csv") >= 1 or proc.poll() is not None,
                     "the first row")  # fmt: skip
        finally:
            end_group(proc, signal.SIGKILL)
        wait_for(lambda: len(studies_on(cluster.address)) == 1, "the killed study's plugin")
        sweep(small_study, tmp_path / "next", fmu_dir, *cluster.options)
        assert studies_on(cluster.address) == []


def test_the_python_api_sweeps_on_a_cluster_of_ones_own(
    fmu_dir: Path, tmp_path: Path, monkeypatch
) -> None:
    """``cosim.sweep`` ran on a local cluster only: a lab's notebook could not use its own
    Dask cluster, as ``auv-cosim sweep --scheduler`` does."""
    monkeypatch.chdir(tmp_path)
    study = {"scenario": "bs-3", "stop_time": 0.5, "grid": {"plant.v_0": [-0.1, 0.1]}}
    with dask_processes(tmp_path / "elsewhere", worker_envs=({},)) as cluster:
        with pytest.raises(CosimError, match=r"workers= .* or scheduler=, not both"):
            cosim.sweep(study, workers=1, scheduler=cluster.address, fmu_dir=fmu_dir)
        result = cosim.sweep(study, scheduler=cluster.address, fmu_dir=fmu_dir)
    assert sorted(result.table["plant.v_0"]) == [-0.1, 0.1]
    assert (result.table["status"] == "complete").all()
