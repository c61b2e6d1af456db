"""Put the native loader (``fmu_runtime/native/``) in front of pythonfmu's binary in a built FMU.

pythonfmu's library uses CPython's symbols without linking libpython, so a host that is
not Python cannot even load it, and it answers fmi2OK for calls our FMUs refuse. The
loader, a small C library compiled here, becomes ``binaries/linux64/<id>.so`` (and
``binaries/win64/<id>.dll`` when asked for with ``AUV_FMU_WIN64=1`` and a win64
cross-compiler, zig, is at hand: zig's first cross-compile on a machine takes about two
minutes, which a first ``auv-cosim run`` should not pay, and the DLL is untested on
Windows); pythonfmu's library
moves beside it as ``<id>_pythonfmu.so`` / ``.dll``. Two files go into ``resources/``:

* ``python_runtime.txt``: the Python environment the FMU is built in (libpython, base
  prefix, site-packages, executable), where the loader starts Python in a host that has
  none (``docs/native-loader.md``; ``AUV_FMU_PYTHON`` overrides it);
* ``fmu_variables.txt``: each variable's value reference, type, causality, variability,
  declared min/max and start value, from modelDescription.xml, for the loader's checks.

The compiler: the system's ``cc`` when there is one, else ``python -m ziglang cc`` (the
``ziglang`` package, a pip-installable clang), else none: the FMU then keeps pythonfmu's
binary alone, and :func:`install_loader` says so (the caller prints it once and the FMU's
documentation page records it).
"""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from dataclasses import dataclass
from pathlib import Path
from xml.etree import ElementTree as ET

import fmu_runtime

SOURCE_DIR = Path(fmu_runtime.__file__).resolve().parent / "native"  # package data
SOURCES = ("loader.c", "runtime.c")
HEADERS = ("loader.h",)
RUNTIME_FILE = "python_runtime.txt"
VARIABLES_FILE = "fmu_variables.txt"
OVERRIDE_VARIABLE = "AUV_FMU_PYTHON"  # the loader's own name for it is in loader.h
WRAPPER_SUFFIX = "_pythonfmu"
NO_COMPILER = (
    "no C compiler (cc) and no ziglang package: the FMUs keep pythonfmu's binary "
    "(non-Python hosts must preload libpython; see docs/native-loader.md)"
)
_FLAGS = ("-shared", "-O2", "-std=c11", "-fvisibility=hidden")
_TARGETS = {  # platform folder: (zig target or None for the host compiler, suffix, libs)
    "linux64": (
        "x86_64-linux-gnu",
        ".so",
        ("-fPIC", "-ldl", "-lpthread", "-lm", "-Wl,-z,nodelete"),
    ),
    "win64": ("x86_64-windows-gnu", ".dll", ()),
}


@dataclass(frozen=True)
class Toolchain:
    """A C compiler command; ``cross`` if it can target win64 too (zig)."""

    name: str
    command: tuple[str, ...]
    cross: bool


def toolchain() -> Toolchain | None:
    """``cc`` on PATH, else ziglang's ``zig cc``, else None."""
    cc = shutil.which("cc")
    if cc:
        return Toolchain("cc", (cc,), cross=False)
    if importlib.util.find_spec("ziglang") is not None:
        return Toolchain("zig", (sys.executable, "-m", "ziglang", "cc"), cross=True)
    return None


def zig() -> Toolchain | None:
    """ziglang's ``zig cc`` (for the win64 cross-compile), or None."""
    if importlib.util.find_spec("ziglang") is None:
        return None
    return Toolchain("zig", (sys.executable, "-m", "ziglang", "cc"), cross=True)


def win64_wanted() -> bool:
    """Whether the build cross-compiles the win64 loader too (``AUV_FMU_WIN64=1``)."""
    return os.environ.get("AUV_FMU_WIN64") == "1"


def source_digest() -> str:
    """SHA-256 of the loader's C sources and header (part of the FMUs' rebuild key), and
    which compiler would build it (an FMU built without one is rebuilt once there is)."""
    digest = hashlib.sha256()
    chain = toolchain()
    digest.update(f"compiler {chain.name if chain else 'none'}\n".encode())
    digest.update(f"win64 {win64_wanted()}\n".encode())
    for name in (*SOURCES, *HEADERS):
        digest.update(f"{name}\n".encode() + (SOURCE_DIR / name).read_bytes())
    digest.update(runtime_record().encode())
    return digest.hexdigest()


def compile_loader(chain: Toolchain, platform: str, out: Path) -> str | None:
    """Compile the loader for ``platform`` (a key of ``_TARGETS``) into ``out``; None if it
    worked, else the compiler's last line."""
    target, _, libs = _TARGETS[platform]
    command = [*chain.command, *_FLAGS]
    if chain.cross:
        command += ["-target", target]
    command += ["-o", str(out), *(str(SOURCE_DIR / s) for s in SOURCES), *libs]
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    if done.returncode == 0 and out.is_file():
        return None
    lines = (done.stderr or done.stdout or f"exit code {done.returncode}").strip().splitlines()
    return lines[-1] if lines else f"exit code {done.returncode}"


def runtime_record() -> str:
    """``python_runtime.txt``: this environment's libpython, base prefix, site-packages and
    executable (``libpython=`` empty when this Python has no shared library)."""
    libpython = ""
    if os.name == "nt":
        dll = Path(sys.base_prefix) / f"python{sys.version_info[0]}{sys.version_info[1]}.dll"
        libpython = str(dll) if dll.is_file() else ""
    elif sysconfig.get_config_var("Py_ENABLE_SHARED"):
        name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY")
        candidate = Path(sysconfig.get_config_var("LIBDIR") or "") / (name or "")
        libpython = str(candidate) if candidate.is_file() else ""
    return (
        f"libpython={libpython}\nhome={sys.base_prefix}\n"
        f"site={sysconfig.get_paths()['purelib']}\nexecutable={sys.executable}\n"
    )


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
    """Put the loader in front of pythonfmu's binaries in the built ``fmu`` (model
    identifier ``name``), in place; return what it could not do, one line each (empty:
    the loader is in for linux64, and for win64 when asked for and zig is installed)."""
    chain = toolchain()
    if chain is None:
        return [NO_COMPILER]
    notes: list[str] = []
    loaders: dict[str, bytes] = {}
    win64 = (chain if chain.cross else zig()) if win64_wanted() else None
    for platform, use in (("linux64", chain), ("win64", win64)):
        if use is None:
            continue
        built = _compiled(use, platform)
        if isinstance(built, bytes):
            loaders[platform] = built
        else:
            notes.append(f"{platform} loader not built ({use.name}): {built}")
    if "linux64" not in loaders:
        notes.append("the FMUs keep pythonfmu's binary: " + notes[0])
    _rewrite(fmu, name, loaders)
    return notes


# Process-wide: (compiler, platform, sources digest) -> the library's bytes or the
# compiler's complaint; the three FMUs of a build share one compilation per platform.
_COMPILED: dict[tuple[str, str, str], bytes | str] = {}


def _compiled(chain: Toolchain, platform: str) -> bytes | str:
    key = (chain.name, platform, source_digest())
    if key not in _COMPILED:
        with tempfile.TemporaryDirectory(prefix="loader_") as tmp:
            out = Path(tmp) / f"loader{_TARGETS[platform][1]}"
            problem = compile_loader(chain, platform, out)
            _COMPILED[key] = out.read_bytes() if problem is None else problem
    return _COMPILED[key]


def _rewrite(fmu: Path, name: str, loaders: dict[str, bytes]) -> None:
    with zipfile.ZipFile(fmu) as archive:
        entries = [(info, archive.read(info)) for info in archive.infolist()]
        description = archive.read("modelDescription.xml")
    partial = fmu.with_name(f".{fmu.name}.loader.tmp")
    try:
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as archive:
            for info, data in entries:
                platform, _, file = info.filename.removeprefix("binaries/").partition("/")
                suffix = _TARGETS.get(platform, ("", "", ()))[1]
                if (
                    info.filename.startswith("binaries/")
                    and file == f"{name}{suffix}"
                    and platform in loaders
                ):
                    info = _renamed(info, f"binaries/{platform}/{name}{WRAPPER_SUFFIX}{suffix}")
                    archive.writestr(info, data)
                    loader = _renamed(info, f"binaries/{platform}/{name}{suffix}")
                    archive.writestr(loader, loaders[platform])
                    continue
                archive.writestr(info, data)
            archive.writestr(f"resources/{RUNTIME_FILE}", runtime_record())
            archive.writestr(f"resources/{VARIABLES_FILE}", variables_table(description))
        os.replace(partial, fmu)
    finally:
        partial.unlink(missing_ok=True)


def _renamed(info: zipfile.ZipInfo, name: str) -> zipfile.ZipInfo:
    copy = zipfile.ZipInfo(name, date_time=info.date_time)
    copy.compress_type = info.compress_type
    copy.external_attr = info.external_attr
    return copy


def loader_in(fmu: Path) -> bool:
    """True if the FMU's linux64 binary is the native loader (pythonfmu's is beside it)."""
    with zipfile.ZipFile(fmu) as archive:
        return any(n.endswith(f"{WRAPPER_SUFFIX}.so") for n in archive.namelist())
