"""The mission a scenario flies: the waypoints of its waypoint guidance (``AuvGuidance``).

Read from the resolved scenario TOML (what a run writes as ``scenario.toml`` and a
recording carries), for the 3D scene (:func:`cosim.viz.scene.log_mission`) and the report's
trajectory figure. The waypoint text is read by the guidance's own parser
(:func:`controller_fmu.los_guidance.parse_waypoints`), so both show what the FMU flew.
"""

from __future__ import annotations

import tomllib

import numpy as np

from controller_fmu.los_guidance import DEFAULT_WAYPOINTS, parse_waypoints

GUIDANCE_FMU = "AuvGuidance"


def mission_waypoints(scenario_toml: str) -> np.ndarray | None:
    """The waypoints (m, NED, one row each) of the first ``AuvGuidance`` instance of a
    resolved scenario (its ``waypoints`` start value, else the FMU's default mission);
    None if it has none, or the text does not read as TOML or as waypoints."""
    try:
        instances = tomllib.loads(scenario_toml).get("instances", {})
    except tomllib.TOMLDecodeError:
        return None
    for instance in instances.values() if isinstance(instances, dict) else ():
        fmu = str(instance.get("fmu", "")) if isinstance(instance, dict) else ""
        if fmu == GUIDANCE_FMU or fmu.endswith(f"{GUIDANCE_FMU}.fmu"):
            text = instance.get("start", {}).get("waypoints", DEFAULT_WAYPOINTS)
            try:
                points = parse_waypoints(text)
            except ValueError:
                return None
            return np.array([[w.north, w.east, w.down] for w in points])
    return None
