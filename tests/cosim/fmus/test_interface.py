"""cosim.fmus.interface: an FMU's variables and units, typed, read once per file version,
and the same reading in scenario loading and export."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from cosim.export.components import components
from cosim.fmus.interface import FmuInterfaceError, read_interface
from cosim.scenario.spec import load_scenario
from plant_fmu.model.dynamics import INPUT_NAMES, Variant


def test_variables_are_typed_as_the_model_description_declares(fmu_paths) -> None:
    plant = read_interface(fmu_paths["AuvPlant"])
    assert plant.path == fmu_paths["AuvPlant"].resolve()
    assert (plant.fmi_version, plant.model_identifier) == ("2.0", "AuvPlant")
    variant = plant.variables["variant"]
    assert (variant.type, variant.causality, variant.variability) == (
        "Integer",
        "parameter",
        "fixed",
    )
    assert variant.start == int(Variant.FULL) and type(variant.start) is int
    assert plant.variables["ideal_fluid"].start is False
    assert plant.variables["vehicle"].start == "remus100"
    yaw = plant.variables["yaw"]
    assert (yaw.type, yaw.causality, yaw.unit) == ("Real", "output", "rad")
    assert isinstance(yaw.start, float) and yaw.description
    assert [v.name for v in plant.with_causality("input")] == list(INPUT_NAMES)
    # The unit definitions as SI base-unit exponents; N is kg m / s^2.
    assert plant.units["N"] == {"kg": 1, "m": 1, "s": -2}
    assert plant.units["rad"] == {"rad": 1}
    # fmpy's own records stay at hand for FMI calls (value references agree).
    assert plant.model_variables["yaw"].valueReference == yaw.value_reference


def test_read_once_per_file_version(fmu_paths, tmp_path: Path) -> None:
    copy = tmp_path / "AuvPlant.fmu"
    shutil.copyfile(fmu_paths["AuvPlant"], copy)
    first = read_interface(copy)
    assert read_interface(str(copy)) is first  # cached, whatever the path's spelling
    stat = copy.stat()
    os.utime(copy, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    again = read_interface(copy)
    assert again is not first and again == first  # re-read after the file changed


def test_missing_or_broken_fmus_are_refused_by_path(tmp_path: Path) -> None:
    missing = tmp_path / "nothing.fmu"
    with pytest.raises(FmuInterfaceError, match=f"FMU {missing} does not exist"):
        read_interface(missing)
    broken = tmp_path / "broken.fmu"
    broken.write_text("not a zip archive")
    with pytest.raises(FmuInterfaceError, match=f"{broken}: not a valid FMU"):
        read_interface(broken)


def test_scenario_and_export_share_one_reading(fmu_paths) -> None:
    scenario = load_scenario("bs-3", fmu_paths["AuvAutopilot"].parent)
    for name, instance in scenario.instances.items():
        assert instance.interface is read_interface(instance.fmu_path), name
        assert instance.variable("yaw").valueReference == (
            instance.interface.variables["yaw"].value_reference
        )
    exported = {c.name: c.interface for c in components(scenario, None)}
    assert all(exported[n] is i.interface for n, i in scenario.instances.items())
