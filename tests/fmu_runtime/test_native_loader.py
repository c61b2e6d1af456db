"""Our FMUs in non-Python hosts through the native loader (fmu_runtime/native/), each run in a
clean environment (``env -i`` with PATH and HOME only: no preload, no PYTHONPATH):

* a minimal FMI 2.0 host in C (``hosts/fmi_host.c``, compiled here) instantiates,
  initialises, steps and frees every FMU, many times, and gets fmi2Error for each call the
  standard forbids (the loader's own checks, made without calling Python);
* without a usable Python, fmi2Instantiate returns NULL and one log line says what was
  looked for and what to set; the override variable names another environment;
* valgrind memcheck finds no invalid access and no definitely lost block in the loader;
* the ecos command-line program runs the exported bs-3 SSP and matches
  ``auv-cosim run bs-3 --algorithm jacobi`` to the 6 decimals of its CSV;
* a build on a machine without a C compiler still gives working FMUs, and says so.

Every process runs in its own process group, ended by the test even on failure.
"""

from __future__ import annotations

import contextlib
import csv
import os
import re
import shutil
import signal
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from repo_paths import ROOT

from cosim.fmus.build import FMUS
from cosim.fmus.native import NO_COMPILER, OVERRIDE_VARIABLE, RUNTIME_FILE

HOST_SOURCE = Path(__file__).parent / "hosts" / "fmi_host.c"
ILLEGAL = {  # case printed by the host -> what the standard forbids
    "second-enterInitializationMode": "initialisation mode entered twice",
    "doStep-before-initialisation": "a step before exitInitializationMode",
    "doStep-at-wrong-point": "currentCommunicationPoint is not the end of the last step",
    "setReal-fixed-parameter-after-initialisation": "a fixed parameter after initialisation",
}


def run_clean(command: list, home: Path, timeout: float = 900, **extra: str):
    """``command`` in a clean environment (PATH, HOME and ``extra`` only), in its own
    process group, which is ended whatever happens."""
    env = {"PATH": "/usr/bin:/bin", "HOME": str(home), **extra}
    process = subprocess.Popen(
        [str(part) for part in command],
        env=env,
        cwd=home,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )
    try:
        out, err = process.communicate(timeout=timeout)
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    return subprocess.CompletedProcess(process.args, process.returncode, out, err)


@pytest.fixture(scope="module")
def host(tmp_path_factory) -> Path:
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) to build the test host")
    binary = tmp_path_factory.mktemp("host") / "fmi_host"
    subprocess.run([cc, "-O1", "-g", "-o", binary, HOST_SOURCE, "-ldl"], check=True)
    return binary


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


def test_each_fmu_page_says_its_binary_is_the_loader_and_how_to_point_it_at_python(fmu_paths):
    for name in FMUS:
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            page = archive.read("documentation/index.html").decode()
            names = archive.namelist()
        assert f"binaries/linux64/{name}_pythonfmu.so" in names
        assert "native loader" in page and OVERRIDE_VARIABLE in page


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_a_c_host_in_a_clean_environment_runs_100_cycles_of_1000_steps(
    name, host, extracted, tmp_path
):
    done = run_clean([host, extracted[name], name, "cycles", 100, 1000], tmp_path)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    assert "cycles: 100 x 1000 ok" in done.stdout


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(FMUS))
def test_calls_the_standard_forbids_return_fmi2error(name, host, extracted, tmp_path):
    """Each forbidden call on a fresh instance returns fmi2Error (3) with one Error logged,
    and the valid call after the refusals still works (0)."""
    done = run_clean([host, extracted[name], name, "illegal"], tmp_path)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    statuses = dict(re.findall(r"^([\w-]+) (\d)$", done.stdout, re.M))
    errors = re.findall(r"^log host \[3\] (.+)$", done.stdout, re.M)
    ranges = [case for case in statuses if case.endswith("-outside-range")]
    assert set(ILLEGAL) <= set(statuses) and ranges, done.stdout
    assert {case: statuses[case] for case in [*ILLEGAL, *ranges]} == dict.fromkeys(
        [*ILLEGAL, *ranges], "3"
    )
    assert statuses["valid-step-after-refusals"] == "0"
    assert statuses["valid-initialisation-after-refusals"] == "0"
    assert len(errors) == len(ILLEGAL) + len(ranges), errors
    assert any("refused: expected" in e for e in errors), errors


def test_without_a_usable_python_instantiate_returns_null_and_says_what_to_set(
    host, extracted, tmp_path
):
    missing = tmp_path / "no-such-venv"
    done = run_clean(
        [host, extracted["AuvPlant"], "AuvPlant", "cycles", 1, 1],
        tmp_path,
        **{OVERRIDE_VARIABLE: str(missing)},
    )
    assert "instantiate returned NULL" in done.stdout
    lines = [line for line in done.stdout.splitlines() if line.startswith("log ")]
    assert len(lines) == 1, done.stdout
    assert f"{OVERRIDE_VARIABLE}={missing}" in lines[0]
    assert "cannot start Python" in lines[0]


@pytest.mark.slow
def test_the_override_names_the_environment_when_the_record_is_gone(host, extracted, tmp_path):
    """An extraction without the build's record of its Python: refused with the file and
    the variable named; with the variable set to a Python executable, it runs."""
    moved = tmp_path / "moved"
    shutil.copytree(extracted["AuvPlant"], moved)
    (moved / "resources" / RUNTIME_FILE).unlink()
    command = [host, moved, "AuvPlant", "cycles", 1, 10]
    refused = run_clean(command, tmp_path)
    assert "instantiate returned NULL" in refused.stdout
    assert RUNTIME_FILE in refused.stdout and OVERRIDE_VARIABLE in refused.stdout
    done = run_clean(command, tmp_path, **{OVERRIDE_VARIABLE: sys.executable})
    assert "cycles: 1 x 10 ok" in done.stdout, done.stdout + done.stderr


def _loader_records(log: str, name: str) -> list[str]:
    """valgrind error records (invalid accesses, definitely lost blocks) made by the
    loader (``<name>.so``, not ``<name>_pythonfmu.so``): the innermost frame in a library
    without debug information, other than valgrind's allocator, is the loader's. (CPython
    and glibc carry debug information here, so their frames name a source file; the
    loader, pythonfmu's library and the extension modules show ``(in <library>)``.) The
    dynamic linker's over-reads in ``strncmp`` while a library loads (glibc's optimised
    string functions, a known valgrind false positive) come from deeper callers."""
    mine = []
    for record in re.split(r"==\d+== \n", log):
        if not re.search(r"Invalid (read|write|free)|definitely lost", record):
            continue
        frames = re.findall(r"(?:at|by) 0x[0-9A-F]+: .*\(in (\S+)\)", record)
        first = next((lib for lib in frames if "vgpreload" not in lib), "")
        if first.endswith(f"/{name}.so"):
            mine.append(record)
    return mine


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind is not installed")
def test_valgrind_finds_nothing_in_the_loader(host, extracted, tmp_path):
    """Two instantiate/step/free cycles and the process exit of a C host under memcheck.
    CPython and pythonfmu's own reports (their allocations at start-up) are not ours."""
    log = tmp_path / "memcheck.log"
    command = ["valgrind", "--leak-check=full", f"--log-file={log}", host]
    done = run_clean(
        [*command, extracted["AuvPlant"], "AuvPlant", "cycles", 2, 20],
        tmp_path,
        timeout=1800,
        PYTHONMALLOC="malloc",
        # the plant's numpy path: numba and LLVM under memcheck took ~4 of the 5 minutes,
        # and the loader's code is the same whichever path the plant steps with
        AUV_COSIM_NO_JIT="1",
    )
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    text = log.read_text()
    assert "ERROR SUMMARY" in text
    assert _loader_records(text, "AuvPlant") == []


def _ecos() -> tuple[Path, dict[str, str]]:
    """The ecos program of the ecospy package and the one variable it needs beyond PATH
    and HOME: where its TBB library is (ecos's own dependency, not Python's)."""
    from importlib.util import find_spec

    spec = find_spec("ecospy")
    if spec is None or spec.origin is None:
        pytest.skip("ecospy is not installed")
    program = Path(spec.origin).parent / "binaries" / "ecos"
    from cosim.export.ecos_support import tbb_library

    tbb = tbb_library()
    return program, ({"LD_LIBRARY_PATH": str(Path(tbb).parent)} if tbb else {})


ECOS_CSV_PRECISION = 5e-7  # ecos writes 6 decimals: half a unit in the last one


@pytest.mark.slow
def test_the_ecos_command_line_runs_the_ssp_in_a_clean_environment(fmu_paths, tmp_path):
    from cosim.export import export_ssp
    from cosim.scenario.spec import load_scenario

    fmu_dir = fmu_paths["AuvPlant"].parent
    program, tbb = _ecos()
    ecos = tmp_path / "ecos"
    shutil.copyfile(program, ecos)
    ecos.chmod(0o755)  # pip installs it without the executable bit
    scenario = load_scenario("bs-3", fmu_dir).with_overrides(stop_time=10.0)
    export_ssp(scenario, tmp_path / "bs-3.ssp")
    done = run_clean(
        [ecos, "simulate", "--path", "bs-3.ssp", "--stepSize", "0.01", "--stopTime", "10",
         "--parameterSet", "initial", "--logLevel", "warn"],
        tmp_path,
        **tbb,
    )  # fmt: skip
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    out = tmp_path / "master"
    master = subprocess.run(
        [sys.executable, "-m", "cosim.cli", "run", "bs-3", "--algorithm", "jacobi",
         "--stop-time", "10", "--step", "0.01", "--no-rrd", "--quiet", "--out", out,
         "--fmu-dir", fmu_dir],
        capture_output=True, text=True, timeout=900, check=False, cwd=ROOT,
    )  # fmt: skip
    assert master.returncode == 0, master.stderr[-3000:]
    with open(tmp_path / "bs-3.csv", newline="") as f:
        theirs = list(csv.DictReader(f, skipinitialspace=True))
    with open(out / "results.csv", newline="") as f:
        ours = list(csv.DictReader(f))
    assert len(theirs) == len(ours) == 1001
    compared = 0
    for mine, their in zip(ours, theirs, strict=True):
        assert abs(float(mine["time"]) - float(their["time"])) < 1e-9
        for column, value in their.items():
            instance, _, rest = column.partition("::")
            variable = f"{instance}.{rest.removesuffix('[REAL]')}"
            if rest.endswith("[REAL]") and variable in mine:
                expected = float(mine[variable])
                assert abs(float(value) - expected) <= ECOS_CSV_PRECISION * 1.0001, (
                    f"{variable} at t = {mine['time']}: ecos {value}, master {expected}"
                )
                compared += 1
    assert compared > 1000 * 10


NO_COMPILER_BUILD = """
import sys
sys.modules["ziglang"] = None  # as if the ziglang package were not installed
from pathlib import Path
from cosim.fmus.build import build_fmu
print(build_fmu("AuvPlant", Path(sys.argv[1]), force=True))
"""

RUN_PLANT = """
import sys
from fmu_harness import Harness
fmu = Harness(sys.argv[1], u_0=1.5)
print("steps", [fmu.step(0.01) for _ in range(10)])
fmu.close()
"""


@pytest.mark.slow
def test_a_build_without_a_compiler_keeps_pythonfmus_binary_and_says_so(run_python, tmp_path):
    bin_dir = tmp_path / "bin"  # PATH without cc or gcc: only this Python
    bin_dir.mkdir()
    (bin_dir / "python").symlink_to(sys.executable)
    env_path = str(bin_dir)
    code = f"import os; os.environ['PATH'] = {env_path!r}\n" + NO_COMPILER_BUILD
    built = run_python(code, tmp_path / "fmus")
    assert built.returncode == 0, built.stderr[-3000:]
    said = [line for line in built.stderr.splitlines() if "no C compiler" in line]
    assert said == [f"auv-cosim build: {NO_COMPILER}"]
    fmu = Path(built.stdout.strip().splitlines()[-1])
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
        page = archive.read("documentation/index.html").decode()
    assert "binaries/linux64/AuvPlant.so" in names
    assert not any(name.endswith("_pythonfmu.so") for name in names)
    assert "built without a C compiler" in page
    ran = run_python(RUN_PLANT, fmu)
    assert ran.returncode == 0, ran.stderr[-3000:]
    assert "steps [0, 0, 0, 0, 0, 0, 0, 0, 0, 0]" in ran.stdout
