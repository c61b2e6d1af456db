"""A study's overlay draws each run's yaw, roll and depth from the unit the study's FMUs
declare: a plant of another tool whose yaw is in deg is not multiplied by 180/pi again."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from cosim.viz.overlay import OverlayRun, write_overlay


def _drawn(path: Path, entity: str) -> list[float]:
    """The scalars logged on ``entity`` of the recording at ``path``."""
    from rerun.chunk import RrdReader

    values: list[float] = []
    for chunk in RrdReader(path).stream():
        if str(chunk.entity_path).strip("/") != entity:
            continue
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            if name.lower().endswith("scalars"):
                values += [float(np.ravel(v)[0]) for v in batch.column(name).to_pylist()]
    return values


@pytest.mark.parametrize(("unit", "shown"), [("deg", 20.0), ("rad", math.degrees(20.0))])
def test_a_yaw_is_drawn_in_degrees_from_the_unit_its_fmu_declares(
    tmp_path: Path, unit: str, shown: float
) -> None:
    t = np.linspace(0.0, 1.0, 3)
    results = {"time": t, "plant.north": t, "plant.east": 0 * t, "plant.down": 0 * t,
               "plant.yaw": 0 * t + 20.0, "plant.roll": 0 * t}  # fmt: skip
    units = {"plant.yaw": unit, "plant.roll": "rad", "plant.down": "m"}
    path = write_overlay(tmp_path / "o.rrd", [OverlayRun("r1", "r1", results)], "s", "", units)
    assert _drawn(path, "yaw_deg/r1") == pytest.approx([shown] * 3)


def test_each_vehicle_of_a_run_has_its_own_lines(tmp_path: Path) -> None:
    """A study of a scenario of two vehicles (plant_a, plant_b): its overlay failed with
    "run r1: its results lack plant.north, ..." (it drew the instance named plant only).
    Each vehicle gets its own path and lines under the run's id, by its plant's name."""
    t = np.linspace(0.0, 1.0, 3)
    results = {"time": t}
    for plant, yaw in (("plant_a", 0.1), ("plant_b", 0.2)):
        results |= {f"{plant}.north": t, f"{plant}.east": 0 * t, f"{plant}.down": 0 * t,
                    f"{plant}.yaw": 0 * t + yaw, f"{plant}.roll": 0 * t}  # fmt: skip
    path = write_overlay(tmp_path / "o.rrd", [OverlayRun("r1", "r1", results)], "s", "")
    assert _drawn(path, "yaw_deg/r1/plant_a") == pytest.approx([math.degrees(0.1)] * 3)
    assert _drawn(path, "yaw_deg/r1/plant_b") == pytest.approx([math.degrees(0.2)] * 3)
    assert _drawn(path, "yaw_deg/r1") == []  # no line of a vehicle named plant
