"""Peak memory of a run against its stop time: vert-2 at 3600 s and at 60 s.

Each run is ``auv-cosim run vert-2 --stop-time T`` (recording included, as users run it) in a
fresh process; its peak resident set size is the kernel's ``ru_maxrss`` for that child
(``os.wait4``). The rows stream to results.csv and the recording, so memory should not grow
with the stop time (the target: the 3600 s run within 50 MB of the 60 s one).
Prints both peaks, their difference and ratio.

Usage: python scripts/bench_memory.py [--long 3600] [--short 60] [--scenario vert-2]
       [--fmu-dir build/fmus] [--no-rrd]
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from cosim.paths import DEFAULT_FMU_DIR

TARGET_MB = 50.0


def peak_rss_mb(scenario: str, stop_time: float, out: Path, fmu_dir: Path, *options: str) -> float:
    """Peak RSS (MB) of one ``auv-cosim run`` process; raises if the run fails."""
    command = [sys.executable, "-m", "cosim.cli", "run", scenario, "--stop-time", str(stop_time)]
    command += ["--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet", *options]
    with tempfile.TemporaryFile() as errors:
        proc = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=errors)
        _, status, usage = os.wait4(proc.pid, 0)
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            errors.seek(0)
            raise SystemExit(f"{scenario} at {stop_time} s failed: {errors.read().decode()}")
    return usage.ru_maxrss / 1024.0  # kB on Linux


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--long", type=float, default=3600.0, help="s [3600]")
    parser.add_argument("--short", type=float, default=60.0, help="s [60]")
    parser.add_argument("--scenario", default="vert-2")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    parser.add_argument("--no-rrd", action="store_true", help="runs without the recording")
    args = parser.parse_args()
    options = ("--no-rrd",) if args.no_rrd else ()
    with tempfile.TemporaryDirectory(prefix="bench_memory_") as tmp:
        folder = Path(tmp)
        short = peak_rss_mb(args.scenario, args.short, folder / "short", args.fmu_dir, *options)
        long = peak_rss_mb(args.scenario, args.long, folder / "long", args.fmu_dir, *options)
    print(f"{args.scenario}: peak RSS {short:.0f} MB at {args.short:g} s, {long:.0f} MB at "
          f"{args.long:g} s: {long - short:+.0f} MB, ratio {long / short:.3f} "
          f"(target: within {TARGET_MB:g} MB)")  # fmt: skip


if __name__ == "__main__":
    main()
