"""How closely a paced run keeps to real time (docs/live-runs.md, Accuracy).

Runs ``auv-cosim run bs-3 --real-time F --stop-time T`` (with its recording) for
(F, T) = (1, 30 s) and (10, 300 s) -- the same wall clock, 30 s, each -- and prints the
wall clock of the stepping loop against T / F, the late steps, the maximum lateness and
the load average (``os.getloadavg``) before and after.

Usage: ``python scripts/bench_real_time.py [--fmu-dir DIR] [--factor F --stop-time T]``.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from cosim.paths import DEFAULT_FMU_DIR


def paced_run(fmu_dir: Path, factor: float, stop_time: float) -> str:
    """One paced run in a fresh process; its figures as one line."""
    load = os.getloadavg()
    with tempfile.TemporaryDirectory() as folder:
        command = [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--quiet",
                   "--out", folder, "--fmu-dir", str(fmu_dir),
                   "--real-time", str(factor), "--stop-time", str(stop_time)]  # fmt: skip
        done = subprocess.run(command, capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise SystemExit(f"the run failed: {done.stderr.strip()}")
        summary = json.loads((Path(folder) / "summary.json").read_text())
    paced, wall, target = summary["real_time"], summary["wall_clock_s"], stop_time / factor
    return (
        f"{factor:g}x over {stop_time:g} s: wall clock {wall:.3f} s for {target:g} s "
        f"({100 * (wall - target) / target:+.2f} %), achieved {paced['achieved_factor']:.4f}x, "
        f"{paced['late_steps']} of {summary['rows'] - 1} steps late, at most "
        f"{1e3 * paced['max_lateness_s']:.1f} ms (at t = {paced['max_lateness_at_s']} s); "
        "load average "
        f"{load[0]:.2f} before, {os.getloadavg()[0]:.2f} after (1 min, {os.cpu_count()} cores)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    parser.add_argument("--factor", type=float, help="one run at this factor ...")
    parser.add_argument("--stop-time", type=float, help="... over this simulated time, s")
    args = parser.parse_args()
    cases = [(1.0, 30.0), (10.0, 300.0)]
    if args.factor is not None:
        cases = [(args.factor, args.stop_time or 30.0 * args.factor)]
    for factor, stop_time in cases:
        print(paced_run(args.fmu_dir, factor, stop_time), flush=True)


if __name__ == "__main__":
    main()
