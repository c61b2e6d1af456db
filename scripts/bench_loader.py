"""Benchmark the native loader's cost per communication step (fmu_runtime/native/).

The bs-3 pair (AuvPlant + AuvAutopilot) stepped by a bare fmpy loop doing what a master
does every 10 ms step (``fmi2GetReal`` of each FMU's outputs, ``fmi2SetReal`` of the other's
same-named inputs, ``fmi2DoStep``), twice in one process: once with the FMUs as built (the
loader in front of pythonfmu's library) and once with pythonfmu's library alone (copies of
the same FMUs with the loader removed; the same build, so one process runs both). Blocks of
``--steps`` steps alternate between the two for ``--rounds`` rounds (each goes first in
every other round); each block is timed
in CPU time of this thread (the machine's other load then matters less than for a wall
clock), and the ratio is the median of the rounds' ratios. Prints us per step of each
(median) and the ratio (target <= 1.03). For the loader's own share of the CPU time, a
profile is sharper than any A/B timing on a busy machine: ``perf record -g python ...``
then ``perf report --sort dso`` shows ``<model>.so`` (the loader) beside
``<model>_pythonfmu.so``.

Usage: ``python scripts/bench_loader.py [--steps 300] [--rounds 30] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
import zipfile
from pathlib import Path

from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from cosim.fmus.build import ensure_fmus
from cosim.paths import DEFAULT_FMU_DIR

H = 0.01  # s, bs-3's communication step


class Pair:
    """The plant (lateral variant) and the autopilot (backstepping) connected by name."""

    def __init__(self, plant: Path, autopilot: Path, label: str) -> None:
        self.slaves, self.links, self.k = [], [], 0
        inputs, outputs = [], []
        for path, start in ((plant, {"variant": 1}), (autopilot, {"heading_mode": 3})):
            md = read_model_description(str(path))
            slave = FMU2Slave(
                guid=md.guid,
                unzipDirectory=extract(str(path)),
                modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=f"{label} {path.stem}",
            )
            slave.instantiate()
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            refs = {v.name: v for v in md.modelVariables}
            for name, value in start.items():
                slave.setInteger([refs[name].valueReference], [value])
            slave.exitInitializationMode()
            self.slaves.append(slave)
            inputs.append(_real_refs(md, "input"))
            outputs.append(_real_refs(md, "output"))
        for to, other in ((0, 1), (1, 0)):
            names = sorted(set(inputs[to]) & set(outputs[other]))
            ins, outs = [inputs[to][n] for n in names], [outputs[other][n] for n in names]
            self.links.append((to, ins, other, outs))

    def run(self, steps: int) -> float:
        """CPU seconds of this thread for ``steps`` communication steps."""
        start = time.thread_time()
        for k in range(self.k, self.k + steps):
            values = [self.slaves[other].getReal(outs) for _, _, other, outs in self.links]
            for (to, ins, _, _), v in zip(self.links, values, strict=True):
                self.slaves[to].setReal(ins, v)
            for slave in self.slaves:
                slave.doStep(k * H, H)
        self.k += steps
        return time.thread_time() - start


def _real_refs(md, causality: str) -> dict[str, int]:
    return {
        v.name: v.valueReference
        for v in md.modelVariables
        if v.causality == causality and v.type == "Real"
    }


def without_loader(fmu: Path, folder: Path) -> Path:
    """A copy of ``fmu`` whose linux64 binary is pythonfmu's library alone."""
    copy = folder / fmu.name
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(copy, "w") as target:
        for info in source.infolist():
            if info.filename == f"binaries/linux64/{fmu.stem}.so":
                continue
            data = source.read(info)
            info.filename = info.filename.replace("_pythonfmu.so", ".so")
            target.writestr(info, data)
    return copy


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="steps per block [300]")
    parser.add_argument("--rounds", type=int, default=30, help="rounds of two blocks [30]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    fmus = ensure_fmus(args.fmu_dir)
    with tempfile.TemporaryDirectory(prefix="bench_loader_") as tmp:
        alone = [without_loader(fmus[n], Path(tmp)) for n in ("AuvPlant", "AuvAutopilot")]
        pairs = {
            "loader": Pair(fmus["AuvPlant"], fmus["AuvAutopilot"], "loader"),
            "pythonfmu alone": Pair(alone[0], alone[1], "alone"),
        }
        for pair in pairs.values():
            pair.run(100)  # warm-up
        times: dict[str, list[float]] = {name: [] for name in pairs}
        for r in range(args.rounds):  # ABBA: neither goes first every time
            for name in list(pairs)[:: 1 if r % 2 == 0 else -1]:
                times[name].append(pairs[name].run(args.steps) / args.steps)
    for name, seconds in times.items():
        print(f"{name}: {statistics.median(seconds) * 1e6:.1f} us CPU per bs-3 step (median)")
    ratios = [a / b for a, b in zip(times["loader"], times["pythonfmu alone"], strict=True)]
    print(
        f"loader / pythonfmu alone: {statistics.median(ratios):.3f} (median of {args.rounds}"
        " rounds; target <= 1.03)"
    )


if __name__ == "__main__":
    main()
