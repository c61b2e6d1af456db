"""A fixed-step run's state at a communication point, taken and given back (``--checkpoint-every``,
``--resume``; docs/runs.md).

At point n (t = n h, row n recorded and handed to the sinks) the state of a run is: every
instance's FMU state, serialized (``fmi2GetFMUstate`` + ``fmi2SerializeFMUstate``, FMI 2.0
section 2.1.8), and the master's own: the exchanged and recorded values ``z``, each
instance's input-extrapolation history (:class:`cosim.engine.extrapolation.InputRates`), the
timeline's events fired and faults' state (:meth:`cosim.engine.timeline.Timeline.snapshot`),
the step count and the rows handed off. :func:`capture` takes it, :func:`restore` puts it
into freshly initialised instances, and :func:`to_json` / :func:`from_json` turn it into
plain JSON and back, every double exactly (``float.hex``) and without pickle (a checkpoint
read from a folder runs no code of whoever wrote it).

What this cannot capture whole is refused by :func:`refusal` before the run starts: the
adaptive algorithm (its step-size controller's history), multi-rate stepping (instances
between their own points), and paced or live runs (their wall clock and override queue).
"""

from __future__ import annotations

import base64
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cosim.engine.slave import Slave
from cosim.engine.timeline import Timeline
from cosim.scenario.spec import Scenario


@dataclass
class Checkpointing:
    """A run's checkpoints: every ``every`` steps (0: only when a signal stops it), each
    handed to ``save`` (the engine state of :func:`capture`); ``start``: the state to resume
    from (:func:`restore`), with the ``rows`` the run wrote up to it (values, (rows,
    columns), time not included)."""

    every: int
    save: Callable[[dict[str, Any]], None]
    start: dict[str, Any] | None = None
    rows: np.ndarray | None = None


def refusal(scenario: Scenario, paced_or_live: bool) -> str | None:
    """Why a checkpoint of ``scenario``'s run could not be resumed exactly (one line), or
    None: an FMU that cannot serialize its state (named), or a coupling whose master state
    is not captured whole."""
    for name, inst in scenario.instances.items():
        cs = inst.model_description.coSimulation
        missing = [
            c for c in ("canGetAndSetFMUstate", "canSerializeFMUstate") if not getattr(cs, c)
        ]
        if missing:
            return (
                f"instance {name!r} ({inst.fmu_path.name}) cannot serialize its state "
                f"({' and '.join(missing)} {'is' if len(missing) == 1 else 'are'} false)"
            )
    coupling = scenario.coupling
    if coupling.algorithm == "adaptive":
        return "algorithm 'adaptive' keeps a step-size history a checkpoint does not hold"
    multi = sorted(name for name, k in coupling.step_multiples.items() if k != 1)
    if multi:
        return f"multi-rate instances ({', '.join(multi)}) step between checkpoints"
    if paced_or_live:
        return "a paced or live run's wall clock and overrides cannot be resumed"
    return None


def capture(
    order: Sequence[Slave], z: np.ndarray, n: int, rows: int, timeline: Timeline | None
) -> dict[str, Any]:
    """The run's state at point ``n`` (``rows`` rows handed off, t = 0 included)."""
    states: dict[str, bytes] = {}
    for slave in order:
        state = slave.fmu.getFMUstate()
        try:
            states[slave.name] = bytes(slave.fmu.serializeFMUstate(state))
        finally:
            slave.fmu.freeFMUstate(state)
    events = None
    if timeline is not None:
        events = {"snapshot": timeline.snapshot(), "fired": list(timeline.fired)}
    return {
        "step": n,
        "rows": rows,
        "z": z.copy(),
        "fmu_states": states,
        "input_rates": {
            s.name: s.input_rates.snapshot() if s.input_rates is not None else None for s in order
        },
        "timeline": events,
    }


def restore(
    state: dict[str, Any], order: Sequence[Slave], z: np.ndarray, timeline: Timeline | None
) -> None:
    """Put ``state`` (:func:`capture`'s) into the initialised instances and the master."""
    for slave in order:
        fmu_state = slave.fmu.deSerializeFMUstate(state["fmu_states"][slave.name])
        try:
            slave.fmu.setFMUstate(fmu_state)
        finally:
            slave.fmu.freeFMUstate(fmu_state)
        rates = state["input_rates"][slave.name]
        if slave.input_rates is not None and rates is not None:
            slave.input_rates.restore(rates)
    z[:] = state["z"]
    events = state["timeline"]
    if timeline is not None and events is not None:
        timeline.fired[:] = events["fired"]
        timeline.restore(events["snapshot"])


def to_json(value: Any) -> Any:
    """``value`` as plain JSON data, tagged so that :func:`from_json` gives it back with
    its types: a double as its hex text (exact, and NaN or inf too), tuples, sets, dicts
    with keys of any type, bytes and numpy arrays."""
    if value is None or isinstance(value, (bool, str)):
        return value
    if isinstance(value, (int, np.integer)) and not isinstance(value, np.bool_):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return {"f": float(value).hex()}
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, np.ndarray):
        data = np.ascontiguousarray(value)
        return {"a": base64.b64encode(data.tobytes()).decode(), "dtype": data.dtype.str,
                "shape": list(data.shape)}  # fmt: skip
    if isinstance(value, bytes):
        return {"b": base64.b64encode(value).decode()}
    if isinstance(value, dict):
        return {"d": [[to_json(k), to_json(v)] for k, v in value.items()]}
    if isinstance(value, tuple):
        return {"t": [to_json(v) for v in value]}
    if isinstance(value, (set, frozenset)):
        return {"s": [to_json(v) for v in sorted(value)]}
    if isinstance(value, list):
        return [to_json(v) for v in value]
    raise TypeError(f"a checkpoint cannot hold a {type(value).__name__}")


def from_json(data: Any) -> Any:
    """:func:`to_json`'s inverse. Raises ValueError (or KeyError, TypeError) for data it
    did not write."""
    if isinstance(data, list):
        return [from_json(v) for v in data]
    if not isinstance(data, dict):
        return data
    if "f" in data:
        return float.fromhex(data["f"])
    if "a" in data:
        raw = base64.b64decode(data["a"], validate=True)
        return np.frombuffer(raw, dtype=np.dtype(data["dtype"])).reshape(data["shape"]).copy()
    if "b" in data:
        return base64.b64decode(data["b"], validate=True)
    if "d" in data:
        return {_key(from_json(k)): from_json(v) for k, v in data["d"]}
    if "t" in data:
        return tuple(from_json(v) for v in data["t"])
    if "s" in data:
        return {from_json(v) for v in data["s"]}
    raise ValueError(f"unknown entry {sorted(data)!r}")


def _key(key: Any) -> Any:
    """A dict key as it was (a list from JSON is a tuple: lists are no keys)."""
    return tuple(key) if isinstance(key, list) else key
