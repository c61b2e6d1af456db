"""The runtime's win64 build (platform_win32.c), cross-compiled with zig and run under Wine
in a small win64 C host: the Windows side of finding Python. There is no Windows machine
here; a stand-in python.exe (hosts/fake_python.c) answers the probe as Python 3.8 would,
after checking that its arguments and environment arrived as sent (a real Windows CPython
runs the FMU in test_win64_cpython.py). Guarded: a file:///Z:/ resource URI with
non-ASCII characters read through UTF-16; a GUID checked; the Windows candidate order
(AUV_FMU_PYTHON as an executable whose path has a space, or a venv folder's
Scripts\\python.exe; the build's Python; python, then py -3 on PATH) with one line each;
the probe's command line quoting, its "-3" for the launcher and PYTHONHOME left out.
Wine is not Windows: docs/native-loader.md says what was and was not run."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path, PureWindowsPath

import pytest
from c_hosts import moved, run_clean
from windows_cpython import end_wineserver, windows, wine, wine_environ

from cosim.fmus import native
from fmu_runtime.entry import RECORD_FILE

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(native.zig() is None, reason="ziglang not installed"),
    pytest.mark.skipif(wine() is None, reason="Wine (wine64) not installed"),
]

HOSTS = Path(__file__).parent / "hosts"
WINE = str(wine())


def _cross_compile(out: Path, *command: str) -> Path:
    zig = native.zig()
    assert zig is not None
    done = subprocess.run(
        [
            *zig.command,
            "-target",
            "x86_64-windows-gnu",
            "-Wall",
            "-Wextra",
            "-Werror",
            *command,
            "-o",
            str(out),
        ],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    return out


@pytest.fixture(scope="module")
def wine(tmp_path_factory, extracted):
    """The win64 host, the stand-in Python, the FMU in a folder named with non-ASCII
    characters and a space, its build Python gone, and the runtime as its win64 binary;
    a Wine prefix of its own, whose wineserver is ended afterwards."""
    root = tmp_path_factory.mktemp("win64")
    host = _cross_compile(root / "host.exe", "-municode", str(HOSTS / "win64_host.c"))
    fake = _cross_compile(root / "fake.exe", str(HOSTS / "fake_python.c"))
    runtime = root / "runtime.dll"
    zig = native.zig()
    assert zig is not None
    done = subprocess.run(
        native.compile_command(zig, runtime, "-Werror", platform="win64"),
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    folder = moved(extracted["AuvPlant"], root)
    unicode = folder.parent / "ünï 📦"
    folder.rename(unicode)
    shutil.copyfile(runtime, unicode / "binaries" / "win64" / "AuvPlant.dll")
    (root / "venv" / "Scripts").mkdir(parents=True)
    shutil.copyfile(fake, root / "venv" / "Scripts" / "python.exe")
    (root / "launcher").mkdir()
    shutil.copyfile(fake, root / "launcher" / "py.exe")
    shutil.copyfile(fake, root / "a python.exe")
    prefix = root / "prefix"
    record = (unicode / "resources" / RECORD_FILE).read_text()
    guid = next(line[5:] for line in record.splitlines() if line.startswith("guid="))
    yield {"root": root, "host": host, "fmu": unicode, "guid": guid, "prefix": prefix}
    end_wineserver(prefix)


def _instantiate(
    wine, guid: str | None = None, spelling: str = "file:///", **environment: str
) -> list[str]:
    """The host's output lines: each log line, then whether an instance was made. The
    resource URI begins with ``spelling`` where ``file:///`` would."""
    fmu = wine["fmu"]
    uri = PureWindowsPath(windows(fmu / "resources")).as_uri()
    uri = spelling + uri.removeprefix("file:///")
    dll = windows(fmu / "binaries" / "win64" / "AuvPlant.dll")
    done = run_clean(
        [WINE, wine["host"], dll, uri, guid or wine["guid"]],
        wine["root"],
        timeout=300,
        **wine_environ(wine["prefix"]),
        WINEDEBUG="-all",
        LANG="C.UTF-8",  # Wine maps Windows names to UTF-8 file names only in a UTF-8 locale
        **environment,
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return done.stdout.splitlines()


def test_wine_makes_its_server_folder_in_the_tests_own_folder(wine):
    """Tests leave nothing behind: Wine makes its server's socket folder (``wine-XXXXXX``)
    in the test's temporary folder, where one stayed in /tmp after every test."""
    _instantiate(wine)
    assert list(Path(wine_environ(wine["prefix"])["TMPDIR"]).glob("wine-*"))


@pytest.mark.parametrize("spelling", ["file:///", "file:/", "file://localhost/", "file://"])
def test_a_unicode_resource_uri_is_read_and_a_wrong_guid_refused(wine, spelling):
    """However a Windows tool spells the URI of Z:\\...\\resources (file:///Z:/, file:/Z:/,
    file://localhost/Z:/, file://Z:/ with the drive where the host goes), the runtime reads
    the FMU's record there: only then can it tell the GUID is not this FMU's."""
    assert "%F0%9F%93%A6" in PureWindowsPath(windows(wine["fmu"])).as_uri()
    lines = _instantiate(wine, guid="{00000000-0000-0000-0000-000000000000}", spelling=spelling)
    assert lines == [
        "LOG 3 logStatusError: fmi2Instantiate refused: GUID "
        "{00000000-0000-0000-0000-000000000000} is not this FMU's "
        f"({wine['guid']}): the host read another build's modelDescription.xml",
        "instance NULL",
    ]


def test_the_windows_candidates_are_each_asked_once_in_order(wine):
    """An executable whose path has a space, PYTHONHOME set in the host (left out of the
    probe's environment), the py launcher on PATH given "-3"."""
    exe = windows(wine["root"] / "a python.exe")
    lines = _instantiate(
        wine,
        AUV_FMU_PYTHON=exe,
        PYTHONHOME="/garbage",
        WINEPATH=windows(wine["root"] / "launcher"),
    )
    launcher = windows(wine["root"] / "launcher" / "py.exe")
    refused = "LOG 3 logStatusError: no Python for this FMU: "
    assert lines == [
        refused + "1. the Python running in this process: none runs",
        refused + f"2. AUV_FMU_PYTHON={exe}: Python 3.8.1 is too old: the FMU needs CPython >= 3.9",
        refused + "3. the build's Python /nonexistent/build-environment/bin/python: does not "
        "exist (the FMU was built in an environment that is not on this machine)",
        refused + "4. python on PATH: not found",
        refused + f"5. py -3 on PATH ({launcher}): Python 3.8.2 is too old: the FMU needs "
        "CPython >= 3.9",
        "instance NULL",
    ]


def test_a_venv_folder_means_its_scripts_python_exe(wine):
    venv = windows(wine["root"] / "venv")
    lines = _instantiate(wine, AUV_FMU_PYTHON=venv)
    assert f"2. AUV_FMU_PYTHON={venv}: Python 3.8.1 is too old" in "\n".join(lines)
    launcher = windows(wine["root"] / "launcher")
    lines = _instantiate(wine, AUV_FMU_PYTHON=launcher)
    assert (
        f"2. AUV_FMU_PYTHON={launcher}: the folder has no Scripts\\python.exe (expected a "
        "virtual environment's folder or a Python executable)" in "\n".join(lines)
    )


def test_a_host_splitting_with_strtok_around_instantiate_keeps_its_place(wine):
    """Three instances named in one strtok loop of a win64 host, each refused (no Python
    here) after the runtime searched PATH for python.exe: all three are tried. The search
    split PATH with strtok, which left the host's next strtok(NULL, ...) in the runtime's
    freed copy of PATH: the host's loop ended after the first."""
    host = _cross_compile(wine["root"] / "strtok_host.exe", str(HOSTS / "strtok_host.c"))
    fmu = wine["root"] / "ascii"  # the host takes narrow arguments: a plain ASCII folder
    if not fmu.exists():
        shutil.copytree(wine["fmu"], fmu)
    done = run_clean(
        [WINE, host, windows(fmu / "binaries" / "win64" / "AuvPlant.dll"),
         PureWindowsPath(windows(fmu / "resources")).as_uri(), wine["guid"], "a,b,c"],
        wine["root"], timeout=300, **wine_environ(wine["prefix"]), WINEDEBUG="-all",
        LANG="C.UTF-8",
    )  # fmt: skip
    assert done.stdout.splitlines() == ["NULL a", "NULL b", "NULL c", "instances: 0"], (
        done.stdout[-2000:] + done.stderr[-2000:]
    )
