"""Export a scenario for other FMI tools: an SSP 1.0 archive or an OSP system structure.

Both exports are written from the same resolved :class:`cosim.run.scenario.Scenario` the master
runs: the instances (named as in the scenario, ``plant`` and ``controller``), their FMUs,
every explicit start value (with its unit), every connection, the stop time and the
communication step (with each instance's step multiple).

* ``export_ssp(scenario, "bs-3.ssp")`` writes ``SystemStructure.ssd`` and the FMUs under
  ``resources/`` in one zip archive (SSP 1.0). The start values are an inline parameter
  set named :data:`PARAMETER_SET` on each component; ecos applies them only when that
  name is given (``EcosSimulation.init(parameter_set="initial")`` or
  ``ecos simulate --parameterSet initial``); libcosim and OMSimulator apply them as they
  load. The step is in annotations that libcosim (``com.opensimulationplatform``) and
  OMSimulator (``org.openmodelica``) read; ecos and fmpy.ssp take it as an argument.
* ``export_osp(scenario, "bs-3-osp")`` writes ``OspSystemStructure.xml`` beside copies of
  the FMUs (the format libcosim and the OSP tools load; it has no unit attribute, so each
  initial value carries its unit in a comment).

libcosim and ecos both step every instance at t from the outputs of t - h (Jacobi); the
master's Gauss-Seidel order has no counterpart in either file.

Failures (unknown scenario, an FMU without a variable the scenario uses, a path that cannot
be written) raise :class:`CosimError` before anything is in place: the archive or folder is
built under a temporary name beside the target and renamed into place at the end.
"""

from __future__ import annotations

import argparse
import os
import secrets
import shutil
import tempfile
import zipfile
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from lxml import etree

from cosim.errors import CosimError
from cosim.run.scenario import Scenario, load_scenario

PARAMETER_SET = "initial"
"""Name of the SSP parameter set holding the scenario's start values."""

OSP_FILE = "OspSystemStructure.xml"

_NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
}
_OSP_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"
_DIMENSIONLESS = "1"
_SI_BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
# Fixed zip timestamps make the same scenario export to the same bytes.
_ZIP_DATE = (2000, 1, 1, 0, 0, 0)


# --- what both formats need, checked against the FMUs that are packaged ----------------


@dataclass(frozen=True)
class _Variable:
    name: str
    type: str  # Real, Integer, Boolean, String, Enumeration
    causality: str
    unit: str | None
    description: str


@dataclass(frozen=True)
class _Component:
    name: str  # instance name
    fmu_path: Path
    resource: str  # file name inside resources/ (SSP) or beside the XML (OSP)
    variables: Mapping[str, _Variable]
    units: Mapping[str, dict[str, float] | None]  # the FMU's UnitDefinitions (SI exponents)
    start: Mapping[str, bool | int | float | str]
    step_multiple: int


def _components(scenario: Scenario, fmu_paths: Mapping[str, Path] | None) -> list[_Component]:
    """The instances with the FMU each will package, every reference checked against it.

    ``fmu_paths`` maps an instance name to the FMU file to package instead of the one the
    scenario resolved (e.g. a copy built elsewhere); its variables must still fit.
    """
    overrides = dict(fmu_paths or {})
    unknown = sorted(set(overrides) - set(scenario.instances))
    if unknown:
        raise CosimError(
            f"fmu_paths names {unknown}, which are not instances of scenario "
            f"{scenario.id!r} (instances: {list(scenario.instances)})"
        )
    components: list[_Component] = []
    resources: dict[str, Path] = {}
    for name, instance in scenario.instances.items():
        fmu_path = Path(overrides.get(name, instance.fmu_path)).resolve()
        resource = fmu_path.name
        if resources.get(resource, fmu_path) != fmu_path:  # two different FMUs, same name
            resource = f"{fmu_path.stem}-{name}{fmu_path.suffix}"
        resources[resource] = fmu_path
        variables, units = _read_model_description(fmu_path, name)
        components.append(
            _Component(
                name=name,
                fmu_path=fmu_path,
                resource=resource,
                variables=variables,
                units=units,
                start=dict(instance.start),
                step_multiple=scenario.coupling.step_multiples.get(name, 1),
            )
        )
    _check(scenario, {c.name: c for c in components})
    return components


def _read_model_description(
    fmu_path: Path, instance: str
) -> tuple[dict[str, _Variable], dict[str, dict[str, float] | None]]:
    """The FMU's variables and its unit definitions (SI base-unit exponents, plus factor
    and offset where they are not 1 and 0; None for a unit declared by name only)."""
    from fmpy import read_model_description

    if not fmu_path.is_file():
        raise CosimError(f"instance {instance!r}: FMU {fmu_path} does not exist")
    try:
        md = read_model_description(str(fmu_path))
    except Exception as exc:  # fmpy raises plain Exception for a broken model description
        raise CosimError(f"instance {instance!r}: {fmu_path} is not a valid FMU: {exc}") from None
    variables = {}
    for v in md.modelVariables:
        unit = v.unit or (v.declaredType.unit if v.declaredType is not None else None)
        variables[v.name] = _Variable(v.name, v.type, v.causality, unit, v.description or "")
    units: dict[str, dict[str, float] | None] = {}
    for unit in md.unitDefinitions:
        base = unit.baseUnit
        if base is None:
            units[unit.name] = None
            continue
        exponents = {k: getattr(base, k) for k in _SI_BASE if getattr(base, k)}
        if base.factor != 1.0:
            exponents["factor"] = base.factor
        if base.offset != 0.0:
            exponents["offset"] = base.offset
        units[unit.name] = exponents
    return variables, units


def _check(scenario: Scenario, components: Mapping[str, _Component]) -> None:
    """Every connection and start value must exist, with the right causality and type."""
    problems = []

    def lookup(instance: str, name: str, causalities: tuple[str, ...], role: str) -> Any:
        comp = components[instance]
        var = comp.variables.get(name)
        if var is None:
            problems.append(
                f"{role} {instance}.{name}: {comp.fmu_path.name} has no variable {name!r}"
            )
        elif var.causality not in causalities:
            problems.append(
                f"{role} {instance}.{name}: it is {var.causality} in {comp.fmu_path.name}, "
                f"expected {' or '.join(causalities)}"
            )
        else:
            return var
        return None

    for c in scenario.connections:
        role = f"connection {c.source} -> {c.target}:"
        src = lookup(c.source_instance, c.source_variable, ("output",), role + " source")
        tgt = lookup(c.target_instance, c.target_variable, ("input",), role + " target")
        if src is not None and tgt is not None and src.type != tgt.type:
            problems.append(f"{role} types differ ({src.type} -> {tgt.type})")
    for comp in components.values():
        for name, value in comp.start.items():
            var = lookup(comp.name, name, ("parameter", "input"), "start value")
            if var is not None and _type_of(value) != _fmi_value_type(var.type):
                problems.append(
                    f"start value {comp.name}.{name} = {value!r}: {name} is {var.type} "
                    f"in {comp.fmu_path.name}"
                )
    if problems:
        raise CosimError(f"cannot export scenario {scenario.id!r}: " + "; ".join(problems))


def _type_of(value: bool | int | float | str) -> str:
    if isinstance(value, bool):
        return "Boolean"
    if isinstance(value, int):
        return "Integer"
    return "Real" if isinstance(value, float) else "String"


def _fmi_value_type(fmi_type: str) -> str:
    return "Integer" if fmi_type == "Enumeration" else fmi_type


def _text(value: bool | int | float | str) -> str:
    """XML literal: xs:boolean for bools, the shortest exact decimal for floats."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)


def _connector_names(comp: _Component) -> list[str]:
    """The component's interface in the SSD: every input and output, and the parameters
    the scenario sets (in modelDescription order)."""
    return [
        v.name
        for v in comp.variables.values()
        if v.causality in ("input", "output")
        or (v.causality == "parameter" and v.name in comp.start)
    ]


# --- SSP --------------------------------------------------------------------------------


def export_ssp(
    scenario: Scenario, path: str | Path, fmu_paths: Mapping[str, Path] | None = None
) -> Path:
    """Write ``scenario`` as an SSP 1.0 archive at ``path``; returns the absolute path.

    ``fmu_paths`` optionally maps instance names to the FMU files to package.
    """
    path = Path(path)
    components = _components(scenario, fmu_paths)
    ssd = ssd_xml(scenario, components)
    with _replacing_file(path) as tmp, zipfile.ZipFile(tmp, "w") as archive:
        _add_bytes(archive, "SystemStructure.ssd", ssd, zipfile.ZIP_DEFLATED)
        for resource, fmu_path in sorted({c.resource: c.fmu_path for c in components}.items()):
            # FMUs are zip archives already: store them, do not compress again.
            _add_bytes(archive, f"resources/{resource}", fmu_path.read_bytes(), zipfile.ZIP_STORED)
    return path.resolve()


def _add_bytes(archive: zipfile.ZipFile, name: str, data: bytes, compression: int) -> None:
    info = zipfile.ZipInfo(name, date_time=_ZIP_DATE)
    info.compress_type = compression
    info.external_attr = 0o644 << 16
    archive.writestr(info, data)


def ssd_xml(scenario: Scenario, components: list[_Component]) -> bytes:
    """``SystemStructure.ssd`` for ``scenario``, built with pyssp-standard's object model.

    Units are declared as the FMUs' own ``UnitDefinitions`` define them (one source).
    Workarounds for pyssp-standard 0.9.1 (each measured):
    * a ``ssv:Real`` without a unit makes it write ``unit=None`` and fail, so every Real
      start value gets a unit, dimensionless ones ``"1"`` (declared with an empty
      ``BaseUnit``, as OMSimulator writes it);
    * it declares ``ssv`` on each inline parameter set and nothing for annotations, so the
      namespaces are all moved onto the root element afterwards (some importers resolve
      prefixes only there);
    * it writes ``ssd:Units`` after ``ssd:DefaultExperiment``, against the schema's order;
    * it stamps the import time as ``generationDateAndTime``: left out, so the same
      scenario exports to the same bytes.
    """
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
        Component,
        Connection,
        Connector,
        DefaultExperiment,
        ParameterBinding,
        System,
    )
    from pyssp_standard.ssv import SSVElem
    from pyssp_standard.unit import BaseUnit, Unit, Units

    types = {"Real": TypeReal, "Integer": TypeInteger, "Enumeration": TypeInteger,
             "Boolean": TypeBoolean, "String": TypeString}  # fmt: skip
    h = scenario.coupling.step
    units: dict[str, Unit] = {}
    definitions: dict[str, tuple[dict[str, float], str]] = {}  # unit -> (exponents, FMU)

    def unit_of(comp: _Component, var: _Variable) -> str:
        """The variable's unit name, declared in the SSD with the FMU's own definition."""
        if var.unit is None:
            name, exponents = _DIMENSIONLESS, {}
        else:
            name, exponents = var.unit, comp.units.get(var.unit)
            if exponents is None:
                raise CosimError(
                    f"{comp.fmu_path.name} declares no SI base units for unit {name!r} "
                    f"(variable {var.name}); an SSP unit needs them"
                )
        if name not in units:
            units[name] = Unit(name, base_unit=BaseUnit(exponents))
            definitions[name] = (exponents, comp.fmu_path.name)
        elif definitions[name][0] != exponents:
            raise CosimError(
                f"unit {name!r} means {definitions[name][0]} in {definitions[name][1]} but "
                f"{exponents} in {comp.fmu_path.name}"
            )
        return name

    system = System(name=scenario.id)
    for comp in components:
        element = Component()
        element.name = comp.name
        element.component_type = "application/x-fmu-sharedlibrary"
        element.source = f"resources/{comp.resource}"
        for name in _connector_names(comp):
            var = comp.variables[name]
            if var.type == "Real":  # a connector's unit is optional: only the FMU's
                type_ = TypeReal(unit_of(comp, var) if var.unit else None)
            else:
                type_ = types[var.type]()
            element.connectors.append(Connector(name=name, kind=var.causality, type_=type_))
        parameters = []
        for name, value in comp.start.items():
            var = comp.variables[name]
            attributes = {"value": _text(value)}
            if var.type == "Real":
                attributes["unit"] = unit_of(comp, var)
            value_type = _fmi_value_type(var.type)
            parameters.append(
                {
                    "name": name,
                    "type_name": value_type,
                    "type_value": ParameterType(value_type, attributes),
                }
            )
        if parameters:
            ssv = SSVElem(
                name=PARAMETER_SET,
                parameters=parameters,
                units=Units(),
                enumerations=None,
                top_level_metadata=TopLevelMetaData(generationTool="", generationDateAndTime=""),
            )
            element.parameter_bindings = [ParameterBinding(ssv=ssv)]
        system.elements.append(element)
    for c in scenario.connections:
        system.connections.append(
            Connection(
                start_element=c.source_instance,
                start_connector=c.source_variable,
                end_element=c.target_instance,
                end_connector=c.target_variable,
            )
        )
    oms = Annotation("org.openmodelica")
    oms_root = etree.SubElement(oms.root, f"{{{_NS['oms']}}}Annotations")
    info = etree.SubElement(oms_root, f"{{{_NS['oms']}}}SimulationInformation")
    etree.SubElement(
        info, f"{{{_NS['oms']}}}FixedStepMaster", description="oms-ma", stepSize=repr(h)
    )
    system.annotations.add_annotation(oms)

    experiment = DefaultExperiment()
    experiment.start_time = 0.0
    experiment.stop_time = scenario.stop_time
    osp = Annotation("com.opensimulationplatform")
    algorithm = etree.SubElement(osp.root, f"{{{_NS['osp']}}}Algorithm")
    etree.SubElement(algorithm, f"{{{_NS['osp']}}}FixedStepAlgorithm", baseStepSize=repr(h))
    experiment.annotations.add_annotation(osp)

    with tempfile.TemporaryDirectory(prefix="auv-cosim-ssd-") as tmp:
        ssd_path = Path(tmp) / "SystemStructure.ssd"
        with SSD(ssd_path, mode="w") as ssd:
            ssd.name = scenario.id
            ssd.version = "1.0"
            ssd.system = system
            ssd.default_experiment = experiment
            ssd.top_level_metadata.generationTool = "auv-cosim export (pyssp-standard)"
            ssd.top_level_metadata.generationDateAndTime = ""
            for unit in units.values():
                ssd.units.add_unit(unit)
        root = etree.parse(str(ssd_path)).getroot()
    _add_step_size_hints(root, scenario, components)
    # pyssp-standard writes ssd:Units after ssd:DefaultExperiment; the SSD schema wants
    # System, Enumerations, Units, DefaultExperiment, Annotations in this order.
    order = ["System", "Enumerations", "Units", "DefaultExperiment", "Annotations"]
    root[:] = sorted(root, key=lambda child: order.index(etree.QName(child).localname))
    etree.cleanup_namespaces(root, top_nsmap=_NS, keep_ns_prefixes=list(_NS))
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _add_step_size_hints(root: Any, scenario: Scenario, components: list[_Component]) -> None:
    """libcosim's per-component step (``osp:StepSizeHint``) for instances stepping every
    k*h; pyssp-standard's Component writes no annotations, so they are added here."""
    for comp in components:
        if comp.step_multiple == 1:
            continue
        element = root.find(f"ssd:System/ssd:Elements/ssd:Component[@name='{comp.name}']", _NS)
        annotations = etree.SubElement(element, f"{{{_NS['ssd']}}}Annotations")
        annotation = etree.SubElement(
            annotations, f"{{{_NS['ssc']}}}Annotation", type="com.opensimulationplatform"
        )
        etree.SubElement(
            annotation,
            f"{{{_NS['osp']}}}StepSizeHint",
            value=repr(comp.step_multiple * scenario.coupling.step),
        )


# --- OSP system structure ------------------------------------------------------------


def export_osp(
    scenario: Scenario, folder: str | Path, fmu_paths: Mapping[str, Path] | None = None
) -> Path:
    """Write ``OspSystemStructure.xml`` and the FMUs into ``folder``; returns the XML's path.

    ``folder`` must not exist, be empty, or hold an earlier export (it is then replaced).
    """
    folder = Path(folder)
    components = _components(scenario, fmu_paths)
    xml = osp_xml(scenario, components)
    with _replacing_folder(folder) as tmp:
        (tmp / OSP_FILE).write_bytes(xml)
        for resource, fmu_path in {c.resource: c.fmu_path for c in components}.items():
            shutil.copyfile(fmu_path, tmp / resource)
    return (folder / OSP_FILE).resolve()


def osp_xml(scenario: Scenario, components: list[_Component]) -> bytes:
    """``OspSystemStructure.xml`` (format version 0.1, the schema libcosim validates)."""

    def sub(parent: Any, tag: str, text: str | None = None, **attrib: str) -> Any:
        element = etree.SubElement(parent, f"{{{_OSP_NS}}}{tag}", attrib)
        element.text = text
        return element

    root = etree.Element(f"{{{_OSP_NS}}}OspSystemStructure", nsmap={None: _OSP_NS}, version="0.1")
    root.append(etree.Comment(f" scenario {scenario.id}: {scenario.summary} "))
    h = scenario.coupling.step
    sub(root, "StartTime", "0.0")
    sub(root, "EndTime", repr(scenario.stop_time))
    sub(root, "BaseStepSize", repr(h))
    sub(root, "Algorithm", "fixedStep")
    simulators = sub(root, "Simulators")
    for comp in components:
        simulator = sub(
            simulators, "Simulator", name=comp.name, source=comp.resource,
            stepSize=repr(comp.step_multiple * h),
        )  # fmt: skip
        if not comp.start:
            continue
        values = sub(simulator, "InitialValues")
        for name, value in comp.start.items():
            var = comp.variables[name]
            unit = f" [{var.unit}]" if var.type == "Real" and var.unit else ""
            about = f": {var.description}" if var.description else ""
            values.append(etree.Comment(f" {name}{unit}{about} "))
            initial = sub(values, "InitialValue", variable=name)
            sub(initial, _fmi_value_type(var.type), value=_text(value))
    connections = sub(root, "Connections")
    for c in scenario.connections:
        connection = sub(connections, "VariableConnection")
        sub(connection, "Variable", simulator=c.source_instance, name=c.source_variable)
        sub(connection, "Variable", simulator=c.target_instance, name=c.target_variable)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


# --- writing without leaving anything partial --------------------------------------------


@contextmanager
def _replacing_file(path: Path) -> Iterator[Path]:
    """Yield a new temporary file beside ``path``; on success it replaces ``path`` atomically.

    (Not ``tempfile.mkstemp``: its files are private (0600); this one gets the umask's
    permissions like any file the user writes.)"""
    if path.is_dir():
        raise CosimError(f"cannot write {path}: it is a folder")
    tmp = path.parent / f".{path.name}.{secrets.token_hex(4)}.tmp"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp.open("xb").close()
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {exc.strerror or exc}") from None
    try:
        yield tmp
        os.replace(tmp, path)
    except OSError as exc:
        raise CosimError(f"cannot write {path}: {exc.strerror or exc}") from None
    finally:
        tmp.unlink(missing_ok=True)


@contextmanager
def _replacing_folder(folder: Path) -> Iterator[Path]:
    """Yield a new temporary folder beside ``folder``; on success it takes ``folder``'s place
    (an earlier export there is replaced; anything else there is an error)."""
    if folder.exists():
        if not folder.is_dir():
            raise CosimError(f"cannot write {folder}: it exists and is not a folder")
        if any(folder.iterdir()) and not (folder / OSP_FILE).is_file():
            raise CosimError(
                f"cannot write {folder}: it is not empty and holds no {OSP_FILE} from an "
                "earlier export; choose a new or empty folder"
            )
    tag = secrets.token_hex(4)
    tmp = folder.parent / f".{folder.name}.{tag}.tmp"
    old = folder.parent / f".{folder.name}.{tag}.old"
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        tmp.mkdir()
        yield tmp
        if folder.exists():
            folder.rename(old)
        tmp.rename(folder)
    except OSError as exc:
        if old.exists() and not folder.exists():
            old.rename(folder)
        raise CosimError(f"cannot write {folder}: {exc.strerror or exc}") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
        shutil.rmtree(old, ignore_errors=True)


# --- command line ----------------------------------------------------------------------


def export_from_cli(args: argparse.Namespace) -> int:
    """``auv-cosim export SCENARIO --ssp FILE | --osp DIR [--fmu-dir DIR]``."""
    if (args.ssp is None) == (args.osp is None):
        raise CosimError("give exactly one of --ssp FILE or --osp DIR")
    scenario = load_scenario(args.scenario, fmu_dir=args.fmu_dir)
    if args.ssp is not None:
        print(f"SSP archive: {export_ssp(scenario, args.ssp)}")
    else:
        print(f"OSP system structure: {export_osp(scenario, args.osp)}")
    if scenario.coupling.algorithm != "jacobi":
        print(
            f"note: libcosim and ecos couple Jacobi-style; {scenario.id} runs "
            f"{scenario.coupling.algorithm} in auv-cosim, so compare with "
            f"`auv-cosim run {scenario.id} --algorithm jacobi`"
        )
    return 0
