"""The master's coupling semantics, failures and Ctrl-C, on two tiny test FMUs.

tests/fmus holds a pythonfmu integrator (x' = u, exact over a step) and a sampled gain
(u = -k x at the start of each step). Their closed loop has recurrences derived by hand
below, so the Jacobi, Gauss-Seidel and multi-rate orderings are checked exactly,
independently of the AUV. The AUV FMUs through the master:
tests/cosim/test_builtin_scenarios.py.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scenario_factory import X0, H, K, loop_toml

from cosim.engine import master
from cosim.engine.rows import NotesIgnored
from cosim.runner import run_scenario
from cosim.scenario.spec import Scenario, scenario_from_toml


@pytest.fixture(scope="module")
def fmu_dir(test_fmu_dir: Path) -> Path:
    return test_fmu_dir


def loop(fmu_dir: Path, **kwargs) -> Scenario:
    return scenario_from_toml(loop_toml(**kwargs), base_dir=fmu_dir)


@pytest.mark.slow
def test_gauss_seidel_is_the_sampled_loop_without_delay(fmu_dir: Path) -> None:
    # controller first: u_n = -k x_n, then x_{n+1} = x_n + h u_n = (1 - k h) x_n
    result = master.run(loop(fmu_dir))
    n = np.arange(11)
    assert result.complete and result.error is None
    np.testing.assert_allclose(result.times, n * H, rtol=0, atol=1e-15)
    np.testing.assert_allclose(result.column("plant.x"), X0 * (1 - K * H) ** n, rtol=1e-14)
    # row n holds the command computed at t_{n-1} (the latest output after stepping to t_n)
    np.testing.assert_allclose(result.column("controller.u")[1:], -K * X0 * (1 - K * H) ** n[:-1])


@pytest.mark.parametrize(
    ("stop_time", "step", "algorithm"),
    [
        (0.7, 0.1, "gauss-seidel"),  # 7 x 0.1 s is 0.7000000000000001 s: past it
        (0.9, 0.3, "jacobi"),  # 3 x 0.3 s is 0.8999999999999999 s: short of it
        (0.7, 0.1, "adaptive"),  # the adaptive steps' points, the same products
        (0.9, 0.3, "adaptive"),
    ],
)
def test_the_last_row_is_at_the_stop_time(
    fmu_dir: Path, tmp_path: Path, stop_time: float, step: float, algorithm: str
) -> None:
    """The last row's time is the stop time itself, not N h a rounding away from it on
    either side (a `time <= stop_time` filter once lost the row past it; a row short of
    it printed 0.8999999999999999 for a stop time of 0.9 s), whatever the algorithm."""
    scenario = loop(fmu_dir, stop_time=stop_time, step=step, algorithm=algorithm)
    outcome = run_scenario(scenario, tmp_path / "run", no_rrd=True)
    assert outcome.result.complete
    last = (tmp_path / "run" / "results.csv").read_text().splitlines()[-1]
    assert last.split(",")[0] == repr(stop_time)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["time_reached"] == summary["stop_time"] == stop_time


def test_master_guards_any_pythonfmu_fmu_against_the_exit_crash(fmu_dir: Path) -> None:
    """The test FMUs are plain pythonfmu slaves (no guard of their own): the master
    installs fmu_runtime.exit_guard for every FMU it instantiates."""
    from fmu_runtime import exit_guard

    assert master.run(loop(fmu_dir)).complete
    guarded = {path.name for path in exit_guard._guarded}
    assert {"CosimTestIntegrator.so", "CosimTestGain.so"} <= guarded


class _HandOffs(NotesIgnored):
    """A sink that records how many rows each hand-off carried."""

    def __init__(self) -> None:
        self.sizes: list[int] = []

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        self.sizes.append(len(times))


@pytest.mark.parametrize(
    ("chunk", "interval_s", "sizes"),
    [
        (200, 1e9, [11]),  # the 11 rows of the run fill no chunk: one hand-off at the end
        (4, 1e9, [4, 4, 3]),  # full chunks, then the rest
        (200, 0.0, [2] + [1] * 9),  # the interval passed at every point: each row at once
    ],
)
def test_rows_are_handed_off_when_a_chunk_fills_or_the_interval_passes(
    fmu_dir: Path, chunk: int, interval_s: float, sizes: list[int]
) -> None:
    """What lets a slow run's rows reach results.csv within about a second: the master
    hands its rows to the sinks when ``rows_per_chunk`` are buffered or once
    ``hand_off_interval`` of wall clock has passed, whichever comes first."""
    sink = _HandOffs()
    result = master.run(loop(fmu_dir), [sink], rows_per_chunk=chunk, hand_off_interval=interval_s)
    assert result.complete
    assert sink.sizes == sizes


def test_jacobi_uses_the_outputs_of_the_previous_step(fmu_dir: Path) -> None:
    # both step from the values at t_n: the plant sees the command computed from x_{n-1}
    # (from the controller's start input x = 0 at n = 0): x_{n+1} = x_n - k h x_{n-1}
    result = master.run(loop(fmu_dir, algorithm="jacobi"))
    expected = [X0, X0]
    for _ in range(9):
        expected.append(expected[-1] - K * H * expected[-2])
    np.testing.assert_allclose(result.column("plant.x"), expected, rtol=1e-14)


def test_multi_rate_holds_the_slow_instance_between_its_steps(fmu_dir: Path) -> None:
    # controller every 3 plant steps (and a shortened last step at t = 0.9)
    result = master.run(loop(fmu_dir, controller_multiple=3))
    x, expected = X0, [X0]
    for n in range(10):
        if n % 3 == 0:
            u = -K * x
        x += H * u
        expected.append(x)
    np.testing.assert_allclose(result.column("plant.x"), expected, rtol=1e-14)


def test_plant_alone_equals_fmpy_simulate_fmu(fmu_dir: Path) -> None:
    from fmpy import simulate_fmu

    scenario = scenario_from_toml(
        """
        stop_time = 2.0
        [coupling]
        step = 0.05
        [instances.plant]
        fmu = "CosimTestIntegrator.fmu"
        [instances.plant.start]
        x0 = 0.3
        u = -0.7
        """,
        base_dir=fmu_dir,
    )
    ours = master.run(scenario)
    theirs = simulate_fmu(
        str(fmu_dir / "CosimTestIntegrator.fmu"),
        stop_time=2.0,
        output_interval=0.05,
        start_values={"x0": 0.3, "u": -0.7},
        output=["x"],
    )
    np.testing.assert_array_equal(ours.times, theirs["time"])
    np.testing.assert_array_equal(ours.column("plant.x"), theirs["x"])
    # unconnected inputs are recorded (constant) by default
    assert ours.columns == ("plant.x", "plant.u")
    assert np.all(ours.column("plant.u") == -0.7)


@pytest.mark.slow
def test_fmu_error_stops_the_run_with_its_reason_and_partial_results(
    fmu_dir: Path, tmp_path: Path
) -> None:
    outcome = run_scenario(
        loop(fmu_dir, plant_start="fail_at = 0.5"), tmp_path / "run", no_rrd=True, keep_rows=True
    )
    result = outcome.result
    assert not result.complete
    assert result.error.startswith("plant: fmi2DoStep returned Discard at t = 0.5 s")
    assert "injected failure at t = 0.500" in result.error
    np.testing.assert_allclose(result.times, np.arange(6) * H)
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["complete"] is False and "injected failure" in summary["error"]
    assert summary["time_reached"] == pytest.approx(0.5)
    csv = (tmp_path / "run" / "results.csv").read_text().splitlines()
    assert csv[0] == "time,plant.x,controller.u" and len(csv) == 1 + 6


def test_non_finite_exchanged_value_stops_the_run_naming_it(fmu_dir: Path) -> None:
    result = master.run(loop(fmu_dir, plant_start="nan_at = 0.3"))
    assert not result.complete
    assert result.error == "non-finite value at t = 0.3 s: plant.x = nan"
    assert np.isfinite(result.values).all() and result.times[-1] == pytest.approx(0.2)


@pytest.mark.parametrize("algorithm", ["gauss-seidel", "adaptive"])
def test_an_input_refused_as_non_finite_names_where_it_came_from(
    fmu_dir: Path, fmu_paths: dict[str, Path], algorithm: str
) -> None:
    """A foreign FMU's output turns NaN and our plant, stepped after it, refuses it as an
    input before the step's own check: the reason names the source too."""
    scenario = scenario_from_toml(
        f"""
        stop_time = 1.0
        [coupling]
        step = 0.1
        algorithm = "{algorithm}"
        [instances.src]
        fmu = "{fmu_dir / "CosimTestIntegrator.fmu"}"
        [instances.src.start]
        u = 1.0
        nan_at = 0.3
        [instances.plant]
        fmu = "AuvPlant"
        [connections]
        same_names = false
        add = [{{ from = "src.x", to = "plant.tunnel_force" }}]
        """,
        fmu_dir=fmu_paths["AuvPlant"].parent,
    )
    result = master.run(scenario)
    assert not result.complete
    assert "plant: fmi2SetReal returned Error" in result.error
    assert result.error.endswith("(non-finite values exchanged: src.x = nan)")


@pytest.mark.slow
def test_cli_failure_exits_non_zero_with_one_line(fmu_dir: Path, tmp_path: Path) -> None:
    scenario = tmp_path / "failing.toml"
    scenario.write_text(loop_toml(plant_start="fail_at = 0.5", fmu_dir=fmu_dir))
    proc = subprocess.run(
        _run_command(scenario, tmp_path / "run"),
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )
    assert proc.returncode == 1
    assert proc.stderr.count("\n") == 1 and "injected failure" in proc.stderr
    assert "partial results in" in proc.stderr
    assert json.loads((tmp_path / "run" / "summary.json").read_text())["complete"] is False


def _run_command(scenario: Path, out: Path) -> list[str]:
    """`auv-cosim run SCENARIO --out OUT --no-rrd` in a fresh interpreter."""
    return [sys.executable, "-m", "cosim.cli", "run", str(scenario), "--out", str(out), "--no-rrd"]


@pytest.mark.slow
def test_ctrl_c_stops_cleanly_with_partial_results(fmu_dir: Path, tmp_path: Path) -> None:
    started = tmp_path / "started"
    scenario = tmp_path / "long.toml"
    start = f'started_file = "{started}"'
    scenario.write_text(loop_toml(stop_time=200.0, step=1e-4, plant_start=start, fmu_dir=fmu_dir))
    proc = subprocess.Popen(
        _run_command(scenario, tmp_path / "run"),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        for _ in range(600):  # the loop has started once the plant touched the file
            if started.exists() or proc.poll() is not None:
                break
            time.sleep(0.1)
        proc.send_signal(signal.SIGINT)
        _, stderr = proc.communicate(timeout=60)
    finally:
        proc.kill()
    assert proc.returncode == 130, stderr
    assert "interrupted (Ctrl-C)" in stderr
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["complete"] is False and 0 < summary["time_reached"] < 200.0
    rows = (tmp_path / "run" / "results.csv").read_text().count("\n") - 1
    assert rows == round(summary["time_reached"] / 1e-4) + 1
