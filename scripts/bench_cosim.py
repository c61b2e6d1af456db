"""Benchmark the co-simulation master (issue 5). Prints three figures:

1. The stepping loop's overhead: ``cosim.run.master.run`` against a bare fmpy loop doing the
   same calls (``setReal`` of the connected inputs, ``doStep``, ``getReal`` of the outputs,
   per instance, Gauss-Seidel order) on the same FMUs in the same process, as a ratio of
   wall-clock times (target <= 1.25). The bare loop records nothing and checks nothing.
   Measured on the AUV FMUs (bs-3) and, if ``tests/fmus`` is present, on two trivial
   FMUs whose own cost is tiny, which shows the master's overhead per step.
2. The real-time factor of bs-3 at a 10 ms communication step (simulated s / wall s).
3. The recording overhead: bs-3 with and without ``recording.rrd``, ratio of the
   stepping-loop wall clocks (target <= 1.10).

Each timing is the best of ``--repeat`` runs (interleaved) to damp other load.
Usage: ``python scripts/bench_cosim.py [--stop-time 20] [--repeat 3] [--fmu-dir DIR]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from fmpy.fmi2 import FMU2Slave

from cosim.fmus.build import pythonfmu_build
from cosim.paths import DEFAULT_FMU_DIR
from cosim.run import master
from cosim.run.runner import run_scenario
from cosim.run.scenario import Scenario, load_scenario, scenario_from_toml
from cosim.run.slave import unzipped

TESTS_FMUS = Path(__file__).resolve().parent.parent / "tests" / "fmus"
TRIVIAL_LOOP = """
stop_time = {stop_time}
[coupling]
step = 0.001
order = ["controller", "plant"]
[instances.plant]
fmu = "CosimTestIntegrator.fmu"
[instances.controller]
fmu = "CosimTestGain.fmu"
"""


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


def trivial_scenario(stop_time: float, folder: Path) -> Scenario | None:
    """Two trivial test FMUs built from tests/fmus (None if that folder is absent)."""
    if not TESTS_FMUS.is_dir():
        return None
    for script, model in (
        ("cosim_test_integrator.py", "CosimTestIntegrator"),
        ("cosim_test_gain.py", "CosimTestGain"),
    ):
        pythonfmu_build(TESTS_FMUS / script, folder, model)
    return scenario_from_toml(
        TRIVIAL_LOOP.format(stop_time=stop_time), "trivial loop", base_dir=folder
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--stop-time", type=float, default=20.0, help="bs-3 stop time, s [20]")
    parser.add_argument("--repeat", type=int, default=3, help="runs per timing [3]")
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()

    bs3 = load_scenario("bs-3", fmu_dir=args.fmu_dir).with_overrides(
        stop_time=args.stop_time, step=0.01
    )
    steps = bs3.n_steps
    ours, bare, ratio = overhead_ratio(bs3, args.repeat)
    print(f"1. stepping loop vs bare fmpy loop, bs-3, {steps} steps of 10 ms:")
    print(f"   master {ours:.3f} s ({1e6 * ours / steps:.0f} us/step), bare {bare:.3f} s "
          f"({1e6 * bare / steps:.0f} us/step): ratio {ratio:.3f} (target <= 1.25)")  # fmt: skip
    with tempfile.TemporaryDirectory(prefix="bench_cosim_") as tmp:
        trivial = trivial_scenario(10.0, Path(tmp))
        if trivial is not None:
            ours_t, bare_t, ratio_t = overhead_ratio(trivial, args.repeat)
            n = trivial.n_steps
            print(f"   trivial FMUs, {n} steps: master {1e6 * ours_t / n:.1f} us/step, bare "
                  f"{1e6 * bare_t / n:.1f} us/step: ratio {ratio_t:.3f}")  # fmt: skip

        plain, recorded = [], []
        for i in range(args.repeat):
            out = Path(tmp) / f"run{i}"
            plain.append(run_scenario(bs3, out / "plain", no_rrd=True).result.wall_clock_s)
            recorded.append(run_scenario(bs3, out / "rrd").result.wall_clock_s)
    print(f"2. real-time factor, bs-3 at 10 ms: {bs3.stop_time / min(plain):.1f}x real time "
          f"({bs3.stop_time:g} s simulated in {min(plain):.2f} s)")  # fmt: skip
    ratio = min(recorded) / min(plain)
    print(f"3. recording overhead, bs-3: {min(recorded):.3f} s with recording.rrd, "
          f"{min(plain):.3f} s without: ratio {ratio:.3f} (target <= 1.10)")  # fmt: skip


if __name__ == "__main__":
    main()
