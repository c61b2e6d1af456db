"""Cost of the Rerun recording (cosim.viz.recording.RerunSink), absolute and relative to a run.

Prints, best of ``--repeat`` (milliseconds unless stated):
  (a) a synthetic run: ``--rows`` rows of every column a closed-loop run records, fed in
      batches of 200 rows as the master does: sink set-up (static scene, blueprint),
      all ``add_rows`` calls, ``close`` (flush to the file), and the cost per row in us;
  (b) the same rows as one ``rr.log`` per step of every signal and the pose, the way not
      to do it, as a ratio to (a) (the first ``--naive-rows`` rows only: it is slow);
  (c) a real run through the master, bs-3 (backstepping autopilot + plant, ``--rows``
      steps of 10 ms), with and without the recording, interleaved: the time
      spent inside the sink (set-up, add_rows, close) as a fraction of the run without
      it, and run_scenario's wall times and their ratio (target <= 1.10; on a busy
      machine this ratio is noisier than the first figure). scripts/bench_cosim.py
      measures the stepping loop alone (the sink's set-up and last send on close are
      outside it).

Usage: python scripts/bench_recording.py [--rows 3000] [--repeat 3] [--fmu-dir build/fmus]
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
import time
from pathlib import Path
from typing import Any
from unittest import mock

import numpy as np
import rerun as rr

import cosim.viz.recording
from cosim.paths import DEFAULT_FMU_DIR
from cosim.runner import run_scenario
from cosim.scenario.spec import Scenario, load_scenario
from cosim.viz.layout import time_index
from cosim.viz.recording import RerunSink

COLUMNS = [
    *(f"plant.{n}" for n in ("north", "east", "down", "roll", "pitch", "yaw")),
    *(f"plant.{n}" for n in ("u", "v", "w", "u_rel", "v_rel", "w_rel", "p", "q", "r")),
    "plant.mass_position",
    "plant.mass_velocity",
    "plant.kinetic_energy",
    *(f"controller.{n}" for n in ("mass_position_cmd", "tunnel_force", "fin_angle", "thrust")),
    *(f"controller.{n}" for n in ("yaw_setpoint", "depth_setpoint")),
    *(f"controller.{n}" for n in ("current_north", "current_east")),
]


def synthetic(rows: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    times = np.arange(rows) * 0.01
    return times, rng.standard_normal((rows, len(COLUMNS))) * 0.1


def sink_run(
    folder: Path, scenario: Scenario, times: np.ndarray, values: np.ndarray
) -> tuple[float, float, float]:
    t0 = time.perf_counter()
    sink = RerunSink(scenario, folder / "sink.rrd")
    t1 = time.perf_counter()
    for k in range(0, len(times), 200):
        sink.add_rows(times[k : k + 200], values[k : k + 200])
    t2 = time.perf_counter()
    sink.close()
    t3 = time.perf_counter()
    return t1 - t0, t2 - t1, t3 - t2


def naive_run(folder: Path, times: np.ndarray, values: np.ndarray) -> float:
    rec = rr.RecordingStream("bench-naive")
    rec.save(folder / "naive.rrd")
    t0 = time.perf_counter()
    for t, row in zip(times, values, strict=True):
        rec.set_time("sim_time", duration=float(t))
        for name, value in zip(COLUMNS, row, strict=True):
            rec.log(name.replace(".", "/"), rr.Scalars(float(value)))
        rec.log("world/vehicle", rr.Transform3D(translation=row[:3]))
    rec.flush()
    return time.perf_counter() - t0


class TimedSink(RerunSink):
    """RerunSink that adds up the wall time spent in its own calls."""

    spent = 0.0

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        t0 = time.perf_counter()
        super().__init__(*args, **kwargs)
        TimedSink.spent += time.perf_counter() - t0

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        t0 = time.perf_counter()
        super().add_rows(times, values)
        TimedSink.spent += time.perf_counter() - t0

    def close(self) -> None:
        t0 = time.perf_counter()
        super().close()
        TimedSink.spent += time.perf_counter() - t0


def real_run(folder: Path, rows: int, fmu_dir: Path, record: bool) -> tuple[float, float]:
    """(run_scenario's wall time, time spent in the sink), s."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir).with_overrides(stop_time=rows * 0.01)
    TimedSink.spent = 0.0
    # run_scenario imports RerunSink at call time
    with mock.patch.object(cosim.viz.recording, "RerunSink", TimedSink):
        t0 = time.perf_counter()
        run_scenario(scenario, folder / "run", no_rrd=not record, fmu_dir=fmu_dir, overwrite=True)
        return time.perf_counter() - t0, TimedSink.spent


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=3000)
    parser.add_argument("--naive-rows", type=int, default=500)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--fmu-dir", type=Path, default=DEFAULT_FMU_DIR)
    args = parser.parse_args()
    times, values = synthetic(args.rows)
    scenario = load_scenario("bs-3", fmu_dir=args.fmu_dir)
    scenario = dataclasses.replace(scenario, id="bench", record=tuple(COLUMNS))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        time_index(times[:2])  # warm up the SDK once
        best = min(
            (sink_run(folder, scenario, times, values) for _ in range(args.repeat)),
            key=lambda s: sum(s),
        )
        total = sum(best)
        print(f"(a) synthetic {args.rows} rows x {len(COLUMNS)} columns, batches of 200:")
        print(f"    set-up {1e3 * best[0]:.1f} ms, add_rows {1e3 * best[1]:.1f} ms, ", end="")
        print(f"close {1e3 * best[2]:.1f} ms; total {1e3 * total:.1f} ms ", end="")
        print(f"= {1e6 * total / args.rows:.1f} us per row")
        n = min(args.naive_rows, args.rows)
        naive = min(naive_run(folder, times[:n], values[:n]) for _ in range(args.repeat))
        print(f"(b) one rr.log per signal per step: {1e6 * naive / n:.0f} us per row, ", end="")
        print(f"{naive / n / (total / args.rows):.0f}x (a)")
        real_run(folder, 10, args.fmu_dir, record=True)  # build/load the FMU, warm up
        bare, recorded = [], []
        for _ in range(args.repeat):
            bare.append(real_run(folder, args.rows, args.fmu_dir, record=False)[0])
            recorded.append(real_run(folder, args.rows, args.fmu_dir, record=True))
        wall, spent = min(recorded)
        print(f"(c) bs-3, {args.rows} steps of 10 ms through the master:")
        print(f"    in the sink {1e3 * spent:.0f} ms = {100 * spent / min(bare):.1f}% of ", end="")
        print(f"the run without recording; run_scenario {min(bare):.2f} s without, ", end="")
        print(f"{wall:.2f} s with: ratio {wall / min(bare):.3f}")


if __name__ == "__main__":
    main()
