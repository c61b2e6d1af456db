"""Our master's stepping loop against ecos stepping the same FMUs, side by side.

bs-3 (the plant and the autopilot through their runtime), ``--stop-time`` s at 10 ms,
Jacobi with the inputs held: ecos steps Jacobi and sends no input derivatives, so our
master runs the same algorithm (``--algorithm jacobi``, extrapolation "none"). ecos gets
the scenario as the SSP archive ``auv-cosim export`` writes. Both sides do the same work,
in two settings measured in every round:

* ``none``: nothing recorded. ecos is given no writer; our master runs the scenario with
  ``output.record = []``, so it reads only the connected outputs, as ecos does;
* ``csv``: every column of the scenario's results.csv written to a CSV file as the run
  goes, by ecos's CSV writer (six decimals) and by ours (results.csv, exact).

Each tool runs in a fresh process of its own (two co-simulation libraries in one process
would share the FMUs' Python), and times its stepping loop alone: ecos's ``step()`` calls,
our ``master.run`` loop. Rounds alternate which tool goes first. Each run is timed by the
wall clock and by the process's CPU time (every thread), which other processes' load
inflates far less than the wall clock. Prints each round with the load average, then per
setting the best of the rounds and their ratio (target: ours / ecos <= 1).

Both processes run on the same single core (Linux), unless ``--all-cores``: ecos steps the
instances of a step in parallel (TBB), and our two FMUs share the process's Python, so its
two threads take turns at the GIL, one spinning while the other steps: on an otherwise idle
2-core machine that run takes 3-4 times as long (twice the CPU time), and whether a run
falls into it is chance. On one core ecos steps them one after the other, as our master
does, with the same resources.

Usage: ``python scripts/bench_ecos.py [--repeat 5] [--stop-time 60] [--fmu-dir DIR]
[--all-cores]``; needs ``ecospy`` (the test extra).
"""

from __future__ import annotations

import argparse
import functools
import os
import subprocess
import sys
import tempfile
from pathlib import Path

from bench_timing import load

from cosim.export import export_ssp
from cosim.paths import DEFAULT_FMU_DIR
from cosim.scenario.spec import load_scenario

SETTINGS = ("none", "csv")

ECOS = """
import sys, time
from cosim.export.ecos_support import preload_tbb
preload_tbb()
from ecospy import EcosLib, EcosSimulation
EcosLib.set_log_level("warn")
ssp, h, n, record, out = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5]
columns = sys.argv[6].split(",")
with EcosSimulation(ssp_path=ssp, step_size=h) as simulation:
    if record == "csv":  # "plant.north" is "plant::north" to ecos
        simulation.add_csv_writer(out, identifiers=[c.replace(".", "::", 1) for c in columns])
    if not simulation.init(parameter_set="initial"):
        raise SystemExit(f"ecos: initialisation failed: {EcosLib.get_last_error()}")
    wall, cpu = time.perf_counter(), time.process_time()
    for _ in range(n):
        simulation.step()
    print(time.perf_counter() - wall, time.process_time() - cpu)
    simulation.terminate()
"""

OURS = """
import sys
from pathlib import Path
from cosim.engine import master
from cosim.outputs.sinks import CsvSink
from cosim.scenario.spec import load_scenario, scenario_from_data
fmu_dir, stop_time, record, out = Path(sys.argv[1]), float(sys.argv[2]), sys.argv[3], sys.argv[4]
scenario = load_scenario("bs-3", fmu_dir)
if record == "none":  # read only what the connections need, as ecos without a writer
    data = scenario.spec.model_dump(by_alias=True, exclude_none=True)
    data.setdefault("output", {})["record"] = []
    scenario = scenario_from_data(data, "bs-3, nothing recorded", scenario.base_dir, fmu_dir)
scenario = scenario.with_overrides(stop_time=stop_time, step=0.01, algorithm="jacobi",
                                   extrapolation="none")
sinks = []
if record == "csv":
    sinks.append(CsvSink(Path(out), scenario.columns))
    sinks[0].warm_up()
result = master.run(scenario, sinks, keep_rows=False)
for sink in sinks:
    sink.close()
if not result.complete:
    raise SystemExit(result.error)
print(result.wall_clock_s, result.cpu_clock_s)
"""


def timed(code: str, *args: str, core: int | None, scratch: str) -> tuple[float, float]:
    """(wall s, CPU s) a child process running ``code`` prints last; on CPU ``core`` only
    when given; its TMPDIR is ``scratch`` (ecos unpacks each SSP there, ecos_ssp_<uuid>,
    and leaves it: so it goes with the benchmark's folder, not into /tmp)."""
    pin = None if core is None else functools.partial(os.sched_setaffinity, 0, {core})
    env = {**os.environ, "TMPDIR": scratch}
    done = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True,
                          check=False, timeout=600, preexec_fn=pin, env=env)  # fmt: skip
    if done.returncode != 0:
        raise SystemExit(f"failed: {done.stderr.strip().splitlines()[-1:]}")
    wall, cpu = done.stdout.split()[-2:]
    return float(wall), float(cpu)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="rounds [5]")
    parser.add_argument("--stop-time", type=float, default=60.0, help="s [60]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    parser.add_argument("--all-cores", action="store_true", help="do not pin to one core")
    args = parser.parse_args()
    pinned = not args.all_cores and hasattr(os, "sched_setaffinity")
    core = min(os.sched_getaffinity(0)) if pinned else None
    scenario = load_scenario("bs-3", args.fmu_dir).with_overrides(
        stop_time=args.stop_time, step=0.01, algorithm="jacobi", extrapolation="none"
    )
    times: dict[tuple[str, str], list[tuple[float, float]]] = {}
    where = f"both on CPU {core}" if core is not None else "on every core"
    print(f"{scenario.n_steps} steps of bs-3, Jacobi, inputs held, {where}; load {load()} at "
          "start")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="bench_ecos_") as tmp:
        ssp = str(export_ssp(scenario, Path(tmp) / "bs-3.ssp"))
        fmu_dir, steps = str(args.fmu_dir.resolve()), str(scenario.n_steps)
        for i in range(args.repeat):
            for record in SETTINGS:
                out = str(Path(tmp) / f"{record}-{i}")
                runs = {
                    "ecos": (ECOS, ssp, "0.01", steps, record, out + "-ecos.csv",
                             ",".join(scenario.columns)),
                    "ours": (OURS, fmu_dir, repr(args.stop_time), record, out + "-ours.csv"),
                }  # fmt: skip
                for tool in sorted(runs, reverse=i % 2 == 1):  # alternate who goes first
                    times.setdefault((record, tool), []).append(
                        timed(*runs[tool], core=core, scratch=tmp)
                    )
                (ew, ec), (ow, oc) = times[record, "ecos"][-1], times[record, "ours"][-1]
                print(f"round {i + 1}, recording {record}: ecos {ew:.3f} s (CPU {ec:.3f}), "
                      f"ours {ow:.3f} s (CPU {oc:.3f}): {ow / ew:.2f} ({oc / ec:.2f} CPU); "
                      f"load {load()}")  # fmt: skip
    for record in SETTINGS:
        ecos, ours = times[record, "ecos"], times[record, "ours"]
        wall = min(t[0] for t in ours) / min(t[0] for t in ecos)
        cpu = min(t[1] for t in ours) / min(t[1] for t in ecos)
        print(f"best of {args.repeat}, recording {record}: ecos {min(t[0] for t in ecos):.3f} s "
              f"(CPU {min(t[1] for t in ecos):.3f}), ours {min(t[0] for t in ours):.3f} s (CPU "
              f"{min(t[1] for t in ours):.3f}): ours / ecos {wall:.2f} wall clock, {cpu:.2f} "
              f"CPU (target <= 1); load {load()}")  # fmt: skip


if __name__ == "__main__":
    main()
