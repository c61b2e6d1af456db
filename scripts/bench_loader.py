"""Benchmark the FMUs' runtime's cost per communication step (fmu_runtime/native/).

The bs-3 pair (AuvPlant + AuvAutopilot) stepped by a bare fmpy loop doing what a master
does every 10 ms step (``fmi2GetReal`` of each FMU's outputs, ``fmi2SetReal`` of the other's
same-named inputs, ``fmi2DoStep``), three ways in one process: with the FMUs as built (the
runtime: values in C, one call into Python a step), with pythonfmu's library alone (copies
of the same FMUs with the runtime removed; the same build, so one process runs both), and
the FMI floor, two trivial pythonfmu FMUs of the same interface shape
(``scripts/bench_floor.py`` builds them) in the same loop. Blocks of ``--steps`` steps rotate
between the three for ``--rounds`` rounds (each goes first in turn); each block is timed
in CPU time of this thread (the machine's other load then matters less than for a wall
clock), and each ratio is the median of the rounds' ratios. Prints us per step of each
(median), the ratios, and the load average before and after. For the runtime's own share
of the CPU time, a profile is sharper than any A/B timing on a busy machine: ``perf record
-g python ...`` then ``perf report --sort dso`` shows ``<model>.so`` (the runtime) beside
``<model>_pythonfmu.so``.

Then ``fmi2SetRealInputDerivatives`` as a master that extrapolates quadratically calls it
on the plant once a step (orders 1 and 2 of its 8 inputs in one call): CPU time per call
with the runtime (answered in C) and with pythonfmu's binary behind it
(``AUV_FMU_RUNTIME=pythonfmu``: the runtime hands the call to the Python slave), each the
median of ``--rounds`` blocks of ``--steps`` calls.

Usage: ``python scripts/bench_loader.py [--steps 300] [--rounds 30] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import statistics
import tempfile
import time
import zipfile
from pathlib import Path

from bench_floor import floor_fmus
from bench_timing import load
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
from fmpy.model_description import ModelDescription

from cosim.fmus.build import ensure_fmus
from cosim.paths import DEFAULT_FMU_DIR

H = 0.01  # s, bs-3's communication step


class Pair:
    """The plant (lateral variant) and the autopilot (backstepping) connected by name; or
    any two FMUs whose same-named outputs and inputs are connected (``starts`` by name)."""

    def __init__(
        self, plant: Path, autopilot: Path, label: str, starts: tuple[dict, dict] | None = None
    ) -> None:
        self.slaves, self.links, self.k = [], [], 0
        inputs, outputs = [], []
        starts = starts or ({"variant": 1}, {"heading_mode": 3})
        for path, start in zip((plant, autopilot), starts, strict=True):
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


def _real_refs(md: ModelDescription, causality: str) -> dict[str, int]:
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


class TrivialPair(Pair):
    """The FMI floor: the trivial pythonfmu pair, its outputs ``y<i>`` to the other's
    inputs ``u<i>`` (what our pair exchanges: 8 plant inputs, 20 autopilot inputs)."""

    def __init__(self, folder: Path) -> None:
        controller, plant = floor_fmus(folder)
        fmus = [plant, controller]
        super().__init__(fmus[0], fmus[1], "floor", starts=({}, {}))
        plant_in, controller_in = (_real_refs(read_model_description(str(f)), "input")
                                   for f in fmus)  # fmt: skip
        plant_out, controller_out = (_real_refs(read_model_description(str(f)), "output")
                                     for f in fmus)  # fmt: skip
        self.links = [
            (0, list(plant_in.values()), 1, list(controller_out.values())[: len(plant_in)]),
            (1, list(controller_in.values()), 0, list(plant_out.values())[: len(controller_in)]),
        ]


def derivative_calls(plant: Path, runtime: str, calls: int, rounds: int) -> float:
    """Median CPU seconds of one fmi2SetRealInputDerivatives call on ``plant`` (orders 1
    and 2 of every Real input, the C function called as the master calls it) with
    ``AUV_FMU_RUNTIME=runtime``, over ``rounds`` blocks."""
    os.environ["AUV_FMU_RUNTIME"] = runtime  # read at instantiation
    try:
        pair = Pair(plant, plant, f"derivatives {runtime or 'runtime'}", starts=({}, {}))
    finally:
        os.environ.pop("AUV_FMU_RUNTIME")
    slave = pair.slaves[0]
    inputs = list(_real_refs(read_model_description(str(plant)), "input").values())
    n = 2 * len(inputs)  # as the master sends them: prebuilt arrays, the C function itself
    vrs = (ctypes.c_uint * n)(*inputs, *inputs)
    orders = (ctypes.c_int * n)(*([1] * len(inputs) + [2] * len(inputs)))
    values = (ctypes.c_double * n)(*([1e-3] * n))
    call, component = slave.dll.fmi2SetRealInputDerivatives, slave.component
    blocks = []
    for _ in range(rounds):
        start = time.thread_time()
        for _ in range(calls):
            if call(component, vrs, n, orders, values) != 0:
                raise SystemExit(f"fmi2SetRealInputDerivatives refused ({runtime or 'runtime'})")
        blocks.append((time.thread_time() - start) / calls)
    for each in pair.slaves:
        each.terminate()
        each.freeInstance()
    return statistics.median(blocks)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=300, help="steps per block [300]")
    parser.add_argument("--rounds", type=int, default=30, help="rounds of two blocks [30]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    fmus = ensure_fmus(args.fmu_dir)
    print(f"load {load()} at the start")
    with tempfile.TemporaryDirectory(prefix="bench_loader_") as tmp:
        alone = [without_loader(fmus[n], Path(tmp)) for n in ("AuvPlant", "AuvAutopilot")]
        pairs = {
            "runtime": Pair(fmus["AuvPlant"], fmus["AuvAutopilot"], "runtime"),
            "pythonfmu alone": Pair(alone[0], alone[1], "alone"),
            "trivial pair (floor)": TrivialPair(Path(tmp)),
        }
        for pair in pairs.values():
            pair.run(100)  # warm-up
        times: dict[str, list[float]] = {name: [] for name in pairs}
        names = list(pairs)
        for r in range(args.rounds):  # each goes first in turn
            for name in names[r % 3 :] + names[: r % 3]:
                times[name].append(pairs[name].run(args.steps) / args.steps)
    for name, seconds in times.items():
        print(f"{name}: {statistics.median(seconds) * 1e6:.1f} us CPU per step (median)")
    for label, (a, b), target in (
        ("runtime / pythonfmu alone", ("runtime", "pythonfmu alone"), ""),
        ("runtime / trivial pair", ("runtime", "trivial pair (floor)"), ""),
        ("pythonfmu alone / trivial pair", ("pythonfmu alone", "trivial pair (floor)"), ""),
    ):
        ratios = [x / y for x, y in zip(times[a], times[b], strict=True)]
        print(f"{label}: {statistics.median(ratios):.3f} (median of {args.rounds} rounds){target}")
    print(f"load {load()} at the end")
    plant = fmus["AuvPlant"]
    calls = {r: derivative_calls(plant, r, args.steps, args.rounds) for r in ("", "pythonfmu")}
    runtime_step = statistics.median(times["runtime"])
    print(f"fmi2SetRealInputDerivatives (plant, 16 values): runtime {calls[''] * 1e6:.2f} us "
          f"CPU per call ({calls[''] / runtime_step:.3f} of a runtime pair step), pythonfmu's "
          f"binary behind it {calls['pythonfmu'] * 1e6:.1f} us; load {load()}")  # fmt: skip


if __name__ == "__main__":
    main()
