"""Virtual environments the tests make with pip: a fresh one of a given Python holding only
the packages a test names, or a skip saying why when pip cannot install them (no network,
no registry)."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest


def make_venv(folder: Path, python: str | Path, *packages: str) -> Path:
    """A virtual environment of ``python`` at ``folder`` holding ``packages`` only (pip,
    up to 900 s), or a skip naming what pip said."""
    subprocess.run([str(python), "-m", "venv", str(folder)], check=True)
    done = subprocess.run(
        [str(folder / "bin" / "python"), "-m", "pip", "install", "-q", *packages],
        capture_output=True,
        text=True,
        timeout=900,
    )
    if done.returncode != 0:
        pytest.skip(f"pip could not install {packages}: {done.stderr.strip()[-300:]}")
    return folder
