"""Every name an export writes is one every FMI importer accepts: OMSimulator's rule
``^[a-zA-Z][a-zA-Z0-9_]*$`` (the strictest; it refuses a model named ``bs-3``), for every
built-in scenario; the scenario's id stays in the description."""

from __future__ import annotations

import re
import zipfile
from pathlib import Path

import pytest
from lxml import etree

from cosim.errors import CosimError
from cosim.export import export_osp, export_ssp
from cosim.scenario.spec import builtin_scenarios, load_scenario, scenario_path

OMSIMULATOR_IDENT = re.compile(r"^[a-zA-Z][a-zA-Z0-9_]*$")  # its ComRef::isValidIdent
SSD = "{http://ssp-standard.org/SSP1/SystemStructureDescription}"
SSV = "{http://ssp-standard.org/SSP1/SystemStructureParameterValues}"
OSP = "{http://opensimulationplatform.com/MSMI/OSPSystemStructure}"
# (element, attribute) of every name the SSD gives (units are unit expressions, not names)
SSD_NAMES = [
    (f"{SSD}SystemStructureDescription", "name"),
    (f"{SSD}System", "name"),
    (f"{SSD}Component", "name"),
    (f"{SSD}Connector", "name"),
    (f"{SSD}Connection", "startElement"),
    (f"{SSD}Connection", "startConnector"),
    (f"{SSD}Connection", "endElement"),
    (f"{SSD}Connection", "endConnector"),
    (f"{SSV}ParameterSet", "name"),
    (f"{SSV}Parameter", "name"),
]
OSP_NAMES = [
    (f"{OSP}Simulator", "name"),
    (f"{OSP}Variable", "simulator"),
    (f"{OSP}Variable", "name"),
    (f"{OSP}InitialValue", "variable"),
    (f"{OSP}LinearTransformation", "name"),
    (f"{OSP}Signal", "function"),
    (f"{OSP}Signal", "name"),
]
# built-in scenarios whose events no export format can carry (cosim.export.transformations)
NOT_EXPORTABLE = {"depth-steps", "mass-jam", "thruster-failure", "zigzag-20"}


def _names(root: etree._Element, kinds: list[tuple[str, str]]) -> dict[str, list[str]]:
    found: dict[str, list[str]] = {}
    for tag, attribute in kinds:
        for element in root.iter(tag):
            found.setdefault(f"{etree.QName(tag).localname}@{attribute}", []).append(
                element.get(attribute)
            )
    return found


def _export(scenario_id: str, fmu_dir: Path, folder: Path) -> tuple[etree._Element, etree._Element]:
    scenario = load_scenario(scenario_id, fmu_dir)
    archive = export_ssp(scenario, folder / f"{scenario_id}.ssp")
    with zipfile.ZipFile(archive) as z:
        ssd = etree.fromstring(z.read("SystemStructure.ssd"))
    osp = etree.parse(str(export_osp(scenario, folder / f"{scenario_id}-osp"))).getroot()
    return ssd, osp


@pytest.mark.parametrize("scenario_id", sorted(builtin_scenarios()))
def test_every_name_an_export_writes_is_an_identifier_every_importer_accepts(
    scenario_id: str, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    fmu_dir = fmu_paths["AuvPlant"].parent
    if scenario_id in NOT_EXPORTABLE:
        with pytest.raises(CosimError, match=r"it has no counterpart for (event|fault)"):
            _export(scenario_id, fmu_dir, tmp_path)
        return
    ssd, osp = _export(scenario_id, fmu_dir, tmp_path)
    names = {**_names(ssd, SSD_NAMES), **_names(osp, OSP_NAMES)}
    for kind in ("SystemStructureDescription@name", "System@name", "Component@name",
                 "Connector@name", "Simulator@name"):  # fmt: skip
        assert names.get(kind), f"{scenario_id}: the export wrote no {kind}"
    bad = {kind: [n for n in found if not OMSIMULATOR_IDENT.match(n or "")]
           for kind, found in names.items()}  # fmt: skip
    assert not any(bad.values()), f"{scenario_id}: {bad}"
    for element in (ssd, ssd.find(f"{SSD}System")):
        assert f"scenario {scenario_id}:" in element.get("description")


def test_a_scenario_id_that_is_no_identifier_becomes_one_in_the_ssd(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """bs-3 is named bs_3 (OMSimulator: "bs-3 is not a valid ident"); an id starting with a
    digit gets a prefix."""
    fmu_dir = fmu_paths["AuvPlant"].parent
    text = scenario_path("bs-3").read_text()
    assert not re.search(r"(?m)^id\b", text)  # the file's name gives its id
    for scenario_id, expected in (("bs-3", "bs_3"), ("3d.run-1", "scenario_3d_run_1")):
        path = tmp_path / f"{scenario_id}.toml"
        path.write_text(f'id = "{scenario_id}"\n{text}')
        archive = export_ssp(load_scenario(path, fmu_dir), tmp_path / f"{scenario_id}.ssp")
        with zipfile.ZipFile(archive) as z:
            root = etree.fromstring(z.read("SystemStructure.ssd"))
        assert root.get("name") == root.find(f"{SSD}System").get("name") == expected
        assert root.get("description").startswith(f"auv-cosim scenario {scenario_id}: ")


def test_an_instance_name_no_importer_accepts_is_refused_before_writing(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    scenario = tmp_path / "underscore.toml"
    scenario.write_text(
        f'id = "underscore"\nstop_time = 1.0\n[coupling]\nstep = 0.01\n'
        f'[instances._plant]\nfmu = "{fmu_paths["AuvPlant"]}"\n'
    )
    target = tmp_path / "underscore.ssp"
    with pytest.raises(CosimError, match=r"instance names \['_plant'\] .* not names every FMI"):
        export_ssp(load_scenario(scenario), target)
    assert not target.exists()
