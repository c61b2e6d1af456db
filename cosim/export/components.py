"""What both export formats need: each instance with the FMU it packages and its interface.

The scenario has resolved and checked every connection and start value against its FMUs
(:mod:`cosim.scenario.spec`); the exporters reuse that. An FMU packaged in place of the one
the scenario resolved (given in ``fmu_paths``, or the same file rebuilt since) is only
checked to offer every variable the scenario uses with the same type and causality, so the
checked connections and start values hold for it too.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import tomli_w

from cosim.errors import CosimError
from cosim.fmus.interface import FmuInterface, FmuInterfaceError, Variable, read_interface
from cosim.scenario.spec import Instance, Scenario

StartValue = bool | int | float | str

# A character XML 1.0 has no place for, not even as a reference (its production Char):
# lxml refuses such a string with a ValueError that names neither value nor character, so
# the scenario's strings are checked first (written by hand: no library gives the test).
NOT_XML = re.compile("[^\t\n\r\x20-\ud7ff\ue000-\ufffd\U00010000-\U0010ffff]")

IDENTIFIER = re.compile(r"[a-zA-Z][a-zA-Z0-9_]*")
"""What every importer accepts as a model, system or component name: OMSimulator's rule
(``^[a-zA-Z][a-zA-Z0-9_]*$``, its ComRef::isValidIdent) is the strictest of them."""


def model_name(scenario: Scenario) -> str:
    """The scenario's id as an identifier (:data:`IDENTIFIER`), the SSD's model and system
    name: every other character an underscore (``bs-3`` -> ``bs_3``), ``scenario_`` before
    one that does not start with a letter. The id itself goes into the description."""
    name = re.sub(r"[^a-zA-Z0-9_]", "_", scenario.id)
    return name if IDENTIFIER.fullmatch(name) else f"scenario_{name}"


def description(scenario: Scenario) -> str:
    """What the exports say the model is: the scenario's id and summary."""
    return f"auv-cosim scenario {scenario.id}: {scenario.summary}"


@dataclass(frozen=True)
class Component:
    """One instance as both formats write it."""

    name: str  # instance name
    fmu_path: Path
    resource: str  # file name inside resources/ (SSP) or beside the XML (OSP)
    interface: FmuInterface  # variables and unit definitions of the packaged FMU
    start: Mapping[str, StartValue]
    step_multiple: int

    def variable(self, name: str) -> Variable:
        return self.interface.variables[name]

    def connector_names(self) -> list[str]:
        """The component's interface in the SSD: every input and output, and the parameters
        the scenario sets (in modelDescription order)."""
        return [
            v.name
            for v in self.interface.variables.values()
            if v.causality in ("input", "output")
            or (v.causality == "parameter" and v.name in self.start)
        ]


def components(scenario: Scenario, fmu_paths: Mapping[str, Path] | None) -> list[Component]:
    """The instances with the FMU each will package.

    ``fmu_paths`` maps an instance name to the FMU file to package instead of the one the
    scenario resolved (e.g. a copy built elsewhere); it must offer the same variables.

    Raises:
        CosimError: an instance name is not an :data:`IDENTIFIER`, ``fmu_paths`` names an
            unknown instance, or an FMU it names is missing, unreadable or lacks a variable
            the scenario uses.
    """
    overrides = dict(fmu_paths or {})
    named = [name for name in scenario.instances if not IDENTIFIER.fullmatch(name)]
    if named:
        raise CosimError(
            f"instance names {named} of scenario {scenario.id!r} are not names every FMI "
            "importer accepts (OMSimulator: a letter, then letters, digits or '_'): rename them"
        )
    _check_xml_text(scenario)
    unknown = sorted(set(overrides) - set(scenario.instances))
    if unknown:
        raise CosimError(
            f"fmu_paths names {unknown}, which are not instances of scenario "
            f"{scenario.id!r} (instances: {list(scenario.instances)})"
        )
    result: list[Component] = []
    resources: dict[str, Path] = {}
    for name, instance in scenario.instances.items():
        interface = _packaged(scenario, instance, Path(overrides.get(name, instance.fmu_path)))
        fmu_path = interface.path
        resource = _plain(fmu_path.name)
        if resources.get(resource, fmu_path) != fmu_path:  # two different FMUs, same name
            resource = f"{_plain(fmu_path.stem)}-{name}{fmu_path.suffix}"
        resources[resource] = fmu_path
        result.append(
            Component(
                name=name,
                fmu_path=fmu_path,
                resource=resource,
                interface=interface,
                start=_portable_start(instance),
                step_multiple=scenario.coupling.step_multiples.get(name, 1),
            )
        )
    return result


def _check_xml_text(scenario: Scenario) -> None:
    """Refuse a summary or String start value holding a character no XML file can carry.

    Raises:
        CosimError: naming the first such text and its character.
    """
    texts = {"summary": scenario.summary}
    for name, instance in scenario.instances.items():
        texts.update({f"{name}.{k}": v for k, v in instance.start.items() if isinstance(v, str)})
    for where, text in texts.items():
        bad = NOT_XML.search(text)
        if bad is not None:
            raise CosimError(
                f"cannot export scenario {scenario.id!r}: {where} = {text!r} holds "
                f"{bad.group()!r}, a character XML 1.0 cannot carry (SSP and OSP files are "
                "XML); remove it"
            )


def _packaged(scenario: Scenario, instance: Instance, fmu_path: Path) -> FmuInterface:
    """The interface of the FMU to package for ``instance``. Unless it is the one the
    scenario resolved (another file, or the file rebuilt since), it must offer every
    variable the scenario uses on that instance with the type and causality resolved."""
    try:
        interface = read_interface(fmu_path)
    except FmuInterfaceError as exc:
        raise CosimError(f"instance {instance.name!r}: {exc}") from None
    if interface is instance.interface:
        return interface
    problems = []
    for role, variable in _uses(scenario, instance.name):
        resolved = instance.interface.variables[variable]
        offered = interface.variables.get(variable)
        where = interface.path.name
        if offered is None:
            problems.append(f"{role}: {where} has no variable {variable!r}")
        elif offered.causality != resolved.causality:
            problems.append(
                f"{role}: it is {offered.causality} in {where}, expected {resolved.causality}"
            )
        elif offered.type != resolved.type:
            problems.append(f"{role}: it is {offered.type} in {where}, expected {resolved.type}")
    if problems:
        raise CosimError(
            f"cannot export scenario {scenario.id!r} with {fmu_path} as {instance.name}: "
            + "; ".join(problems)
        )
    return interface


def _uses(scenario: Scenario, instance: str) -> list[tuple[str, str]]:
    """(role, variable) of every variable of ``instance`` the scenario connects or sets."""
    uses = []
    for c in scenario.connections:
        role = f"connection {c.source} -> {c.target}"
        if c.source_instance == instance:
            uses.append((f"{role}: source {c.source}", c.source_variable))
        if c.target_instance == instance:
            uses.append((f"{role}: target {c.target}", c.target_variable))
    for name in scenario.instances[instance].start:
        uses.append((f"start value {instance}.{name}", name))
    return uses


def _plain(file_name: str) -> str:
    """A file name as a URI reference takes it unescaped (``source`` in SSP and OSP): every
    character but letters, digits, ``.``, ``-`` and ``_`` as ``_`` (libcosim took the ``#``
    of ``Plant#1.fmu`` for a fragment; ecos split ``%20`` and non-ASCII names)."""
    return re.sub(r"[^A-Za-z0-9._-]", "_", file_name)


def copied_file_name(instance: str, file: Path) -> str:
    """The name a file a start value of ``instance`` names takes beside an OSP system
    structure: ``<instance>-<name>`` (URI-plain, :func:`_plain`), one folder level as the
    export's record lists it, and never an FMU's or the XML's name (those end otherwise)."""
    return _plain(f"{instance}-{file.name}")


def file_starts(instance: Instance) -> dict[str, Path]:
    """The start values naming a file that is not written inline (every one but a vehicle
    set of the plant or the autopilot): variable -> file, absolute."""
    start = _portable_start(instance)
    return {var: file for var, file in instance.files().items() if start[var] == str(file)}


def _portable_start(instance: Instance) -> dict[str, StartValue]:
    """The start values, a vehicle set file of the plant or the autopilot given inline: the
    set's TOML text (its ``base`` chain resolved), which they take in place of a path, so
    that it travels with the system structure (a path, relative or absolute, names a
    file no host finds once the export is moved; a host runs from any folder)."""
    from plant_fmu.model.parameters import load_vehicle

    start = dict(instance.start)
    if instance.interface.model_identifier in ("AuvPlant", "AuvAutopilot"):
        vehicle = instance.files().get("vehicle")
        if vehicle is not None:
            start["vehicle"] = tomli_w.dumps(load_vehicle(vehicle).as_dict())
    return start


def value_type(fmi_type: str) -> str:
    """The type a start value of this FMI type is written as (Enumerations as Integer)."""
    return "Integer" if fmi_type == "Enumeration" else fmi_type


def xml_literal(value: StartValue) -> str:
    """XML literal: xs:boolean for bools, the shortest exact decimal for floats."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(value) if isinstance(value, float) else str(value)
