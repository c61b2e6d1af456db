"""The manoeuvre metrics of a run as its rows stream by (cosim.outputs.manoeuvre): the same
as from the whole table, whatever the chunks; a run ending on NaN, or with no rows, still
gets every metric name (None), never an exception."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from cosim.metrics.manoeuvres import manoeuvre_metrics, metric_names
from cosim.outputs.manoeuvre import ManoeuvreSink, fault_start, scenario_metric_names
from cosim.scenario.spec import load_scenario

H = 0.01
RECORD = ["plant.roll", "plant.north", "plant.east", "plant.yaw", "plant.mass_position_cmd",
          "plant.u"]  # fmt: skip


def turning_rows(t_end: float = 60.0) -> tuple[np.ndarray, np.ndarray]:
    """A circle of radius 5 m at 1 m/s from t = 0, rolled 0.2 rad, the command at 0.06."""
    t = np.arange(round(t_end / H) + 1) * H
    theta = t / 5.0
    values = np.column_stack([np.full_like(t, 0.2), 5.0 * np.sin(theta),
                              5.0 * (1.0 - np.cos(theta)), theta, np.full_like(t, 0.06),
                              np.ones_like(t)])  # fmt: skip
    return t, values


def test_streamed_metrics_equal_those_of_the_whole_table():
    t, values = turning_rows()
    sink = ManoeuvreSink("turning-circle", RECORD)
    for start in range(0, len(t), 137):  # chunks as the master hands them over
        sink.add_rows(t[start : start + 137], values[start : start + 137])
    values[:, 0] = -1.0  # the sink keeps copies: later changes to the master's buffer
    summary = sink.summary()
    columns = {"time": t, **{name: values[:, k] for k, name in enumerate(RECORD)}}
    columns["plant.roll"] = np.full_like(t, 0.2)
    expected = manoeuvre_metrics("turning-circle", columns)
    assert summary == {"manoeuvre": "turning-circle", **expected}
    assert summary["steady_turning_diameter_m"] == pytest.approx(10.0, rel=1e-6)


def test_a_run_ending_on_nan_or_without_rows_gets_none():
    t, values = turning_rows()
    values[-500:, 1:3] = np.nan  # the track blew up
    sink = ManoeuvreSink("turning-circle", RECORD)
    sink.add_rows(t, values)
    summary = sink.summary()
    assert set(summary) - {"manoeuvre_error"} == {"manoeuvre", *metric_names("turning-circle")}
    assert all(
        v is None or math.isfinite(v) for k, v in summary.items() if k.endswith(("m", "deg", "pct"))
    )
    json.dumps(summary, allow_nan=False)  # what summary.json accepts
    empty = ManoeuvreSink("survey", ["guidance.cross_track_error", "guidance.legs_completed"])
    assert empty.summary() == {"manoeuvre": "survey", **dict.fromkeys(metric_names("survey"))}


def test_a_column_the_kind_needs_must_be_recorded():
    with pytest.raises(ValueError, match=r"'zigzag' needs the variable 'yaw_setpoint'"):
        ManoeuvreSink("zigzag", RECORD)


def test_a_scenarios_metric_names_and_fault_start(fmu_paths) -> None:
    """What a study's table is laid out by before any run: a depth step per time event
    that sets a depth set-point; the fault-recovery metrics count from the first fault."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    depth = load_scenario("depth-steps", fmu_dir=fmu_dir)
    assert scenario_metric_names(depth) == metric_names("depth-steps", steps=2)
    jam = load_scenario("mass-jam", fmu_dir=fmu_dir)
    assert fault_start(jam) == 3.0 and scenario_metric_names(jam)[0] == "heading_error_at_fault_deg"
    plain = load_scenario("bs-3", fmu_dir=fmu_dir)
    assert fault_start(plain) == 0.0 and scenario_metric_names(plain) == ()
