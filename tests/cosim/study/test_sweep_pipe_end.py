"""``auv-cosim sweep`` ends its workers' fork server itself once its cluster has closed:
the server no longer outlives the command, holding its stderr (a pipe reading the command,
``| tee`` or a CI log, waited for it to end: 0.03-0.08 s after the command, under load).

A wrapper, made the subreaper of what the sweep leaves behind (Linux's
``PR_SET_CHILD_SUBREAPER``), runs the sweep with its stderr to a pipe, names the sweep's
children while it runs and, once the sweep has exited, prints those of them handed over to
it: the processes still alive (or not yet reaped by the sweep) when the sweep ended."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from process_group import run_in_group

from cosim.study import fork_server

pytestmark = [
    pytest.mark.slow,
    pytest.mark.cluster,
    pytest.mark.skipif(
        not sys.platform.startswith("linux") or not fork_server.available(),
        reason="a subreaper and /proc: Linux only",
    ),
]

STUDY = 'scenario = "bs-3"\nstop_time = 1.0\n[grid]\n"plant.v_0" = [-0.05, 0.05]\n'
WRAPPER = """
import ctypes, os, subprocess, sys, threading, time
from pathlib import Path

ctypes.CDLL(None, use_errno=True).prctl(36, 1, 0, 0, 0)  # PR_SET_CHILD_SUBREAPER
read, write = os.pipe()
sweep = subprocess.Popen([sys.executable, "-m", "cosim.cli", "sweep", *sys.argv[1:]],
                         stdout=subprocess.DEVNULL, stderr=write)
os.close(write)
names, ended, status = {}, threading.Event(), []


def wait():
    status.append(os.waitpid(sweep.pid, 0)[1])
    ended.set()


threading.Thread(target=wait).start()
while not ended.wait(0.05):
    for task in Path(f"/proc/{sweep.pid}/task").glob("*/children"):
        for child in task.read_text().split() if task.exists() else []:
            try:
                line = Path(f"/proc/{child}/cmdline").read_bytes()
            except OSError:
                continue
            names.setdefault(int(child), line.replace(b"\\0", b" ").decode()[:120])
left = Path(f"/proc/{os.getpid()}/task/{os.getpid()}/children").read_text().split()
for pid in left:
    print("left:", names.get(int(pid), "?"), flush=True)
while err := os.read(read, 65536):
    sys.stderr.buffer.write(err)
for pid in left:
    os.waitpid(int(pid), 0)
sys.exit(os.waitstatus_to_exitcode(status[0]))
"""


@pytest.mark.parametrize("resumed", [False, True], ids=["fresh", "resumed"])
def test_the_sweep_ends_its_fork_server_before_it_exits(
    fmu_dir: Path, tmp_path: Path, resumed: bool
) -> None:
    """A fresh sweep and a resumed one (its cluster opened late, once the runs left are
    known) alike; the wrapper exits with the sweep's code."""
    study = tmp_path / "study.toml"
    study.write_text(STUDY, encoding="utf-8")
    wrapper = tmp_path / "wrapper.py"
    wrapper.write_text(WRAPPER, encoding="utf-8")
    out = tmp_path / "out"
    args = [str(study), "--fmu-dir", str(fmu_dir), "--out", str(out)]
    if resumed:  # a study whose last run is left to run
        sweep = [sys.executable, "-m", "cosim.cli", "sweep", *args, "--workers", "1", "--quiet"]
        assert run_in_group(sweep, timeout=600).returncode == 0
        table = out / "runs.csv"
        table.write_text("".join(table.read_text("utf-8").splitlines(True)[:-1]), "utf-8")
        args.append("--resume")
    done = run_in_group([sys.executable, str(wrapper), *args, "--workers", "2", "--quiet"],
                        timeout=600)  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert "multiprocessing.forkserver" not in done.stdout, done.stdout


def test_the_wrapper_sees_what_a_command_leaves(tmp_path: Path) -> None:
    """The wrapper itself: a child the command does not wait for is handed over to it."""
    wrapper = tmp_path / "wrapper.py"
    wrapper.write_text(WRAPPER.replace('"-m", "cosim.cli", "sweep", ', ""), encoding="utf-8")
    script = tmp_path / "leaves.py"
    script.write_text(
        "import subprocess, sys, time\n"
        "subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(1)', 'orphan'])\n"
        "time.sleep(0.5)\n",
        encoding="utf-8",
    )
    done = run_in_group([sys.executable, str(wrapper), str(script)], timeout=60,
                        stderr=subprocess.STDOUT)  # fmt: skip
    assert "left:" in done.stdout and "orphan" in done.stdout, done.stdout
