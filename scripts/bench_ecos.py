"""Our master's stepping loop against ecos stepping the same FMUs, side by side.

bs-3 (the plant and the autopilot through their runtime), ``--stop-time`` s at 10 ms,
Jacobi with the inputs held: ecos steps Jacobi and sends no input derivatives, so our
master runs the same algorithm (``--algorithm jacobi``, extrapolation "none"). ecos gets
the scenario as the SSP archive ``auv-cosim export`` writes. Each round runs ecos, then our
master, each in a fresh process of its own (two co-simulation libraries in one process
would share the FMUs' Python), and times the stepping loop alone inside it: ecos's
``step()`` calls, our ``master.run`` loop (``wall_clock_s``: it also records every row,
which ecos is not asked to). Prints each round with the load average, then the best of
the rounds and their ratio (target: ours / ecos <= 1).

Usage: ``python scripts/bench_ecos.py [--repeat 3] [--stop-time 60] [--fmu-dir DIR]``;
needs ``ecospy`` (the test extra).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from cosim.export import export_ssp
from cosim.paths import DEFAULT_FMU_DIR
from cosim.scenario.spec import load_scenario

ECOS = """
import sys, time
from cosim.export.ecos_support import preload_tbb
preload_tbb()
from ecospy import EcosLib, EcosSimulation
EcosLib.set_log_level("warn")
h, n = float(sys.argv[2]), int(sys.argv[3])
with EcosSimulation(ssp_path=sys.argv[1], step_size=h) as simulation:
    if not simulation.init(parameter_set="initial"):
        raise SystemExit(f"ecos: initialisation failed: {EcosLib.get_last_error()}")
    started = time.perf_counter()
    for _ in range(n):
        simulation.step()
    print(time.perf_counter() - started)
    simulation.terminate()
"""

OURS = """
import sys
from pathlib import Path
from cosim.engine import master
from cosim.scenario.spec import load_scenario
scenario = load_scenario("bs-3", Path(sys.argv[1])).with_overrides(
    stop_time=float(sys.argv[2]), step=0.01, algorithm="jacobi", extrapolation="none")
result = master.run(scenario, keep_rows=False)
if not result.complete:
    raise SystemExit(result.error)
print(result.wall_clock_s)
"""


def load() -> str:
    """The load average, 1/5/15 minutes."""
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def timed(code: str, *args: str) -> float:
    """The seconds a child process running ``code`` prints last."""
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          check=False, timeout=600)  # fmt: skip
    if done.returncode != 0:
        raise SystemExit(f"failed: {done.stderr.strip().splitlines()[-1:]}")
    return float(done.stdout.split()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="rounds [3]")
    parser.add_argument("--stop-time", type=float, default=60.0, help="s [60]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    scenario = load_scenario("bs-3", args.fmu_dir).with_overrides(
        stop_time=args.stop_time, step=0.01, algorithm="jacobi", extrapolation="none"
    )
    ecos, ours = [], []
    with tempfile.TemporaryDirectory(prefix="bench_ecos_") as tmp:
        ssp = export_ssp(scenario, Path(tmp) / "bs-3.ssp")
        steps = str(scenario.n_steps)
        for i in range(args.repeat):
            ecos.append(timed(ECOS, str(ssp), "0.01", steps))
            ours.append(timed(OURS, str(args.fmu_dir.resolve()), repr(args.stop_time)))
            print(f"round {i + 1}: ecos {ecos[-1]:.3f} s, ours {ours[-1]:.3f} s "
                  f"({ours[-1] / ecos[-1]:.2f}); load {load()}")  # fmt: skip
    print(f"best of {args.repeat}: ecos {min(ecos):.3f} s, ours {min(ours):.3f} s "
          f"({scenario.n_steps} steps of bs-3, Jacobi, inputs held): ours / ecos "
          f"{min(ours) / min(ecos):.2f} (target <= 1); load {load()}")  # fmt: skip


if __name__ == "__main__":
    main()
