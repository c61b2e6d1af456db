"""A connection between Real variables whose declared units differ (FMI 2.0
UnitDefinitions) is refused at load, naming both ends, their units and how they differ:
the master passes numbers, and the input would read them in its own unit. The FMUs are
the Reference BouncingBall (h in m) and our plant (its commands in m and N), one copy of
BouncingBall declaring h in cm, one of our autopilot taking its measured yaw in degrees."""

from __future__ import annotations

import re
import zipfile
from collections.abc import Callable
from pathlib import Path
from types import SimpleNamespace

import pytest
from repo_paths import TESTS

from cosim.scenario.checks import ScenarioError
from cosim.scenario.connection_units import BASE_UNITS, unit_difference
from cosim.scenario.spec import scenario_from_toml

BALL = TESTS / "data" / "reference-fmus" / "BouncingBall.fmu"


def scenario(ball: Path, wiring: str, same_names: bool = False) -> str:
    return f"""
stop_time = 1.0
[coupling]
step = 0.01
[instances.plant]
fmu = "AuvPlant"
[instances.plant.start]
variant = "lateral"
[instances.ball]
fmu = "{ball}"
[connections]
same_names = {str(same_names).lower()}
add = [{{ from = "ball.h", to = "plant.{wiring}" }}]
"""


def with_description(fmu: Path, copy: Path, edit: Callable[[str], str]) -> Path:
    """``fmu`` copied to ``copy`` with its modelDescription.xml edited."""
    with zipfile.ZipFile(fmu) as src, zipfile.ZipFile(copy, "w") as out:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = edit(data.decode()).encode()
            out.writestr(item, data)
    return copy


@pytest.fixture
def ball_in_cm(tmp_path: Path) -> Path:
    """BouncingBall whose length unit is the centimetre (1 cm = 0.01 m)."""

    def edit(text: str) -> str:
        text = text.replace(
            '<Unit name="m">\n      <BaseUnit m="1"/>',
            '<Unit name="cm">\n      <BaseUnit m="1" factor="0.01"/>',
        )
        return text.replace('unit="m"/>', 'unit="cm"/>')

    return with_description(BALL, tmp_path / "BouncingBall.fmu", edit)


def test_a_length_into_a_force_is_refused(fmu_paths: dict[str, Path]) -> None:
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(scenario(BALL, "tunnel_force"), fmu_dir=fmu_paths["AuvPlant"].parent)
    assert "connections.add[0]" in str(refused.value)
    assert (
        "ball.h is in m and plant.tunnel_force in N (different quantities): the master "
        "passes numbers, not quantities" in str(refused.value)
    )


def test_centimetres_into_metres_are_refused_with_the_factor(
    fmu_paths: dict[str, Path], ball_in_cm: Path
) -> None:
    with pytest.raises(ScenarioError, match=r"ball\.h is in cm and plant\.mass_position_cmd "
                       r"in m \(1 cm is 0\.01 m\)"):  # fmt: skip
        scenario_from_toml(
            scenario(ball_in_cm, "mass_position_cmd"), fmu_dir=fmu_paths["AuvPlant"].parent
        )


def test_one_unit_at_both_ends_connects(fmu_paths: dict[str, Path]) -> None:
    loaded = scenario_from_toml(
        scenario(BALL, "mass_position_cmd"), fmu_dir=fmu_paths["AuvPlant"].parent
    )
    assert [(c.source, c.target) for c in loaded.connections] == [
        ("ball.h", "plant.mass_position_cmd")
    ]


def test_a_same_named_pair_in_other_units_is_refused_naming_the_way_out(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """The plant's yaw (rad) meets an autopilot taking yaw in degrees: the connection the
    same names make is refused, saying how to leave it unconnected."""

    def edit(text: str) -> str:
        text = text.replace(
            '<Unit name="rad">',
            '<Unit name="deg">\n      <BaseUnit rad="1" '
            'factor="0.017453292519943295" />\n    </Unit>\n    <Unit name="rad">',
        )
        # (its display unit, degrees of rad, goes too: "deg" is a unit of its own here)
        yaw = r'(name="yaw" [^>]*>\s*<Real start="0" unit=")rad"(?: displayUnit="deg")?'
        return re.sub(yaw, r'\1deg"', text)

    autopilot = with_description(fmu_paths["AuvAutopilot"], tmp_path / "Degrees.fmu", edit)
    text = f"""
stop_time = 1.0
[coupling]
step = 0.01
[instances.plant]
fmu = "AuvPlant"
[instances.controller]
fmu = "{autopilot}"
"""
    with pytest.raises(ScenarioError) as refused:
        scenario_from_toml(text, fmu_dir=fmu_paths["AuvPlant"].parent)
    message = str(refused.value)
    assert "connections.same_names" in message
    assert "plant.yaw is in rad and controller.yaw in deg (1 rad is 57.2958 deg)" in message
    assert 'add "controller.yaw" to connections.remove to leave it unconnected' in message


def _temperature(unit: str, relative: bool) -> tuple[SimpleNamespace, SimpleNamespace]:
    """A model description declaring K and degC (FMI 2.0's example), and one Real in
    ``unit``."""
    base = {d: 0 for d in BASE_UNITS} | {"K": 1}
    units = [
        SimpleNamespace(name="K", baseUnit=SimpleNamespace(**base, factor=1.0, offset=0.0)),
        SimpleNamespace(name="degC", baseUnit=SimpleNamespace(**base, factor=1.0, offset=273.15)),
    ]
    var = SimpleNamespace(type="Real", unit=unit, declaredType=None, relativeQuantity=relative)
    return SimpleNamespace(unitDefinitions=units), var


@pytest.mark.parametrize("relative", [False, True])
def test_celsius_into_kelvin_differ_by_the_offset_unless_relative(relative: bool) -> None:
    """degC into K: 1 degC is 274.15 K; a temperature difference (relativeQuantity) in
    degC is the same number in K."""
    source, target = _temperature("degC", relative), _temperature("K", False)
    difference = unit_difference(("a.t", *source), ("b.t", *target))
    if relative:
        assert difference is None
    else:
        assert difference is not None and "(1 degC is 274.15 K)" in difference
