"""Cost of one 10 ms plant step: in-process vs through AuvPlant.fmu in fmpy.

Prints, as medians over many repetitions (microseconds):
  (a) one 10 ms step of the full 6-DOF model in-process (plant_fmu.model.stepping.advance:
      one RK4 step, four derivative evaluations, projections and checks);
  (b) one derivative evaluation, and the ratio (a)/(b);
  (c) one FMU step through fmpy's FMU2Slave: setReal of the 8 inputs + doStep + getReal of
      the 22 outputs, and the ratio (c)/(a);
  (d) the same three calls on the AuvPlant class in Python (no C wrapper, no ctypes),
      which splits (c) - (a) into our slave's overhead and pythonfmu's + fmpy's;
  (e) one derivative evaluation with the two-body moving mass (moving_mass_model = 1),
      and its ratio to (b);
  (f) (a) and (b) with the compiled plant (plant_fmu.model.compiled, numba), and the
      speed-up over the reference in the same process.

Usage: python scripts/bench_plant.py [--fmu-dir build/fmus] [--steps 3000]
"""

from __future__ import annotations

import argparse
from collections.abc import Callable
from pathlib import Path

from bench_timing import median_us
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from cosim.fmus.build import build_fmu
from plant_fmu.auv_plant import AuvPlant
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import INPUT_NAMES, PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.moving_mass import MovingMassModel
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance

H = 0.01
START = dict(u=1.5, v=0.1, w=0.02, p=0.1, q=0.02, r=0.2, roll=0.1, pitch=0.05)
INPUTS = dict(thrust=9.0, tunnel_force=1.0, fin_angle=0.05, mass_position_cmd=0.03)


def in_process(steps: int) -> tuple[float, float, float]:
    model = PlantModel(load_vehicle("remus100"), Variant.FULL)
    two_body = PlantModel(
        load_vehicle("remus100"), Variant.FULL, moving_mass_model=MovingMassModel.TWO_BODY
    )
    inputs = input_vector(INPUTS)
    state = {"x": state_vector(START)}

    def step() -> None:
        state["x"] = advance(model, state["x"], inputs, H)

    x = state_vector({**START, "mass_position": 0.02, "mass_velocity": 0.05})
    return (
        median_us(step, steps),
        median_us(lambda: model.derivative(x, inputs), steps * 4),
        median_us(lambda: two_body.derivative(x, inputs), steps * 4),
    )


def compiled_in_process(steps: int) -> tuple[float, float]:
    """(10 ms step via advance(..., compiled), one compiled derivative), microseconds."""
    model = PlantModel(load_vehicle("remus100"), Variant.FULL)
    fast = CompiledPlant(model)
    inputs = input_vector(INPUTS)
    state = {"x": state_vector(START)}

    def step() -> None:
        state["x"] = advance(model, state["x"], inputs, H, compiled=fast)

    x = state_vector({**START, "mass_position": 0.02, "mass_velocity": 0.05})
    return median_us(step, steps), median_us(lambda: fast.derivative(x, inputs), steps * 4)


def through_fmpy(fmu: Path, steps: int) -> float:
    md = read_model_description(str(fmu))
    refs = {v.name: v.valueReference for v in md.modelVariables}
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output"]
    slave = FMU2Slave(
        guid=md.guid,
        unzipDirectory=extract(str(fmu)),
        modelIdentifier="AuvPlant",
        instanceName="bench",
    )
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.setReal([refs[f"{n}_0"] for n in START], list(START.values()))
    slave.exitInitializationMode()
    input_refs = [refs[n] for n in INPUT_NAMES]
    input_values = list(input_vector(INPUTS))
    clock = {"t": 0.0}

    def step() -> None:
        slave.setReal(input_refs, input_values)
        slave.doStep(clock["t"], H)
        slave.getReal(outputs)
        clock["t"] += H

    cost = median_us(step, steps)
    slave.terminate()
    slave.freeInstance()
    return cost


def initialise(plant: AuvPlant) -> None:
    """Start values in initialisation mode, as a master sets them."""
    refs = {v.name: vr for vr, v in plant.vars.items()}
    plant.enter_initialization_mode()
    plant.set_real([refs[f"{n}_0"] for n in START], list(START.values()))
    plant.exit_initialization_mode()


def class_step(plant: AuvPlant) -> Callable[[], None]:
    """One FMU step of an initialised AuvPlant called as a Python class: set the inputs,
    doStep, read every output."""
    refs = {v.name: vr for vr, v in plant.vars.items()}
    outputs = [vr for vr, v in plant.vars.items() if v.causality.name == "output"]
    input_refs = [refs[n] for n in INPUT_NAMES]
    input_values = [float(v) for v in input_vector(INPUTS)]
    clock = {"t": 0.0}

    def step() -> None:
        plant.set_real(input_refs, input_values)
        if not plant.do_step(clock["t"], H):
            raise RuntimeError(plant.log_queue[-1].msg)
        plant.get_real(outputs)
        clock["t"] += H

    return step


def direct_class(steps: int) -> float:
    plant = AuvPlant(instance_name="bench")
    initialise(plant)
    return median_us(class_step(plant), steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fmu-dir", type=Path, default=Path("build/fmus"))
    parser.add_argument("--steps", type=int, default=3000, help="timed steps per measurement")
    args = parser.parse_args()
    fmu = build_fmu("AuvPlant", args.fmu_dir)

    step_us, derivative_us, two_body_us = in_process(args.steps)
    fmu_us = through_fmpy(fmu, args.steps)
    class_us = direct_class(args.steps)
    print(f"(a) in-process 10 ms step, full 6-DOF (advance, RK4): {step_us:8.1f} us")
    print(f"(b) one derivative evaluation:                         {derivative_us:8.1f} us")
    print(f"    ratio (a)/(b):                                     {step_us / derivative_us:8.2f}")
    print(f"(c) FMU step via fmpy (setReal 8 + doStep + getReal 22): {fmu_us:6.1f} us")
    print(f"    ratio (c)/(a):                                     {fmu_us / step_us:8.2f}")
    print(f"(d) same calls on the AuvPlant class in Python:        {class_us:8.1f} us")
    print(
        f"    overhead over (a): slave {class_us - step_us:6.1f} us, "
        f"pythonfmu + fmpy {fmu_us - class_us:6.1f} us"
    )
    print(f"(e) one derivative, two-body moving mass:              {two_body_us:8.1f} us")
    print(
        f"    ratio (e)/(b):                                     {two_body_us / derivative_us:8.2f}"
    )
    fast_step, fast_derivative = compiled_in_process(args.steps)
    print(f"(f) compiled 10 ms step (target <= 10 us): {fast_step:6.1f} us, "
          f"{step_us / fast_step:.0f}x faster than (a)")  # fmt: skip
    speedup = derivative_us / fast_derivative
    print(f"    compiled derivative (target <= 2 us, incl. the Python call): "
          f"{fast_derivative:6.2f} us, {speedup:.0f}x faster than (b)")  # fmt: skip


if __name__ == "__main__":
    main()
