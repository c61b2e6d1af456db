"""The compiled sample of the autopilot (controller_fmu.compiled_autopilot, through
``Autopilot.step_into``) against the reference ``Autopilot.step``: the same commands,
heading set-point and backstepping state to the last bit, sample after sample, for the
heading laws it covers, inputs held or varying (input derivatives set: the backstepping
filters' first-order hold); a sample it refuses leaves the autopilot as it was and raises the
reference's error."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from controller_fmu.autopilot import MEASUREMENT_NAMES, Autopilot, AutopilotConfig
from plant_fmu.model import compiled

pytestmark = pytest.mark.skipif(not compiled.AVAILABLE, reason="numba is off")

H = 0.01  # s

configs = st.fixed_dictionaries(
    {
        "heading_mode": st.sampled_from([0, 3]),
        "depth_mode": st.sampled_from([0, 1]),
        "compensate_current": st.booleans(),
        "mass_lock_time": st.sampled_from([-1.0, 0.0, 0.05]),
        "tunnel_force_limit": st.sampled_from([10.0, 0.0]),
        "depth_pitch_limit": st.sampled_from([0.0, 0.05, 1.5]),
    }
)
measurement = st.floats(-0.5, 0.5, allow_nan=False, allow_subnormal=True)
depth = st.floats(0.0, 0.5, allow_subnormal=True)  # m: a set-point above the surface is refused
samples = st.lists(
    st.tuples(
        st.lists(
            measurement, min_size=len(MEASUREMENT_NAMES) - 1, max_size=len(MEASUREMENT_NAMES) - 1
        ),
        depth,
    ).map(lambda row: [*row[0], row[1]]),
    min_size=1,
    max_size=8,
)


def _pair(config: dict) -> tuple[Autopilot, Autopilot]:
    built = AutopilotConfig.build(**config)
    fast, reference = Autopilot(built), Autopilot(built)
    reference._kernel = None  # step_into then steps the reference
    assert fast._kernel is not None
    return fast, reference


def _never(*args: object) -> None:
    pytest.fail("the compiled sample refused a sample the reference takes")


def _bits(values) -> list[bytes]:
    return [np.float64(v).tobytes() for v in values]


@settings(max_examples=60, deadline=None)
@given(config=configs, rows=samples, varying=st.booleans())
def test_the_compiled_sample_gives_the_references_commands_to_the_bit(config, rows, varying):
    fast, reference = _pair(config)
    fast._step_reference = _never  # every sample here is one the kernel takes
    rates = np.zeros(len(MEASUREMENT_NAMES))
    for k, row in enumerate(rows):
        t = k * H
        out_fast, out_reference = np.empty(4), np.empty(4)
        measurements = np.array(row)
        rates[MEASUREMENT_NAMES.index("yaw")] = 0.1 * k if varying else 0.0
        fast.step_into(t, measurements, out_fast, rates)
        reference.step_into(t, measurements, out_reference, rates)
        assert _bits(out_fast) == _bits(out_reference), (k, out_fast, out_reference)
        assert _bits([fast.heading_setpoint]) == _bits([reference.heading_setpoint])
        assert _bits(fast.commands.values()) == _bits(out_reference)
        if fast.backstepping is not None and reference.backstepping is not None:
            assert fast.backstepping.state.tobytes() == reference.backstepping.state.tobytes()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"v_rel": math.nan}, "measurement v_rel = nan"),
        ({"current_east": 2.0}, "cross-current 2 m/s is not slower than the design speed"),
        ({"depth_setpoint": -3.0}, r"depth_setpoint = -3\.0 m is above the surface"),
    ],
)
def test_a_refused_sample_changes_nothing_and_raises_the_references_error(change, message):
    fast, _ = _pair({"heading_mode": 3, "depth_mode": 1, "compensate_current": True})
    measurements = np.full(len(MEASUREMENT_NAMES), 0.01)
    commands, rates = np.zeros(4), np.zeros(len(MEASUREMENT_NAMES))
    fast.step_into(0.0, measurements, commands, rates)
    before = (fast.backstepping.state.copy(), commands.copy(), fast.heading_setpoint)
    for name, value in change.items():
        measurements[MEASUREMENT_NAMES.index(name)] = value
    with pytest.raises(ValueError, match=message):
        fast.step_into(H, measurements, commands, rates)
    assert fast.backstepping.state.tobytes() == before[0].tobytes()
    assert commands.tobytes() == before[1].tobytes() and fast.heading_setpoint == before[2]
