"""The unit of every column a study plots, factors and metrics, and how a plot shows it.

A factor or final value ``<instance>.<variable>`` (``final.<instance>.<variable>``, an
event's ``events.<name>.set.<instance>.<variable>``) has the unit the FMU's model
description declares (:func:`cosim.fmus.interface.read_interface`); an event's or fault's
time key (``time``, ``ramp``, ``start``, ``stop``) and ``time_reached`` are in s; a key
figure or manoeuvre metric carries its unit in its name's last part
(``yaw_settling_time_s``, ``peak_abs_tunnel_force_N``, ``overshoot_pct``; a rate's ends
in ``_per_s``, ``tunnel_force_variation_N_per_s`` in N/s). A quantity
without a unit is "1" (dimensionless, as SI writes it).

On plots (:func:`shown`), angles are in degrees as everywhere else on this tool's plots
(files keep radians): a quantity in rad or rad/s is drawn scaled to deg or deg/s. Its title
(:func:`title`) is readable: ``peak_abs_tunnel_force_N`` is "peak |tunnel force|",
``final.plant.yaw`` "plant.yaw at the end", ``events.turn.time`` "time of event turn".
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from pathlib import Path

from cosim.fmus.interface import read_interface

SUFFIX_UNITS = {"s": "s", "m": "m", "N": "N", "deg": "deg", "pct": "%", "rad": "rad"}
TIME_KEYS = ("time", "ramp", "start", "stop")
DIMENSIONLESS = "1"
IN_DEGREES = {"rad": "deg", "rad/s": "deg/s"}  # units drawn in degrees on plots


def units(names: Iterable[str], fmu_paths: Mapping[str, Path]) -> dict[str, str]:
    """name -> unit of each factor or metric ``name`` of a study of these FMUs
    (instance -> FMU file)."""
    variables = {inst: read_interface(path).variables for inst, path in fmu_paths.items()}
    found = {}
    for name in names:
        ref = name.removeprefix("final.").rpartition(".set.")[2]
        instance, _, variable = ref.partition(".")
        if variable in variables.get(instance, {}):
            unit = variables[instance][variable].unit
        elif name == "time_reached" or (
            name.startswith(("events.", "faults.")) and name.rsplit(".", 1)[-1] in TIME_KEYS
        ):
            unit = "s"
        else:
            unit = suffix_unit(name)
        found[name] = unit or DIMENSIONLESS
    return found


def suffix_unit(name: str) -> str | None:
    """The unit a metric's name ends in: ``_m`` m, ``_N_per_s`` N/s (a rate); None if
    its last part names none."""
    stem, per_second = name.removesuffix("_per_s"), name.endswith("_per_s")
    unit = SUFFIX_UNITS.get(stem.rsplit("_", 1)[-1])
    return f"{unit}/s" if unit and per_second else unit


def shown(name: str, unit_of: Mapping[str, str]) -> tuple[float, str]:
    """(scale, unit) of ``name`` on a plot: values times scale are in that unit (angles
    in degrees)."""
    unit = unit_of.get(name, DIMENSIONLESS)
    if unit in IN_DEGREES:
        return math.degrees(1.0), IN_DEGREES[unit]
    return 1.0, unit


def title(name: str) -> str:
    """A readable title of a factor or metric column (see the module docstring)."""
    if name.startswith("final."):
        return f"{name.removeprefix('final.')} at the end"
    kind, _, rest = name.partition(".")
    if kind in ("events", "faults") and rest:
        owner, _, key = rest.partition(".")
        what = "event" if kind == "events" else "fault"
        if key.startswith("set."):
            return f"{key.removeprefix('set.')} set by {what} {owner}"
        return f"{key} of {what} {owner}"
    if "." in name:
        return name  # an <instance>.<variable>: the scenario's own name
    words = name.removesuffix("_per_s").split("_")
    if words[-1] in SUFFIX_UNITS:
        words = words[:-1]
    if "abs" in words:  # peak_abs_tunnel_force -> peak |tunnel force|
        at = words.index("abs")
        words = [*words[:at], "|" + " ".join(words[at + 1 :]) + "|"]
    return " ".join(words)
