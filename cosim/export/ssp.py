"""A scenario as an SSP 1.0 archive: ``SystemStructure.ssd`` and the FMUs under ``resources/``.

The SSD is built with pyssp-standard's object model (:func:`ssd_xml`); see
:mod:`cosim.export` for what importers read from it.
"""

from __future__ import annotations

import dataclasses
import tempfile
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from lxml import etree
from pyssp_standard.common_content_ssc import (
    Annotation,
    TopLevelMetaData,
    TypeBoolean,
    TypeInteger,
    TypeReal,
    TypeString,
)
from pyssp_standard.parameter_types import ParameterType
from pyssp_standard.ssd import (
    SSD,
    Connection,
    Connector,
    DefaultExperiment,
    ParameterBinding,
    System,
)
from pyssp_standard.ssd import Component as SsdComponent
from pyssp_standard.ssv import SSVElem
from pyssp_standard.unit import BaseUnit, Unit, Units

from cosim.errors import CosimError
from cosim.export.components import (
    Component,
    components,
    description,
    file_starts,
    model_name,
    value_type,
    xml_literal,
)
from cosim.export.files import replacing_file
from cosim.export.transformations import linear_transformations
from cosim.fmus.interface import Variable
from cosim.limits import unwritten
from cosim.scenario.spec import Scenario

PARAMETER_SET = "initial"
"""Name of the SSP parameter set holding the scenario's start values."""

NAMESPACES = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
# The SSD schema's order of the root's children (pyssp-standard writes Units too late).
_ROOT_ORDER = ("System", "Enumerations", "Units", "DefaultExperiment", "Annotations")
_SSC_TYPES = {"Real": TypeReal, "Integer": TypeInteger, "Enumeration": TypeInteger,
              "Boolean": TypeBoolean, "String": TypeString}  # fmt: skip
_DIMENSIONLESS = "1"
# pyssp-standard writes a Real value's unit even when it is None (and fails): a value in a
# unit the SSD cannot declare carries this name through it, taken off afterwards
_NO_UNIT = "auv-cosim: no unit"
# Fixed zip timestamps make the same scenario export to the same bytes.
_ZIP_DATE = (2000, 1, 1, 0, 0, 0)


def export_ssp(
    scenario: Scenario,
    path: str | Path,
    fmu_paths: Mapping[str, Path] | None = None,
    overwrite: bool = False,
) -> Path:
    """Write ``scenario`` as an SSP 1.0 archive at ``path``; returns the absolute path.

    An existing file at ``path`` is replaced only if an earlier export wrote it, or with
    ``overwrite``.

    ``fmu_paths`` optionally maps instance names to the FMU files to package. A custom
    ``vehicle`` set of the plant or the autopilot is written inline (its TOML text, which
    they take in place of a path: :func:`cosim.export.components.components`); other files
    that start values name are packed as ``resources/<instance>/<name>`` and the start
    value becomes that path, relative to the archive's root.

    Raises:
        CosimError: ``path`` is not named ``*.ssp`` (SSP 1.0 names its archives so, and
            libcosim unpacks no other file), or the export fails.
    """
    path = Path(path)
    if path.suffix != ".ssp" and not path.is_dir():  # (a folder: replacing_file says so)
        raise CosimError(
            f"cannot write {path}: an SSP archive's name ends in '.ssp' (SSP 1.0; libcosim "
            f"loads no other), got {path.name!r}"
        )
    linear_transformations(scenario, "SSP")  # refuse what SSP cannot carry, before work
    parts = components(scenario, fmu_paths)
    packed: dict[str, Path] = {}
    for i, part in enumerate(parts):
        files = file_starts(scenario.instances[part.name])
        moved = {var: f"resources/{part.name}/{file.name}" for var, file in files.items()}
        packed.update({moved[var]: file for var, file in files.items()})
        parts[i] = dataclasses.replace(part, start={**part.start, **moved})
    ssd = ssd_xml(scenario, parts)
    with replacing_file(path, overwrite) as tmp, zipfile.ZipFile(tmp, "w") as archive:
        _add_bytes(archive, "SystemStructure.ssd", ssd, zipfile.ZIP_DEFLATED)
        for resource, fmu_path in sorted({c.resource: c.fmu_path for c in parts}.items()):
            # FMUs are zip archives already: store them, do not compress again.
            _add_bytes(archive, f"resources/{resource}", fmu_path.read_bytes(), zipfile.ZIP_STORED)
        for name, file in sorted(packed.items()):
            _add_bytes(archive, name, file.read_bytes(), zipfile.ZIP_DEFLATED)
    return path.resolve()


def _add_bytes(archive: zipfile.ZipFile, name: str, data: bytes, compression: int) -> None:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = compression
    info.external_attr = 0o644 << 16
    archive.writestr(info, data)


def ssd_xml(scenario: Scenario, parts: Sequence[Component]) -> bytes:
    """``SystemStructure.ssd`` for ``scenario``, built with pyssp-standard's object model.

    The model and system are named :func:`~cosim.export.components.model_name` (an
    identifier every importer accepts), their description holds the scenario's id. Units
    are declared as the FMUs' own ``UnitDefinitions`` define them (one source).
    Workarounds for pyssp-standard 0.9.1 (each measured):
    * a ``ssv:Real`` without a unit makes it write ``unit=None`` and fail, so every Real
      start value gets a unit, dimensionless ones ``"1"`` (declared with an empty
      ``BaseUnit``, as OMSimulator writes it), and one in a unit its FMU gives no base
      units for (which the SSD cannot declare) :data:`_NO_UNIT`, removed afterwards;
    * it declares ``ssv`` on each inline parameter set and nothing for annotations, so the
      namespaces are all moved onto the root element afterwards (some importers resolve
      prefixes only there);
    * it writes ``ssd:Units`` after ``ssd:DefaultExperiment``, against the schema's order;
    * it stamps the import time as ``generationDateAndTime``: left out, so the same
      scenario exports to the same bytes.
    """
    units = _UnitTable()
    system = System(name=model_name(scenario))
    for comp in parts:
        system.elements.append(_ssd_component(comp, units))
    for c in scenario.connections:
        system.connections.append(
            Connection(
                start_element=c.source_instance,
                start_connector=c.source_variable,
                end_element=c.target_instance,
                end_connector=c.target_variable,
            )
        )
    system.annotations.add_annotation(_openmodelica_step(scenario.coupling.step))
    root = _written(scenario, system, units)
    for element in (root, root.find("ssd:System", NAMESPACES)):  # pyssp-standard writes none
        element.set("description", description(scenario))
    for value in root.iterfind(f".//ssv:Real[@unit='{_NO_UNIT}']", NAMESPACES):
        del value.attrib["unit"]  # as on its connector: a unit is optional in SSP
    _add_step_size_hints(root, scenario, parts)
    _add_linear_transformations(root, scenario)
    root[:] = sorted(root, key=lambda child: _ROOT_ORDER.index(etree.QName(child).localname))
    etree.cleanup_namespaces(root, top_nsmap=NAMESPACES, keep_ns_prefixes=list(NAMESPACES))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


class _UnitTable:
    """The SSD's unit declarations: each unit once, as the FMU using it defines it."""

    def __init__(self) -> None:
        self.units: dict[str, Unit] = {}
        self._defined: dict[str, tuple[Mapping[str, float], str]] = {}  # -> (exponents, FMU)

    def name_of(self, comp: Component, var: Variable) -> str | None:
        """The variable's unit name, declared in the SSD with the FMU's own definition;
        None for a unit the FMU gives no SI base units for (a unit is optional on an SSP
        connector and parameter: one the SSD cannot define is left off, as the FMU's own
        description still names it).

        Raises:
            CosimError: two FMUs define the same unit name differently.
        """
        fmu = comp.fmu_path.name
        exponents: Mapping[str, float] | None
        if var.unit is None:
            name, exponents = _DIMENSIONLESS, {}
        else:
            name, exponents = var.unit, comp.interface.units.get(var.unit)
            if exponents is None:
                return None
        if name not in self.units:
            self.units[name] = Unit(name, base_unit=BaseUnit(dict(exponents)))
            self._defined[name] = (exponents, fmu)
        elif self._defined[name][0] != exponents:
            first, where = self._defined[name]
            raise CosimError(f"unit {name!r} means {first} in {where} but {exponents} in {fmu}")
        return name


def _ssd_component(comp: Component, units: _UnitTable) -> SsdComponent:
    """The SSD component: its connectors and the start values as a parameter set."""
    element = SsdComponent()
    element.name = comp.name
    element.component_type = "application/x-fmu-sharedlibrary"
    element.source = f"resources/{comp.resource}"
    for name in comp.connector_names():
        var = comp.variable(name)
        if var.type == "Real":  # a connector's unit is optional: only the FMU's
            type_ = TypeReal(units.name_of(comp, var) if var.unit else None)
        else:
            type_ = _SSC_TYPES[var.type]()
        element.connectors.append(Connector(name=name, kind=var.causality, type_=type_))
    if comp.start:
        element.parameter_bindings = [ParameterBinding(ssv=_parameter_set(comp, units))]
    return element


def _parameter_set(comp: Component, units: _UnitTable) -> SSVElem:
    """The inline parameter set :data:`PARAMETER_SET` holding ``comp``'s start values."""
    parameters = []
    for name, value in comp.start.items():
        var = comp.variable(name)
        attributes = {"value": xml_literal(value)}
        if var.type == "Real":
            attributes["unit"] = units.name_of(comp, var) or _NO_UNIT
        kind = value_type(var.type)
        parameters.append(
            {"name": name, "type_name": kind, "type_value": ParameterType(kind, attributes)}
        )
    return SSVElem(
        name=PARAMETER_SET,
        parameters=parameters,
        units=Units(),
        enumerations=None,
        top_level_metadata=TopLevelMetaData(generationTool="", generationDateAndTime=""),
    )


def _openmodelica_step(step: float) -> Annotation:
    """OMSimulator's fixed-step master annotation for the system."""
    oms = Annotation("org.openmodelica")
    root = etree.SubElement(oms.root, f"{{{NAMESPACES['oms']}}}Annotations")
    info = etree.SubElement(root, f"{{{NAMESPACES['oms']}}}SimulationInformation")
    etree.SubElement(
        info, f"{{{NAMESPACES['oms']}}}FixedStepMaster", description="oms-ma", stepSize=repr(step)
    )
    return oms


def _experiment(scenario: Scenario) -> DefaultExperiment:
    """Start and stop time, and libcosim's base step as an OSP annotation."""
    experiment = DefaultExperiment()
    experiment.start_time = 0.0
    experiment.stop_time = scenario.stop_time
    osp = Annotation("com.opensimulationplatform")
    algorithm = etree.SubElement(osp.root, f"{{{NAMESPACES['osp']}}}Algorithm")
    etree.SubElement(
        algorithm,
        f"{{{NAMESPACES['osp']}}}FixedStepAlgorithm",
        baseStepSize=repr(scenario.coupling.step),
    )
    experiment.annotations.add_annotation(osp)
    return experiment


def _written(scenario: Scenario, system: System, units: _UnitTable) -> Any:
    """The SSD pyssp-standard writes for ``system``, parsed back as an lxml root. Raises
    CosimError naming the temporary folder when it cannot be written there (a full disk,
    the file-size limit: pyssp-standard's error names no file)."""
    temp = tempfile.gettempdir()
    try:
        with tempfile.TemporaryDirectory(prefix="auv-cosim-ssd-") as tmp:
            ssd_path = Path(tmp) / "SystemStructure.ssd"
            with SSD(ssd_path, mode="w") as ssd:
                ssd.name = model_name(scenario)
                ssd.version = "1.0"
                ssd.system = system
                ssd.default_experiment = _experiment(scenario)
                ssd.top_level_metadata.generationTool = "auv-cosim export (pyssp-standard)"
                ssd.top_level_metadata.generationDateAndTime = ""
                for unit in units.units.values():
                    ssd.units.add_unit(unit)
            return etree.parse(str(ssd_path)).getroot()
    except OSError as exc:
        raise CosimError(
            f"cannot write the system structure into the temporary folder {temp} (TMPDIR): "
            f"{unwritten(exc)}"
        ) from None


def _add_step_size_hints(root: Any, scenario: Scenario, parts: Sequence[Component]) -> None:
    """libcosim's per-component step (``osp:StepSizeHint``) for instances stepping every
    k*h; pyssp-standard's Component writes no annotations, so they are added here."""
    for comp in parts:
        if comp.step_multiple == 1:
            continue
        element = root.find(
            f"ssd:System/ssd:Elements/ssd:Component[@name='{comp.name}']", NAMESPACES
        )
        annotations = etree.SubElement(element, f"{{{NAMESPACES['ssd']}}}Annotations")
        annotation = etree.SubElement(
            annotations, f"{{{NAMESPACES['ssc']}}}Annotation", type="com.opensimulationplatform"
        )
        etree.SubElement(
            annotation,
            f"{{{NAMESPACES['osp']}}}StepSizeHint",
            value=repr(comp.step_multiple * scenario.coupling.step),
        )


def _add_linear_transformations(root: Any, scenario: Scenario) -> None:
    """Each whole-run gain or bias fault as its connection's ``ssc:LinearTransformation``
    (:mod:`cosim.export.transformations`); pyssp-standard 0.9.1 writes none itself."""
    for target, (factor, offset) in linear_transformations(scenario, "SSP").items():
        instance, variable = target.split(".", 1)
        connection = root.find(
            f"ssd:System/ssd:Connections/ssd:Connection[@endElement='{instance}']"
            f"[@endConnector='{variable}']",
            NAMESPACES,
        )
        etree.SubElement(
            connection,
            f"{{{NAMESPACES['ssc']}}}LinearTransformation",
            factor=repr(factor),
            offset=repr(offset),
        )
