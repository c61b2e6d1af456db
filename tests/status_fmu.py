"""``status_fmu(folder, status, at, terminated)``: the Reference FMU Dahlquist rebuilt from
the sources it ships with the doStep statuses of tests/fmus/cosim_test_status.c (gcc, a few
tenths of a second), as ``<folder>/Status.fmu``."""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
from repo_paths import TESTS

DAHLQUIST = TESTS / "data" / "reference-fmus" / "Dahlquist.fmu"
SHIM = TESTS / "fmus" / "cosim_test_status.c"
STATUS_CODES = {"Warning": 1, "Discard": 2, "Error": 3, "Pending": 5}


def status_fmu(folder: Path, status: str, at: float, terminated: bool = False) -> Path:
    """Dahlquist whose doStep answers fmi2``status`` from the step that starts at ``at``
    (s); after a Discard, fmi2Terminated is ``terminated``."""
    sources = folder / "sources"
    with zipfile.ZipFile(DAHLQUIST) as archive:
        for name in archive.namelist():
            if name.startswith("sources/"):
                archive.extract(name, folder)
    library = folder / "Dahlquist.so"
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        raise RuntimeError("no C compiler (gcc or cc) to build the status FMU")
    defines = [f"-DSTEP_STATUS={STATUS_CODES[status]}", f"-DSTATUS_AT={at!r}",
               f"-DTERMINATED={int(terminated)}"]  # fmt: skip
    headers = Path(fmpy.__file__).parent / "c-code"  # fmpy ships the FMI 2.0 headers
    command = [gcc, "-shared", "-fPIC", f"-I{sources}", f"-I{headers}", *defines, str(SHIM)]
    subprocess.run([*command, "-o", str(library)], check=True, capture_output=True, timeout=120)
    path = folder / "Status.fmu"
    with zipfile.ZipFile(DAHLQUIST) as source, zipfile.ZipFile(path, "w") as target:
        for item in source.infolist():
            if item.filename != "binaries/linux64/Dahlquist.so":
                target.writestr(item, source.read(item))
        target.write(library, "binaries/linux64/Dahlquist.so")
    return path
