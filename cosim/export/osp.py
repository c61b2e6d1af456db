"""A scenario as an OSP system structure: ``OspSystemStructure.xml`` beside the FMUs.

The format libcosim and the OSP tools load (version 0.1). It has no unit attribute, so each
initial value carries its unit and description in a comment.
"""

from __future__ import annotations

import dataclasses
import shutil
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from lxml import etree

from cosim.export.components import (
    Component,
    components,
    copied_file_name,
    file_starts,
    value_type,
    xml_literal,
)
from cosim.export.files import replacing_folder
from cosim.export.transformations import linear_transformations
from cosim.scenario.spec import Scenario

OSP_FILE = "OspSystemStructure.xml"
_OSP_NS = "http://opensimulationplatform.com/MSMI/OSPSystemStructure"


def export_osp(
    scenario: Scenario, folder: str | Path, fmu_paths: Mapping[str, Path] | None = None
) -> Path:
    """Write ``OspSystemStructure.xml`` and the FMUs into ``folder``; returns the XML's path.

    ``folder`` must not exist, be empty, or hold an earlier export, unchanged (it is then
    replaced). A file a start value names (other than a vehicle set, written inline) is
    copied beside the XML (:func:`~cosim.export.components.copied_file_name`) and the start
    value names the copy, relative: a host run from the folder finds it.
    ``fmu_paths`` optionally maps instance names to the FMU files to package.
    """
    folder = Path(folder)
    linear_transformations(scenario, "OSP")  # refuse what OSP cannot carry, before work
    parts = components(scenario, fmu_paths)
    copied: dict[str, Path] = {}
    for i, part in enumerate(parts):
        files = file_starts(scenario.instances[part.name])
        moved = {var: copied_file_name(part.name, file) for var, file in files.items()}
        copied.update({moved[var]: file for var, file in files.items()})
        parts[i] = dataclasses.replace(part, start={**part.start, **moved})
    xml = osp_xml(scenario, parts)
    with replacing_folder(folder) as tmp:
        (tmp / OSP_FILE).write_bytes(xml)
        for resource, fmu_path in {c.resource: c.fmu_path for c in parts}.items():
            shutil.copyfile(fmu_path, tmp / resource)
        for name, file in copied.items():
            shutil.copyfile(file, tmp / name)
    return (folder / OSP_FILE).resolve()


def _sub(parent: Any, tag: str, text: str | None = None, **attrib: str) -> Any:
    element = etree.SubElement(parent, f"{{{_OSP_NS}}}{tag}", attrib)
    element.text = text
    return element


def osp_xml(scenario: Scenario, parts: Sequence[Component]) -> bytes:
    """``OspSystemStructure.xml`` (format version 0.1, the schema libcosim validates)."""
    root = etree.Element(f"{{{_OSP_NS}}}OspSystemStructure", nsmap={None: _OSP_NS}, version="0.1")
    root.append(_comment(f"scenario {scenario.id}: {scenario.summary}"))
    h = scenario.coupling.step
    _sub(root, "StartTime", "0.0")
    _sub(root, "EndTime", repr(scenario.stop_time))
    _sub(root, "BaseStepSize", repr(h))
    _sub(root, "Algorithm", "fixedStep")
    simulators = _sub(root, "Simulators")
    for comp in parts:
        simulator = _sub(
            simulators, "Simulator", name=comp.name, source=comp.resource,
            stepSize=repr(comp.step_multiple * h),
        )  # fmt: skip
        if comp.start:
            _initial_values(simulator, comp)
    transformations = linear_transformations(scenario, "OSP")
    if transformations:
        functions = _sub(root, "Functions")
        for target, (factor, offset) in transformations.items():
            _sub(functions, "LinearTransformation", name=f"fault-{target}",
                 factor=repr(factor), offset=repr(offset))  # fmt: skip
    connections = _sub(root, "Connections")
    for c in scenario.connections:
        if c.target in transformations:  # source -> function "in", function "out" -> target
            for end, signal in ((c.source, "in"), (c.target, "out")):
                connection = _sub(connections, "SignalConnection")
                instance, variable = end.split(".", 1)
                _sub(connection, "Variable", simulator=instance, name=variable)
                _sub(connection, "Signal", function=f"fault-{c.target}", name=signal)
            continue
        connection = _sub(connections, "VariableConnection")
        _sub(connection, "Variable", simulator=c.source_instance, name=c.source_variable)
        _sub(connection, "Variable", simulator=c.target_instance, name=c.target_variable)
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _initial_values(simulator: Any, comp: Component) -> None:
    """The start values, each after a comment with its unit and description."""
    values = _sub(simulator, "InitialValues")
    for name, value in comp.start.items():
        var = comp.variable(name)
        unit = f" [{var.unit}]" if var.type == "Real" and var.unit else ""
        about = f": {var.description}" if var.description else ""
        values.append(_comment(f"{name}{unit}{about}"))
        initial = _sub(values, "InitialValue", variable=name)
        _sub(initial, value_type(var.type), value=xml_literal(value))


def _comment(text: str) -> Any:
    """An XML comment of ``text``, which XML forbids to hold ``--`` ("a -- b" in a summary
    or a foreign FMU's description): each written ``- -``."""
    while "--" in text:
        text = text.replace("--", "- -")
    return etree.Comment(f" {text} ")
