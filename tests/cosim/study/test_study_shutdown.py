"""A study that succeeds ends quietly: no Dask traceback reaches its stderr, however its
local cluster closes. Several studies at once, on more workers than cores, each in its
own `auv-cosim sweep` process as a user starts them; and, every time, a local cluster
closed while each worker's heartbeat waits for the scheduler's answer."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from process_group import run_in_group

pytestmark = [pytest.mark.slow, pytest.mark.cluster]

STUDY = """
scenario = "bs-3"
stop_time = 1.0
[grid]
"plant.v_0" = [-0.10, -0.05, 0.05, 0.10]
"""
ROUNDS = 3  # of two studies at once: 6 studies (2 of 11 ended with a traceback before)
NOISE = ("Traceback", "heartbeat", "CommClosedError", "distributed.")


def _sweep(study: Path, fmu_dir: Path, out: Path) -> subprocess.Popen[str]:
    """`auv-cosim sweep STUDY` on 3 local workers (beyond the cores), in its own session."""
    command = ["sweep", str(study), "--fmu-dir", str(fmu_dir), "--out", str(out)]
    command += ["--workers", "3", "--oversubscribe", "--quiet"]
    return subprocess.Popen(
        [sys.executable, "-m", "cosim.cli", *command], stdout=subprocess.PIPE,
        stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip


def test_studies_at_once_on_too_many_workers_end_without_a_traceback(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A successful study sometimes ended with a worker's "Failed to communicate with
    scheduler during heartbeat" CommClosedError traceback, exit 0: the worker closed its
    connections to the scheduler while a heartbeat was waiting for the answer."""
    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    for i in range(ROUNDS):
        sweeps = [_sweep(study, fmu_dir, tmp_path / f"out-{i}-{k}") for k in range(2)]
        try:
            done = [proc.communicate(timeout=600) for proc in sweeps]
        finally:
            for proc in sweeps:
                with contextlib.suppress(ProcessLookupError):  # a worker left behind too
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
        for proc, (out, err) in zip(sweeps, done, strict=True):
            assert proc.returncode == 0, err
            assert "4 runs, 4 complete" in out
            assert not any(word in err for word in NOISE), err


SLOW_ANSWER = """
import asyncio, time
from cosim.study.execution import open_client

if __name__ == "__main__":
    with open_client(2) as client:
        scheduler = client.cluster.scheduler  # in this process, on the cluster's loop
        answer = scheduler.handlers["heartbeat_worker"]

        async def slowly(**message):
            await asyncio.sleep(1.0)
            return answer(**message)

        scheduler.handlers["heartbeat_worker"] = slowly
        time.sleep(1.5)  # every worker's next heartbeat is now waiting for its answer
    print("closed")
"""


def test_a_cluster_closed_while_heartbeats_wait_for_their_answer_ends_quietly(
    tmp_path: Path,
) -> None:
    """The cause of the heartbeat traceback, made certain: the scheduler answers each
    heartbeat a second late, and the cluster closes while every worker waits for that
    answer. A worker closed its connection to the scheduler under the waiting heartbeat
    and logged "Failed to communicate with scheduler during heartbeat" (CommClosedError)."""
    returncode, out, err = _run_script(tmp_path / "slow_answer.py", SLOW_ANSWER)
    assert returncode == 0 and out.strip() == "closed", err
    assert not any(word in err for word in NOISE), err


LATE_MESSAGE = """
import asyncio, logging
from distributed import Scheduler
from cosim.study.execution import open_client

close = Scheduler.close

async def close_then_log(self, *args, **kwargs):
    result = await close(self, *args, **kwargs)
    # what a batched stream does when its connection closed under it (INFO, with the
    # CommClosedError's traceback), on the cluster's loop as soon as the closing yields
    asyncio.get_running_loop().call_soon(
        logging.getLogger("distributed.batched").info, "Batched Comm Closed"
    )
    return result

Scheduler.close = close_then_log

if __name__ == "__main__":
    with open_client(1) as client:
        pass
    print("closed")
"""


def test_a_message_after_the_scheduler_closed_stays_off_stderr(tmp_path: Path) -> None:
    """Dask's own silencing of a local cluster's messages ended as soon as its scheduler
    had closed, while the cluster's loop still ran what was pending: a batched stream
    whose connection had closed then logged "Batched Comm Closed" with a CommClosedError
    traceback on a successful study's stderr (1 of ~90 studies here, several at once)."""
    returncode, out, err = _run_script(tmp_path / "late_message.py", LATE_MESSAGE)
    assert returncode == 0 and out.strip() == "closed", err
    assert not any(word in err for word in NOISE), err


PLUGIN_GONE = """
from cosim.study.execution import open_client, run_on_worker

if __name__ == "__main__":
    with open_client(1) as client:
        record = client.submit(run_on_worker, "auv-cosim-study-gone", {}, pure=False).result()
    print(record.status, record.error)
"""


def test_a_run_that_starts_after_its_study_ended_ends_quietly(tmp_path: Path) -> None:
    """A study stopped by a signal removes its worker plugin while a worker may still hold
    runs it was handed: each started, found no plugin and failed with a KeyError, which
    the worker logged ("Compute Failed", one traceback per run) on the study's stderr
    after its one-line message. The runs left are cancelled first, and a run that starts
    all the same returns a failed record nobody waits for."""
    returncode, out, err = _run_script(tmp_path / "plugin_gone.py", PLUGIN_GONE)
    assert returncode == 0, err
    assert out.strip() == "failed the study ended before this run started"
    assert "Compute Failed" not in err and "Traceback" not in err, err


def _run_script(script: Path, code: str) -> tuple[int, str, str]:
    """Write ``code`` to ``script`` and run it in a fresh process in its own session (the
    project's packages on its path): its return code, stdout and stderr. Its process
    group is killed at the end, whatever happened."""
    script.write_text(code, encoding="utf-8")
    env = {**os.environ, "PYTHONPATH": _packages()}
    done = run_in_group([sys.executable, str(script)], timeout=300, env=env)
    return done.returncode, done.stdout, done.stderr


def _packages() -> str:
    """PYTHONPATH for a script outside the repository: the project's packages first."""
    import cosim

    root = str(Path(cosim.__file__).resolve().parents[1])
    return os.pathsep.join(filter(None, [root, os.environ.get("PYTHONPATH")]))
