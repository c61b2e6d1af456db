"""``mypy --strict`` as a downstream user runs it on their own scripts calling cosim."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

import cosim


def users_mypy(scripts: list[Path], folder: Path, cache: Path) -> tuple[str, int]:
    """``mypy --strict`` of a user's ``scripts`` calling the package, read as installed (its
    own errors are not the user's), with a configuration of the user's in ``folder`` (not
    this repository's pyproject.toml) and mypy's incremental cache in ``cache``: mypy's
    report and exit status.

    ``cache`` is the ``users_mypy_cache`` fixture of tests/conftest.py, one per test
    process: mypy's incremental mode re-reads a module whose source or options changed and
    gives the report a fresh cache gives, so the tests share the analysis of numpy, pandas
    and cosim (each run with a fresh cache took minutes on a loaded 2-core machine)."""
    api = pytest.importorskip("mypy.api")
    config = folder / "mypy.ini"
    package_root = Path(cosim.__file__).resolve().parents[1]
    config.write_text(f"[mypy]\nmypy_path = {package_root}\n", encoding="utf-8")
    arguments = ["--strict", "--follow-imports", "silent", "--config-file", str(config)]
    arguments += ["--cache-dir", str(cache), *map(str, scripts)]
    limit = sys.getrecursionlimit()
    config_folder = os.environ.get("MYPY_CONFIG_FILE_DIR")
    try:
        out, err, status = api.run(arguments)
    finally:  # mypy raises it for good (2**14): a deeply nested TOML then reads as valid
        sys.setrecursionlimit(limit)  # in the tests that run after it in this process
        # and sets MYPY_CONFIG_FILE_DIR to the folder of the config file it read
        if config_folder is None:
            os.environ.pop("MYPY_CONFIG_FILE_DIR", None)
        else:
            os.environ["MYPY_CONFIG_FILE_DIR"] = config_folder
    return out + err, status
