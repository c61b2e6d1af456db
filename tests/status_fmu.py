"""``status_fmu(folder, status, at, ...)``: the Reference FMU Dahlquist rebuilt from the
sources it ships with the doStep and fmi2Terminate statuses of tests/fmus/cosim_test_status.c
(gcc, a few tenths of a second), as ``<folder>/Status.fmu``."""

from __future__ import annotations

import shutil
import subprocess
import zipfile
from pathlib import Path

import fmpy
from repo_paths import TESTS

DAHLQUIST = TESTS / "data" / "reference-fmus" / "Dahlquist.fmu"
SHIM = TESTS / "fmus" / "cosim_test_status.c"
STATUS_CODES = {"OK": 0, "Warning": 1, "Discard": 2, "Error": 3, "Fatal": 4, "Pending": 5}


def status_fmu(
    folder: Path,
    status: str | int,
    at: float,
    terminated: bool = False,
    *,
    block_s: int = 0,
    terminate: str | int = "OK",
    answers: dict[str, str | int] | None = None,
) -> Path:
    """Dahlquist whose doStep answers fmi2``status`` (or that number, one out of the
    standard) from the step that starts at ``at`` (s), blocking ``block_s`` seconds once
    first; after a Discard, fmi2Terminated is ``terminated``. fmi2Terminate answers
    fmi2``terminate``. ``answers`` maps a macro of the shim (ENTER_STATUS, EXIT_STATUS,
    SET_REAL_STATUS, SET_STATE_STATUS, GET_STATE_STATUS) to the status that call answers
    after its work."""
    sources = folder / "sources"
    with zipfile.ZipFile(DAHLQUIST) as archive:
        for name in archive.namelist():
            if name.startswith("sources/"):
                archive.extract(name, folder)
    library = folder / "Dahlquist.so"
    gcc = shutil.which("gcc") or shutil.which("cc")
    if gcc is None:
        raise RuntimeError("no C compiler (gcc or cc) to build the status FMU")
    defines = [f"-DSTEP_STATUS={_code(status)}", f"-DSTATUS_AT={at!r}",
               f"-DTERMINATED={int(terminated)}", f"-DBLOCK_S={int(block_s)}",
               f"-DTERMINATE_STATUS={_code(terminate)}"]  # fmt: skip
    defines += [f"-D{macro}={_code(code)}" for macro, code in (answers or {}).items()]
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


def _code(status: str | int) -> int:
    """The fmi2Status named ``status``, or the number given."""
    return status if isinstance(status, int) else STATUS_CODES[status]
