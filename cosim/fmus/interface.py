"""An FMU's interface as its ``modelDescription.xml`` declares it: variables and units.

:func:`read_interface` is the one reader of an FMU's interface: scenario loading
(:mod:`cosim.scenario.spec`) and the exporters (:mod:`cosim.export`) both use it. It is
built on ``fmpy.read_model_description``, which reads the XML from the archive without
loading the FMU's binary, and cached on (resolved path, modification time, size), so an
FMU is read once per build however many scenarios use it, and a rebuilt FMU is read again.

Values are typed as the FMI type says (``start``, ``min``, ``max``: float for Real, int for
Integer and Enumeration, bool for Boolean, str for String); units are the variable's own
or its declared type's, and ``units`` holds the FMU's ``UnitDefinitions`` as SI base-unit
exponents (plus ``factor`` / ``offset`` where they are not 1 and 0). An Integer that
chooses among named values (``heading_mode``: ``"backstepping"`` is 3) has them in
``names``, read from our annotation on the variable (``<Tool name="auv-cosim">``, which
fmpy does not read); an Enumeration has its declared type's items there.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import os
import re
import shutil
import sys
import zipfile
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path, PurePosixPath
from typing import IO, Any, cast
from xml.etree import ElementTree

from cosim.errors import CosimError
from cosim.paths import path_text, undecoded

Value = bool | int | float | str
SI_BASE_UNITS = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
_CACHED_FMUS = 32
# What an FMU may unpack to, as its archive declares it (zipfile never gives more bytes
# than an entry declares): a larger one is refused before anything is read or written, as
# a zip bomb would be. Ours unpack to ~2 MB, large FMUs of other tools to some 100 MB.
MAX_UNPACKED_BYTES = 4 << 30  # bytes, all of its files together
MAX_DESCRIPTION_BYTES = 256 << 20  # bytes of its modelDescription.xml, read whole


# why an FMU without a co-simulation interface is refused, and what makes it one
NOT_COSIMULATION = (
    "not a co-simulation FMU (model exchange only: `fmpy add-cswrapper FILE.fmu` adds a "
    "co-simulation interface with a solver of fmpy's)"
)


# The Python packages of this project that an FMU build ships (cosim.fmus.build) and that
# this process imports itself. A build puts them under a package of its own
# (``auvfmu_<hash>``); an FMU built before that ships them at the top of ``resources/``.
OWN_PACKAGES = ("plant_fmu", "controller_fmu", "fmu_runtime")


# the declared quantities (FMI 2.0 ``quantity``, Modelica's SI names) of an angle and a turn
# rate: a variable in rad or rad/s declaring another ("AngularFrequency", a filter's natural
# frequency) is neither, so it is not shown in degrees nor doubted as degrees typed by habit
ANGLE_QUANTITIES = frozenset({"Angle", "AngularVelocity"})


# What FMI 2.0 forbids in a variable name under either naming convention (section 2.2.9:
# a flat name is any Unicode character but these; a structured one allows fewer). A name
# holding one ran and split results.csv's header over two lines. Checked by hand: fmpy's
# check of names is private and, for structured names, needs lark, no dependency of ours.
FORBIDDEN_IN_NAMES = {"\n": "a line feed (U+000A)", "\r": "a carriage return (U+000D)",
                      "\t": "a tab (U+0009)"}  # fmt: skip


class FmuInterfaceError(CosimError):
    """An FMU that does not exist or whose model description cannot be read."""


@dataclass(frozen=True)
class Variable:
    """One scalar variable of an FMU."""

    name: str
    type: str  # Real, Integer, Enumeration, Boolean or String
    causality: str  # parameter, calculatedParameter, input, output, local, independent
    variability: str  # constant, fixed, tunable, discrete, continuous
    value_reference: int
    unit: str | None  # the variable's unit or its declared type's; None if it has none
    start: Value | None
    min: float | int | None
    max: float | int | None
    description: str
    names: Mapping[str, int] = dataclasses.field(default_factory=dict)  # name -> value
    initial: str | None = None  # exact, approx, calculated; None where the file gives none
    # what the number is (FMI 2.0 quantity: "Angle", "AngularFrequency"), the variable's
    # or its declared type's; None if it declares none
    quantity: str | None = None

    @property
    def takes_start_value(self) -> bool:
        """Whether a host may set it before initialisation (FMI 2.0, 2.2.7: a variable not
        constant that is a parameter or an input or has ``initial`` "exact" or "approx",
        as an output may: BouncingBall's height)."""
        if self.variability == "constant":
            return False
        return self.causality in ("parameter", "input") or self.initial in ("exact", "approx")


@dataclass(frozen=True)
class FmuInterface:
    """What an FMU offers, read from its model description."""

    path: Path  # resolved
    fmi_version: str
    guid: str
    model_identifier: str | None  # of the co-simulation interface; None if it has none
    variables: Mapping[str, Variable]  # by name, in modelDescription order
    units: Mapping[str, Mapping[str, float] | None]  # unit -> SI exponents; None: name only
    # fmpy's own description and variables, for code that calls the FMU through fmpy
    model_description: Any = dataclasses.field(repr=False, compare=False)
    model_variables: Mapping[str, Any] = dataclasses.field(repr=False, compare=False)
    # the names of its <LogCategories> (FMI 2.0, 2.2.4), in file order; () if it declares none
    log_categories: tuple[str, ...] = ()
    # the SHA-256 (hex) of the file's bytes it was read from, read just before its model
    # description: which content it is the interface of where path, time and size agree
    sha256: str = dataclasses.field(default="", repr=False, compare=False)

    def with_causality(self, causality: str) -> list[Variable]:
        """The variables of this causality, in modelDescription order."""
        return [v for v in self.variables.values() if v.causality == causality]


def read_interface(fmu_path: str | Path) -> FmuInterface:
    """The interface of the FMU at ``fmu_path`` (cached until the file changes).

    Raises:
        FmuInterfaceError: the file does not exist or holds no valid model description.
    """
    path = Path(fmu_path).resolve()
    try:
        stat = path.stat()
    except OSError:
        raise FmuInterfaceError(f"FMU {path} does not exist") from None
    if not path.is_file():
        raise FmuInterfaceError(f"FMU {path} is not a file")
    given = _given.get((path, stat.st_mtime_ns, stat.st_size))
    return given if given is not None else _read(path, stat.st_mtime_ns, stat.st_size)


# interfaces another process read, of a file as it is here (given_interface): by the
# file's resolved path, modification time (ns) and size, as _read's cache
_given: dict[tuple[Path, int, int], FmuInterface] = {}


def given_interface(fmu_path: str | Path, interface: FmuInterface) -> None:
    """Take ``interface``, which another process read from an FMU of the same content, as
    the interface of the FMU file at ``fmu_path`` as that file is now: :func:`read_interface`
    returns it (its ``path`` this file's) until the file changes, and reads the file no
    more. For the workers' fork server (:mod:`cosim.study.server_warm`), which warms up on
    the client's copies of the FMUs the client has read (~0.02 s of CPU for bs-3's two on
    the way to the first run, most of it validating the XML against the FMI schema, which
    the client has done). Raises OSError when the file cannot be found."""
    path = Path(fmu_path).resolve()
    stat = path.stat()
    _given[(path, stat.st_mtime_ns, stat.st_size)] = dataclasses.replace(interface, path=path)


def check_archive(path: Path) -> None:
    """Refuse, in one line naming ``path``, an FMU that is not a zip archive, holds a path
    that is absolute or leaves its folder, has no modelDescription.xml or is not FMI 2.0
    (read from the description's root before fmpy's schema check, whose report of an FMI
    1.0 description is a page of schema errors)."""
    try:
        with zipfile.ZipFile(path) as archive:
            names = archive.namelist()
            unpacked_size(path, archive)
            with archive.open("modelDescription.xml") as description:
                root = root_attributes(description)
    except KeyError:
        raise FmuInterfaceError(f"{path}: not a valid FMU: no modelDescription.xml") from None
    except (OSError, zipfile.BadZipFile, ElementTree.ParseError, ValueError) as exc:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        raise FmuInterfaceError(f"{path}: not a valid FMU: {reason}") from None
    for name in names:
        parts = PurePosixPath(name.replace("\\", "/")).parts
        if name.startswith(("/", "\\")) or ".." in parts or re.match(r"[A-Za-z]:", name):
            raise FmuInterfaceError(
                f"{path}: not a valid FMU: illegal path {name!r} in the archive (absolute or "
                "leaving the FMU's folder)"
            )
    version = root.get("fmiVersion")
    if version != "2.0":
        raise FmuInterfaceError(f"{path}: fmiVersion {version!r}: expected an FMI 2.0 FMU")


_ROOT_CHUNK = 1 << 16  # bytes read at a time until the root element's start tag
_TOOL = "auv-cosim"  # the <Tool name> of our annotations: fmu_runtime.safe_slave.TOOL,
# not imported, for pythonfmu and numpy that module imports
_OUR_TOOL = re.compile(rb"<Tool\s+name\s*=\s*[\"']" + _TOOL.encode() + rb"[\"']")


def root_attributes(stream: IO[bytes]) -> dict[str, str]:
    """The attributes of the root element of the XML document ``stream`` reads, read up to
    the root's start tag and no further: the model description's ``fmiVersion`` and
    ``guid`` without parsing its variables (a whole parse took seconds for 10^5 of them,
    before fmpy parsed them again). ElementTree's pull parser, fed in chunks, stops there.

    Raises:
        ElementTree.ParseError: the document is no XML up to its root's start tag, or has
            no root element.
    """
    parser: ElementTree.XMLPullParser[ElementTree.Element] = ElementTree.XMLPullParser(["start"])
    while chunk := stream.read(_ROOT_CHUNK):
        for _event, element in _pulled(parser, chunk):
            return dict(element.attrib)
    parser.close()  # raises ParseError for a document without a root element
    raise ElementTree.ParseError("no element found")


def unpacked_size(path: Path, archive: zipfile.ZipFile) -> int:
    """The bytes the FMU ``archive`` (read from ``path``) unpacks to, as it declares them.

    Raises:
        FmuInterfaceError: over :data:`MAX_UNPACKED_BYTES`, or a modelDescription.xml over
            :data:`MAX_DESCRIPTION_BYTES` (a zip bomb), in one line naming ``path``.
    """
    infos = archive.infolist()
    size = sum(info.file_size for info in infos)
    if size > MAX_UNPACKED_BYTES:
        raise FmuInterfaceError(
            f"{path}: unpacks to {size} bytes; at most {MAX_UNPACKED_BYTES} (a zip bomb?)"
        )
    description = sum(i.file_size for i in infos if i.filename == "modelDescription.xml")
    if description > MAX_DESCRIPTION_BYTES:
        raise FmuInterfaceError(
            f"{path}: modelDescription.xml is {description} bytes; at most "
            f"{MAX_DESCRIPTION_BYTES} (a zip bomb?)"
        )
    return size


def extract_fmu(path: Path, folder: Path, include: Callable[[str], bool] | None = None) -> None:
    """Extract the FMU at ``path`` into ``folder`` with fmpy (which refuses a name with a
    drive or a leading slash; zipfile drops ``..`` and makes no symbolic link), after
    :func:`unpacked_size` and a check that ``folder``'s disk has room: a refusal comes
    before a byte is written. ``include``: the members to extract (by name; all without).

    Raises:
        FmuInterfaceError: too large (:func:`unpacked_size`), or larger than the free
            space of ``folder``'s disk, in one line naming ``path``.
        OSError, zipfile.BadZipFile: the file cannot be read or extracted.
    """
    from fmpy import extract

    with zipfile.ZipFile(path) as archive:
        size = unpacked_size(path, archive)
    existing = folder
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent  # a folder not made yet: the disk it will be on
    free = shutil.disk_usage(existing).free
    if size > free:
        raise FmuInterfaceError(
            f"{path}: unpacks to {size} bytes; the disk of {folder} has {free} bytes free"
        )
    extract(os.fspath(path), unzipdir=os.fspath(folder), include=include)


def check_binary(path: Path, model_identifier: str | None) -> None:
    """Refuse, in one line naming ``path``, an FMU without the co-simulation binary for
    this platform (fmpy would end in a traceback when loading it)."""
    from fmpy import platform, sharedLibraryExtension

    member = f"binaries/{platform}/{model_identifier}{sharedLibraryExtension}"
    names = _members_now(path)
    if member not in names:
        found = sorted({n.split("/")[1] for n in names if n.count("/") >= 2 and
                        n.startswith("binaries/") and n.split("/")[2]})  # fmt: skip
        sources = any(n.startswith("sources/") and n.endswith(".c") for n in names)
        raise FmuInterfaceError(
            f"{path}: no {member} in the FMU: expected a co-simulation binary for {platform} "
            f"(binaries for: {', '.join(found) or 'none'})"
            + (f"; it ships its C sources: `fmpy compile {path}` builds one" if sources else "")
        )


def check_own_packages(path: Path) -> None:
    """Refuse, in one line naming ``path``, an FMU built by an older auv-cosim whose Python
    code sits in top-level packages of :data:`OWN_PACKAGES`: in a process that runs this
    auv-cosim (its master, a study's worker) it would import this version's modules of
    those names instead of its own (failing inside its instantiation, or running this
    version's code as the old FMU's). Another host, or the auv-cosim that built it, runs it."""
    names = _members_now(path)  # none if unreadable: check_archive names what is wrong
    shipped = [p for p in OWN_PACKAGES if f"resources/{p}/__init__.py" in names]
    if shipped:
        raise FmuInterfaceError(
            f"{path}: built by an older auv-cosim: its code is in the top-level packages "
            f"{', '.join(sorted(shipped))}, whose newer versions this auv-cosim runs in the "
            "same process; rebuild it with `auv-cosim build`, or run it with the auv-cosim "
            "that built it or another FMI host"
        )


def _members_now(path: Path) -> frozenset[str]:
    """The names in the FMU archive ``path`` (none if it cannot be read), read once per
    version of the file: every run's checks (:func:`check_binary`,
    :func:`check_own_packages`) ask, a study's runs in each worker alike."""
    try:
        info = path.stat()
    except OSError:
        return frozenset()
    return _members(path, info.st_mtime_ns, info.st_size)


@functools.lru_cache(maxsize=_CACHED_FMUS)
def _members(path: Path, mtime_ns: int, size: int) -> frozenset[str]:
    """:func:`_members_now`; ``mtime_ns`` and ``size`` are only the cache key's freshness."""
    try:
        with zipfile.ZipFile(path) as archive:
            return frozenset(archive.namelist())
    except (OSError, zipfile.BadZipFile):
        return frozenset()


@functools.lru_cache(maxsize=_CACHED_FMUS)
def _read(path: Path, mtime_ns: int, size: int) -> FmuInterface:
    """Read ``path``; ``mtime_ns`` and ``size`` are only the cache key's freshness."""
    from fmpy import read_model_description

    check_archive(path)
    digest = hashlib.sha256(path.read_bytes()).hexdigest()  # ~1.5 ms for our FMUs
    try:
        md = read_model_description(str(path))
    except UnicodeEncodeError as exc:  # lxml names the XML by the working folder, in UTF-8
        raise FmuInterfaceError(_unnamed_working_folder(path) or f"{path}: {exc}") from None
    except Exception as exc:  # fmpy raises plain Exception for an invalid model description
        reason = " ".join(str(exc).split())  # its schema report spans lines: one line here
        raise FmuInterfaceError(f"{path}: not a valid FMU: {reason}") from None
    _check_names(path, md.modelVariables)
    names, categories = _annotations(path)
    return FmuInterface(
        path=path,
        fmi_version=md.fmiVersion,
        guid=md.guid,
        model_identifier=md.coSimulation.modelIdentifier if md.coSimulation else None,
        variables={v.name: _variable(v, names.get(v.name, {})) for v in md.modelVariables},
        units={unit.name: _base_unit(unit.baseUnit) for unit in md.unitDefinitions},
        model_description=md,
        model_variables={v.name: v for v in md.modelVariables},
        log_categories=categories,
        sha256=digest,
    )


def _check_names(path: Path, variables: list[Any]) -> None:
    """Refuse a variable name holding a character FMI 2.0 forbids in one
    (:data:`FORBIDDEN_IN_NAMES`), naming it."""
    for variable in variables:
        for character, what in FORBIDDEN_IN_NAMES.items():
            if character in variable.name:
                raise FmuInterfaceError(
                    f"{path}: not a valid FMU: the variable name {variable.name!r} holds "
                    f"{what}, which FMI 2.0 forbids in a variable name"
                )


def _unnamed_working_folder(path: Path) -> str | None:
    """Why the model description of ``path`` cannot be read from this working folder, if
    its name holds bytes Python read as surrogates (named in Latin-1, or anything beyond
    ASCII where Python reads file names as ASCII: ``LC_ALL=C`` with its UTF-8 mode off):
    lxml, fmpy's XML reader, names the XML by the working folder, in UTF-8. None for a
    folder whose name is UTF-8."""
    folder = os.getcwd()
    if not undecoded(folder):
        return None
    cure = "run from another folder"
    if sys.getfilesystemencoding().lower() not in ("utf-8", "utf8"):
        cure += f" or set PYTHONUTF8=1 (file names are read as {sys.getfilesystemencoding()})"
    return (
        f"{path}: cannot read its model description from the working folder "
        f"{path_text(folder)}, whose name lxml cannot take (bytes that are no UTF-8 here): "
        f"{cure}"
    )


def _annotations(path: Path) -> tuple[dict[str, dict[str, int]], tuple[str, ...]]:
    """What fmpy's model description leaves out: ``{variable: {name: value}}`` from the
    annotations our FMUs put on their variables (see :mod:`fmu_runtime.safe_slave`; empty
    for another FMU), and the names of the FMU's ``<LogCategories>`` (FMI 2.0, 2.2.4)."""
    from lxml import etree

    with zipfile.ZipFile(path) as archive:
        description = archive.read("modelDescription.xml")
    if not _OUR_TOOL.search(description):  # another tool's FMU: no variable to look at
        return {}, _log_categories(description)
    root = etree.fromstring(description)
    names = {
        variable.attrib["name"]: {item.attrib["name"]: int(item.attrib["value"]) for item in values}
        for variable in root.iterfind("ModelVariables/ScalarVariable")
        for values in variable.iterfind(f"Annotations/Tool[@name='{_TOOL}']/NamedValues")
    }
    categories = tuple(c.get("name", "") for c in root.iterfind("LogCategories/Category"))
    return names, categories


def _pulled(
    parser: ElementTree.XMLPullParser[ElementTree.Element], chunk: bytes
) -> Iterator[tuple[str, ElementTree.Element]]:
    """The events of elements that ``chunk``, fed to ``parser``, completes."""
    parser.feed(chunk)
    # typeshed's events include a one-item tuple no event of ours is: every one is a pair
    for event, element in cast(Iterator[tuple[str, object]], parser.read_events()):
        if isinstance(element, ElementTree.Element):  # not a namespace's event (none asked)
            yield event, element


def _log_categories(description: bytes) -> tuple[str, ...]:
    """The names of the ``<LogCategories>`` of ``description``, parsed up to its
    ``<ModelVariables>`` (which FMI 2.0 puts after them) and no further: a third-party
    FMU's 10^5 variables took seconds to parse a second time for nothing."""
    parser: ElementTree.XMLPullParser[ElementTree.Element]
    parser = ElementTree.XMLPullParser(["start", "end"])
    open_tags: list[str] = []
    categories: list[str] = []
    for offset in range(0, len(description), _ROOT_CHUNK):
        for event, element in _pulled(parser, description[offset : offset + _ROOT_CHUNK]):
            if event == "start" and element.tag == "ModelVariables" and len(open_tags) == 1:
                return tuple(categories)
            if event == "start":
                open_tags.append(element.tag)
                continue
            open_tags.pop()  # now the element's ancestors
            if element.tag == "Category" and open_tags[1:] == ["LogCategories"]:
                categories.append(element.get("name", ""))
    return tuple(categories)


def _variable(v: Any, names: Mapping[str, int]) -> Variable:
    declared = v.declaredType
    return Variable(
        name=v.name,
        type=v.type,
        causality=v.causality,
        variability=v.variability,
        value_reference=v.valueReference,
        unit=v.unit or (declared.unit if declared is not None else None),
        start=_typed(v.type, v.start),
        min=_bound(v.type, v.min),
        max=_bound(v.type, v.max),
        description=v.description or "",
        names=names or _items(declared),
        initial=v.initial,
        quantity=v.quantity or (declared.quantity if declared is not None else None),
    )


def _items(declared: Any) -> dict[str, int]:
    """``{name: value}`` of an Enumeration type's items (FMI 2.0 ``<Item>``); empty for
    another declared type or none."""
    if declared is None or declared.type != "Enumeration":
        return {}
    return {item.name: int(item.value) for item in declared.items}


def _typed(fmi_type: str, text: str | None) -> Value | None:
    """An attribute of the model description as the Python value of its FMI type."""
    if text is None:
        return None
    if fmi_type == "Real":
        return float(text)
    if fmi_type in ("Integer", "Enumeration"):
        return int(text)
    if fmi_type == "Boolean":
        return text in ("true", "1")
    return text


def _bound(fmi_type: str, text: str | None) -> float | int | None:
    """A min or max attribute: a number (FMI declares them on numeric types only)."""
    value = _typed(fmi_type, text)
    return value if isinstance(value, int | float) else None


def _base_unit(base: Any) -> dict[str, float] | None:
    """SI base-unit exponents of a unit definition (None if it declares none)."""
    if base is None:
        return None
    exponents = {k: getattr(base, k) for k in SI_BASE_UNITS if getattr(base, k)}
    if base.factor != 1.0:
        exponents["factor"] = base.factor
    if base.offset != 0.0:
        exponents["offset"] = base.offset
    return exponents
