"""A recording draws each column in the unit its plot's label says: a column is scaled
from the unit its FMU declares, so an FMU of another tool that declares an angle in deg
is not multiplied by 180/pi again, and every line of our own FMUs stays in its plot."""

from __future__ import annotations

from pathlib import Path

import pytest

from cosim.fmus.interface import read_interface
from cosim.viz.display_units import DEG
from cosim.viz.layout import PANELS, plan_panels

INSTANCES = {"plant": "AuvPlant", "controller": "AuvAutopilot", "guidance": "AuvGuidance"}


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


def test_a_guidance_set_point_is_drawn_beside_the_value_it_steers() -> None:
    """The survey's heading and depth set-points come from its guidance instance: they were
    drawn apart under other/guidance/, the heading in rad beside a yaw plot in deg."""
    units = {"time": "s", "plant.yaw": "rad", "plant.down": "m",
             "guidance.yaw_setpoint": "rad", "guidance.depth_setpoint": "m"}  # fmt: skip
    assert _drawn("guidance.yaw_setpoint", units) == [("attitude/yaw_deg", DEG, "deg")]
    assert _drawn("guidance.depth_setpoint", units) == [("position/depth_m", 1.0, "m")]


@pytest.mark.parametrize(("declared", "shown"), [("rad", "deg"), ("rad/s", "deg/s")])
def test_a_column_no_plot_knows_is_drawn_in_degrees_when_declared_in_radians(
    declared: str, shown: str
) -> None:
    """An angle or a rate of a column without a plot of its own is drawn as every other
    angle is, in degrees (it was drawn in rad under other/, beside plots in deg)."""
    units = {"time": "s", "other_fmu.bearing": declared, "other_fmu.range": "m"}
    assert _drawn("other_fmu.bearing", units) == [("other/other_fmu/bearing", DEG, shown)]
    assert _drawn("other_fmu.range", units) == [("other/other_fmu/range", 1.0, "m")]
