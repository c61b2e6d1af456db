"""Build AuvPlant.fmu, AuvAutopilot.fmu and AuvGuidance.fmu with pythonfmu; complete their
modelDescription.xml; lay out their Python code under the build's own package.

Steps for one FMU (:func:`build_fmu`):

1. Stage the sources in a temporary folder: the packages every FMU ships whole
   (:data:`PACKAGES`: ``plant_fmu``, ``controller_fmu``, ``fmu_runtime``; ``*.py`` and
   ``*.toml`` only, located through the imported packages' ``__file__`` so an installed
   distribution builds too), and a small entry script importing the slave class
   (``plant_fmu.auv_plant.AuvPlant``).
2. Run pythonfmu's builder in a subprocess (``python -m pythonfmu build``): it writes
   modelDescription.xml from the class and packs pythonfmu's binaries. It imports the entry
   as a top-level module and puts its folder on ``sys.path``, which must not leak into the
   caller (a rebuilt class would otherwise shadow the FMU's own).
3. Complete ``modelDescription.xml`` (:func:`complete_model_description`): a GUID that is a
   function of the FMU's content (:func:`guid`: the same sources give the same GUID; no
   MAC address, no time), the package's version and licence, capability flags
   (``needsExecutionTool="false"``, FMU state get/set/serialise), ``UnitDefinitions`` for
   every unit the Reals use (with SI base-unit exponents, and degrees as the display unit
   of angles and turn rates: :data:`DISPLAY_UNITS`), ``InitialUnknowns`` by the FMI
   2.0 rule. What only the slave knows it already
   wrote through :meth:`fmu_runtime.safe_slave.SafeSlave.to_xml`: the unit of every Real,
   the ``ModelStructure/Outputs`` dependencies, which outputs are ``initial="calculated"``
   (they depend on parameters: read in initialisation mode, they give the value the FMU
   starts from), ``canInterpolateInputs`` for a slave that takes input derivatives. Our
   FMUs hold their outputs over a communication step, so no output depends directly on an
   input and every dependency list is empty: no false algebraic loop for importers.
4. Replace ``resources/`` (:func:`lay_out_resources`): the staged packages with the
   project's ``LICENSE``, and pythonfmu's pure-Python package with its licence (copied
   from this environment, as pythonfmu's builder embeds it)
   under one package named after their content, ``auvfmu_<hash>``, their imports renamed
   (:mod:`cosim.fmus.staging`); pythonfmu's entry module for its own binary (the fallback);
   ``fmu_runtime.txt`` (the GUID, the package, the slave class, the Python the FMU was built
   with, or none for a ``portable`` build, which names no path of the build machine) and
   ``fmu_variables.txt`` (each variable's rules) for the FMU's runtime; and the code
   compiled by the build's Python (:mod:`cosim.fmus.bytecode`: checked-hash ``.pyc``
   files, so a host with that Python compiles nothing when it imports the FMU's code).
5. The FMU's runtime (:mod:`cosim.fmus.native`, ``docs/native-loader.md``) becomes its
   linux64 binary, with pythonfmu's renamed beside it; without a C compiler the FMU keeps
   pythonfmu's binary and the build says so in one line. The documentation page says which
   binary the FMU has. The completed FMU is checked (units, descriptions, outputs
   ``initial="exact"`` with a start value or ``initial="calculated"``, a
   ``DefaultExperiment``) and validated with ``fmpy.validation.validate_fmu``; any problem
   fails the build.
6. Date every zip entry and the description as :mod:`cosim.fmus.reproducible` says (no
   time of the build's: the same sources give the same bytes), then write ``<Name>.fmu``
   atomically and ``<Name>.fmu.sha256`` beside it: a ``source`` line, the content hash of
   the version, every shipped file, this module and pythonfmu's version (the GUID's
   source), an ``fmu`` line, the hash of the built file itself, a ``date`` line,
   ``SOURCE_DATE_EPOCH`` or ``none``, and a ``python`` line, the Python the FMU records
   (:func:`recorded_python`). :func:`ensure_fmus` rebuilds when the sources, that date
   or that Python changed, and when the FMU
   fails that integrity check (a truncated or edited file is never used). Both files are
   written under the FMU's lock (:func:`fmu_lock`, ``.<Name>.fmu.lock`` beside it): a
   process that finds the FMU out of date waits for another one building it, then uses
   what that one built; an FMU built is also kept in the user's cache
   (:mod:`cosim.fmus.kept_builds`), which gives another folder of this user's a copy
   instead of a build.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import importlib.metadata
import importlib.util
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from importlib import metadata
from pathlib import Path
from xml.etree import ElementTree as ET

import locket

from cosim.errors import CosimError, unmade_folder
from cosim.fmus import bytecode, kept_builds, native, reproducible, staging
from cosim.fmus import docs as fmu_docs
from cosim.fmus.interface import ANGLE_QUANTITIES, OWN_PACKAGES
from cosim.limits import unwritten
from cosim.version import DISTRIBUTION, version
from cosim.whole_file import write_whole
from fmu_runtime import entry

HASH_SUFFIX = ".sha256"
SHIPPED_SUFFIXES = (".py", ".toml")
# Every FMU ships these whole, the same files in each: one build's FMUs in one process
# then share one copy of the code (and numba's cache of it).
PACKAGES = OWN_PACKAGES
VENDORED = "pythonfmu"  # pythonfmu's pure-Python package, from this environment
# The namespace of the FMUs' name-based (version 5) GUIDs; any fixed UUID would do.
_GUID_NAMESPACE = uuid.UUID("3f6c1e52-9d4b-4c1e-8a51-5b2f8f0c7a11")


@dataclass(frozen=True)
class FmuSource:
    """Where one FMU's slave class lives: the package holding its module, and the module's
    file name (named like the FMU)."""

    package: str  # the package holding the slave class's module
    script: str  # file name of that module


FMUS: dict[str, FmuSource] = {
    "AuvPlant": FmuSource("plant_fmu", "auv_plant.py"),
    "AuvAutopilot": FmuSource("controller_fmu", "auv_autopilot.py"),
    "AuvGuidance": FmuSource("controller_fmu", "auv_guidance.py"),
}

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
# unit -> (display unit, factor): a tool shows and takes angles and turn rates in degrees
# (FMI 2.0 DisplayUnit: value in the display unit = factor * value in the unit)
DISPLAY_UNITS: dict[str, tuple[str, float]] = {
    "rad": ("deg", math.degrees(1.0)),
    "rad/s": ("deg/s", math.degrees(1.0)),
}


# how a refusal of an FMU folder ends: the option that names another, where a command
# builds into the FMU folder it runs from (run, validate, export, sweep) ...
OTHER_FMU_FOLDER = "name a folder you can write with --fmu-dir (fmu_dir= in Python)"
# ... and where it builds into the folder it is given (auv-cosim build, cosim.build_fmus)
OTHER_BUILD_FOLDER = "name a folder you can write with --out (out= in Python)"


def build_fmus(
    out_dir: Path, force: bool = False, other: str = OTHER_FMU_FOLDER, portable: bool = False
) -> dict[str, Path]:
    """Build every FMU of :data:`FMUS` into ``out_dir`` (only those out of date unless
    ``force``); ``other`` ends a refusal of the folder, naming the option that names
    another (:data:`OTHER_FMU_FOLDER`, or :data:`OTHER_BUILD_FOLDER` for ``auv-cosim
    build``); ``portable``: FMUs to hand on, recording no Python of this machine
    (:func:`recorded_python`).

    Raises:
        CosimError: a script is missing or a build step failed; the message says which
            and why.
    """
    return {
        name: build_fmu(name, out_dir, force=force, other=other, portable=portable) for name in FMUS
    }


def ensure_fmus(out_dir: Path) -> dict[str, Path]:
    """Every FMU in ``out_dir``, built on first use or when their sources changed."""
    return build_fmus(out_dir, force=False)


def out_of_date(out_dir: Path, portable: bool | None = None) -> list[str]:
    """The FMUs of :data:`FMUS` that a run (or a build, ``portable`` as
    :func:`build_fmu` takes it) would build in ``out_dir`` now."""
    out_dir = Path(out_dir)
    digest = source_hash(shipped_files())
    stale = []
    for name in FMUS:
        target = out_dir / f"{name}.fmu"
        hash_file = target.with_name(target.name + HASH_SUFFIX)
        python = recorded_python(_built_portable(hash_file) if portable is None else portable)
        if not _is_intact(target, hash_file, digest, python):
            stale.append(name)
    return stale


def _check_out_dir(name: str, out_dir: Path, other: str) -> None:
    """Make ``out_dir`` if missing and check that this user can write it, before the
    build's seconds rather than after them: a shared FMU folder installed read-only and
    out of date for this auv-cosim (an upgrade since its build), or build/fmus in a
    working folder the user cannot write. Raises CosimError naming the folder."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CosimError(
            f"cannot build {name}.fmu into {out_dir}: expected a folder that exists or can "
            f"be made ({unmade_folder(out_dir, exc)}); {other}"
        ) from None
    if not os.access(out_dir, os.W_OK | os.X_OK):
        raise CosimError(
            f"cannot build {name}.fmu into {out_dir}: the folder cannot be written "
            f"(Permission denied) and its {name}.fmu is missing or out of date for this "
            f"auv-cosim; have its owner run `auv-cosim build --out {out_dir}`, or "
            f"{other}"
        )


def build_fmu(
    name: str,
    out_dir: Path,
    force: bool = False,
    other: str = OTHER_FMU_FOLDER,
    portable: bool | None = False,
) -> Path:
    """Build the FMU ``name`` (a key of :data:`FMUS`) into ``out_dir`` if it is missing, out
    of date or ``force``; return its path. Another process building it into the same
    folder is waited for (:func:`fmu_lock`), and what it built used. ``other`` and
    ``portable``: as :func:`build_fmus` takes them; ``portable=None``: as the FMU there
    was built (portable if its record names no Python), so that a run or an export from
    a folder of portable FMUs keeps them portable."""
    if name not in FMUS:
        raise CosimError(f"unknown FMU {name!r}: expected one of {sorted(FMUS)}")
    out_dir = Path(out_dir)
    target = out_dir / f"{name}.fmu"
    hash_file = target.with_name(target.name + HASH_SUFFIX)
    if portable is None:
        portable = _built_portable(hash_file)
    if not script_path(name).is_file():
        raise CosimError(f"cannot build {name}.fmu: {script_path(name)} does not exist")
    files = shipped_files()
    digest, python = source_hash(files), recorded_python(portable)
    if not force and _is_intact(target, hash_file, digest, python):
        return target
    _check_out_dir(name, out_dir, other)
    with fmu_lock(name, out_dir):
        if not force and _is_intact(target, hash_file, digest, python):
            return target  # another process built it while this one waited
        if not force and os.path.lexists(target) and not hash_file.exists():
            raise CosimError(
                f"cannot build {name}.fmu into {out_dir}: {target} is not a file a build "
                f"wrote (no {hash_file.name} beside it), so it is left as it is; move it "
                f"away, name another FMU folder, or replace it with "
                f"`auv-cosim build --out {out_dir} --force`"
            )
        version = f"{name} source {digest} date {reproducible.stamp()} python {python}"

        def whole(fmu: Path, record_file: Path) -> bool:
            return _is_intact(fmu, record_file, digest, python)

        if not force and kept_builds.fetch(name, version, target, hash_file, whole):
            return target  # built for another folder of this user's, from these sources
        _build(name, files, digest, target, portable)
        record = (
            f"source {digest}\nfmu {file_hash(target)}\ndate {reproducible.stamp()}\n"
            f"python {python}\n"
        )
        try:
            write_whole(hash_file, lambda tmp: tmp.write_text(record))
        except OSError as exc:  # as _install names the FMU's own file
            raise CosimError(f"cannot write {hash_file}: {unwritten(exc)}") from None
        kept_builds.keep(name, version, target, hash_file, whole)
    return target


@contextlib.contextmanager
def fmu_lock(name: str, out_dir: Path) -> Iterator[None]:
    """Hold the lock of ``out_dir``'s ``<name>.fmu`` (the file ``.<name>.fmu.lock`` beside
    it, ``flock``: released by the system if the process dies) while a build writes the
    FMU and its hash file or a check reads both; waits, saying so once, while another
    process holds it. Raises OSError if the lock file cannot be made (a read-only
    folder), CosimError if it is a symbolic link (never opened through it)."""
    path = str(out_dir / f".{name}.fmu.lock")
    try:  # made here, not through a link: locket opens it for writing, which truncates
        os.close(os.open(path, os.O_WRONLY | os.O_CREAT | getattr(os, "O_NOFOLLOW", 0), 0o666))
    except OSError as exc:
        if not os.path.islink(path):
            raise
        raise CosimError(
            f"{path} is a symbolic link, expected the lock file of the builds of "
            f"{name}.fmu in {out_dir}, a file of its own; remove the link"
        ) from exc
    lock = locket.lock_file(path, timeout=0)
    try:
        lock.acquire()
    except locket.LockError:
        _waiting(name, out_dir)
        lock = locket.lock_file(path)  # blocks until the other process is done
        lock.acquire()
    try:
        yield
    finally:
        lock.release()


def _waiting(name: str, out_dir: Path) -> None:
    """Say that another process is building ``name`` into ``out_dir`` and this one waits."""
    print(
        f"auv-cosim build: waiting for another process building {name}.fmu in {out_dir}",
        file=sys.stderr,
    )


# what a write that found no room fails with: a full disk, the file-size limit, a quota
NO_ROOM = frozenset({errno.ENOSPC, errno.EFBIG, errno.EDQUOT})
_NO_ROOM_LINE = re.compile(r"OSError: \[Errno (\d+)\] ")  # pythonfmu's last line then


def _build(name: str, files: dict[str, Path], digest: str, target: Path, portable: bool) -> None:
    """Build ``name`` from the shipped ``files`` (their hash ``digest``) in a temporary
    folder, check it and install it at ``target``; ``portable``: see :func:`build_fmus`.
    Raises CosimError naming the temporary folder (``TMPDIR``) if it has no room."""
    try:
        _build_in_temporary_folder(name, files, digest, target, portable)
    except OSError as exc:
        if exc.errno not in NO_ROOM:
            raise
        raise CosimError(
            f"cannot build {name}.fmu in the temporary folder {tempfile.gettempdir()} "
            f"(TMPDIR): {unwritten(exc)}"
        ) from None


def _build_in_temporary_folder(
    name: str, files: dict[str, Path], digest: str, target: Path, portable: bool
) -> None:
    """:func:`_build` (raises OSError, as pythonfmu's build does)."""
    with tempfile.TemporaryDirectory(prefix=f"build_{name}_") as tmp:
        stage, dest = Path(tmp) / "stage", Path(tmp) / "out"
        shipped = {relative: source.read_bytes() for relative, source in files.items()}
        staged = {k: v for k, v in shipped.items() if not k.startswith(f"{VENDORED}/")}
        staged[FMUS[name].script] = _builder_entry(name).encode()
        for relative, data in staged.items():
            (stage / relative).parent.mkdir(parents=True, exist_ok=True)
            (stage / relative).write_bytes(data)
        built = _run_pythonfmu(name, stage, dest)
        complete_fmu(built, guid(name, digest))
        lay_out_resources(built, name, shipped, portable)
        notes = native.install_loader(built, name)  # the FMU's binary: our runtime
        if not native.loader_in(built):  # pythonfmu's binary alone: no input derivatives
            _declare_no_input_derivatives(built)
        _say_once(notes)
        fmu_docs.add_documentation(built)  # documentation/index.html from the description
        reproducible.normalize(built)  # no date of the build's, no permission of the umask's
        problems = _check_built(built)
        if problems:
            raise CosimError(f"{name}.fmu failed validation: " + "; ".join(problems))
        _install(built, target)


def _install(built: Path, target: Path) -> None:
    """Put the FMU ``built`` at ``target`` whole or not at all (a copy beside it, then a
    rename); a copy that fails (a full disk) leaves no half file and names ``target``."""
    try:
        write_whole(target, lambda tmp: shutil.copyfile(built, tmp))
    except OSError as exc:  # (copyfile's own error names the file it read)
        raise CosimError(f"cannot write {target}: {unwritten(exc)}") from None


_said: set[str] = set()  # process-wide: each build note is printed once per process


def _say_once(notes: list[str]) -> None:
    """Print each build note (no compiler, a platform's loader not built) once."""
    for note in notes:
        if note not in _said:
            _said.add(note)
            print(f"auv-cosim build: {note}", file=sys.stderr)


def recorded_python(portable: bool) -> str:
    """The ``python`` line of a build's record: the Python this build records in the FMUs
    as theirs (:func:`cosim.fmus.native.build_python_identity`), the first their runtime
    tries after the host's own and ``AUV_FMU_PYTHON``; ``none`` for a ``portable`` build,
    whose FMUs name no path of this machine (a host then finds ``python3`` on PATH)."""
    return "none" if portable else native.build_python_identity()


def _built_portable(hash_file: Path) -> bool:
    """Whether the build record ``hash_file`` is a ``portable`` build's (names no Python)."""
    return recorded_hashes(hash_file).get("python") == recorded_python(portable=True)


def recorded_hashes(hash_file: Path) -> dict[str, str]:
    """The ``source`` and ``fmu`` hashes, the ``date`` and the ``python`` a build recorded
    (empty if unreadable)."""
    text = _read(hash_file) or ""
    return dict(line.split(" ", 1) for line in text.splitlines() if " " in line)


def file_hash(path: Path) -> str:
    """SHA-256 of a file's bytes."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _is_intact(target: Path, hash_file: Path, digest: str, python: str) -> bool:
    """The FMU exists, was built from these sources, dated as this build would date it
    (``SOURCE_DATE_EPOCH``), records the Python this build would (``python``:
    :func:`recorded_python`), and is the file that build wrote."""
    recorded = recorded_hashes(hash_file)
    return (
        target.is_file()
        and recorded.get("source") == digest
        and recorded.get("date") == reproducible.stamp()
        and recorded.get("python") == python
        and recorded.get("fmu") == file_hash(target)
    )


def shipped_files() -> dict[str, Path]:
    """``{path inside the build package: source file}``: the ``*.py``/``*.toml`` files of
    every package of :data:`PACKAGES`, whole, with the project's licence (``LICENSE``), and
    the ``*.py`` files of pythonfmu's package (what pythonfmu's builder embeds) with its
    licence. The same for every FMU."""
    files = {}
    for package in PACKAGES:
        root = _package_dir(package)
        for path in sorted(root.rglob("*")):
            relative = path.relative_to(root)
            if (
                path.is_file()
                and path.suffix in SHIPPED_SUFFIXES
                and "__pycache__" not in relative.parts
            ):
                files[f"{package}/{relative.as_posix()}"] = path
    own = _own_licence()
    if own is not None:
        files["LICENSE"] = own
    vendored = _package_dir(VENDORED)
    for path in sorted(vendored.glob("*.py")):
        files[f"{VENDORED}/{path.name}"] = path
    licence = _licence(VENDORED)
    if licence is not None:
        files[f"{VENDORED}/LICENSE"] = licence
    return files


def _licence(distribution: str) -> Path | None:
    """The licence file an installed distribution carries, if any."""
    for file in metadata.distribution(distribution).files or ():
        if Path(str(file)).name.upper().startswith(("LICENSE", "LICENCE", "COPYING")):
            return Path(str(file.locate()))
    return None


def _own_licence() -> Path | None:
    """This project's licence file: the installed distribution's, or the source tree's
    beside the packages where it is not installed (a checkout on ``sys.path``)."""
    try:
        return _licence(DISTRIBUTION)
    except metadata.PackageNotFoundError:
        checkout = _package_dir(PACKAGES[0]).parent / "LICENSE"
        return checkout if checkout.is_file() else None


def _builder_entry(name: str) -> str:
    """The script pythonfmu's builder imports to find FMU ``name``'s slave class."""
    source = FMUS[name]
    module = f"{source.package}.{source.script.removesuffix('.py')}"
    return f"from {module} import {name}  # noqa: F401\n"


def guid(name: str, digest: str) -> str:
    """FMU ``name``'s GUID: a name-based UUID of its source hash (:func:`source_hash`), so
    one for every build of the same model, wherever and with whichever Python it is
    built, and another when a shipped file, the runtime or the version changes."""
    return str(uuid.uuid5(_GUID_NAMESPACE, f"{name}\n{digest}"))


def lay_out_resources(
    fmu: Path, name: str, shipped: dict[str, bytes], portable: bool = False
) -> None:
    """Replace everything pythonfmu's builder put in ``resources/`` of ``fmu`` with the
    build package (see the module docstring, step 4); ``portable``: no build Python in
    ``fmu_runtime.txt``."""
    package = staging.package_name(shipped)
    names = frozenset((*PACKAGES, VENDORED))
    resources = {
        f"{package}/{path}": (
            staging.rename_imports(data.decode("utf-8"), package, names, path).encode()
            if path.endswith(".py")
            else data
        )
        for path, data in shipped.items()
    }
    resources[f"{package}/__init__.py"] = entry.package_init_source(
        name, PACKAGES, (*PACKAGES, VENDORED)
    ).encode()
    source = FMUS[name]
    module = f"{package}.{source.package}.{source.script.removesuffix('.py')}"
    entry_name = f"{package}_{source.script.removesuffix('.py')}"
    resources[f"{entry_name}.py"] = entry.entry_source(name, package, module, name).encode()
    resources["slavemodule.txt"] = entry_name.encode()
    with zipfile.ZipFile(fmu) as archive:
        description = archive.read("modelDescription.xml")
    python = "" if portable else sys.executable
    record = runtime_record(description, package, module, name, python)
    resources[entry.RECORD_FILE] = record.encode()
    resources[native.VARIABLES_FILE] = native.variables_table(description).encode()
    resources.update(bytecode.compiled(resources))  # what importing it would compile
    _replace_resources(fmu, resources)


def runtime_record(description: bytes, package: str, module: str, cls: str, python: str) -> str:
    """``resources/fmu_runtime.txt``: what the FMU's runtime needs from the build;
    ``python``: the build's Python executable, or "" to name none."""
    root = ET.fromstring(description)
    cosimulation = _child(root, "CoSimulation")
    interpolates = cosimulation.get("canInterpolateInputs") == "true"
    categories = ",".join(c.get("name", "") for c in root.iterfind("LogCategories/Category"))
    return (
        f"guid={root.attrib['guid']}\npackage={package}\nmodule={module}\nclass={cls}\n"
        f"build_python={python}\ninterpolates_inputs={int(interpolates)}\n"
        f"log_categories={categories}\n"
    )


def _replace_resources(fmu: Path, resources: dict[str, bytes]) -> None:
    with zipfile.ZipFile(fmu) as archive:
        kept = [
            (info, archive.read(info))
            for info in archive.infolist()
            if not info.filename.startswith("resources/")
        ]
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for info, data in kept:
            archive.writestr(info, data)
        for path, data in sorted(resources.items()):
            archive.writestr(f"resources/{path}", data)


def source_hash(files: dict[str, Path]) -> str:
    """SHA-256 over this package's version (:mod:`cosim.version`: a version bumped
    builds again), the shipped files (names and bytes), this module, the documentation
    generator (:mod:`cosim.fmus.docs`), the renaming of imports (:mod:`cosim.fmus.staging`),
    the dating of the archive (:mod:`cosim.fmus.reproducible`),
    the FMU's runtime (its C sources, the compiler that builds it and the Python it
    records: :func:`cosim.fmus.native.source_digest`), pythonfmu's version, and the
    compiling of the code (:mod:`cosim.fmus.bytecode`, for this Python's cache tag)."""
    digest = hashlib.sha256()
    digest.update(f"auv-cosim {version()}\n".encode())  # the version its description states
    digest.update(f"pythonfmu {metadata.version('pythonfmu')}\n".encode())
    digest.update(f"bytecode {sys.implementation.cache_tag}\n".encode())
    digest.update(f"runtime {native.source_digest()}\n".encode())
    generators = {
        "<cosim/fmus/build.py>": Path(__file__),
        "<fmu_bytecode>": Path(bytecode.__file__),
        "<fmu_docs>": Path(fmu_docs.__file__),
        "<fmu_native>": Path(native.__file__),
        "<fmu_reproducible>": Path(reproducible.__file__),
        "<fmu_staging>": Path(staging.__file__),
    }
    for relative, path in sorted({**files, **generators}.items()):
        digest.update(f"{relative}\n{len(path.read_bytes())}\n".encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _declare_no_input_derivatives(fmu: Path) -> None:
    """``canInterpolateInputs="false"`` in ``fmu``'s description: an FMU that keeps
    pythonfmu's binary alone (no runtime built) cannot take input derivatives (pythonfmu
    answers fmi2SetRealInputDerivatives with "not supported"), so a master holds its
    inputs instead of failing at its first step."""
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        for info, data in entries:
            if info.filename == "modelDescription.xml":
                root = ET.fromstring(data)
                _child(root, "CoSimulation").set("canInterpolateInputs", "false")
                data = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
            archive.writestr(info, data)


def complete_fmu(fmu: Path, guid: str) -> None:
    """Rewrite ``modelDescription.xml`` inside ``fmu`` with :func:`complete_model_description`."""
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    with zipfile.ZipFile(fmu, "w") as archive:
        for info, data in entries:
            if info.filename == "modelDescription.xml":
                data = complete_model_description(data, guid)
            archive.writestr(info, data)


def _provenance(root: ET.Element) -> None:
    """The model's ``version`` and ``license`` (what an FMI tool shows of an FMU it loads)
    and a ``generationTool`` naming this package and pythonfmu: the version from
    :mod:`cosim.version`, the licence from the installed package's metadata; pythonfmu's
    own attributes where there is none."""
    own = version()
    if own is not None:
        root.set("version", own)
        tool = root.get("generationTool", "")
        if not tool.startswith("auv-cosim "):  # completed once already: as it is
            root.set("generationTool", f"auv-cosim {own} ({tool})")
    try:
        metadata = importlib.metadata.metadata(DISTRIBUTION)
    except importlib.metadata.PackageNotFoundError:
        return
    licence = metadata["License-Expression"] or metadata["License"]  # None if absent
    if licence:
        root.set("license", licence)


def complete_model_description(xml: bytes, guid: str | None = None) -> bytes:
    """The FMI 2.0 description pythonfmu wrote, completed (see the module docstring), with
    ``guid`` in place of pythonfmu's time-and-MAC-address one when given."""
    root = ET.fromstring(xml)
    if guid is not None:
        root.set("guid", guid)
    _provenance(root)
    root.attrib.pop("generationDateAndTime", None)  # pythonfmu's: the time of the build
    generated = reproducible.generation_date()
    if generated is not None:
        root.set("generationDateAndTime", generated)
    cosim = _child(root, "CoSimulation")
    for flag, value in (
        ("needsExecutionTool", "false"),
        ("canGetAndSetFMUstate", "true"),
        ("canSerializeFMUstate", "true"),
    ):
        cosim.set(flag, value)

    variables = list(_child(root, "ModelVariables"))
    units = sorted({unit for real in root.iter("Real") if (unit := real.get("unit"))})
    for old in root.findall("UnitDefinitions"):
        root.remove(old)
    if units:
        definitions = ET.Element("UnitDefinitions")
        for unit in units:
            node = ET.SubElement(definitions, "Unit", name=unit)
            exponents = base_units(unit)
            if exponents is not None:
                ET.SubElement(node, "BaseUnit", {k: str(v) for k, v in exponents.items()})
            if unit in DISPLAY_UNITS:
                display, factor = DISPLAY_UNITS[unit]
                ET.SubElement(node, "DisplayUnit", name=display, factor=repr(factor))
        root.insert(list(root).index(cosim) + 1, definitions)
        for real in root.iter("Real"):  # a frequency in rad/s is shown in rad/s, as given
            quantity = real.get("quantity")
            if real.get("unit") in DISPLAY_UNITS and quantity in (None, *ANGLE_QUANTITIES):
                real.set("displayUnit", DISPLAY_UNITS[real.get("unit", "")][0])

    structure = _child(root, "ModelStructure")
    declared = {  # what the slave declared its initial unknowns depend on (SafeSlave.to_xml)
        unknown.get("index"): unknown.get("dependencies")
        for old in structure.findall("InitialUnknowns")
        for unknown in old
    }
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
            unknown = ET.SubElement(node, "Unknown", index=str(index))
            if declared.get(str(index)) is not None:  # else: depends on every known
                unknown.set("dependencies", str(declared[str(index)]))
    ET.indent(root, space="  ")
    completed: bytes = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
    return completed


def _child(root: ET.Element, tag: str) -> ET.Element:
    """The ``tag`` element of a model description (pythonfmu always writes it)."""
    node = root.find(tag)
    if node is None:
        raise ValueError(f"modelDescription.xml has no <{tag}>: expected pythonfmu's layout")
    return node


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
        initial = var.get("initial")
        if var.get("causality") == "output" and initial not in ("exact", "calculated"):
            problems.append(f'output {name!r} is declared initial="{initial}"')
        exact = var.get("causality") == "output" and initial == "exact"
        if exact and real is not None and real.get("start") is None:
            problems.append(f'output {name!r} is initial="exact" without a start value')
    for unknown in root.iterfind("ModelStructure/Outputs/Unknown"):
        if unknown.get("dependencies") is None:
            problems.append(f"output index {unknown.get('index')} declares no dependencies")
    return problems


def _run_pythonfmu(name: str, stage: Path, dest: Path) -> Path:
    # pythonfmu's command line sets every capability flag, canInterpolateInputs="false"
    # unless told: a slave that takes input derivatives (SafeSlave.interpolates_inputs) says so
    interpolates = getattr(slave_class(name), "interpolates_inputs", False)
    return pythonfmu_build(
        stage / FMUS[name].script,
        dest,
        name,
        "--no-external-tool",
        "--handle-state",
        "--serialize-state",
        *(("--interpolate-inputs",) if interpolates else ()),
        *(str(stage / package) for package in PACKAGES),
        cwd=stage,
    )


def slave_class(name: str) -> type:
    """FMU ``name``'s slave class, imported in this process."""
    source = FMUS[name]
    module = importlib.import_module(f"{source.package}.{source.script.removesuffix('.py')}")
    cls: type = getattr(module, name)
    return cls


def pythonfmu_build(
    script: Path, dest: Path, model_identifier: str, *options: str, cwd: Path | None = None
) -> Path:
    """Run ``pythonfmu build`` on ``script`` (extra ``options`` and project files after it)
    in a fresh interpreter, since pythonfmu imports the script and this process would
    reuse a class it imported before; return ``dest/<model_identifier>.fmu``.

    Raises CosimError with pythonfmu's last lines if the build fails; OSError (with its
    errno) if it failed for want of room (a full disk, the file-size limit).
    """
    command = [sys.executable, "-m", "pythonfmu", "build", "--file", str(script)]
    command += ["--dest", str(dest), *options]
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    result = subprocess.run(command, cwd=cwd, env=env, capture_output=True, text=True, check=False)
    built = dest / f"{model_identifier}.fmu"
    if result.returncode != 0 or not built.is_file():
        tail = (result.stderr or result.stdout).strip().splitlines()[-5:]
        refused = _NO_ROOM_LINE.match(tail[-1]) if tail else None
        if refused is not None and int(refused[1]) in NO_ROOM:  # said by the caller
            raise OSError(int(refused[1]), os.strerror(int(refused[1])))
        raise CosimError(
            f"pythonfmu could not build {model_identifier}.fmu (exit code {result.returncode}): "
            + " | ".join(tail)
        )
    return built


def _package_dir(package: str) -> Path:
    """The folder of the installed package ``package``, found without importing it (every
    run and study checks its FMUs are up to date: importing pythonfmu, its builder
    included, cost ~0.03 s of CPU before the first step)."""
    spec = importlib.util.find_spec(package)
    if spec is None:
        raise ModuleNotFoundError(f"No module named {package!r}", name=package)
    if spec.origin is None or not spec.submodule_search_locations:
        raise CosimError(f"package {package!r} has no __init__.py: cannot locate its sources")
    return Path(spec.origin).parent


def script_path(name: str) -> Path:
    """The module of FMU ``name``'s slave class in the imported package."""
    source = FMUS[name]
    return _package_dir(source.package) / source.script


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None
