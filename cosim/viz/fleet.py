"""The vehicles a run draws, from its scenario or from its folder afterwards.

A run's vehicles are those its key figures describe (:func:`cosim.metrics.key_figures.vehicles`):
one, whatever its plant and autopilot are named, or each plant's of several with the
autopilot a connection joins to it. The recording draws each under an entity of its own
(:func:`scene_root`: ``world`` for one, ``world/<plant>`` for each of several), which the
layouts that follow a vehicle name: the recording's own (:mod:`cosim.viz.recording`) and
the notebook's (:mod:`cosim.viz.notebook`, which reads the run's folder).
"""

from __future__ import annotations

import json
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any

import rerun as rr

from cosim.metrics.key_figures import Vehicle, vehicles
from cosim.viz.delivered import connection_sources, read_scenario
from cosim.viz.scene import WORLD


def scene_root(plant: str, several: bool) -> str:
    """The entity the 3-D shapes of the vehicle of instance ``plant`` hang under:
    :data:`cosim.viz.scene.WORLD` for a run's one vehicle, ``world/<plant>`` for each of
    ``several``."""
    return f"{WORLD}/{rr.escape_entity_path_part(plant)}" if several else WORLD


def drawn_roots(fleet: Sequence[Vehicle], columns: Collection[str]) -> list[tuple[Vehicle, str]]:
    """The vehicles of ``fleet`` the 3-D scene draws, each with its :func:`scene_root`:
    those whose plant has a recorded column among ``columns`` (no hull standing at the
    origin for a plant that records nothing)."""
    several = len(fleet) > 1
    return [
        (vehicle, scene_root(vehicle.roles["plant"], several))
        for vehicle in fleet
        if any(c.startswith(f"{vehicle.roles['plant']}.") for c in columns)
    ]


def run_vehicles(run_dir: Path, summary: dict[str, Any]) -> list[Vehicle]:
    """The run's vehicles (:func:`cosim.metrics.key_figures.vehicles`) from the FMUs its
    summary.json names and the connections of its scenario.toml: one, its plant and
    autopilot whatever they are named (plant and controller when summary.json names no
    FMU), or each plant's of several, with its autopilot."""
    sources = connection_sources(read_scenario(run_dir) or {})
    fmus = summary.get("fmus")
    each = fmus.items() if isinstance(fmus, dict) else ()
    models = {str(k): str(v.get("model")) for k, v in each if isinstance(v, dict)}
    return vehicles(models, [(source, target) for target, source in sources.items()])


def read_summary(run_dir: Path) -> dict[str, Any]:
    """The run's summary.json as a dict; empty where it cannot be read (a killed run's)."""
    try:
        summary = json.loads((run_dir / "summary.json").read_text("utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return {}
    return summary if isinstance(summary, dict) else {}


def pairs(fleet: Sequence[Vehicle]) -> list[tuple[str, str]]:
    """The (plant, autopilot) instances of each vehicle of ``fleet``."""
    return [(v.roles["plant"], v.roles["controller"]) for v in fleet]
