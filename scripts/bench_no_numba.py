"""What a host without numba pays: the plant FMU's step with and without its compiled path.

numba is optional in the FMUs: a host without it steps the numpy reference of the plant
(``plant_fmu/model/stepping.py``) and the FMU logs a warning saying so and what it costs.
This measures that cost as a ratio, both paths in this one process and interleaved in
rounds (the machine's other load hits both alike):

  (a) one 10 ms step of the AuvPlant slave class (set_real of the 8 inputs + do_step +
      get_real of the 22 outputs), the full 6-DOF model, with the compiled path;
  (b) the same without it, as a host without numba runs it;
  (c) the step alone, ``advance`` with and without the compiled plant.

Prints the medians (microseconds), the ratios (b)/(a) and (c), and the load average.

Usage: python scripts/bench_no_numba.py [--steps 2000] [--rounds 3]
"""

from __future__ import annotations

import argparse
import os
from collections.abc import Callable
from typing import Any

from bench_plant import INPUTS, START, H, class_step, initialise
from bench_timing import median_us

from plant_fmu.auv_plant import AuvPlant
from plant_fmu.model import compiled
from plant_fmu.model.compiled import CompiledPlant
from plant_fmu.model.dynamics import PlantModel, Variant
from plant_fmu.model.linearization import input_vector, state_vector
from plant_fmu.model.parameters import load_vehicle
from plant_fmu.model.stepping import advance


def slave_step(with_numba: bool) -> Callable[[], None]:
    """One FMU step of a fresh, initialised AuvPlant; without numba the slave is built as
    in a host where numba cannot be imported (the compiled path reported unsupported)."""
    supports = compiled.supports
    if not with_numba:
        compiled.supports = _unsupported  # what AuvPlant asks before using the compiled plant
    try:
        plant = AuvPlant(instance_name="bench")
        initialise(plant)
    finally:
        compiled.supports = supports
    assert (plant._compiled is not None) == with_numba, "the path asked for"
    return class_step(plant)


def _unsupported(model: PlantModel) -> str:
    return "numba cannot be imported (benchmark)"


def advance_step(with_numba: bool) -> Callable[[], None]:
    """One 10 ms step of the model itself, with or without the compiled plant."""
    model = PlantModel(load_vehicle("remus100"), Variant.FULL)
    inputs = input_vector(INPUTS)
    state: dict[str, Any] = {"x": state_vector(START)}
    path = CompiledPlant(model) if with_numba else None

    def step() -> None:
        state["x"] = advance(model, state["x"], inputs, H, compiled=path)

    return step


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="timed steps per measurement")
    parser.add_argument("--rounds", type=int, default=3, help="interleaved rounds (best kept)")
    args = parser.parse_args()
    if not compiled.AVAILABLE:
        raise SystemExit(f"numba is not usable here ({compiled.NO_JIT_REASON}): nothing to compare")
    calls = {
        "slave, compiled": slave_step(True),
        "slave, reference": slave_step(False),
        "advance, compiled": advance_step(True),
        "advance, reference": advance_step(False),
    }
    best = dict.fromkeys(calls, float("inf"))
    for _ in range(args.rounds):
        for name, call in calls.items():
            best[name] = min(best[name], median_us(call, args.steps))
    load = os.getloadavg()
    print(f"(a) AuvPlant step with numba:    {best['slave, compiled']:8.1f} us")
    print(f"(b) AuvPlant step without numba: {best['slave, reference']:8.1f} us")
    print(f"    ratio (b)/(a): {best['slave, reference'] / best['slave, compiled']:.0f}x")
    print(
        f"(c) advance alone: {best['advance, compiled']:.1f} us compiled, "
        f"{best['advance, reference']:.1f} us reference, ratio "
        f"{best['advance, reference'] / best['advance, compiled']:.0f}x"
    )
    print(f"load average: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")


if __name__ == "__main__":
    main()
