"""What a Windows DLL exports and imports, read with ``objdump -p`` (binutils reads PE
files on Linux), for the tests of the FMUs' win64 binaries."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

_EXPORTED = re.compile(r"^\s*\[\s*\d+\]\s+(\S+)\s*$")


def _private_headers(dll: Path) -> list[str]:
    done = subprocess.run(["objdump", "-p", str(dll)], capture_output=True, text=True, check=True)
    return done.stdout.splitlines()


def exported_names(dll: Path) -> list[str]:
    """The names of the export table, in its order."""
    lines = _private_headers(dll)
    start = next(
        (i for i, line in enumerate(lines) if "[Ordinal/Name Pointer] Table" in line), len(lines)
    )
    names = []
    for line in lines[start + 1 :]:
        match = _EXPORTED.match(line)
        if match is None:
            break
        names.append(match.group(1))
    return names


def imported_dlls(dll: Path) -> list[str]:
    """The DLLs the import table names, as written there."""
    return [
        line.split("DLL Name:", 1)[1].strip()
        for line in _private_headers(dll)
        if "DLL Name:" in line
    ]
