"""What a run's connection faults delivered, rebuilt from its folder for the report.

results.csv records the FMUs' outputs: a connection's source, not what a fault on it made
of the value its target got (docs/events.md). This module replays the master's own fault
code (:func:`cosim.engine.timeline.replay`) over the recorded source column, in the
order the run delivered: a target takes its inputs at every point n at which it is due;
under Gauss-Seidel (and the adaptive algorithm) a source that stepped before it at that
point gave it the value recorded in the next row, else (Jacobi, or a source after it in
``coupling.order``, or not due) the value of row n. What it needs it reads from the run's
resolved ``scenario.toml``: the faults, the connections and the coupling.

An actuator fault on an unconnected input needs none of this: the input's own column, when
recorded, is what the plant got. A source whose output feeds through from its inputs is
read again after its step (``cosim.engine.points.refresh``), so its next row may differ
from what the target took; the autopilot and the guidance feed nothing through.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from cosim.engine.adaptive import MIN_LEVEL
from cosim.engine.timeline import replay
from cosim.scenario.spec import FAULT_COLUMN_PREFIX
from cosim.scenario.timeline_spec import (
    ACTUATOR_FAULTS,
    MASS_POSITION,
    Fault,
    FaultSpec,
    fault_of,
)

DELIVERED_SUFFIX = " (delivered)"  # the table column of a target's delivered values
ACTING_SUFFIX = " (fault acting)"  # ... and of where one of its faults acts (1.0, else 0.0)


@dataclass(frozen=True)
class Delivery:
    """The faults on one connection and what its target got at each row of a run."""

    target: str  # "<instance>.<input>"
    source: str  # the connection's source column, "<instance>.<output>"
    faults: tuple[Fault, ...]  # in file order
    values: np.ndarray  # per row: what the target held from that row's time on (NaN: none)
    acting: np.ndarray  # per row: 1.0 where one of the faults acts, else 0.0

    @property
    def column(self) -> str:
        return self.target + DELIVERED_SUFFIX

    @property
    def acting_column(self) -> str:
        return self.target + ACTING_SUFFIX

    @property
    def label(self) -> str:
        """The faults as a legend names them: "fault jam (mass-jam)"."""
        return ", ".join(f"fault {f.name} ({f.kind})" for f in self.faults)


def deliveries(
    run_dir: Path, table: dict[str, np.ndarray], summary: dict[str, Any]
) -> list[Delivery]:
    """What each faulted connection of the run in ``run_dir`` delivered (``table``: its
    results.csv by column; ``summary``: its summary.json), one per target whose source
    was recorded; none where the scenario.toml cannot be read or names no fault."""
    scenario = read_scenario(run_dir)
    if scenario is None:
        return []
    found = []
    for target, source, faults in faulted_connections(scenario, summary):
        if source not in table or "time" not in table:
            continue  # a source the run did not record
        values = _replayed(scenario, table, source, target, list(faults))
        if values is None:
            continue
        flags = [table[c] > 0 for f in faults if (c := FAULT_COLUMN_PREFIX + f.name) in table]
        acting = np.any(flags, axis=0) if flags else np.zeros(len(table["time"]), dtype=bool)
        found.append(Delivery(target, source, tuple(faults), values, acting.astype(float)))
    return found


def faulted_connections(
    scenario: dict[str, Any], summary: dict[str, Any]
) -> list[tuple[str, str, tuple[Fault, ...]]]:
    """(target, source, its faults in file order) of each connection of the resolved
    ``scenario`` a fault acts on (``summary``: the run's summary.json); a fault on an
    unconnected input is none of them."""
    sources = connection_sources(scenario)
    by_target: dict[str, list[Fault]] = {}
    for fault in _faults(scenario, summary, sources):
        by_target.setdefault(fault.target, []).append(fault)
    return [(t, sources[t], tuple(faults)) for t, faults in by_target.items() if t in sources]


def read_scenario(run_dir: Path) -> dict[str, Any] | None:
    """The run's resolved ``scenario.toml`` as TOML data; None where it cannot be read."""
    try:
        return tomllib.loads((run_dir / "scenario.toml").read_text("utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return None


def connection_sources(scenario: dict[str, Any]) -> dict[str, str]:
    """{target: source} of the resolved scenario's connections (each spelled out)."""
    added = (scenario.get("connections") or {}).get("add") or []
    return {
        str(c["to"]): str(c["from"])
        for c in added
        if isinstance(c, dict) and isinstance(c.get("to"), str) and isinstance(c.get("from"), str)
    }


def _faults(
    scenario: dict[str, Any], summary: dict[str, Any], sources: dict[str, str]
) -> list[Fault]:
    """The scenario's faults, each with the target the run gave it (summary.json names an
    actuator fault's; else the plant input of its kind that a connection drives)."""
    targets = {
        f.get("name"): f.get("target") for f in summary.get("faults") or [] if isinstance(f, dict)
    }
    faults = []
    for i, table in enumerate(scenario.get("faults") or []):
        try:
            spec = FaultSpec.model_validate(table)
        except ValidationError:
            continue  # not a fault this version runs: nothing to draw of it
        name = spec.name or f"fault-{i + 1}"
        target = spec.target or targets.get(name)
        if target is None and spec.kind in ACTUATOR_FAULTS:
            wanted = "." + ACTUATOR_FAULTS[spec.kind]
            target = next((t for t in sources if t.endswith(wanted)), None)
        if not isinstance(target, str):
            continue
        hold = None
        if spec.kind == "mass-jam":
            hold = f"{target.split('.', 1)[0]}.{MASS_POSITION}"
        faults.append(fault_of(spec, name, target, hold))
    return faults


def _replayed(
    scenario: dict[str, Any],
    table: dict[str, np.ndarray],
    source: str,
    target: str,
    faults: list[Fault],
) -> np.ndarray | None:
    """Per row, the value ``target`` held from that row's time on: its delivery at the
    row's point when it was due there, else the one before (see the module docstring);
    NaN at the last row (no step from it). None without the coupling or, for a mass-jam,
    the recorded mass position."""
    coupling = scenario.get("coupling") or {}
    step = coupling.get("step")
    if not isinstance(step, int | float) or step <= 0:
        return None
    algorithm = coupling.get("algorithm", "jacobi")
    adaptive = algorithm == "adaptive"
    h = step / 2**MIN_LEVEL if adaptive else float(step)  # s between points
    per_step = 2**MIN_LEVEL if adaptive else 1  # points per communication step
    multiples = coupling.get("step_multiples") or {}
    order = list(coupling.get("order") or [])
    into, out_of = target.split(".", 1)[0], source.split(".", 1)[0]

    def due(instance: str, n: int) -> bool:
        k = int(multiples.get(instance, 1))
        return k == 1 or n % (k * per_step) == 0

    before = (
        algorithm != "jacobi"
        and out_of != into
        and out_of in order
        and into in order
        and order.index(out_of) < order.index(into)
    )
    time = table["time"]
    rows = len(time) - 1  # a delivery at each row's point but the last
    points = np.rint(time[:rows] / h).astype(np.int64)
    taken = np.array([due(into, int(n)) for n in points], dtype=bool)
    ahead = np.array([before and due(out_of, int(n)) for n in points], dtype=bool)
    at = np.flatnonzero(taken)
    gathered = table[source][at + ahead[at]]
    held = None
    if any(f.hold_source is not None for f in faults):
        hold = next(f.hold_source for f in faults if f.hold_source is not None)
        if hold not in table:
            return None
        held = table[hold][at]
    values = np.full(len(time), np.nan)
    values[at] = replay(faults, h, [int(n) for n in points[at]], gathered, held)
    # between a slow target's points it holds its last delivery
    last = np.maximum.accumulate(np.where(np.isnan(values[:rows]), -1, np.arange(rows)))
    values[:rows] = np.where(last >= 0, values[np.maximum(last, 0)], np.nan)
    return values
