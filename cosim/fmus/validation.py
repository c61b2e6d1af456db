"""Check built FMUs: fmpy's validation plus what our FMI contract (docs/interfaces.md) adds.

:func:`validate_fmus` returns a list of problems, each prefixed with the FMU's name; an
empty list means valid. :func:`validate_folder` checks the built-in FMUs of a folder as
they are (``auv-cosim validate``): it never builds or repairs one (that is ``auv-cosim
build``'s job); a missing folder is an error, a missing FMU or one that is not the file
the build wrote (its ``.sha256`` record) a problem. :func:`validate_files` checks any FMU
files, ours or not (``auv-cosim validate FILE.fmu ...``), for what a run needs of them:
fmpy's validation, what a run refuses an FMU for (no co-simulation interface, no binary
for this platform) and the smoke run below; our contract's descriptions, units and
dependencies are not asked of an FMU nobody here wrote. Checks per built FMU:Checks per FMU:

* ``fmpy.validation.validate_fmu`` (schema, names, start values, units, ModelStructure);
* ``needsExecutionTool="false"``, a ``DefaultExperiment``;
* a description on every variable, a unit on every Real input/output/parameter;
* ``ModelStructure/Outputs``: exactly the outputs, each with a ``dependencies`` list;
* a ``dependenciesKind`` only with as many entries as its ``dependencies`` (fmpy checks
  this from 0.3.29 on; we pin fmpy below 0.3.26);
* a smoke run of all FMUs together in one fresh Python process (pythonfmu FMUs share the
  host's ``sys.modules``, and a broken one can crash its host): instantiate, initialise
  with the start values, one ``doStep`` of the default step, every Real output finite.
"""

from __future__ import annotations

import contextlib
import json
import math
import shlex
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

SMOKE_TIMEOUT_S = 120.0


def validate_folder(fmu_dir: Path) -> list[str]:
    """Problems of the built-in FMUs in ``fmu_dir`` as they are (nothing is built).

    Raises:
        CosimError: ``fmu_dir`` is not a folder.
    """
    from cosim.errors import CosimError
    from cosim.fmus.build import FMUS, HASH_SUFFIX

    fmu_dir = Path(fmu_dir)
    build = f"auv-cosim build --out {shlex.quote(str(fmu_dir))}"  # a command to paste
    if not fmu_dir.is_dir():
        raise CosimError(f"--fmu-dir {fmu_dir}: no such folder; `{build}` builds the FMUs there")
    paths = {name: fmu_dir / f"{name}.fmu" for name in FMUS}
    problems = []
    for name, path in paths.items():
        if not path.is_file():
            problems.append(f"{name}: {path} does not exist (`{build}`)")
            continue
        if not _as_built(name, path):
            problems.append(
                f"{name}: {path} is not the file the build wrote (its SHA-256 differs from "
                f"{path.name}{HASH_SUFFIX}): damaged or replaced; `{build} --force` rebuilds it"
            )
    return problems or validate_fmus(paths)


def _as_built(name: str, path: Path) -> bool:
    """``path`` (the FMU ``name``) is the file its hash file names, or has no hash file;
    read under the folder's build lock, so a build installing a new FMU and then its hash
    file is waited for (a folder where no lock can be made is read as it is)."""
    from cosim.fmus.build import HASH_SUFFIX, file_hash, fmu_lock, recorded_hashes

    with contextlib.ExitStack() as held:
        with contextlib.suppress(OSError):  # a read-only folder: nothing builds there
            held.enter_context(fmu_lock(name, path.parent))
        recorded = recorded_hashes(path.with_name(path.name + HASH_SUFFIX)).get("fmu")
        return recorded is None or recorded == file_hash(path)


def validate_fmus(paths: dict[str, Path]) -> list[str]:
    """Problems found in the FMUs ``{name: path}``; empty if all are valid."""
    problems: list[str] = []
    for name, path in paths.items():
        problems += [f"{name}: {p}" for p in _static_problems(Path(path))]
    if not problems:
        problems += smoke_run(paths)
    return problems


def validate_files(paths: list[Path]) -> list[str]:
    """Problems found in the FMU files ``paths`` (any FMI 2.0 co-simulation FMU), each
    prefixed with its path; empty if every one can be run here."""
    problems: list[str] = []
    for path in paths:
        problems += [f"{path}: {p}" for p in _runnable_problems(Path(path))]
    if not problems:
        problems += smoke_run({str(path): Path(path) for path in paths})
    return problems


def _runnable_problems(path: Path) -> list[str]:
    if path.is_dir():
        return ["is a folder: give its .fmu files, or --fmu-dir for the built FMUs in it"]
    if not path.is_file():  # a pipe or a device is no FMU either (an FMU is a zip file)
        return ["not a file: a pipe or a device" if path.exists() else "no such file"]
    return _readable(path, _foreign_problems)


def _foreign_problems(path: Path) -> list[str]:
    """What a run refuses an FMU for, with the same checks: an archive that is not an FMI
    2.0 FMU (in one line, before fmpy's schema report of it), one an older auv-cosim
    built into packages this process runs itself, fmpy's validation, no
    co-simulation interface, no binary for this platform."""
    from fmpy.validation import validate_fmu

    from cosim.fmus.interface import (
        NOT_COSIMULATION,
        FmuInterfaceError,
        check_archive,
        check_binary,
        check_own_packages,
        read_interface,
    )

    try:
        check_archive(path)
        check_own_packages(path)
    except FmuInterfaceError as exc:
        return [str(exc).removeprefix(f"{path}: ")]
    problems = list(validate_fmu(str(path)))
    if problems:
        return problems
    try:
        interface = read_interface(path)
        if interface.model_identifier is None:
            return [NOT_COSIMULATION]
        check_binary(path, interface.model_identifier)
    except FmuInterfaceError as exc:
        return [str(exc).removeprefix(f"{path}: ")]
    return []


def checked_files(paths: list[Path]) -> list[str]:
    """One line per FMU file saying what :func:`validate_files` checked in it."""
    import fmpy
    from fmpy import read_model_description

    lines = []
    for path in paths:
        md = read_model_description(str(path))
        step = float((md.defaultExperiment.stepSize if md.defaultExperiment else None) or 0.01)
        reals = sum(v.causality == "output" and v.type == "Real" for v in md.modelVariables)
        lines.append(
            f"{path}: fmpy's validation; FMI 2.0 co-simulation "
            f"({md.coSimulation.modelIdentifier}); a {fmpy.platform} binary; "
            f"{len(md.modelVariables)} variables; one step of {step:g} s with "
            f"{_outputs(reals)}"
        )
    return lines


def checked(paths: dict[str, Path]) -> list[str]:
    """One line per FMU ``{name: path}`` saying what :func:`validate_fmus` checked in it:
    how many variables of each causality, how many Reals with units, how many outputs
    with dependencies, and the smoke run's step."""
    from fmpy import read_model_description

    lines = []
    for name, path in paths.items():
        md = read_model_description(str(path))
        variables = md.modelVariables
        count = {c: sum(v.causality == c for v in variables) for c in
                 ("input", "output", "parameter")}  # fmt: skip
        with_units = sum(
            v.type == "Real" and v.causality in ("input", "output", "parameter") and bool(v.unit)
            for v in variables
        )
        step = float((md.defaultExperiment.stepSize if md.defaultExperiment else None) or 0.01)
        finite = sum(v.causality == "output" and v.type == "Real" for v in variables)
        lines.append(
            f"{name} ({Path(path).name}): fmpy's validation; {len(variables)} variables "
            f"described ({count['input']} inputs, {count['output']} outputs, "
            f"{count['parameter']} parameters); {with_units} Reals with a unit; "
            f"{len(md.outputs)} outputs with dependencies; one step of {step:g} s with "
            f"{_outputs(finite)}"
        )
    return lines


def _outputs(count: int) -> str:
    """``count`` finite Real output(s), in words."""
    return f"{count} finite Real output" + ("" if count == 1 else "s")


def _static_problems(path: Path) -> list[str]:
    if not path.is_file():
        return [f"{path} does not exist"]
    return _readable(path, _description_problems, f"{path} is ")


def _readable(path: Path, check: Callable[[Path], list[str]], prefix: str = "") -> list[str]:
    """``check(path)``'s problems; what fmpy raises reading a damaged archive (anything),
    one line: ``<prefix>not a readable FMU (<type>: <reason>)``."""
    try:
        return check(path)
    except Exception as exc:  # fmpy raises anything from a damaged archive: one line each
        reason = " ".join(str(exc).split()) or type(exc).__name__
        return [f"{prefix}not a readable FMU ({type(exc).__name__}: {reason})"]


def _description_problems(path: Path) -> list[str]:
    from fmpy import read_model_description
    from fmpy.validation import validate_fmu

    problems = list(validate_fmu(str(path)))
    if problems:
        return problems
    md = read_model_description(str(path))
    if md.coSimulation is None:
        return ["no CoSimulation interface"]
    if md.coSimulation.needsExecutionTool:
        problems.append('needsExecutionTool is not "false"')
    if md.defaultExperiment is None:
        problems.append("no DefaultExperiment")
    for v in md.modelVariables:
        if not v.description:
            problems.append(f"variable {v.name!r} has no description")
        if v.type == "Real" and v.causality in ("input", "output", "parameter") and not v.unit:
            problems.append(f"Real {v.causality} {v.name!r} has no unit")
    outputs = {v.name for v in md.modelVariables if v.causality == "output"}
    declared = {u.variable.name for u in md.outputs}
    if declared != outputs:
        problems.append(
            f"ModelStructure/Outputs lists {sorted(declared)}, expected {sorted(outputs)}"
        )
    problems += [
        f"output {u.variable.name!r} declares no dependencies"
        for u in md.outputs
        if u.dependencies is None
    ]
    problems += [
        f"{kind} {u.variable.name!r} lists {len(u.dependencies or ())} dependencies and "
        f"{len(u.dependenciesKind)} dependenciesKind"
        for kind, unknowns in (("output", md.outputs), ("initial unknown", md.initialUnknowns))
        for u in unknowns
        if u.dependenciesKind and len(u.dependenciesKind) != len(u.dependencies or ())
    ]
    return problems


def smoke_run(paths: dict[str, Path]) -> list[str]:
    """Instantiate, initialise and step every FMU once, all in one fresh process, which
    extracts them into a temporary folder removed here once it has ended (however)."""
    arguments = json.dumps({name: str(path) for name, path in paths.items()})
    code = "import sys; from cosim.fmus.validation import _smoke_main; _smoke_main(*sys.argv[1:])"
    try:
        with tempfile.TemporaryDirectory(prefix="auv-cosim-validate-") as folder:
            result = subprocess.run(
                [sys.executable, "-c", code, arguments, folder],
                capture_output=True,
                text=True,
                timeout=SMOKE_TIMEOUT_S,
                check=False,
            )
    except subprocess.TimeoutExpired:
        return [f"smoke run: no answer within {SMOKE_TIMEOUT_S:g} s"]
    lines = result.stdout.strip().splitlines()
    if result.returncode != 0 or not lines:
        tail = " | ".join(result.stderr.strip().splitlines()[-3:])
        when = "at exit, after the checks ran" if lines else "during the checks"
        return [f"smoke run: the host process died {when} (exit code {result.returncode}): {tail}"]
    return json.loads(lines[-1])


def _extracted(path: Path, folder: Path) -> str:
    """``path`` extracted into ``folder`` (:func:`cosim.fmus.interface.extract_fmu`)."""
    from cosim.fmus.interface import extract_fmu

    extract_fmu(path, folder)
    return str(folder)


def _smoke_main(arguments: str, folder: str) -> None:
    """Subprocess side of :func:`smoke_run`: extracts each FMU into ``folder``, prints a
    JSON list of problems last."""
    from fmpy import read_model_description
    from fmpy.fmi2 import FMU2Slave

    problems: list[str] = []
    for index, (name, path) in enumerate(json.loads(arguments).items()):
        try:
            md = read_model_description(path)
            step = float((md.defaultExperiment.stepSize if md.defaultExperiment else None) or 0.01)
            slave = FMU2Slave(
                guid=md.guid,
                unzipDirectory=_extracted(Path(path), Path(folder, str(index))),
                modelIdentifier=md.coSimulation.modelIdentifier,
                instanceName=f"smoke_{name}",
            )
            slave.instantiate(loggingOn=True)
            slave.setupExperiment(startTime=0.0)
            slave.enterInitializationMode()
            slave.exitInitializationMode()
            slave.doStep(0.0, float(step))
            outputs = [v for v in md.modelVariables if v.causality == "output"]
            reals = [v for v in outputs if v.type == "Real"]
            values = slave.getReal([v.valueReference for v in reals])
            problems += [
                f"{name}: output {v.name} = {x!r} after one step"
                for v, x in zip(reals, values, strict=True)
                if not math.isfinite(x)
            ]
            slave.terminate()
            slave.freeInstance()
        except Exception as exc:
            problems.append(f"{name}: smoke run failed: {type(exc).__name__}: {exc}")
    print(json.dumps(problems), flush=True)
