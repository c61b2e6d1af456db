"""Make the FMU's runtime (``fmu_runtime/native/``) the linux64 binary of a built FMU.

The runtime, a small C library compiled here, answers every FMI 2.0 co-simulation call
itself and calls the FMU's Python slave directly through the CPython C API, every function
resolved with ``dlsym`` from the libpython in the process (one binary for every CPython >=
3.9); it finds and starts a Python when the host has none (``docs/native-loader.md``).
It becomes ``binaries/linux64/<id>.so``; pythonfmu's library moves beside it, unchanged, as
``<id>_pythonfmu.so``: the fallback ``AUV_FMU_RUNTIME=pythonfmu`` chooses.

win64, in every build: the same runtime cross-compiled with ``zig cc -target
x86_64-windows-gnu`` (``platform_win32.c`` in place of ``platform_posix.c``) becomes
``binaries/win64/<id>.dll``, pythonfmu's DLL beside it as ``<id>_pythonfmu.dll``. The DLL
comes prebuilt with the package (``fmu_runtime/native/prebuilt/win64/``, made by
``scripts/build_win64_runtime.py``), with a record of the SHA-256 of the C sources, headers
and flags it was built from (:func:`win64_sources_digest`): the build uses it only while
that digest is today's, else the win64 binary stays pythonfmu's and :func:`install_loader`
says so in one line. With ``AUV_FMU_WIN64=1`` and the ``ziglang`` package the build
compiles it afresh instead (zig's first cross-compile on a machine takes about two minutes
while it builds its MinGW libraries); ``-s`` (no debug information) makes zig's output
byte-reproducible. The DLL was run under Wine (docs/native-loader.md), not on Windows.

The compiler: the system's ``cc`` when there is one (``-Wall -Wextra``; the runtime pins
the few glibc symbols newer than 2.17 to their old versions itself, ``glibc_floor.h``),
else ``python -m ziglang cc -target x86_64-linux-gnu.2.17`` (the optional ``ziglang``
package, a pip-installable clang), else none: the FMU then keeps pythonfmu's binary alone,
and :func:`install_loader` says so (the caller prints it once and the FMU's documentation
page records it). Either way the runtime's binary needs glibc 2.17 or later (manylinux2014);
pythonfmu's needs 2.32.

:func:`variables_table` writes ``resources/fmu_variables.txt`` from modelDescription.xml:
each variable's value reference, type, causality, variability, declared min/max and start
value, for the runtime's checks.
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import fmu_runtime

SOURCE_DIR = Path(fmu_runtime.__file__).resolve().parent / "native"  # package data
SOURCES = (  # every platform's
    "loader.c",
    "values.c",
    "runtime.c",
    "probe.c",
    "python.c",
    "slave.c",
    "slave_values.c",
    "forward.c",
)
PLATFORM_SOURCES = {"linux64": "platform_posix.c", "win64": "platform_win32.c"}
SUFFIXES = {"linux64": ".so", "win64": ".dll"}
HEADERS = ("loader.h", "probe.h", "python.h", "slave.h", "glibc_floor.h", "platform.h")
VARIABLES_FILE = "fmu_variables.txt"
OVERRIDE_VARIABLE = "AUV_FMU_PYTHON"  # the runtime's own name for it is in loader.h
RUNTIME_VARIABLE = "AUV_FMU_RUNTIME"  # "pythonfmu": the fallback
WIN64_VARIABLE = "AUV_FMU_WIN64"  # "1": compile the win64 runtime afresh (zig), not prebuilt
WRAPPER_SUFFIX = "_pythonfmu"
GLIBC_FLOOR = "2.17"
NO_COMPILER = (
    "no C compiler (cc) and no ziglang package: the FMUs' linux64 binary stays pythonfmu's "
    "(non-Python hosts must preload libpython; see docs/native-loader.md)"
)
WARNINGS = ("-Wall", "-Wextra", "-Wno-format-truncation")  # a log line may be cut: intended
# What the tests hold the runtime's C to besides (tests/fmu_runtime/test_static_analysis.py),
# with -Werror: stricter warnings and GCC's static analyser. Not in a build's flags: another
# compiler's version may warn where this one does not, and a user's build must not fail.
STRICT_WARNINGS = ("-Wpedantic", "-Wconversion", "-Wsign-conversion", "-Wshadow", "-Wcast-qual",
                   "-Wformat=2", "-Wnull-dereference", "-Wdouble-promotion",
                   "-Wstrict-prototypes")  # fmt: skip
ANALYZER = ("-fanalyzer",)  # GCC 10 and later
_FLAGS = ("-shared", "-O2", "-std=c11", "-fvisibility=hidden", "-fPIC", *WARNINGS)
# libdl and libpthread by file name: before glibc 2.34 dlopen & co. live in libdl.so.2,
# and the link must name it even where it is an empty stub (glibc_floor.h); zig makes its
# own glibc 2.17 stubs of both
_LIBS = ("-Wl,--no-as-needed", "-l:libdl.so.2", "-l:libpthread.so.0", "-Wl,-z,nodelete")
_ZIG_LIBS = ("-ldl", "-lpthread", "-Wl,-z,nodelete")
_ZIG_TARGET = f"x86_64-linux-gnu.{GLIBC_FLOOR}"
# win64: __declspec(dllexport) decides what the DLL exports; UCRT and KERNEL32 only; -s:
# no PDB, whose paths would change the DLL's build hash with the folders it is built in
_WIN64_FLAGS = ("-shared", "-O2", "-std=c11", "-s", *WARNINGS)
_WIN64_TARGET = "x86_64-windows-gnu"
PREBUILT_DIR = SOURCE_DIR / "prebuilt" / "win64"  # package data
PREBUILT_DLL = PREBUILT_DIR / "runtime.dll"
PREBUILT_RECORD = PREBUILT_DIR / "built_from.txt"
PREBUILT_SCRIPT = "scripts/build_win64_runtime.py"


@dataclass(frozen=True)
class Toolchain:
    """A C compiler command; ``zig`` if it is zig's (which targets glibc 2.17 itself)."""

    name: str
    command: tuple[str, ...]
    zig: bool


def toolchain() -> Toolchain | None:
    """``cc`` on PATH, else ziglang's ``zig cc``, else None."""
    cc = shutil.which("cc")
    if cc:
        return Toolchain("cc", (cc,), zig=False)
    if importlib.util.find_spec("ziglang") is not None:
        return Toolchain("zig", (sys.executable, "-m", "ziglang", "cc"), zig=True)
    return None


def zig() -> Toolchain | None:
    """ziglang's ``zig cc`` (the win64 cross-compiler), or None."""
    if importlib.util.find_spec("ziglang") is None:
        return None
    return Toolchain("zig", (sys.executable, "-m", "ziglang", "cc"), zig=True)


def win64_wanted() -> bool:
    """Whether the build compiles the win64 runtime afresh (``AUV_FMU_WIN64=1``)."""
    return os.environ.get(WIN64_VARIABLE) == "1"


def source_digest() -> str:
    """SHA-256 of the runtime's C sources and headers (part of the FMUs' rebuild key and
    GUID), which compiler would build it (an FMU built without one is rebuilt once there
    is), whether the win64 runtime is compiled afresh, and the prebuilt one (DLL and
    record). The Python the FMUs record is not in it but in the build's record beside
    them (:func:`build_python_identity`): it names the build machine's folders, and two
    builds of one model at two paths are one model."""
    digest = hashlib.sha256()
    chain = toolchain()
    digest.update(f"compiler {chain.name if chain else 'none'}\n".encode())
    digest.update(f"win64 {win64_wanted() and zig() is not None}\n".encode())
    for name in (*SOURCES, *PLATFORM_SOURCES.values(), *HEADERS):
        digest.update(f"{name}\n".encode() + (SOURCE_DIR / name).read_bytes())
    for path in (PREBUILT_DLL, PREBUILT_RECORD):
        data = path.read_bytes() if path.is_file() else b"none"
        digest.update(f"{path.name}\n".encode() + hashlib.sha256(data).digest())
    return digest.hexdigest()


def build_python_identity() -> str:
    """The Python a build records (``sys.executable``) as the rebuild key sees it: the
    folder it runs from (the environment whose packages it imports) and the interpreter
    its name resolves to. The names of one interpreter in one folder (a virtual
    environment's ``python`` and ``python3``: the console script ``auv-cosim`` runs the
    second, ``python -m cosim.cli`` the first) are one Python; by name, a command run the
    other way rebuilt every FMU."""
    executable = Path(sys.executable)
    return f"{executable.parent} {executable.resolve()}"


def win64_sources_digest() -> str:
    """SHA-256 of what the win64 runtime is compiled from: the target, the flags, and the
    names and bytes of its C sources and every header."""
    digest = hashlib.sha256()
    digest.update(f"{_WIN64_TARGET} {' '.join(_WIN64_FLAGS)}\n".encode())
    for name in (*SOURCES, PLATFORM_SOURCES["win64"], *HEADERS):
        digest.update(f"{name}\n".encode() + (SOURCE_DIR / name).read_bytes())
    return digest.hexdigest()


def prebuilt_record() -> dict[str, str]:
    """The prebuilt win64 runtime's record, ``key=value`` lines (``sources_sha256``,
    ``dll_sha256``, ``zig``, ``command``); empty if there is none."""
    if not PREBUILT_RECORD.is_file():
        return {}
    lines = PREBUILT_RECORD.read_text(encoding="utf-8").splitlines()
    return dict(line.split("=", 1) for line in lines if "=" in line and line[0] != "#")


def prebuilt_win64() -> bytes | str:
    """The prebuilt win64 runtime's bytes if it was built from today's sources (its record
    says so, and the DLL is the one recorded), else why not, in one line."""
    record = prebuilt_record()
    dll = PREBUILT_DLL.read_bytes() if PREBUILT_DLL.is_file() else None
    if dll is None or not record:
        why = "there is no prebuilt win64 runtime"
    elif record.get("sources_sha256") != win64_sources_digest():
        why = "the runtime's C sources changed since the prebuilt win64 runtime was built"
    elif record.get("dll_sha256") != hashlib.sha256(dll).hexdigest():
        why = "the prebuilt win64 runtime is not the DLL its record names"
    else:
        return dll
    return (
        f"the win64 binary stays pythonfmu's: {why} (regenerate it: python "
        f"{PREBUILT_SCRIPT}, which needs ziglang; or build with {WIN64_VARIABLE}=1 and ziglang)"
    )


def compile_command(
    chain: Toolchain, out: Path, *extra: str, platform: str = "linux64"
) -> list[str]:
    """The command that compiles the runtime for ``platform`` (``linux64``, or ``win64``
    with zig) into ``out`` (``extra`` flags appended, as the tests' ``-Werror``)."""
    sources = [str(SOURCE_DIR / s) for s in (*SOURCES, PLATFORM_SOURCES[platform])]
    if platform == "win64":
        return [*chain.command, "-target", _WIN64_TARGET, *_WIN64_FLAGS, *extra, "-o", str(out),
                *sources]  # fmt: skip
    command = [*chain.command, *_FLAGS, *extra]
    if chain.zig:
        command += ["-target", _ZIG_TARGET, "-DAUV_GLIBC_TARGET"]
    return [*command, "-o", str(out), *sources, *(_ZIG_LIBS if chain.zig else _LIBS)]


def compile_runtime(chain: Toolchain, out: Path, platform: str = "linux64") -> str | None:
    """Compile the runtime for ``platform`` into ``out``; None if it worked, else the
    compiler's first error line (file, line and what is wrong; GCC, clang and zig end
    theirs with the code and a caret), or its last line when none says "error"."""
    command = compile_command(chain, out, platform=platform)
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode == 0 and out.is_file():
        return None
    lines = (done.stderr or done.stdout or "").strip().splitlines()
    errors = [line.strip() for line in lines if "error" in line.lower()]
    return (errors or lines or [f"exit code {done.returncode}"])[0 if errors else -1]


def variables_table(model_description: bytes) -> str:
    """``fmu_variables.txt``: one line per variable, ``vr type causality variability min
    max start name`` with ``-`` for what is not declared."""
    lines = []
    for var in ET.fromstring(model_description).iter("ScalarVariable"):
        element = next(iter(var))
        fields = [
            var.get("valueReference", ""),
            element.tag[0],  # Real Integer Boolean String -> R I B S
            var.get("causality", "local"),
            var.get("variability", "continuous"),
            element.get("min", "-"),
            element.get("max", "-"),
            _number(element.get("start")),
            var.get("name", ""),
        ]
        lines.append(" ".join(fields))
    return "\n".join(lines) + "\n"


def _number(start: str | None) -> str:
    if start in ("true", "false"):
        return "1" if start == "true" else "0"
    if start is None:
        return "-"
    try:
        float(start)
    except ValueError:
        return "-"
    return start


def install_loader(fmu: Path, name: str) -> list[str]:
    """Make the runtime the linux64 and the win64 binary of the built ``fmu`` (model
    identifier ``name``), in place, pythonfmu's renamed beside each; return what it could
    not do, one line each (empty: all is in; :func:`loader_in` tells which is)."""
    runtimes: dict[str, bytes] = {}
    notes = []
    chain = toolchain()
    built = _compiled(chain, "linux64") if chain else NO_COMPILER
    if isinstance(built, bytes):
        runtimes["linux64"] = built
    elif chain is None:
        notes.append(built)
    else:
        notes.append(f"the FMUs keep pythonfmu's binary: the runtime did not compile ({built})")
    win64 = _win64()
    if isinstance(win64, bytes):
        runtimes["win64"] = win64
    else:
        notes.append(win64)
    if runtimes:
        _rewrite(fmu, name, runtimes)
    return notes


def _win64() -> bytes | str:
    """The win64 runtime: compiled afresh when asked and zig is there, else prebuilt."""
    cross = zig() if win64_wanted() else None
    if cross is None:
        return prebuilt_win64()
    built = _compiled(cross, "win64")
    if isinstance(built, bytes):
        return built
    return f"{WIN64_VARIABLE}=1, but the win64 binary stays pythonfmu's: {built}"


# Process-wide: (compiler, platform, sources digest) -> the library's bytes or the
# compiler's complaint; the three FMUs of a build share one compilation per platform.
_COMPILED: dict[tuple[str, str, str], bytes | str] = {}


def _compiled(chain: Toolchain, platform: str) -> bytes | str:
    key = (chain.name, platform, source_digest())
    if key not in _COMPILED:
        with tempfile.TemporaryDirectory(prefix="runtime_") as tmp:
            out = Path(tmp) / f"runtime{SUFFIXES[platform]}"
            problem = compile_runtime(chain, out, platform)
            _COMPILED[key] = out.read_bytes() if problem is None else problem
    return _COMPILED[key]


def _rewrite(fmu: Path, name: str, runtimes: dict[str, bytes]) -> None:
    """Each platform's runtime as its binary, pythonfmu's renamed beside it."""
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
    binaries = {f"binaries/{p}/{name}{SUFFIXES[p]}": p for p in runtimes}
    partial = fmu.with_name(f".{fmu.name}.runtime.tmp")
    try:
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for info, data in entries:
                platform = binaries.get(info.filename)
                if platform is not None:
                    wrapper = f"binaries/{platform}/{name}{WRAPPER_SUFFIX}{SUFFIXES[platform]}"
                    archive.writestr(_renamed(info, wrapper), data)
                    archive.writestr(_renamed(info, info.filename), runtimes[platform])
                else:
                    archive.writestr(info, data)
        partial.replace(fmu)
    finally:
        partial.unlink(missing_ok=True)


def _renamed(info: zipfile.ZipInfo, name: str) -> zipfile.ZipInfo:
    copy = zipfile.ZipInfo(name, date_time=info.date_time)
    copy.compress_type = info.compress_type
    copy.external_attr = info.external_attr
    return copy


def loader_in_folder(folder: Path, platform: str) -> bool:
    """True if the FMU extracted in ``folder`` has the runtime as its ``platform`` binary
    (:func:`loader_in` of its archive); False for a platform the runtime is not built for."""
    suffix = SUFFIXES.get(platform)
    binaries = folder / "binaries" / platform
    return suffix is not None and any(binaries.glob(f"*{WRAPPER_SUFFIX}{suffix}"))


def loader_in(fmu: Path, platform: str = "linux64") -> bool:
    """True if the FMU's ``platform`` binary is the runtime (pythonfmu's is beside it)."""
    wrapper = f"binaries/{platform}/"
    with zipfile.ZipFile(fmu) as archive:
        return any(
            n.startswith(wrapper) and n.endswith(f"{WRAPPER_SUFFIX}{SUFFIXES[platform]}")
            for n in archive.namelist()
        )
