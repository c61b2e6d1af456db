"""A doStep of the plant and of the autopilot allocates nothing: from the value buffers to
the compiled kernel and back, the only memory tracemalloc sees during a step is what numba
itself takes to call a compiled function with that many array arguments (a descriptor per
array, freed when it returns), measured in the same process; and nothing stays behind
after thousands of steps.

The communication step is 2^-7 s, so that every step's interval is the same double and the
backstepping's command filters compute their transition once (a new interval computes one
with the matrix exponential, which allocates: with 10 ms steps that happens about 14 times in 60 s).
"""

from __future__ import annotations

import statistics
import tracemalloc
from collections.abc import Callable

import numpy as np
import pytest

from controller_fmu.auv_autopilot import AuvAutopilot
from fmu_runtime.safe_slave import SafeSlave
from fmu_runtime.value_buffers import DERIVATIVES
from plant_fmu.auv_plant import AuvPlant
from plant_fmu.model import compiled

H = 2.0**-7  # s
KERNEL_ARRAYS = 7  # the array arguments of compiled.step_into and compiled_autopilot.sample

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(not compiled.AVAILABLE, reason="numba is off"),
]


def _initialised(
    slave: SafeSlave, reals: dict[str, float] | None = None, **integers: int
) -> SafeSlave:
    slave.setup_experiment(0.0, None, None)
    slave.enter_initialization_mode()
    vrs = {var.name: vr for vr, var in slave.vars.items()}
    for name, real in (reals or {}).items():
        slave.set_real([vrs[name]], [real])
    for name, value in integers.items():
        slave.set_integer([vrs[name]], [value])
    slave.exit_initialization_mode()
    return slave


def _transient_bytes(
    call: Callable[[float], object],
    times: list[float],
    prepare: Callable[[], object] = lambda: None,
) -> list[int]:
    """tracemalloc's peak above the memory in use at the start of each call (``prepare``
    runs before, unmeasured)."""
    get, reset = tracemalloc.get_traced_memory, tracemalloc.reset_peak
    peaks = []
    for t in times:
        prepare()
        before = get()[0]
        reset()
        call(t)
        peaks.append(get()[1] - before)
    return peaks


def _numba_call_bytes() -> int:
    """What calling a compiled function with KERNEL_ARRAYS array arguments takes."""
    arrays = [np.zeros(4) for _ in range(KERNEL_ARRAYS)]

    @compiled.numba.njit
    def nothing(a, b, c, d, e, f, g, t):  # a numba baseline
        return 0

    nothing(*arrays, 0.0)
    return int(statistics.median(_transient_bytes(lambda t: nothing(*arrays, t), [0.0] * 500)))


def _derivatives(slave: SafeSlave, name: str, first: float, second: float) -> Callable[[], None]:
    """Input derivatives of ``name`` for the next step, written into the slave's buffer as
    the FMU's runtime writes them in C (fmi2SetRealInputDerivatives)."""
    slot = slave._values.slots[slave._vr_of[name]]
    values = slave._values

    def write() -> None:
        values.derivatives[0, slot], values.derivatives[1, slot] = first, second
        values.control[DERIVATIVES] = 1

    return write


@pytest.mark.parametrize(
    ("plant_variant", "heading_mode", "depth_mode", "varying"),
    [(0, 3, 1, False), (1, 3, 0, False), (2, 0, 1, False), (0, 3, 1, True)],
)
def test_a_step_allocates_nothing_but_numbas_call(plant_variant, heading_mode, depth_mode, varying):
    """Held inputs, or input derivatives set before every step (the shipped quadratic
    extrapolation: the plant's varying RK4 stages, the autopilot's first-order hold)."""
    # the full variant 10 m deep: a buoyant hull starting at the surface leaves the water
    # within the steps, which the plant says once (a Warning), and every step here is to log
    # nothing (the reduced variants keep their depth, and warn of a start value for it)
    deep = {"down_0": 10.0} if plant_variant == 0 else {}
    plant = _initialised(AuvPlant(instance_name="plant"), reals=deep, variant=plant_variant)
    autopilot = _initialised(
        AuvAutopilot(instance_name="autopilot"), heading_mode=heading_mode, depth_mode=depth_mode
    )
    prepare = {
        plant: _derivatives(plant, "mass_position_cmd", 1e-3, -1e-3),
        autopilot: _derivatives(autopilot, "yaw", 1e-3, 0.0),
    }
    if not varying:
        prepare = {plant: lambda: None, autopilot: lambda: None}
    times = [k * H for k in range(10000)]
    later = times[3500:9500]
    tracemalloc.start()
    try:
        baseline = _numba_call_bytes()
        for t in times[:500]:  # warm: the filters' transition, free lists
            prepare[autopilot](), prepare[plant]()
            assert autopilot.do_step(t, H) and plant.do_step(t, H)
        steps = {
            name: _transient_bytes(
                lambda t, slave=slave: slave.do_step(t, H), times[500:3500], prepare[slave]
            )
            for name, slave in (("autopilot", autopilot), ("plant", plant))
        }
        in_use = tracemalloc.get_traced_memory()[0]
        for t in later:
            prepare[autopilot](), prepare[plant]()
            autopilot.do_step(t, H)
            plant.do_step(t, H)
        left = tracemalloc.get_traced_memory()[0] - in_use
    finally:
        tracemalloc.stop()
    assert not plant.log_queue and not autopilot.log_queue  # every step was taken
    assert 0 < baseline <= 64 * KERNEL_ARRAYS, baseline
    for name, peaks in steps.items():
        assert statistics.median(peaks) <= baseline, (name, baseline, sorted(set(peaks)))
        assert sum(p > baseline for p in peaks) <= len(peaks) // 100, (name, sorted(set(peaks)))
    assert left <= 2048, left  # 6,000 steps leave nothing behind
