"""What a host that cannot use an FMU's prepared files pays, per process: the figures of
docs/hosts.md ("A read-only or shared extraction").

* Python of another minor version: the FMUs ship their modules compiled for the build's
  Python; another one compiles the modules an instance imports, in memory. Measured as
  the seconds ``compile`` takes on the sources of exactly the modules one instance
  imported, beside that instantiation (with the shipped compiled modules) as the
  baseline, each FMU in a fresh process.
* No writable numba cache: the plant compiles its kernels in every process. Measured as
  the plant FMU's instantiation and initialisation in a fresh process with an empty
  numba cache folder (cold: compiled) against the same with the folder it filled (warm:
  loaded), ``--rounds`` times alternating.

The load average is printed beside the figures::

    python scripts/bench_host_costs.py [--fmu-dir build/fmus] [--rounds 2]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from cosim.fmus.build import FMUS, ensure_fmus
from cosim.paths import DEFAULT_FMU_DIR

# One instance of the FMU argv[1] in a fresh process, numba's cache in argv[2]: the
# seconds of its instantiation and initialisation, and of compiling the sources of the
# modules it imported from its extraction.
_INSTANCE = """
import json, os, sys, time
os.environ["NUMBA_CACHE_DIR"] = sys.argv[2]
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave
md = read_model_description(sys.argv[1])
folder = extract(sys.argv[1], unzipdir=sys.argv[3])
start = time.perf_counter()
fmu = FMU2Slave(guid=md.guid, unzipDirectory=folder, instanceName="i",
                modelIdentifier=md.coSimulation.modelIdentifier)
fmu.instantiate()
instantiated = time.perf_counter()
fmu.setupExperiment(startTime=0.0)
fmu.enterInitializationMode()
fmu.exitInitializationMode()
initialised = time.perf_counter()
files = [m.__file__ for m in list(sys.modules.values())
         if str(getattr(m, "__file__", "")).startswith(folder)]
compile_start = time.perf_counter()
for file in files:
    with open(file, "rb") as source:
        compile(source.read(), file, "exec")
compiled = time.perf_counter()
fmu.terminate()
fmu.freeInstance()
print(json.dumps({"instantiate": instantiated - start, "initialise": initialised - instantiated,
                  "compile": compiled - compile_start, "modules": len(files)}))
"""


def instance(fmu: Path, cache: Path, folder: Path) -> dict[str, float]:
    """The figures of one instance of ``fmu`` in a fresh process (:data:`_INSTANCE`)."""
    unzipped = Path(tempfile.mkdtemp(dir=folder))
    done = subprocess.run(
        [sys.executable, "-c", _INSTANCE, str(fmu), str(cache), str(unzipped)],
        capture_output=True,
        text=True,
        check=False,
    )
    if done.returncode != 0:
        raise SystemExit(f"{fmu.name}: {done.stderr.strip()[-2000:]}")
    figures: dict[str, float] = json.loads(done.stdout.strip().splitlines()[-1])
    return figures


def _load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def other_python(fmus: dict[str, Path], folder: Path) -> None:
    """Each FMU's modules compiled, against its instantiation."""
    print("another minor version of Python: compiling the modules an instance imports")
    cache = folder / "numba-warm"
    for name in FMUS:
        got = instance(fmus[name], cache, folder)
        ratio = got["compile"] / got["instantiate"]
        print(
            f"  {name:<13} {int(got['modules']):>3} modules compiled in {got['compile']:.2f} s; "
            f"instantiation {got['instantiate']:.2f} s (ratio {ratio:.2f})  load {_load()}"
        )


def no_numba_cache(plant: Path, folder: Path, rounds: int) -> None:
    """The plant's instantiation and initialisation, cold numba cache against warm."""
    print("no writable numba cache: the plant's instantiation + initialisation")
    for round_ in range(rounds):
        cold_cache = folder / f"numba-cold-{round_}"
        cold = instance(plant, cold_cache, folder)  # an empty folder: compiled
        warm = instance(plant, cold_cache, folder)  # the folder it filled: loaded
        cold_s = cold["instantiate"] + cold["initialise"]
        warm_s = warm["instantiate"] + warm["initialise"]
        print(
            f"  round {round_ + 1}: cold {cold_s:.2f} s, warm {warm_s:.2f} s "
            f"(cold/warm {cold_s / warm_s:.1f})  load {_load()}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args()
    fmus = ensure_fmus(args.fmu_dir)
    print(f"machine: {os.cpu_count()} cores; load {_load()} at the start")
    with tempfile.TemporaryDirectory(prefix="bench-host-costs-") as temporary:
        folder = Path(temporary)
        instance(fmus["AuvPlant"], folder / "numba-warm", folder)  # fills the warm cache
        other_python(fmus, folder)
        no_numba_cache(fmus["AuvPlant"], folder, args.rounds)


if __name__ == "__main__":
    main()
