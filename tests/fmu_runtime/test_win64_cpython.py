"""The plant FMU's win64 binaries run by a real Windows CPython under Wine: python.org's
embeddable CPython 3.13 for win64 with numpy 2.1.3 (``windows_cpython.py``), in one C
host, ``hosts/stepper.c``, compiled for Windows (zig) and for Linux (cc) from the same
file. Guarded: the runtime (the prebuilt DLL the build put in the FMU) starts that CPython
in the host's process when ``AUV_FMU_PYTHON`` names its python.exe, a venv-like folder
(its ``Scripts\\python.exe``) or when it is ``python`` on PATH, and steps the plant as the
linux64 runtime steps it on Linux (to 1e-12 relative; measured: 2.5e-16); the fallback
(``AUV_FMU_RUNTIME=pythonfmu``) loads pythonfmu's DLL beside it and gives the same values;
pythonfmu's DLL loaded alone gives them too but refuses input derivatives; fmpy itself,
in that CPython, simulates the built FMU file (the runtime uses the CPython running in the
process) with the same values. Which ``python313.dll`` and which FMU DLLs were loaded is
read from Wine's ``loaddll`` trace.
Wine is not Windows: docs/native-loader.md says what was and was not run."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path, PureWindowsPath

import pytest
from c_hosts import moved, run_clean
from windows_cpython import end_wineserver, windows, wine, wine_environ

from cosim.fmus import native

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(native.zig() is None, reason="ziglang not installed"),
    pytest.mark.skipif(wine() is None, reason="Wine (wine64) not installed"),
    pytest.mark.skipif(shutil.which("cc") is None, reason="no cc for the Linux host"),
]

STEPPER = Path(__file__).parent / "hosts" / "stepper.c"
STEPS, H = 20, 0.1  # s
# thrust, tunnel force, fin angle, mass position command: a turn that dives and rolls
SETS = "0=9,2=1.5,3=0.05,4=0.01"
OUTS = ",".join(str(vr) for vr in range(8, 30))  # every Real output of the plant
LOADED = re.compile(r'Loaded L"([^"]+)"')


@pytest.fixture(scope="module")
def machine(tmp_path_factory, extracted, windows_python):
    """The stepper for both systems, the plant's extraction with its build's Python gone,
    a venv-like folder whose Scripts\\python.exe is the Windows CPython, and a Wine prefix
    of its own, whose wineserver is ended afterwards."""
    root = tmp_path_factory.mktemp("win64_cpython")
    zig = native.zig()
    assert zig is not None
    for command in (
        [*zig.command, "-target", "x86_64-windows-gnu", "-o", str(root / "stepper.exe")],
        [str(shutil.which("cc")), "-O1", "-o", str(root / "stepper"), "-ldl"],
    ):
        done = subprocess.run(
            [*command, "-Wall", "-Wextra", "-Werror", str(STEPPER)],
            capture_output=True,
            text=True,
        )
        assert done.returncode == 0, done.stderr[-3000:]
    plant = moved(extracted["AuvPlant"], root)
    shutil.copytree(windows_python, root / "venv" / "Scripts")
    description = (plant / "modelDescription.xml").read_text()
    guid = re.search(r'guid="([^"]+)"', description)
    assert guid is not None
    prefix = root / "prefix"
    yield {"root": root, "plant": plant, "guid": guid.group(1), "prefix": prefix}
    end_wineserver(prefix)


def _steps(stdout: str) -> list[list[float]]:
    rows = [line.split() for line in stdout.splitlines() if line[:1].isdigit()]
    return [[float(value) for value in row] for row in rows]


def _wine_run(machine, command: list, **environment: str) -> tuple[str, list[str]]:
    """``command`` (a Windows program and its arguments) under Wine in the test's prefix:
    its stdout, and the DLLs Wine loaded (its trace); a failure shows the output's end."""
    done = run_clean(
        [wine(), *command],
        machine["root"],
        timeout=600,
        **wine_environ(machine["prefix"]),
        WINEDEBUG="-all,+loaddll",
        **environment,
    )
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    return done.stdout, LOADED.findall(done.stderr.replace("\\\\", "\\"))


def _on_wine(machine, dll: str = "AuvPlant.dll", **environment: str):
    """The Windows stepper under Wine: its stdout, and the DLLs Wine loaded (its trace)."""
    plant = machine["plant"]
    uri = PureWindowsPath(windows(plant / "resources")).as_uri()
    return _wine_run(
        machine,
        [machine["root"] / "stepper.exe", windows(plant / "binaries" / "win64" / dll),
         uri, machine["guid"], STEPS, H, SETS, OUTS],
        **environment,
    )  # fmt: skip


def _python_dlls(loaded: list[str]) -> set[str]:
    return {path for path in loaded if path.lower().endswith("python313.dll")}


@pytest.fixture(scope="module")
def on_linux(machine, clean_home):
    """The same steps by the linux64 runtime, with this test's Python."""
    plant = machine["plant"]
    done = run_clean(
        [machine["root"] / "stepper", plant / "binaries" / "linux64" / "AuvPlant.so",
         (plant / "resources").as_uri(), machine["guid"], STEPS, H, SETS, OUTS],
        clean_home,
        AUV_FMU_PYTHON=sys.executable,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    assert "exit 0" in done.stdout
    return _steps(done.stdout)


@pytest.fixture(scope="module")
def on_wine(machine, windows_python):
    stdout, loaded = _on_wine(machine, AUV_FMU_PYTHON=windows(windows_python / "python.exe"))
    assert _python_dlls(loaded) == {windows(windows_python / "python313.dll")}
    return stdout


def test_a_real_windows_cpython_steps_the_plant_as_linux_does(on_wine, on_linux):
    """The runtime takes the input derivatives (status 0) and every output of every step
    equals Linux's to 1e-12 relative (Linux steps with numba, this CPython without)."""
    assert "derivatives 0" in on_wine and "exit 0" in on_wine
    windows_steps = _steps(on_wine)
    assert len(windows_steps) == len(on_linux) == STEPS
    worst = max(
        abs(a - b) / max(abs(a), abs(b), 1e-300)
        for row, other in zip(windows_steps, on_linux, strict=True)
        for a, b in zip(row, other, strict=True)
    )
    print(f"worst relative difference from Linux: {worst:.2g}")  # shown with pytest -s
    assert worst <= 1e-12


@pytest.mark.parametrize("how", ["venv folder", "python on PATH"])
def test_a_venv_folder_or_python_on_path_is_used(how, machine, windows_python, on_wine):
    venv = machine["root"] / "venv"
    if how == "venv folder":
        environment, used = {"AUV_FMU_PYTHON": windows(venv)}, venv / "Scripts"
    else:
        environment, used = {"WINEPATH": windows(windows_python)}, windows_python
    stdout, loaded = _on_wine(machine, **environment)
    assert _python_dlls(loaded) == {windows(used / "python313.dll")}
    assert _steps(stdout) == _steps(on_wine)
    if how == "python on PATH":  # the build's Python is not on this machine: passed over
        assert "passed over the build's Python /nonexistent/build-environment" in stdout


def test_the_fallback_loads_pythonfmus_dll_with_the_same_cpython(machine, windows_python, on_wine):
    """``AUV_FMU_RUNTIME=pythonfmu``: pythonfmu's DLL steps; the runtime hands the input
    derivatives to the slave itself (pythonfmu's DLL would refuse them)."""
    stdout, loaded = _on_wine(
        machine,
        AUV_FMU_PYTHON=windows(windows_python / "python.exe"),
        AUV_FMU_RUNTIME="pythonfmu",
    )
    assert windows(machine["plant"] / "binaries" / "win64" / "AuvPlant_pythonfmu.dll") in loaded
    assert "derivatives 0" in stdout and "exit 0" in stdout
    assert _steps(stdout) == _steps(on_wine)


def test_pythonfmus_dll_alone_refuses_input_derivatives(machine, windows_python, on_wine):
    """pythonfmu's DLL as a host's binary (the win64 binary of a build whose C sources are
    not the prebuilt DLL's): it embeds the CPython whose python3.dll is on PATH, refuses
    fmi2SetRealInputDerivatives (fmi2Error: 3) and steps as the runtime does."""
    stdout, loaded = _on_wine(
        machine, dll="AuvPlant_pythonfmu.dll", WINEPATH=windows(windows_python)
    )
    assert _python_dlls(loaded) == {windows(windows_python / "python313.dll")}
    assert "derivatives 3" in stdout and "exit 0" in stdout
    assert _steps(stdout) == _steps(on_wine)


FMPY_RUN = """
import sys
sys.modules["_wmi"] = None  # platform's WMI queries need propsys.VariantToString: not in Wine 8
sys.path.insert(0, sys.argv[1])
import fmpy
result = fmpy.simulate_fmu(sys.argv[2], stop_time=2.0, output_interval=0.1, output=[
    "north", "down", "pitch", "kinetic_energy"], start_values={"thrust": 9.0,
    "tunnel_force": 1.5, "fin_angle": 0.05, "mass_position_cmd": 0.01})
for row in result:
    print(*["%.17g" % value for value in row])
"""


def test_fmpy_in_the_windows_cpython_simulates_the_fmu(
    machine, windows_python, windows_fmpy, fmu_paths, on_wine
):
    """fmpy as the Windows FMI host: it extracts the FMU, loads its win64 binary with
    ctypes, and the runtime uses the CPython of the process (no second one: python313.dll
    is loaded once, by python.exe). Its rows at t = 0.1 ... 2 s equal the stepper's."""
    fmu = machine["root"] / "AuvPlant.fmu"
    shutil.copyfile(fmu_paths["AuvPlant"], fmu)
    script = machine["root"] / "run_fmpy.py"
    script.write_text(FMPY_RUN)
    stdout, loaded = _wine_run(
        machine,
        [windows_python / "python.exe", windows(script), windows(windows_fmpy), windows(fmu)],
    )
    assert [path for path in loaded if path.lower().endswith("python313.dll")] == [
        windows(windows_python / "python313.dll")
    ]
    assert any(path.endswith("\\binaries\\win64\\AuvPlant.dll") for path in loaded)
    rows = _steps(stdout)[1:]  # after t = 0
    columns = [0, 2, 4, 21]  # north, down, pitch, kinetic_energy in OUTS
    expected = [[row[0], *(row[1 + k] for k in columns)] for row in _steps(on_wine)]
    assert len(rows) == len(expected) == STEPS
    for row, other in zip(rows, expected, strict=True):
        assert row == pytest.approx(other, rel=1e-12, abs=1e-15)
