"""Benchmark the co-simulation. Prints, in one run:

1. Per scenario (bs-3 and vert-2, 60 s at 10 ms, no recording, through ``run_scenario``,
   what ``auv-cosim run --no-rrd`` does), each with its shipped coupling settings (input
   derivatives, quadratic) and with its inputs held (``extrapolation = "none"``, marked
   "held"): the real-time factor, the FMI floor and the ratio of the two loops' wall
   clocks, and of their CPU times (the process's, which other processes' load on a shared
   machine inflates far less than the wall clock) (targets: bs-3 <= 0.8, vert-2 <= 1.2).
   The floor is
   two trivial pythonfmu FMUs with our interface shape (8 inputs / 20 outputs and back,
   ``scripts/bench_floor.py`` builds them) stepped by a bare fmpy loop: what any pair of
   pythonfmu FMUs costs. Each round measures the floor and both scenarios one after the
   other and prints them with the load average (1/5/15 min) at its end; the summary is
   the best of the rounds. ``--loops-only`` stops after this part.
2. In process: one 10 ms step of the full 6-DOF plant (RK4 + projection), one derivative
   (targets 10 us, 2 us), one autopilot step of vert-2 (backstepping + depth PD, 10 us);
   compiled and reference.
3. Start-up: ``auv-cosim run bs-3 --no-rrd`` as a whole command, first run (fresh FMU
   folder and numba cache: build plus compilation, target <= 20 s) and second (<= 3 s).
4. The stepping loop against a bare fmpy loop doing the same FMI calls on our FMUs
   (bs-3 with inputs held: the bare loop sends no derivatives; target <= 1.25), and the
   recording overhead (bs-3 with and without recording.rrd, target <= 1.10).

Each timing is the best of ``--repeat`` runs, interleaved in rounds, to damp other load.
Usage: ``python scripts/bench_cosim.py [--stop-time 60] [--repeat 3] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np
from bench_floor import floor_fmus
from bench_timing import load, median_us
from fmpy import read_model_description
from fmpy.fmi2 import FMU2Slave

from controller_fmu.autopilot import Autopilot, AutopilotConfig
from cosim.analysis.closed_loop import measurements
from cosim.engine import master
from cosim.engine.slave import unzipped
from cosim.paths import DEFAULT_FMU_DIR
from cosim.runner import run_scenario
from cosim.scenario.spec import Scenario, load_scenario
from fmu_runtime import exit_guard
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance


def bare_fmpy_loop(scenario: Scenario) -> float:
    """The same FMI calls as the master, written the plain fmpy way; returns loop seconds."""
    slaves: dict[str, FMU2Slave] = {}
    for name, inst in scenario.instances.items():
        md = inst.model_description
        fmu = FMU2Slave(
            guid=md.guid,
            unzipDirectory=str(unzipped(inst.fmu_path)),
            modelIdentifier=md.coSimulation.modelIdentifier,
            instanceName=name,
        )
        fmu.instantiate(loggingOn=True)
        fmu.setupExperiment(startTime=0.0, stopTime=scenario.stop_time)
        for var_name, value in inst.start.items():
            var = inst.variable(var_name)
            setter = {"Real": fmu.setReal, "Integer": fmu.setInteger,
                      "Boolean": fmu.setBoolean, "String": fmu.setString}[var.type]  # fmt: skip
            setter([var.valueReference], [value])
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        slaves[name] = fmu
    # per instance: its connected inputs' value references, and where each input's value
    # is in the lists returned by the sources' getReal of all their outputs
    outputs = {name: [v.valueReference for v in inst.variables("output")]
               for name, inst in scenario.instances.items()}  # fmt: skip
    plan = []
    for name in scenario.coupling.order:
        conns = [c for c in scenario.connections if c.target_instance == name]
        inst = scenario.instances[name]
        inputs = [inst.variable(c.target_variable).valueReference for c in conns]
        sources = [
            (c.source_instance, outputs[c.source_instance].index(
                scenario.instances[c.source_instance].variable(c.source_variable).valueReference))
            for c in conns
        ]  # fmt: skip
        plan.append((name, slaves[name], inputs, sources, outputs[name]))
    latest = {name: [0.0] * len(vrs) for name, vrs in outputs.items()}
    h, n_steps = scenario.coupling.step, scenario.n_steps
    started = time.perf_counter()
    for n in range(n_steps):
        t = n * h
        for name, fmu, inputs, sources, outs in plan:
            fmu.setReal(inputs, [latest[i][j] for i, j in sources])
            fmu.doStep(t, h)
            latest[name] = fmu.getReal(outs)
    elapsed = time.perf_counter() - started
    for fmu in slaves.values():
        fmu.terminate()
        fmu.freeInstance()
    return elapsed


def overhead_ratio(scenario: Scenario, repeat: int) -> tuple[float, float, float]:
    """(master s, bare s, ratio), best of ``repeat`` interleaved runs each."""
    ours, bare = [], []
    for _ in range(repeat):
        result = master.run(scenario, keep_rows=False)  # rows recorded, streamed to no sink
        if not result.complete:
            raise SystemExit(f"{scenario.id}: {result.error}")
        ours.append(result.wall_clock_s)
        bare.append(bare_fmpy_loop(scenario))
    return min(ours), min(bare), min(ours) / min(bare)


def floor_per_step(fmus: list[Path], n_steps: int) -> tuple[float, float]:
    """(wall clock, CPU time) seconds per 10 ms step of the trivial pythonfmu pair in a
    bare fmpy loop."""
    slaves = []
    for fmu in fmus:
        name = fmu.stem
        md = read_model_description(str(fmu))
        slave = FMU2Slave(guid=md.guid, unzipDirectory=str(unzipped(fmu)),
                          modelIdentifier=name, instanceName=name)  # fmt: skip
        # pythonfmu's own binary can abort this process at exit: see exit_guard
        exit_guard.install(unzipped(fmu) / "resources")
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        refs: dict[str, list[int]] = {v.causality: [] for v in md.modelVariables}
        for v in md.modelVariables:
            refs[v.causality].append(v.valueReference)
        slaves.append((slave, refs["input"], refs["output"]))
    latest = [0.0] * 20
    started, cpu = time.perf_counter(), time.process_time()
    for n in range(n_steps):
        for slave, inputs, outputs in slaves:
            slave.setReal(inputs, latest[: len(inputs)])
            slave.doStep(n * 0.01, 0.01)
            latest = slave.getReal(outputs)
    elapsed, cpu = time.perf_counter() - started, time.process_time() - cpu
    for slave, _, _ in slaves:
        slave.terminate()
        slave.freeInstance()
    return elapsed / n_steps, cpu / n_steps


def in_process(repetitions: int) -> dict[str, float]:
    """Microseconds: plant step and derivative (compiled, reference), autopilot step."""
    model = PlantModel(load_vehicle("remus100"), Variant.FULL)
    fast = CompiledPlant(model)
    inputs = input_vector({"thrust": 9.0, "tunnel_force": 1.0, "fin_angle": 0.05,
                           "mass_position_cmd": 0.03})  # fmt: skip
    x = state_vector({"u": 1.5, "v": 0.1, "w": 0.02, "p": 0.1, "q": 0.02, "r": 0.2,
                      "roll": 0.1, "pitch": 0.05, "mass_position": 0.02})  # fmt: skip
    autopilot = Autopilot(AutopilotConfig.build(heading_mode=3, depth_mode=1))
    meas = measurements(model, x, inputs, 0.0, 1.0)
    clock = iter(np.arange(0.0, 1e6, 0.01))
    return {
        "step": median_us(lambda: advance(model, x, inputs, 0.01, compiled=fast), repetitions),
        "step_ref": median_us(lambda: advance(model, x, inputs, 0.01), repetitions // 10),
        "derivative": median_us(lambda: fast.derivative(x, inputs), repetitions),
        "derivative_ref": median_us(lambda: model.derivative(x, inputs), repetitions // 10),
        "autopilot": median_us(lambda: autopilot.step(next(clock), meas), repetitions),
    }


def startup(folder: Path) -> tuple[float, float]:
    """Wall clock of ``auv-cosim run bs-3 --no-rrd``, first (fresh FMU folder and numba
    cache) and second run, s."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(folder / "numba")}
    command = ["auv-cosim", "run", "bs-3", "--no-rrd", "--quiet", "--overwrite", "--fmu-dir",
               str(folder / "fmus"), "--out", str(folder / "run")]  # fmt: skip
    times = []
    for _ in range(2):
        started = time.perf_counter()
        subprocess.run(command, env=env, check=True, capture_output=True)
        times.append(time.perf_counter() - started)
    shutil.rmtree(folder / "numba", ignore_errors=True)
    return times[0], times[1]


TARGETS = {"bs-3": 0.8, "vert-2": 1.2}  # loop / floor, with the shipped coupling settings
HELD = " held"  # the suffix of a scenario run with its inputs held (extrapolation "none")


Timing = tuple[float, float]  # (wall clock, CPU time) s per step


def best_of(timings: list[Timing]) -> Timing:
    """The best wall clock and the best CPU time of the rounds."""
    return min(t[0] for t in timings), min(t[1] for t in timings)


def rounds(
    scenarios: dict[str, Scenario], folder: Path, repeat: int, recording: bool = True
) -> tuple[Timing, dict[str, Timing], float]:
    """(floor per step, each scenario's loop per step without recording, loop s of bs-3
    with recording.rrd, or NaN without ``recording``), each the best of ``repeat`` rounds,
    wall clock and CPU time (the process's, which other processes' load inflates far less);
    a round measures all of them in a row, so a burst of other load on this shared machine
    hits a whole round, not one figure of a ratio. Prints each round with the load."""
    floors: list[Timing] = []
    recorded: list[float] = []
    loops: dict[str, list[Timing]] = {sid: [] for sid in scenarios}
    fmus = floor_fmus(folder)
    for i in range(repeat):
        floors.append(floor_per_step(fmus, scenarios["bs-3"].n_steps))
        for sid, scenario in scenarios.items():
            result = run_scenario(scenario, folder / f"{sid}-{i}", no_rrd=True).result
            n = scenario.n_steps
            loops[sid].append((result.wall_clock_s / n, result.cpu_clock_s / n))
        if recording:
            outcome = run_scenario(scenarios["bs-3"], folder / f"rrd-{i}")
            recorded.append(outcome.result.wall_clock_s)
        (floor, floor_cpu), last = floors[-1], {sid: times[-1] for sid, times in loops.items()}
        shown = ", ".join(f"{sid} {1e6 * w:.1f} us ({w / floor:.2f}x; CPU {1e6 * c:.1f} us, "
                          f"{c / floor_cpu:.2f}x)" for sid, (w, c) in last.items())  # fmt: skip
        print(f"   round {i + 1}: floor {1e6 * floor:.1f} us/step (CPU {1e6 * floor_cpu:.1f}), "
              f"{shown}; load {load()}")  # fmt: skip
    best = min(recorded) if recorded else float("nan")
    return best_of(floors), {sid: best_of(times) for sid, times in loops.items()}, best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop-time", type=float, default=60.0, help="scenario stop time, s")
    parser.add_argument("--repeat", type=int, default=3, help="runs per timing [3]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    parser.add_argument("--loops-only", action="store_true", help="part 1 only")
    args = parser.parse_args()
    scenarios = {}
    for sid in ("bs-3", "vert-2"):  # as shipped (input derivatives), then inputs held
        shipped = load_scenario(sid, fmu_dir=args.fmu_dir)
        scenarios[sid] = shipped.with_overrides(stop_time=args.stop_time, step=0.01)
        scenarios[sid + HELD] = shipped.with_overrides(
            stop_time=args.stop_time, step=0.01, extrapolation="none"
        )
    with tempfile.TemporaryDirectory(prefix="bench_cosim_") as tmp:
        folder = Path(tmp)
        print(f"1. loops against the FMI floor, {args.repeat} rounds (load {load()} at start):")
        (floor, floor_cpu), loops, recorded = rounds(scenarios, folder, args.repeat,
                                                     not args.loops_only)  # fmt: skip
        print(f"   best: FMI floor (trivial pythonfmu pair, bare fmpy loop) {1e6 * floor:.1f} "
              f"us per 10 ms step (CPU {1e6 * floor_cpu:.1f} us), {0.01 / floor:.0f}x real "
              "time")  # fmt: skip
        for sid, scenario in scenarios.items():
            (wall, cpu), coupling = loops[sid], scenario.coupling
            target = TARGETS.get(sid.removesuffix(HELD))
            print(f"   {sid} ({coupling.algorithm}, inputs {coupling.extrapolation}): "
                  f"{0.01 / wall:.0f}x real time, {1e6 * wall:.1f} us/step: {wall / floor:.2f}x "
                  f"the floor; CPU {1e6 * cpu:.1f} us/step: {cpu / floor_cpu:.2f}x the floor's "
                  f"(target <= {target}); load {load()}")  # fmt: skip
        if args.loops_only:
            return
        us = in_process(20000)
        print(f"2. in process: 10 ms plant step {us['step']:.1f} us (target <= 10; reference "
              f"{us['step_ref']:.0f}), derivative {us['derivative']:.2f} us (target <= 2; "
              f"reference {us['derivative_ref']:.1f}), autopilot step (vert-2 laws) "
              f"{us['autopilot']:.1f} us (target <= 10)")  # fmt: skip
        first, second = startup(folder / "startup")
        print(f"3. start-up, auv-cosim run bs-3 --no-rrd: first run {first:.1f} s (target "
              f"<= 20), second {second:.1f} s (target <= 3)")  # fmt: skip
        # the bare loop sends no input derivatives: against the master with inputs held
        ours, bare, ratio = overhead_ratio(scenarios["bs-3" + HELD], args.repeat)
        print(f"4. master vs bare fmpy loop, bs-3 held: {ours:.3f} s vs {bare:.3f} s: ratio "
              f"{ratio:.3f} (target <= 1.25)")  # fmt: skip
        without = loops["bs-3"][0] * scenarios["bs-3"].n_steps
        print(f"   recording overhead, bs-3: {recorded:.3f} s with recording.rrd, "
              f"{without:.3f} s without: ratio {recorded / without:.3f} "
              "(target <= 1.10)")  # fmt: skip


if __name__ == "__main__":
    main()
