"""What a shared library needs from glibc, read with ``objdump -T`` (for the tests of the
FMUs' binaries)."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path


def glibc_versions(library: Path) -> list[tuple[int, ...]]:
    """Every GLIBC_x.y version the library's dynamic symbols need, oldest first."""
    out = subprocess.run(["objdump", "-T", str(library)], capture_output=True, text=True).stdout
    found = {tuple(map(int, v.split("."))) for v in re.findall(r"GLIBC_([0-9.]+)\b", out)}
    return sorted(found)


def unresolvable(library: Path) -> list[str]:
    """Functions the library needs that no versioned glibc symbol provides (a library the
    link forgot, as libm's fmax once was): strong undefined symbols without a version."""
    out = subprocess.run(["objdump", "-T", str(library)], capture_output=True, text=True).stdout
    return [
        line.split()[-1]
        for line in out.splitlines()
        if "*UND*" in line and " w " not in line and "GLIBC_" not in line
    ]
