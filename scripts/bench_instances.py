"""Memory kept per FMU instance: RSS growth over instantiate/free cycles.

For each FMU, in this process, through one fmpy ``FMU2Slave`` (the library loaded once,
as a host that creates and frees instances does): ``--warmup`` cycles, then ``--cycles``
cycles of fmi2Instantiate, setupExperiment, enter/exitInitializationMode, one doStep,
terminate and fmi2FreeInstance, with a full garbage collection before each reading.
Prints the growth of the resident set (``/proc/self/statm``, Linux) over the measured
cycles, per cycle, and the 2 MB per 1,000 cycles budget scaled to ``--cycles``:

    AuvPlant: 1000 cycles grow RSS by 1.02 MB (1.0 KiB per cycle; budget 2.00 MB)

What remains is pythonfmu 0.7's own, about 1 KiB per fmi2Instantiate (the MRO list and
class reprs it never releases and the ``resources`` string; see fmu_runtime/entry.py).
Before the entry module stopped redefining the slave class, each cycle kept about 47 KiB
(plant) and 26 KiB (autopilot).

Usage: python scripts/bench_instances.py [--fmu-dir build/fmus] [--cycles 1000]
                                         [--warmup 50] [--fmu AuvPlant ...]
"""

from __future__ import annotations

import argparse
import gc
import os
import shutil
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from cosim.fmus.build import FMUS, build_fmu

BUDGET_MB_PER_1000 = 2.0


def rss_mb() -> float:
    """The resident set size of this process, MB (2**20 bytes)."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def growth_mb(fmu: Path, cycles: int, warmup: int) -> float:
    """RSS growth over ``cycles`` instantiate/free cycles of ``fmu`` after ``warmup``."""
    md = read_model_description(str(fmu))
    unzipped = extract(str(fmu))
    try:
        slave = FMU2Slave(
            guid=md.guid,
            unzipDirectory=unzipped,
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName="bench",
        )
        step = float(md.defaultExperiment.stepSize)

        def cycle() -> None:
            slave.instantiate()
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            slave.doStep(0.0, step)
            slave.terminate()
            slave.fmi2FreeInstance(slave.component)  # fmpy's freeInstance also unloads

        for _ in range(warmup):
            cycle()
        gc.collect()
        before = rss_mb()
        for _ in range(cycles):
            cycle()
        gc.collect()
        return rss_mb() - before
    finally:
        shutil.rmtree(unzipped, ignore_errors=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus"))
    parser.add_argument("--cycles", type=int, default=1000)
    parser.add_argument("--warmup", type=int, default=50)
    parser.add_argument("--fmu", action="append", choices=sorted(FMUS), help="default: both")
    args = parser.parse_args()
    budget = BUDGET_MB_PER_1000 * args.cycles / 1000
    for name in args.fmu or list(FMUS):
        growth = growth_mb(build_fmu(name, args.fmu_dir), args.cycles, args.warmup)
        print(
            f"{name}: {args.cycles} cycles grow RSS by {growth:.2f} MB "
            f"({growth * 1024 / args.cycles:.1f} KiB per cycle; budget {budget:.2f} MB)",
            flush=True,
        )


if __name__ == "__main__":
    main()
