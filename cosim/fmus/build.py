"""Build AuvPlant.fmu and AuvAutopilot.fmu with pythonfmu, then complete modelDescription.xml.

Steps for one FMU (:func:`build_fmu`):

1. Stage the sources in a temporary folder: the pythonfmu script at the top level
   (``auv_plant.py`` / ``auv_autopilot.py``, globally unique module names) and the packages
   it imports (``plant_fmu``; ``controller_fmu`` + ``plant_fmu``), ``*.py`` and ``*.toml``
   only, located through the imported packages' ``__file__`` so an installed
   (non-editable) distribution builds too. Scripts are not shipped inside the packages.
2. Run pythonfmu's builder in a subprocess (``python -m pythonfmu build``): it imports the
   script as a top-level module and puts the script's folder on ``sys.path``, which must
   not leak into the caller (a rebuilt class would otherwise shadow the FMU's own).
3. Complete ``modelDescription.xml`` (:func:`complete_model_description`): capability
   flags (``needsExecutionTool="false"``, FMU state get/set/serialise), ``UnitDefinitions``
   for every unit the Reals use (with SI base-unit exponents), ``InitialUnknowns`` by the
   FMI 2.0 rule. What only the slave knows it already wrote through
   :meth:`fmu_runtime.safe_slave.SafeSlave.to_xml`: the unit of every Real and the
   ``ModelStructure/Outputs`` dependencies. Both our FMUs hold their outputs over a
   communication step (the plant's are the state after the step, the autopilot's are
   computed from the inputs at the step start and held), so no output depends directly
   on an input and every dependency list is empty: no false algebraic loop for importers.
   The completed description is then checked (units, descriptions, outputs
   ``initial="exact"`` with a start value, a ``DefaultExperiment``) and validated with
   ``fmpy.validation.validate_fmu``; any problem fails the build.
4. Write ``<Name>.fmu`` atomically and ``<Name>.fmu.sha256`` beside it: the content hash
   of every shipped file, this module and pythonfmu's version. :func:`ensure_fmus`
   rebuilds only when that hash changed.
"""

from __future__ import annotations

import hashlib
import importlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from xml.etree import ElementTree as ET

from cosim.errors import CosimError
from cosim.fmus import docs as fmu_docs

HASH_SUFFIX = ".sha256"
SHIPPED_SUFFIXES = (".py", ".toml")


@dataclass(frozen=True)
class FmuSource:
    """Where one FMU's code lives: its pythonfmu script and the packages it ships."""

    package: str  # the package holding the script
    script: str  # file name of the pythonfmu script in that package
    ships: tuple[str, ...]  # packages copied into resources/


FMUS: dict[str, FmuSource] = {
    "AuvPlant": FmuSource("plant_fmu", "auv_plant.py", ("plant_fmu", "fmu_runtime")),
    "AuvAutopilot": FmuSource(
        "controller_fmu", "auv_autopilot.py", ("controller_fmu", "plant_fmu", "fmu_runtime")
    ),
}
_SCRIPTS = {source.script for source in FMUS.values()}

# SI base-unit exponents of the unit symbols our variables use (FMI 2.0 BaseUnit).
_BASE_UNITS: dict[str, dict[str, int]] = {
    "1": {},
    "m": {"m": 1},
    "kg": {"kg": 1},
    "s": {"s": 1},
    "rad": {"rad": 1},
    "N": {"kg": 1, "m": 1, "s": -2},
    "J": {"kg": 1, "m": 2, "s": -2},
    "W": {"kg": 1, "m": 2, "s": -3},
}
_UNIT_FACTOR = re.compile(r"^([A-Za-z]+|1)(-?\d+)?$")


def build_fmus(out_dir: Path, force: bool = False) -> dict[str, Path]:
    """Build both FMUs into ``out_dir`` (only those out of date unless ``force``).

    Raises:
        CosimError: a script is missing or a build step failed; the message says which
            and why.
    """
    return {name: build_fmu(name, out_dir, force=force) for name in FMUS}


def ensure_fmus(out_dir: Path) -> dict[str, Path]:
    """Both FMUs in ``out_dir``, built on first use or when their sources changed."""
    return build_fmus(out_dir, force=False)


def build_fmu(name: str, out_dir: Path, force: bool = False) -> Path:
    """Build the FMU ``name`` (a key of :data:`FMUS`) into ``out_dir`` if it is missing, out
    of date or ``force``; return its path."""
    if name not in FMUS:
        raise CosimError(f"unknown FMU {name!r}: expected one of {sorted(FMUS)}")
    out_dir = Path(out_dir)
    target = out_dir / f"{name}.fmu"
    hash_file = target.with_name(target.name + HASH_SUFFIX)
    if not script_path(name).is_file():
        raise CosimError(f"cannot build {name}.fmu: {script_path(name)} does not exist")
    files = shipped_files(name)
    digest = source_hash(files)
    if not force and target.is_file() and _read(hash_file) == digest:
        return target
    out_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix=f"build_{name}_") as tmp:
        stage, dest = Path(tmp) / "stage", Path(tmp) / "out"
        for relative, source in files.items():
            (stage / relative).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(source, stage / relative)
        built = _run_pythonfmu(name, stage, dest)
        complete_fmu(built)
        fmu_docs.add_documentation(built)  # documentation/index.html from the description
        problems = _check_built(built)
        if problems:
            raise CosimError(f"{name}.fmu failed validation: " + "; ".join(problems))
        partial = out_dir / f".{name}.fmu.{os.getpid()}.tmp"
        shutil.copyfile(built, partial)
        os.replace(partial, target)
    hash_file.write_text(digest + "\n")
    return target


def shipped_files(name: str) -> dict[str, Path]:
    """``{path inside the staging folder: source file}`` for FMU ``name``: the script at the
    top level and the ``*.py``/``*.toml`` files of every shipped package (no scripts)."""
    source = FMUS[name]
    files = {source.script: script_path(name)}
    for package in source.ships:
        root = _package_dir(package)
        for path in sorted(root.rglob("*")):
            relative = path.relative_to(root)
            if (
                path.is_file()
                and path.suffix in SHIPPED_SUFFIXES
                and "__pycache__" not in relative.parts
                and path.name not in _SCRIPTS
            ):
                files[f"{package}/{relative.as_posix()}"] = path
    return files


def source_hash(files: dict[str, Path]) -> str:
    """SHA-256 over the shipped files (names and bytes), this module, the documentation
    generator (:mod:`cosim.fmus.docs`) and pythonfmu's version."""
    digest = hashlib.sha256()
    digest.update(f"pythonfmu {metadata.version('pythonfmu')}\n".encode())
    generators = {"<cosim/fmus/build.py>": Path(__file__), "<fmu_docs>": Path(fmu_docs.__file__)}
    for relative, path in sorted({**files, **generators}.items()):
        digest.update(f"{relative}\n{len(path.read_bytes())}\n".encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def complete_fmu(fmu: Path) -> None:
    """Rewrite ``modelDescription.xml`` inside ``fmu`` with :func:`complete_model_description`."""
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    with zipfile.ZipFile(fmu, "w") as archive:
        for info, data in entries:
            if info.filename == "modelDescription.xml":
                data = complete_model_description(data)
            archive.writestr(info, data)


def complete_model_description(xml: bytes) -> bytes:
    """The FMI 2.0 description pythonfmu wrote, completed (see the module docstring)."""
    root = ET.fromstring(xml)
    cosim = root.find("CoSimulation")
    for flag, value in (
        ("needsExecutionTool", "false"),
        ("canGetAndSetFMUstate", "true"),
        ("canSerializeFMUstate", "true"),
    ):
        cosim.set(flag, value)

    variables = list(root.find("ModelVariables"))
    units = sorted({real.get("unit") for real in root.iter("Real") if real.get("unit")})
    for old in root.findall("UnitDefinitions"):
        root.remove(old)
    if units:
        definitions = ET.Element("UnitDefinitions")
        for unit in units:
            node = ET.SubElement(definitions, "Unit", name=unit)
            exponents = base_units(unit)
            if exponents is not None:
                ET.SubElement(node, "BaseUnit", {k: str(v) for k, v in exponents.items()})
        root.insert(list(root).index(cosim) + 1, definitions)

    structure = root.find("ModelStructure")
    for old in structure.findall("InitialUnknowns"):
        structure.remove(old)
    initial_unknowns = [
        i + 1
        for i, v in enumerate(variables)
        if (v.get("causality") == "output" and v.get("initial") in ("approx", "calculated"))
        or v.get("causality") == "calculatedParameter"
    ]
    if initial_unknowns:
        node = ET.SubElement(structure, "InitialUnknowns")
        for index in initial_unknowns:
            ET.SubElement(node, "Unknown", index=str(index))
    ET.indent(root, space="  ")
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def base_units(unit: str) -> dict[str, int] | None:
    """SI base-unit exponents of a unit written as ``N.m/rad``, ``kg.m2``, ``1/s``, ...;
    None if it uses a symbol we do not know (the Unit is then declared by name only)."""
    exponents: dict[str, int] = {}
    numerator, _, denominator = unit.partition("/")
    for part, sign in ((numerator, 1), (denominator, -1)):
        for factor in part.split(".") if part else ():
            match = _UNIT_FACTOR.match(factor)
            if match is None or match.group(1) not in _BASE_UNITS:
                return None
            power = sign * int(match.group(2) or 1)
            for base, exponent in _BASE_UNITS[match.group(1)].items():
                exponents[base] = exponents.get(base, 0) + power * exponent
    return {base: e for base, e in exponents.items() if e != 0}


def _check_built(fmu: Path) -> list[str]:
    """Problems in a completed FMU: fmpy's validation and what the FMI contract needs."""
    from fmpy.validation import validate_fmu

    problems = list(validate_fmu(str(fmu)))
    with zipfile.ZipFile(fmu) as archive:
        root = ET.fromstring(archive.read("modelDescription.xml"))
    if root.find("DefaultExperiment") is None:
        problems.append("no DefaultExperiment (set the slave's default_experiment)")
    for var in root.iter("ScalarVariable"):
        name = var.get("name")
        if not var.get("description"):
            problems.append(f"variable {name!r} has no description")
        real = var.find("Real")
        if real is not None and not real.get("unit"):
            problems.append(f"Real variable {name!r} has no unit")
        if var.get("causality") == "output" and var.get("initial") != "exact":
            problems.append(f'output {name!r} is not declared initial="exact"')
    for unknown in root.iterfind("ModelStructure/Outputs/Unknown"):
        if unknown.get("dependencies") is None:
            problems.append(f"output index {unknown.get('index')} declares no dependencies")
    return problems


def _run_pythonfmu(name: str, stage: Path, dest: Path) -> Path:
    source = FMUS[name]
    return pythonfmu_build(
        stage / source.script,
        dest,
        name,
        "--no-external-tool",
        "--handle-state",
        "--serialize-state",
        *(str(stage / package) for package in source.ships),
        cwd=stage,
    )


def pythonfmu_build(
    script: Path, dest: Path, model_identifier: str, *options: str, cwd: Path | None = None
) -> Path:
    """Run ``pythonfmu build`` on ``script`` (extra ``options`` and project files after it)
    in a fresh interpreter, since pythonfmu imports the script and this process would
    reuse a class it imported before; return ``dest/<model_identifier>.fmu``.

    Raises CosimError with pythonfmu's last lines if the build fails.
    """
    command = [sys.executable, "-m", "pythonfmu", "build", "--file", str(script)]
    command += ["--dest", str(dest), *options]
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    built = dest / f"{model_identifier}.fmu"
    if result.returncode != 0 or not built.is_file():
        tail = (result.stderr or result.stdout).strip().splitlines()[-5:]
        raise CosimError(
            f"pythonfmu could not build {model_identifier}.fmu (exit code {result.returncode}): "
            + " | ".join(tail)
        )
    return built


def _package_dir(package: str) -> Path:
    module = importlib.import_module(package)
    if module.__file__ is None:
        raise CosimError(f"package {package!r} has no __init__.py: cannot locate its sources")
    return Path(module.__file__).parent


def script_path(name: str) -> Path:
    """The pythonfmu script of FMU ``name`` in the imported package."""
    source = FMUS[name]
    return _package_dir(source.package) / source.script


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None
