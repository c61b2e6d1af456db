"""Benchmark the native loader's cost per communication step (fmu_runtime/native/).

The bs-3 pair (AuvPlant + AuvAutopilot, backstepping) stepped by a bare fmpy loop doing
what a master does every 10 ms step (``fmi2SetReal`` of each FMU's inputs from the other's
same-named outputs, ``fmi2DoStep``, ``fmi2GetReal`` of the outputs), once with the FMUs as
built (the loader in front of pythonfmu's library) and once with pythonfmu's library alone
(the loader removed from copies of the same FMUs). Each timing runs in a fresh process
(pythonfmu keeps its modules per process), times ``--steps`` steps after 200 warm-up steps,
and is the best of ``--repeat`` rounds, interleaved to damp other load. Prints us per step
of each and the ratio (target <= 1.03).

Usage: ``python scripts/bench_loader.py [--steps 3000] [--repeat 3] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

from cosim.fmus.build import ensure_fmus
from cosim.paths import DEFAULT_FMU_DIR

LOOP = """
import sys, time
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

paths, steps = sys.argv[1:3], int(sys.argv[3])
slaves, inputs, outputs = [], [], []
for path, start in zip(paths, ({"variant": 1}, {"heading_mode": 3})):
    md = read_model_description(path)
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(path),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName=path)
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    variables = {v.name: v for v in md.modelVariables}
    for name, value in start.items():
        slave.setInteger([variables[name].valueReference], [value])
    slave.exitInitializationMode()
    slaves.append(slave)
    inputs.append({v.name: v.valueReference for v in md.modelVariables
                   if v.causality == "input" and v.type == "Real"})
    outputs.append({v.name: v.valueReference for v in md.modelVariables
                    if v.causality == "output" and v.type == "Real"})
links = []  # (to, [input vr], from, [output vr]) for same-named variables
for to, other in ((0, 1), (1, 0)):
    names = sorted(set(inputs[to]) & set(outputs[other]))
    links.append((to, [inputs[to][n] for n in names], other, [outputs[other][n] for n in names]))
h = 0.01


def run(first, n):
    for k in range(first, first + n):
        values = [slaves[o].getReal(vrs) for _, _, o, vrs in links]
        for (to, vrs, _, _), v in zip(links, values):
            slaves[to].setReal(vrs, v)
        for slave in slaves:
            slave.doStep(k * h, h)


run(0, 200)
start = time.perf_counter()
run(200, steps)
print((time.perf_counter() - start) / steps * 1e6)
"""


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


def time_loop(plant: Path, autopilot: Path, steps: int) -> float:
    """us per step of the bs-3 pair in a fresh process."""
    command = [sys.executable, "-c", LOOP, str(plant), str(autopilot), str(steps)]
    done = subprocess.run(command, capture_output=True, text=True, check=True)
    return float(done.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=3000, help="timed steps [3000]")
    parser.add_argument("--repeat", type=int, default=3, help="rounds [3]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    fmus = ensure_fmus(args.fmu_dir)
    with tempfile.TemporaryDirectory(prefix="bench_loader_") as tmp:
        variants = {
            "loader": (fmus["AuvPlant"], fmus["AuvAutopilot"]),
            "pythonfmu alone": tuple(
                without_loader(fmus[n], Path(tmp)) for n in ("AuvPlant", "AuvAutopilot")
            ),
        }
        best = dict.fromkeys(variants, float("inf"))
        for _ in range(args.repeat):
            for name, (plant, autopilot) in variants.items():
                best[name] = min(best[name], time_loop(plant, autopilot, args.steps))
    for name, us in best.items():
        print(f"{name}: {us:.1f} us per bs-3 step (plant + autopilot)")
    ratio = best["loader"] / best["pythonfmu alone"]
    print(f"loader / pythonfmu alone: {ratio:.3f} (target <= 1.03)")


if __name__ == "__main__":
    main()
