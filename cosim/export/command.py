"""``auv-cosim export``: load a scenario, write it in one format, say where (stdout) and
what to mind (stderr)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

from cosim.errors import CosimError
from cosim.export.components import copied_file_name, file_starts
from cosim.export.osp import export_osp
from cosim.export.ssp import export_ssp
from cosim.scenario.coupling_graph import feedthrough
from cosim.scenario.spec import Scenario, load_scenario


def export_scenario(
    scenario: str | Path,
    *,
    ssp: Path | None,
    osp: Path | None,
    fmu_dir: Path,
    force: bool = False,
) -> int:
    """Export the built-in scenario id or scenario file ``scenario`` as an SSP archive at
    ``ssp`` or an OSP system structure in the folder ``osp`` (exactly one); 0 on success.

    ``fmu_dir`` is where the built-in FMUs live (built there on first use). An existing
    ``ssp`` file is replaced only if an earlier export wrote it, or with ``force``.

    Raises:
        CosimError: both or neither of ``ssp`` and ``osp`` given, or the export failed.
    """
    if (ssp is None) == (osp is None):
        raise CosimError("give exactly one of --ssp FILE or --osp DIR")
    resolved = load_scenario(scenario, fmu_dir=fmu_dir)
    flag, target = ("--ssp", ssp) if ssp is not None else ("--osp", osp)
    try:
        if ssp is not None:
            print(f"SSP archive: {export_ssp(resolved, ssp, overwrite=force)}")
        elif osp is not None:
            print(f"OSP system structure: {export_osp(resolved, osp)}")
    except CosimError as exc:
        raise CosimError(_flag_named(str(exc), flag, target)) from None
    notes = _notes(resolved, scenario) + _feedthrough_notes(resolved)
    if ssp is not None:
        notes += _skipped_start_notes(resolved)
    notes += _file_notes(resolved, "ssp" if ssp is not None else "osp")
    notes += _debug_log_notes(resolved)
    for note in notes:  # messages, not what was written: stderr
        print(f"auv-cosim export: note: {note}", file=sys.stderr)
    return 0


def _flag_named(message: str, flag: str, target: Path | None) -> str:
    """A writer's refusal, "cannot write PATH: ...", with the flag that named PATH:
    "cannot write --ssp PATH: ..." (the writers name the path only: they serve Python
    callers too)."""
    written = f"cannot write {target}:"
    if message.startswith(written):
        return f"cannot write {flag} {target}:{message.removeprefix(written)}"
    return message


def _notes(resolved: Scenario, scenario: str | Path) -> list[str]:
    """What another tool running the export does otherwise than ``auv-cosim run``."""
    notes = []
    coupling = resolved.coupling
    if coupling.algorithm == "adaptive":
        notes.append(
            f"SSP and OSP have no error-controlled step: {resolved.id} exported at the "
            f"fixed step coupling.step = {coupling.step!r} s (its first step)"
        )
    if coupling.algorithm != "jacobi" or coupling.extrapolation != "none":
        notes.append(
            f"libcosim and ecos couple Jacobi-style with held inputs; {resolved.id} "
            f"runs {coupling.algorithm} with {_inputs(coupling.extrapolation)} in "
            f"auv-cosim, so compare with "
            f"`auv-cosim run {shlex.quote(str(scenario))} --algorithm jacobi "
            "--extrapolation none`"
        )
    sources = {c.source_instance for c in resolved.connections}
    slow = {n: k for n, k in coupling.step_multiples.items() if k > 1 and n in sources}
    if slow:
        notes.append(
            f"{', '.join(f'{n} steps every {k} h' for n, k in slow.items())}: libcosim "
            "hands a slow instance's outputs on when its step ends, auv-cosim and ecos from "
            "the next base step: results differ (docs/hosts.md)"
        )
    used = [c.source for c in resolved.connections] + [c.target for c in resolved.connections]
    used += [f"{n}.{v}" for n, inst in resolved.instances.items() for v in inst.start]
    enums = sorted({ref for ref in used if _type_of(resolved, ref) == "Enumeration"})
    if enums:
        notes.append(
            f"{', '.join(enums)}: Enumeration, written as Integer (libcosim reads no "
            "Enumeration variable: it refuses an OSP file or an SSP connection naming one "
            "and skips an SSP start value of one)"
        )
    return notes


def _feedthrough_notes(scenario: Scenario) -> list[str]:
    """Each instance passing a connected input on to an output within a step (its
    ModelStructure says so: :func:`cosim.scenario.coupling_graph.feedthrough`, as the
    master reads it): auv-cosim hands on the same point's value, even under Jacobi
    (docs/coupling.md), libcosim and ecos the previous step's."""
    driven: dict[str, set[str]] = {}
    for c in scenario.connections:
        driven.setdefault(c.target_instance, set()).add(c.target_variable)
    notes = []
    for name, instance in scenario.instances.items():
        passes = [
            f"{name}.{given} on to {output}"
            for output, inputs in feedthrough(instance.model_description).items()
            for given in sorted(inputs & driven.get(name, set()))
        ]
        if passes:
            notes.append(
                f"{name} passes {', '.join(passes)} within a step (direct feedthrough): "
                "auv-cosim hands on the value of the same point, libcosim and ecos the "
                "previous step's to the instances it drives: results differ (docs/hosts.md)"
            )
    return notes


def _skipped_start_notes(scenario: Scenario) -> list[str]:
    """Start values libcosim's SSP loader skips (with a log line): it applies a parameter
    set to parameters and inputs only, not to an output or local with initial "exact"."""
    skipped = [
        f"{name}.{variable} ({causality})"
        for name, instance in scenario.instances.items()
        for variable in instance.start
        if (causality := instance.interface.variables[variable].causality)
        not in ("parameter", "input")
    ]
    if not skipped:
        return []
    one = len(skipped) == 1
    return [
        f"{', '.join(skipped)}: {'a start value' if one else 'start values'} libcosim skips "
        "in an SSP (its loader sets a parameter set on parameters and inputs only); ecos, "
        f"and libcosim from an --osp export, set {'it' if one else 'them'}"
    ]


def _file_notes(scenario: Scenario, fmt: str) -> list[str]:
    """Start values naming a file a host finds only from the right folder: the SSP packs
    the file but can name it only by a path relative to the archive, which libcosim and
    ecos resolve from their working folder; the OSP export copies it beside the system
    structure and names the copy, found from the export's folder."""
    notes = []
    for name, instance in scenario.instances.items():
        for var, file in file_starts(instance).items():
            if fmt == "ssp":
                notes.append(
                    f"{name}.{var} names a file, written as resources/{name}/{file.name} in "
                    "the archive, a path libcosim and ecos resolve from their working "
                    "folder, not the archive: give the FMU the file where the system runs"
                )
            else:
                notes.append(
                    f"{name}.{var} names a file, copied beside the system structure and "
                    f"written as {copied_file_name(name, file)}, a path libcosim and ecos "
                    "resolve from their working folder: run the system from that folder"
                )
    return notes


def _debug_log_notes(scenario: Scenario) -> list[str]:
    """The instances whose debug log the scenario turns on (``debug_logging``,
    ``log_categories``): neither SSP 1.0 nor OSP's system structure has a place for an
    FMU's debug logging, so the export cannot carry it."""
    logged = [
        f"{name} ({', '.join(instance.debug_logging) or 'every category'})"
        for name, instance in scenario.instances.items()
        if instance.debug_logging is not None
    ]
    if not logged:
        return []
    return [
        f"the debug log of {', '.join(logged)} is not carried: SSP and OSP have no place "
        "for an FMU's debug logging; turn it on in the host that runs the export"
    ]


def _type_of(scenario: Scenario, ref: str) -> str | None:
    instance, _, variable = ref.partition(".")
    var = scenario.instances[instance].interface.variables.get(variable)
    return None if var is None else var.type


def _inputs(extrapolation: str) -> str:
    """The extrapolation in words: ``held inputs``, ``quadratic extrapolation``."""
    return "held inputs" if extrapolation == "none" else f"{extrapolation} extrapolation"
