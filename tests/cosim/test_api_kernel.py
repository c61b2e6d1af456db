"""The Python API in a real Jupyter kernel: what a notebook's stop button does to a sweep.

The kernel is started by jupyter_client in its own process group (its default on POSIX) and
that group is killed at the end, also when an assertion fails."""

from __future__ import annotations

import contextlib
import os
import queue
import signal
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import cosim

jupyter_client = pytest.importorskip("jupyter_client", reason="needs jupyter_client (dev extra)")
pytest.importorskip("ipykernel", reason="needs ipykernel (dev extra)")
psutil = pytest.importorskip("psutil", reason="needs psutil")

REPLY_TIMEOUT_S = 600  # a busy machine; not a measurement
SWEEP = """
import cosim
grid = {{"plant.v_0": [round(-0.1 + 0.02 * i, 2) for i in range(10)]}}
study = {{"scenario": "bs-3", "stop_time": 30.0, "grid": grid}}
cosim.sweep(study, workers=1, out="study", fmu_dir={fmu_dir!r})
"""


@pytest.fixture
def kernel(tmp_path: Path) -> Iterator[tuple[Any, Any]]:
    """A started kernel importing this checkout's cosim, in ``tmp_path``, and its client."""
    env = dict(os.environ, PYTHONPATH=str(Path(cosim.__file__).resolve().parents[1]))
    manager = jupyter_client.KernelManager(kernel_name="python3")
    manager.start_kernel(env=env, cwd=str(tmp_path))
    pid = manager.provisioner.process.pid
    client = manager.client()
    try:
        client.start_channels()
        client.wait_for_ready(timeout=REPLY_TIMEOUT_S)
        yield manager, client
    finally:
        client.stop_channels()
        with contextlib.suppress(Exception):
            manager.shutdown_kernel(now=True)
        with contextlib.suppress(ProcessLookupError):
            os.killpg(pid, signal.SIGKILL)


def _outputs(client: Any, msg_id: str, on_wait: Any = None) -> list[dict[str, Any]]:
    """The iopub messages of the cell ``msg_id`` until the kernel is idle again;
    ``on_wait()`` is called whenever no message came for 0.1 s."""
    messages = []
    deadline = time.monotonic() + REPLY_TIMEOUT_S
    while time.monotonic() < deadline:
        try:
            message = client.get_iopub_msg(timeout=0.1)
        except queue.Empty:
            if on_wait is not None:
                on_wait()
            continue
        if message["parent_header"].get("msg_id") != msg_id:
            continue
        if message["msg_type"] == "status" and message["content"]["execution_state"] == "idle":
            return messages
        messages.append(message)
    raise AssertionError(f"the cell did not end within {REPLY_TIMEOUT_S} s: {messages}")


@pytest.mark.cluster
@pytest.mark.slow
def test_a_notebooks_stop_button_ends_a_sweep_keeping_its_rows_and_no_worker(
    tmp_path: Path, fmu_paths: dict[str, Path], kernel: tuple[Any, Any]
) -> None:
    """Interrupting the kernel during cosim.sweep ended the cell in a KeyboardInterrupt
    traceback from inside Dask, saying nothing of the runs already finished."""
    manager, client = kernel
    runs_csv = tmp_path / "study" / "runs.csv"
    interrupted = []

    def interrupt_after_the_first_row() -> None:
        if not interrupted and runs_csv.is_file() and len(runs_csv.read_bytes().splitlines()) > 1:
            manager.interrupt_kernel()  # the notebook's stop button
            interrupted.append(True)

    fmu_dir = str(fmu_paths["AuvPlant"].parent)
    cell_text = SWEEP.format(fmu_dir=fmu_dir)
    cell = client.execute(cell_text)
    messages = _outputs(client, cell, interrupt_after_the_first_row)
    errors = [m["content"] for m in messages if m["msg_type"] == "error"]
    assert interrupted and len(errors) == 1, messages
    assert errors[0]["ename"] == "SweepInterrupted", errors[0]
    kept = len(runs_csv.read_bytes().splitlines()) - 1
    runs = f"{kept} finished run{'s' * (kept != 1)}"  # 1 run in the singular
    assert errors[0]["evalue"].startswith(f"interrupted (Ctrl-C): {runs} kept")
    assert 1 <= kept < 10

    # the study stopped its workers: the kernel's children are its fork server and
    # multiprocessing's resource tracker, with no worker forked from the server left
    kernel_process = psutil.Process(manager.provisioner.process.pid)
    forked = [p for c in kernel_process.children() for p in c.children(recursive=True)]
    _, alive = psutil.wait_procs(forked, timeout=60)
    assert alive == [], [p.cmdline() for p in alive]

    resumed = client.execute(cell_text.replace('out="study"', 'out="study", resume=True'))
    messages = _outputs(client, resumed)
    assert not [m for m in messages if m["msg_type"] == "error"], messages
    assert len(runs_csv.read_bytes().splitlines()) == 1 + 10
