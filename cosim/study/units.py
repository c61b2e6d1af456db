"""The unit of every column a study plots: factors and metrics, for the axis labels.

A factor or final value ``<instance>.<variable>`` (``final.<instance>.<variable>``, an
event's ``events.<name>.set.<instance>.<variable>``) has the unit the FMU's model
description declares (:func:`cosim.fmus.interface.read_interface`); an event's or fault's
time key (``time``, ``ramp``, ``start``, ``stop``) and ``time_reached`` are in s; a key
figure or manoeuvre metric carries its unit in its name's last part
(``yaw_settling_time_s``, ``peak_abs_tunnel_force_N``, ``overshoot_pct``). A quantity
without a unit is "1" (dimensionless, as SI writes it).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from pathlib import Path

from cosim.fmus.interface import read_interface

SUFFIX_UNITS = {"s": "s", "m": "m", "N": "N", "deg": "deg", "pct": "%", "rad": "rad"}
TIME_KEYS = ("time", "ramp", "start", "stop")
DIMENSIONLESS = "1"


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
            unit = SUFFIX_UNITS.get(name.rsplit("_", 1)[-1])
        found[name] = unit or DIMENSIONLESS
    return found
