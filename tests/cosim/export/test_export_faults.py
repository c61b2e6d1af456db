"""Events and faults in the exports: whole-run gain and bias faults become linear
transformations of their connection (SSP ``ssc:LinearTransformation``, an OSP
``LinearTransformation`` function) that libcosim runs like our master; anything else is
refused in one message listing it all, before anything is written."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from lxml import etree
from repo_paths import TESTS

from cosim.errors import CosimError
from cosim.export import export_osp, export_ssp
from cosim.scenario.spec import SCENARIO_FOLDER, Scenario, load_scenario

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "o": "http://opensimulationplatform.com/MSMI/OSPSystemStructure",
}
STOP_TIME = 10.0  # s
VARIABLES = ["plant.yaw", "plant.mass_position", "controller.tunnel_force"]
LINEAR = """
[[faults]]
name = "weak-thruster"
kind = "gain"
target = "plant.tunnel_force"
value = 0.5
[[faults]]
name = "offset"
kind = "bias"
target = "plant.tunnel_force"
value = 0.25
"""


def bs3_file(folder: Path, extra: str) -> Path:
    text = (SCENARIO_FOLDER / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace("stop_time = 60.0", f"stop_time = {STOP_TIME}")
    path = folder / "bs-3-faulty.toml"
    path.write_text(text + extra, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def faulty(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Scenario, Path]:
    path = bs3_file(tmp_path_factory.mktemp("faulty"), LINEAR)
    return load_scenario(path, fmu_dir), path


def test_whole_run_linear_faults_are_the_connections_transformation(
    faulty: tuple[Scenario, Path], tmp_path: Path
) -> None:
    scenario, _ = faulty
    with zipfile.ZipFile(export_ssp(scenario, tmp_path / "f.ssp")) as archive:
        root = etree.fromstring(archive.read("SystemStructure.ssd"))
    (transformation,) = root.iterfind(".//ssd:Connection/ssc:LinearTransformation", NS)
    connection = transformation.getparent()
    assert (connection.get("endElement"), connection.get("endConnector")) == (
        "plant",
        "tunnel_force",
    )
    # gain 0.5 then bias 0.25: 0.5 x + 0.25
    assert (float(transformation.get("factor")), float(transformation.get("offset"))) == (0.5, 0.25)
    osp = etree.parse(str(export_osp(scenario, tmp_path / "f-osp"))).getroot()
    (function,) = osp.iterfind("o:Functions/o:LinearTransformation", NS)
    assert (float(function.get("factor")), float(function.get("offset"))) == (0.5, 0.25)
    ends = {
        (s.find("o:Variable", NS).get("name"), s.find("o:Signal", NS).get("name"))
        for s in osp.iterfind("o:Connections/o:SignalConnection", NS)
    }
    assert ends == {("tunnel_force", "in"), ("tunnel_force", "out")}
    plain = [
        v.get("name") for v in osp.iterfind("o:Connections/o:VariableConnection/o:Variable", NS)
    ]
    assert "tunnel_force" not in plain


def _master_trace(source: Path, fmu_dir: Path, out: Path) -> np.ndarray:
    command = [sys.executable, "-m", "cosim.cli", "run", str(source), "--algorithm", "jacobi",
               "--extrapolation", "none",
               "--no-rrd", "--quiet", "--out", str(out), "--fmu-dir", str(fmu_dir)]  # fmt: skip
    done = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stderr
    return _read(out / "results.csv")


def _read(path: Path) -> np.ndarray:
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return np.array([[float(row[v]) for v in ["time", *VARIABLES]] for row in rows])


def _libcosim_trace(source: Path, folder: Path) -> np.ndarray:
    """Run in tests/interop_runner.py (its own process; see tests/cosim/export/test_interop.py)."""
    job = {"tool": "libcosim", "source": str(source), "step": 0.01,
           "n_steps": round(STOP_TIME / 0.01), "out": str(folder / "trace.csv"),
           "variables": VARIABLES}  # fmt: skip
    spec = folder / "job.json"
    spec.write_text(json.dumps(job))
    command = [sys.executable, "-P", str(TESTS / "interop_runner.py"), str(spec)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    if done.returncode == 77:
        pytest.skip(done.stderr.strip())
    if done.returncode != 0 and "No module named 'libcosimpy'" in done.stderr:
        pytest.skip("libcosimpy is not installed")
    assert done.returncode == 0, done.stderr
    return _read(folder / "trace.csv")


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["ssp", "osp"])
def test_libcosim_runs_the_exported_gain_fault_like_our_master(
    faulty: tuple[Scenario, Path], fmu_dir: Path, tmp_path: Path, fmt: str
) -> None:
    scenario, path = faulty
    ours = _master_trace(path, fmu_dir, tmp_path / "ours")
    healthy = _master_trace(bs3_file(tmp_path, ""), fmu_dir, tmp_path / "healthy")
    if fmt == "ssp":
        source = export_ssp(scenario, tmp_path / "f.ssp")
    else:
        source = export_osp(scenario, tmp_path / "f-osp").parent
    theirs = _libcosim_trace(source, tmp_path)
    np.testing.assert_allclose(theirs[:, 0], ours[1:, 0], rtol=0, atol=1e-9)
    assert np.max(np.abs(theirs[:, 1:] - ours[1:, 1:])) <= 1e-9
    assert np.max(np.abs(ours[:, 1] - healthy[:, 1])) > 1e-3  # the fault matters


def test_events_and_other_faults_are_refused_in_one_message_listing_them(
    fmu_dir: Path, tmp_path: Path
) -> None:
    extra = """
[[events]]
name = "turn"
time = 5.0
set = { "controller.yaw_setpoint" = 0.5 }
[[faults]]
name = "jam"
kind = "stuck"
target = "plant.mass_position_cmd"
[[faults]]
name = "late-gain"
kind = "gain"
target = "plant.tunnel_force"
value = 2.0
start = 1.0
"""
    scenario = load_scenario(bs3_file(tmp_path, LINEAR + extra), fmu_dir)
    for export, target in ((export_ssp, tmp_path / "x.ssp"), (export_osp, tmp_path / "x-osp")):
        with pytest.raises(CosimError) as info:
            export(scenario, target)
        message = str(info.value)
        assert "\n" not in message
        for part in (
            "event 'turn'",
            "fault 'jam' (stuck on plant.mass_position_cmd)",
            "fault 'late-gain' (gain on plant.tunnel_force, not over the whole run)",
        ):
            assert part in message, message
        assert "weak-thruster" not in message  # that one can be exported
        assert not target.exists()


@pytest.mark.parametrize("stop", [STOP_TIME, 1e6])
def test_a_linear_fault_stopping_at_or_after_the_stop_time_acts_over_the_whole_run(
    fmu_dir: Path, tmp_path: Path, stop: float
) -> None:
    """A gain with ``stop`` at the stop time or beyond acts on every step of the run, as
    one without a stop does: it is the connection's transformation (it was refused as
    'not over the whole run')."""
    timed = LINEAR.replace("value = 0.5\n", f"value = 0.5\nstop = {stop!r}\n")
    scenario = load_scenario(bs3_file(tmp_path, timed), fmu_dir)
    osp = etree.parse(str(export_osp(scenario, tmp_path / "f-osp"))).getroot()
    (function,) = osp.iterfind("o:Functions/o:LinearTransformation", NS)
    assert (float(function.get("factor")), float(function.get("offset"))) == (0.5, 0.25)
