"""A run killed (SIGKILL, its tail guard with it: a job's cgroup killed, a power cut) in
the middle of saving a checkpoint: the new checkpoint.json and the manifest recording it
(with results.csv as of it) are two files, so the kill may fall between them. The folder
resumes, from the last checkpoint the manifest records whole, to the uninterrupted
results."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest
from process_group import run_in_group
from repo_paths import TESTS

# the run, its renames watched: at the second checkpoint, the run and its tail guard are
# SIGKILLed before the manifest recording it is saved ("unrecorded"), or just before
# ("before") or just after ("after") checkpoint.json is renamed into place
KILLED_WHILE_CHECKPOINTING = """
import os, signal, sys
sys.path.insert(0, sys.argv[1])
from killed_runs import _children
when, real, renamed = sys.argv[2], os.replace, []


def kill() -> None:
    for pid in _children(os.getpid()):  # the tail guard, in a session of its own
        os.kill(pid, signal.SIGKILL)
    os.kill(os.getpid(), signal.SIGKILL)


def replace(source, target):
    name, folder = os.path.basename(target), os.path.dirname(os.path.abspath(target))
    pending = any(n.startswith(".checkpoint.json.") for n in os.listdir(folder))
    if name == ".auv-cosim-run.json" and pending and len(renamed) == 1 and when == "unrecorded":
        kill()
    if name == "checkpoint.json":
        renamed.append(target)
    if len(renamed) == 2 and name == "checkpoint.json" and when == "before":
        kill()
    real(source, target)
    if len(renamed) == 2 and name == "checkpoint.json" and when == "after":
        kill()


os.replace = replace
from cosim.cli import main
sys.argv = ["auv-cosim", "run", *sys.argv[3:]]
main()
"""


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "cosim.cli", "run", *args, "--no-rrd"]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("when", "resumed_at"), [("unrecorded", 10), ("before", 20), ("after", 20)]
)
def test_a_run_killed_between_a_checkpoint_and_its_record_resumes(
    fmu_dir: Path, tmp_path: Path, when: str, resumed_at: int
) -> None:
    """Killed just after checkpoint.json was renamed into place and before the manifest
    recorded it, the folder was refused ("results.csv is not a file the earlier run wrote
    (changed since, replaced, or a link); resume the folder it was checkpointed in, or
    start the run again"), though it was that folder. The manifest records a checkpoint
    before it is renamed into place, and a resume finishes a rename the kill cut short:
    killed before the record, the run resumes from the checkpoint before (10 s), on
    either side of the rename from the new one (20 s), to the uninterrupted results."""
    common = ("--fmu-dir", str(fmu_dir), "--stop-time", "30")
    whole, killed = tmp_path / "whole", tmp_path / "killed"
    first = run_in_group(_cli("bs-3", "--out", str(whole), *common), timeout=600)
    assert first.returncode == 0, first.stderr
    args = ["bs-3", "--out", str(killed), *common, "--checkpoint-every", "10", "--quiet",
            "--no-rrd"]  # fmt: skip
    script = [sys.executable, "-c", KILLED_WHILE_CHECKPOINTING, str(TESTS), when, *args]
    done = run_in_group(script, timeout=600)
    assert done.returncode == -9, done.stderr
    resumed = run_in_group(_cli("--resume", str(killed), "--fmu-dir", str(fmu_dir)), timeout=600)
    assert resumed.returncode == 0, resumed.stderr
    assert f"resumed the run in {killed} at t = {resumed_at} s" in resumed.stderr
    assert (killed / "results.csv").read_bytes() == (whole / "results.csv").read_bytes()
