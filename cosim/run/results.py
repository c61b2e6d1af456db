"""Run outputs: ``results.csv``, ``scenario.toml`` (resolved) and ``summary.json``.

``results.csv``: a ``time`` column (s), then one column per recorded variable named
``<instance>.<variable>``, SI units (angles in rad), one row per communication step
including t = 0; values printed as the shortest text that reads back to the same double.

``summary.json``: scenario id, stop_time, step, algorithm, wall_clock_s (the stepping loop
alone), complete, error (null if complete), the time reached, the final value of every
column and the key figures of :func:`key_figures`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from cosim.errors import CosimError
from cosim.run.master import RunResult

YAW_TOLERANCE_RAD = math.radians(1.0)  # "settled" band of the yaw settling time


def write_outputs(result: RunResult, out_dir: Path) -> dict[str, Path]:
    """Write the three files into ``out_dir`` (created); returns name -> path."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        paths = {
            "results": out_dir / "results.csv",
            "scenario": out_dir / "scenario.toml",
            "summary": out_dir / "summary.json",
        }
        write_csv(result, paths["results"])
        paths["scenario"].write_text(result.scenario.to_toml(), encoding="utf-8")
        paths["summary"].write_text(json.dumps(summary(result), indent=2) + "\n", encoding="utf-8")
    except OSError as exc:
        raise CosimError(f"cannot write the run outputs to {out_dir}: {exc}") from None
    return paths


def write_csv(result: RunResult, path: Path) -> None:
    """Floats as Python's repr: the shortest text that reads back to the same double."""
    table = np.column_stack([result.times, result.values]).tolist()
    lines = [",".join(["time", *result.columns])]
    lines += [",".join(map(repr, row)) for row in table]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    """Column names and the (rows, columns) table of a results.csv (``time`` first)."""
    with path.open(encoding="utf-8") as f:
        columns = f.readline().strip().split(",")
    return columns, np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)


def summary(result: RunResult) -> dict[str, Any]:
    """The content of summary.json (plain JSON types; NaN written as null)."""
    scenario = result.scenario
    final = dict(zip(result.columns, result.values[-1].tolist(), strict=True))
    return {
        "scenario": scenario.id,
        "stop_time": scenario.stop_time,
        "step": scenario.coupling.step,
        "algorithm": scenario.coupling.algorithm,
        "wall_clock_s": result.wall_clock_s,
        "real_time_factor": _finite(float(result.times[-1]) / result.wall_clock_s)
        if result.wall_clock_s > 0
        else None,
        "complete": result.complete,
        "error": result.error,
        "time_reached": float(result.times[-1]),
        "final_values": {name: _finite(value) for name, value in final.items()},
        "key_figures": key_figures(result),
        "fmu_messages": {name: lines for name, lines in result.messages.items() if lines},
    }


def key_figures(result: RunResult) -> dict[str, float | None]:
    """Settling time of yaw, peak |mass_position|, peak |tunnel_force| (None if not recorded).

    ``yaw_settling_time_s``: the first time after which |yaw - yaw_setpoint| stays below
    1 deg to the end of the run (angles compared on the circle); None if the last sample is
    outside the band. The setpoint is ``controller.yaw_setpoint`` if recorded, else 0
    (with the autopilot's ``compensate_current`` on, that set-point is the course; the
    heading then settles off it by the crab angle, so the figure is None).
    """
    cols = set(result.columns)
    figures: dict[str, float | None] = {
        "yaw_settling_time_s": None,
        "peak_abs_mass_position_m": None,
        "peak_abs_tunnel_force_N": None,
    }
    if "plant.yaw" in cols:
        setpoint = (
            result.column("controller.yaw_setpoint") if "controller.yaw_setpoint" in cols else 0.0
        )
        figures["yaw_settling_time_s"] = settling_time(
            result.times, result.column("plant.yaw") - setpoint, YAW_TOLERANCE_RAD, angle=True
        )
    if "plant.mass_position" in cols:
        figures["peak_abs_mass_position_m"] = _peak(result.column("plant.mass_position"))
    force = next((c for c in ("controller.tunnel_force", "plant.tunnel_force") if c in cols), None)
    if force is not None:
        figures["peak_abs_tunnel_force_N"] = _peak(result.column(force))
    return figures


def settling_time(
    times: np.ndarray, error: np.ndarray, tolerance: float, angle: bool = False
) -> float | None:
    """First time after which |error| < tolerance to the end; None if the end is outside.

    With ``angle`` the error is wrapped to (-pi, pi] first.
    """
    if angle:
        error = np.angle(np.exp(1j * np.asarray(error)))
    outside = np.flatnonzero(~(np.abs(error) < tolerance))
    if outside.size == 0:
        return float(times[0])
    last = outside[-1]
    return None if last == len(times) - 1 else float(times[last + 1])


def _peak(values: np.ndarray) -> float | None:
    return _finite(float(np.max(np.abs(values)))) if values.size else None


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None
