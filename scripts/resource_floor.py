"""The least address space (``ulimit -v``) in which a run and a study complete, found by
bisection, and each one's peak resident memory: the figures of docs/runs.md's
"Resources" and of :mod:`cosim.limits`.

    python scripts/resource_floor.py [--step-mb 50] [--fmu-dir build/fmus]

Each try is the command in a fresh temporary folder under the limit (set in the child
before it starts), ended after 120 s (a library that spins for want of memory counts as a
failure), with the refusal of :mod:`cosim.limits` lifted in it (its limit read as none),
so that the figures it states are measured, not echoed. Takes some minutes: a few dozen
short runs."""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from pathlib import Path

MB = 1 << 20
TRY_S = 120.0  # s; a try that takes longer is a failure (a hang)
STUDY = 'scenario = "bs-3"\nstop_time = 5.0\n[grid]\n"plant.v_0" = [-0.1, 0.1]\n'
COMMANDS = {  # what is measured -> the command's arguments after `python -m cosim`
    "run bs-3 (with its recording)": ["run", "bs-3", "--out", "r"],
    "run bs-3 --no-rrd": ["run", "bs-3", "--no-rrd", "--out", "r"],
    "sweep (2 runs, local workers)": ["sweep", "s.toml", "--quiet", "--out", "s"],
}


# the command, its refusal lifted, printing its peak resident memory (kB) and that of its
# children (a study's workers) last on stderr
CHILD = """
import resource, sys
import cosim.limits
cosim.limits.address_space_limit = lambda: None
from cosim.cli import main
code = main(sys.argv[1:])
usage = (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN)
print("peak", max(resource.getrusage(who).ru_maxrss for who in usage), file=sys.stderr)
sys.exit(code)
"""


def _limited(limit: int) -> Callable[[], None]:
    def apply() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    return apply


def attempt(args: Sequence[str], fmu_dir: Path, limit_mb: int | None) -> float | None:
    """The peak resident memory in MB (the largest process) of ``auv-cosim ARGS`` run in a
    temporary folder under ``limit_mb`` MB of address space (None: no limit), or None if
    it failed or took more than :data:`TRY_S` s."""
    limit = None if limit_mb is None else _limited(limit_mb * MB)
    with tempfile.TemporaryDirectory() as folder:
        (Path(folder) / "s.toml").write_text(STUDY)
        command = [sys.executable, "-c", CHILD, *args, "--fmu-dir", str(fmu_dir)]
        try:
            done = subprocess.run(
                command, cwd=folder, capture_output=True, text=True, timeout=TRY_S,
                preexec_fn=limit, start_new_session=True,
            )  # fmt: skip
        except subprocess.TimeoutExpired:
            return None
    last = done.stderr.split()[-2:]
    if done.returncode != 0 or len(last) != 2 or last[0] != "peak":
        return None
    return int(last[1]) / 1024


def completes(args: Sequence[str], fmu_dir: Path, limit_mb: int) -> bool:
    """Whether ``auv-cosim ARGS`` completes under ``limit_mb`` MB of address space."""
    return attempt(args, fmu_dir, limit_mb) is not None


def floor_mb(args: Sequence[str], fmu_dir: Path, low: int, high: int, step: int) -> int:
    """The least limit in MB, to ``step``, at which the command completes, between ``low``
    (assumed to fail) and ``high`` (checked to complete)."""
    if not completes(args, fmu_dir, high):
        raise SystemExit(f"{' '.join(args)} fails even at {high} MB")
    while high - low > step:
        middle = (low + high) // 2
        low, high = (low, middle) if completes(args, fmu_dir, middle) else (middle, high)
    return high


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step-mb", type=int, default=50, help="MB [%(default)s]")
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus").resolve())
    parser.add_argument("--high-mb", type=int, default=8000, help="MB [%(default)s]")
    args = parser.parse_args()
    fmu_dir = args.fmu_dir.resolve()
    for name, command in COMMANDS.items():
        least = floor_mb(command, fmu_dir, 500, args.high_mb, args.step_mb)
        peak = attempt(command, fmu_dir, None)
        shown = "?" if peak is None else f"{peak:.0f}"
        print(f"{name}: completes in {least} MB of address space, peak resident {shown} MB")


if __name__ == "__main__":
    main()
