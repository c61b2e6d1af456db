"""Benchmark checkpoints: bs-3 for 120 s with a checkpoint every 10 simulated seconds
against the same run with none, alternated in one process (``--rounds`` of each, no
recording, through ``run_scenario``, what ``auv-cosim run --no-rrd`` does). Prints each
round's stepping-loop CPU time (the process's, which other processes' load inflates far
less than the wall clock) and the ratio of the medians, with checkpoints over without,
and the checkpoint file's size.

Usage: ``python scripts/bench_checkpoint.py [--rounds 5] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.paths import DEFAULT_FMU_DIR
from cosim.runner import run_scenario

STOP_TIME = 120.0  # s of bs-3
EVERY = 10.0  # s between checkpoints


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    cpu: dict[str, list[float]] = {"none": [], "every 10 s": []}
    size = 0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.rounds):
            for label, every in (("none", None), ("every 10 s", EVERY)):
                out = Path(tmp) / f"{i}-{every}"
                outcome = run_scenario("bs-3", out, stop_time=STOP_TIME, no_rrd=True,
                                       fmu_dir=args.fmu_dir, checkpoint_every=every)  # fmt: skip
                assert outcome.result.complete, outcome.result.error
                cpu[label].append(outcome.result.cpu_clock_s)
                if every is not None:
                    size = (out / CHECKPOINT_FILE).stat().st_size
            print(f"round {i + 1}: " + ", ".join(f"{k} {v[-1]:.3f} s" for k, v in cpu.items()))
    with_, without = statistics.median(cpu["every 10 s"]), statistics.median(cpu["none"])
    each = (with_ - without) / (STOP_TIME / EVERY) * 1e3
    print(f"stepping-loop CPU, median of {args.rounds}: checkpoints every {EVERY:g} s / none "
          f"= {with_ / without:.3f} ({STOP_TIME:g} s of bs-3, {without:.3f} s without; "
          f"{each:.1f} ms a checkpoint; checkpoint.json {size} bytes)")  # fmt: skip


if __name__ == "__main__":
    main()
