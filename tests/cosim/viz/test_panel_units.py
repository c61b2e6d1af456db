"""A recording draws each column in the unit its plot's label says: a column is scaled
from the unit its FMU declares, so an FMU of another tool that declares an angle in deg
is not multiplied by 180/pi again, and every line of our own FMUs stays in its plot."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.fmus.interface import read_interface
from cosim.viz.layout import PANELS, plan_panels

INSTANCES = {"plant": "AuvPlant", "controller": "AuvAutopilot"}  # the catalogue's instances


def _drawn(column: str, units: dict[str, str]) -> list[tuple[str, float, str]]:
    """(entity, scale, unit drawn in) of every line showing ``column``."""
    return [
        (panel.entity, panel.scales[k], panel.units[k])
        for panel in plan_panels(list(units), units)
        for k, series in enumerate(panel.series)
        if series.column == column
    ]


def test_a_set_point_declared_in_degrees_is_drawn_in_degrees_unscaled() -> None:
    units = {"time": "s", "plant.yaw": "rad", "controller.yaw_setpoint": "deg"}
    drawn = _drawn("controller.yaw_setpoint", units)
    assert drawn, "the set-point is not drawn at all"
    for entity, scale, unit in drawn:  # 20 deg must be drawn as 20 deg
        assert (unit, scale) == ("deg", 1.0), (entity, scale, unit)


def test_a_rate_declared_in_deg_s_is_not_scaled_from_rad_s() -> None:
    units = {"time": "s", "plant.r": "deg/s", "plant.p": "rad/s"}
    for entity, scale, unit in _drawn("plant.r", units):
        assert (unit, scale) == ("deg/s", 1.0), (entity, scale, unit)


@pytest.mark.fmu
def test_every_catalogue_line_fits_what_our_fmus_declare(fmu_paths: dict[str, Path]) -> None:
    declared = {
        f"{instance}.{name}": variable.unit or "1"
        for instance, model in INSTANCES.items()
        for name, variable in read_interface(fmu_paths[model]).variables.items()
    }
    columns = [s.column for panel in PANELS for s in panel.series if s.column in declared]
    units = {column: declared[column] for column in columns}
    moved = [
        panel.entity for panel in plan_panels(columns, units) if panel.entity.startswith("other/")
    ]
    assert not moved, f"catalogue columns whose declared unit their plot does not take: {moved}"
