"""Fixtures for running our FMUs in hosts that are not this test process:

* ``host`` (module): the C host ``hosts/fmi_host.c`` compiled with ``-Wall -Wextra
  -Werror`` (skipped without ``cc``);
* ``extracted`` (module): every built FMU extracted into a folder of its own;
* ``clean_home`` (session): one HOME for the clean environments, so that the FMUs'
  numba cache (under ``$HOME/.cache``) is compiled once, not in every test;
* ``windows_python`` (session): the folder of a real Windows CPython's ``python.exe``
  with numpy (``windows_cpython.py``), cached in pytest's cache; skipped without Wine or
  when it cannot be downloaded;
* ``windows_fmpy`` (session): a folder with fmpy (this environment's version) and the
  packages it imports, for that CPython, cached and skipped the same way.
"""

from __future__ import annotations

import zipfile
from importlib import metadata
from pathlib import Path

import pytest
from c_hosts import HOST_SOURCE, compiled_host
from windows_cpython import FMPY_IMPORTS, windows_cpython, windows_site, wine

from cosim.fmus.build import FMUS


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    return compiled_host(HOST_SOURCE, tmp_path_factory.mktemp("host"))


@pytest.fixture(scope="module")
def extracted(fmu_paths, tmp_path_factory) -> dict[str, Path]:
    """Every FMU extracted into a folder of its own."""
    folders = {}
    for name in FMUS:
        folder = tmp_path_factory.mktemp(name)
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            archive.extractall(folder)
        folders[name] = folder
    return folders


@pytest.fixture(scope="session")
def clean_home(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("home")


@pytest.fixture(scope="session")
def windows_cache(request, tmp_path_factory) -> Path:
    """Where the Windows CPython and its packages are kept: pytest's cache, if it is on."""
    if wine() is None:
        pytest.skip("Wine (wine64) not installed")
    cache = getattr(request.config, "cache", None)
    if cache is None:
        return tmp_path_factory.mktemp("windows-cpython")
    return Path(cache.mkdir("windows-cpython"))


@pytest.fixture(scope="session")
def windows_python(windows_cache) -> Path:
    home = windows_cpython(windows_cache)
    if isinstance(home, str):
        pytest.skip(home)
    return home


@pytest.fixture(scope="session")
def windows_fmpy(windows_cache, windows_python) -> Path:
    version = metadata.version("fmpy")
    site = windows_site(windows_cache, f"fmpy-{version}", (f"fmpy=={version}", *FMPY_IMPORTS))
    if isinstance(site, str):
        pytest.skip(site)
    return site
