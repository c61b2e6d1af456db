"""Our exported systems in third-party FMI masters: OSP's libcosim, ecos and fmpy's
container FMU (the OSP system packed into one FMU, run by ``fmpy.simulate_fmu``).

Each system is exported with ``cosim.export`` and run in libcosim (``libcosimpy``: the SSP
archive and the OSP system structure) and in ecos (``ecospy``: the SSP archive), once per
session, each run in its own subprocess (``tests/interop_runner.py``: a crashing master
must not take pytest down, and a pythonfmu FMU cannot be loaded twice in one process).
The traces are compared step by step with
``auv-cosim run SYSTEM --algorithm jacobi --extrapolation none`` at the same step:

* ``bs-3`` (backstepping autopilot + plant, docs/model.md#scenarios), 10 s at 10 ms;
* the plant alone with prescribed (constant) inputs, 10 s at 10 ms;
* ``survey`` (three FMUs: waypoint guidance + autopilot + 6-DOF plant), 10 s at 10 ms.

libcosim and ecos both step every instance from the outputs of the previous communication
point (Jacobi), initialise the same way (start values, then the outputs after
initialisation feed the first step) and integrate nothing themselves, so the traces agree
to :data:`TOLERANCE`. They are not bit-identical: the step size each master hands to
``fmi2DoStep`` differs in the last bit (our master steps ``(n+1) h - n h``, libcosim exactly
``h`` from integer nanoseconds, ecos ``t_{n+1} - t_n`` of an accumulated float time).
fmpy's container makes the very calls our master makes, so its traces are bit-identical.
"""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from repo_paths import TESTS

from cosim.export import export_osp, export_ssp
from cosim.scenario.spec import load_scenario

TOLERANCE = 1e-9  # absolute, in each variable's SI unit
STOP_TIME = 10.0  # s
RUNNER = TESTS / "interop_runner.py"

PLANT_ALONE = """\
id = "plant-alone"
summary = "AuvPlant alone, lateral variant, constant prescribed inputs"
stop_time = {stop_time}
[coupling]
step = 0.01
algorithm = "jacobi"
[instances.plant]
fmu = "{fmu}"
[instances.plant.start]
variant = 1
u_0 = 1.5
v_0 = -0.1
r_0 = 0.05
thrust = 9.0
roll_torque = 0.2
tunnel_force = 0.5
mass_position_cmd = 0.02
current_east = 0.1
"""

PLANT_VARIABLES = ["plant.yaw", "plant.roll", "plant.v", "plant.r", "plant.north",
                   "plant.east", "plant.mass_position"]  # fmt: skip
LOOP_VARIABLES = [*PLANT_VARIABLES, "controller.tunnel_force", "controller.mass_position_cmd"]
MISSION_VARIABLES = [*LOOP_VARIABLES, "plant.down", "guidance.yaw_setpoint",
                     "guidance.cross_track_error"]  # fmt: skip


@pytest.fixture(scope="module")
def systems(fmu_paths: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> dict:
    """{name: (scenario, variables, source file for `auv-cosim run`)}, 10 s each."""
    folder = tmp_path_factory.mktemp("systems")
    fmu_dir = fmu_paths["AuvPlant"].parent
    plant_file = folder / "plant-alone.toml"
    plant_file.write_text(PLANT_ALONE.format(stop_time=STOP_TIME, fmu=fmu_paths["AuvPlant"]))
    # a vehicle set of its own beside the scenario: the exports carry it (a packed file
    # named by a relative path was looked for in the host's working directory)
    heavy_file = folder / "plant-heavy.toml"
    (folder / "heavy.toml").write_text('base = "remus100"\nname = "heavy"\nm = 31.0\nz_g = 0.03\n')
    heavy_file.write_text(
        PLANT_ALONE.format(stop_time=STOP_TIME, fmu=fmu_paths["AuvPlant"])
        + 'vehicle = "heavy.toml"\n'
    )
    bs3 = load_scenario("bs-3", fmu_dir).with_overrides(stop_time=STOP_TIME)
    survey = load_scenario("survey", fmu_dir).with_overrides(stop_time=STOP_TIME)
    return {
        "plant-alone": (load_scenario(plant_file, fmu_dir), PLANT_VARIABLES, plant_file),
        "plant-heavy": (load_scenario(heavy_file, fmu_dir), PLANT_VARIABLES, heavy_file),
        "bs-3": (bs3, LOOP_VARIABLES, "bs-3"),
        "survey": (survey, MISSION_VARIABLES, "survey"),
    }


@pytest.fixture(scope="module")
def exported(systems: dict, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """{name: {"ssp": archive, "osp": folder}} for every system."""
    folder = tmp_path_factory.mktemp("exported")
    return {
        name: {
            "ssp": export_ssp(scenario, folder / f"{name}.ssp"),
            "osp": export_osp(scenario, folder / f"{name}-osp").parent,
        }
        for name, (scenario, _, _) in systems.items()
    }


@pytest.fixture(scope="module")
def master_traces(systems: dict, fmu_paths: dict, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """{name: (times, {variable: values})} from
    `auv-cosim run NAME --algorithm jacobi --extrapolation none`."""
    folder = tmp_path_factory.mktemp("master")
    traces = {}
    for name, (scenario, variables, source) in systems.items():
        out = folder / name
        command = [sys.executable, "-m", "cosim.cli", "run", str(source), "--algorithm",
                   "jacobi", "--extrapolation", "none", "--stop-time", str(STOP_TIME), "--step",
                   repr(scenario.coupling.step), "--no-rrd", "--quiet", "--out", str(out),
                   "--fmu-dir", str(fmu_paths["AuvPlant"].parent)]  # fmt: skip
        done = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
        assert done.returncode == 0, f"auv-cosim run {name} failed:\n{done.stderr}"
        traces[name] = _read_csv(out / "results.csv", variables)
    return traces


# what each tool runs: libcosim both exports, ecos the SSP archive, fmpy's container the
# OSP system packed into one FMU, stepping its FMUs one after another or in threads
FORMATS = {"libcosim": ("ssp", "osp"), "ecos": ("ssp",), "fmpy-container": ("osp", "osp-parallel")}
# fmpy 0.3.25's container writes a String start value into its modelDescription.xml
# unescaped, so an inline vehicle set (TOML text with quotes) makes the XML unreadable
# (docs/hosts.md, fmpy)
NOT_IN_CONTAINER = {"plant-heavy"}
# the container's threads wait for work spinning on a mutex (parallelDoStep): 10 s of
# bs-3 took many times the serial run's time here, so they run the first second only
PARALLEL_STEPS = 100


def _third_party(tool: str, systems: dict, exported: dict, folder: Path) -> dict:
    """Run every exported system in ``tool``, each in its own subprocess (see
    ``interop_runner.py`` for why); {(name, format): trace}."""
    traces = {}
    for name, (scenario, variables, _) in systems.items():
        if tool == "fmpy-container" and name in NOT_IN_CONTAINER:
            continue
        for fmt in FORMATS[tool]:
            job = {"tool": tool, "source": str(exported[name][fmt.removesuffix("-parallel")]),
                   "step": scenario.coupling.step,
                   "n_steps": PARALLEL_STEPS if fmt.endswith("-parallel") else scenario.n_steps,
                   "out": str(folder / f"{name}.{fmt}.csv"), "variables": variables,
                   "parallel": fmt.endswith("-parallel")}  # fmt: skip
            spec = folder / f"{name}.{fmt}.json"
            spec.write_text(json.dumps(job))
            # -P: not tests/ on sys.path, whose folders named like our packages shadow them
            command = [sys.executable, "-P", str(RUNNER), str(spec)]
            # TMPDIR: the test's folder, where ecos unpacks each SSP (ecos_ssp_<uuid>) and
            # leaves it: in /tmp, one stayed behind per run of these tests
            env = {**os.environ, "TMPDIR": str(folder)}
            done = subprocess.run(command, capture_output=True, text=True, timeout=600,
                                  check=False, env=env)  # fmt: skip
            if done.returncode == 77:
                pytest.skip(done.stderr.strip())
            assert done.returncode == 0, (
                f"{name} ({fmt}) in {tool} failed (exit {done.returncode}):\n{done.stderr}"
            )
            traces[name, fmt] = _read_csv(Path(job["out"]), variables)
    return traces


@pytest.fixture(scope="module")
def libcosim_traces(systems: dict, exported: dict, tmp_path_factory) -> dict:
    return _third_party("libcosim", systems, exported, tmp_path_factory.mktemp("libcosim"))


@pytest.fixture(scope="module")
def container_traces(systems: dict, exported: dict, tmp_path_factory) -> dict:
    return _third_party("fmpy-container", systems, exported, tmp_path_factory.mktemp("container"))


@pytest.fixture(scope="module")
def ecos_folder(tmp_path_factory) -> Path:
    return tmp_path_factory.mktemp("ecos")


@pytest.fixture(scope="module")
def ecos_traces(systems: dict, exported: dict, ecos_folder: Path) -> dict:
    return _third_party("ecos", systems, exported, ecos_folder)


def test_ecos_unpacks_its_ssps_in_the_tests_folder(ecos_traces: dict, ecos_folder: Path) -> None:
    """Tests leave nothing behind: ecos unpacks each SSP into TMPDIR and leaves it there;
    its runs get the test's folder as TMPDIR, so none stays in /tmp."""
    assert ecos_traces
    assert list(ecos_folder.glob("ecos_ssp_*"))


def _read_csv(path: Path, variables: list[str]) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    times = np.array([float(row["time"]) for row in rows])
    return times, {v: np.array([float(row[v]) for row in rows]) for v in variables}


def _assert_same_trace(name: str, tool: str, theirs: tuple, master: tuple) -> None:
    """``theirs`` holds t = h ... N h; the master's results also start with t = 0."""
    their_times, their_values = theirs
    times, values = master
    assert len(their_times) == len(times) - 1, f"{tool} ran {len(their_times)} steps"
    np.testing.assert_allclose(their_times, times[1:], rtol=0, atol=1e-9)
    # a trace that hardly moves would make the comparison meaningless
    assert np.ptp(values["plant.yaw"]) > 0.05, f"{name}: yaw barely changes"
    for variable, theirs_v in their_values.items():
        deviation = np.max(np.abs(theirs_v - values[variable][1:]))
        assert deviation <= TOLERANCE, (
            f"{name} in {tool}: {variable} deviates from "
            f"`auv-cosim run --algorithm jacobi --extrapolation none` "
            f"by up to {deviation:.3g} (tolerance {TOLERANCE:g})"
        )


SYSTEMS = ["plant-alone", "plant-heavy", "bs-3", "survey"]


@pytest.mark.slow
@pytest.mark.parametrize("name", SYSTEMS)
@pytest.mark.parametrize("fmt", ["ssp", "osp"])
def test_libcosim_matches_master(
    name: str, fmt: str, libcosim_traces: dict, master_traces: dict
) -> None:
    _assert_same_trace(name, f"libcosim ({fmt})", libcosim_traces[name, fmt], master_traces[name])


@pytest.mark.slow
@pytest.mark.parametrize("name", SYSTEMS)
def test_ecos_matches_master(name: str, ecos_traces: dict, master_traces: dict) -> None:
    _assert_same_trace(name, "ecos (ssp)", ecos_traces[name, "ssp"], master_traces[name])


@pytest.mark.slow
@pytest.mark.parametrize("name", [name for name in SYSTEMS if name not in NOT_IN_CONTAINER])
@pytest.mark.parametrize("threads", [False, True], ids=["serial", "parallelDoStep"])
def test_fmpy_container_matches_master_bit_for_bit(
    name: str, threads: bool, container_traces: dict, master_traces: dict
) -> None:
    """fmpy's container FMU passes every connection from the outputs of the communication
    point, holds them across the step (Jacobi, no input derivatives), and its host
    (``simulate_fmu``) steps ``(n+1) h - n h`` as our master does: the very same calls, so
    the very same numbers, whether it steps its FMUs in turn or each in a thread of its own
    (``parallelDoStep``: our FMUs stepped from threads that did not instantiate them)."""
    times, values = container_traces[name, "osp-parallel" if threads else "osp"]
    master_times, master_values = master_traces[name]
    assert np.ptp(master_values["plant.yaw"]) > 0.05, f"{name}: yaw barely changes"
    steps = PARALLEL_STEPS if threads else len(master_times) - 1
    np.testing.assert_allclose(times, master_times[1 : steps + 1], rtol=0, atol=1e-9)
    for variable, theirs in values.items():
        expected = master_values[variable][1 : steps + 1]
        np.testing.assert_array_equal(theirs, expected, err_msg=variable)
