"""A fixed-step run's state at a communication point, taken and given back (``--checkpoint-every``,
``--resume``; docs/runs.md).

At point n (t = n h, row n recorded and handed to the sinks) the state of a run is: every
instance's FMU state, serialized (``fmi2GetFMUstate`` + ``fmi2SerializeFMUstate``, FMI 2.0
section 2.1.8), and the master's own: the exchanged and recorded values ``z``, each
instance's input-extrapolation history (:class:`cosim.engine.extrapolation.InputRates`), the
timeline's events fired and faults' state (:meth:`cosim.engine.timeline.Timeline.snapshot`)
and the notes of the events log so far (a resumed run's recording has them again),
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
import math
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from fmpy.fmi1 import FMICallException

from cosim.engine.slave import Slave, describe
from cosim.engine.timeline import Timeline
from cosim.scenario.spec import Scenario


class SavedRows(Protocol):
    """The rows a run wrote up to its checkpoint, read as they are replayed, a chunk at a
    time (a long run's rows do not fit in memory whole: 620 MB for 6 h of bs-3)."""

    last: np.ndarray | None  # the values of the last row (columns,), time left out

    def chunks(self) -> Iterator[np.ndarray]:
        """The rows' values (rows, columns), time left out, in order; the source closed at
        the end."""
        ...

    def close(self) -> None:
        """Close the source (the rows unread)."""
        ...


@dataclass
class Checkpointing:
    """A run's checkpoints: every ``every`` steps (0: only when a signal stops it), each
    handed to ``save`` (the engine state of :func:`capture`); ``start``: the state to resume
    from (:func:`restore`), with the ``rows`` the run wrote up to it (:class:`SavedRows`);
    ``source``: where ``start`` was read (named when it does
    not fit the run)."""

    every: int
    save: Callable[[dict[str, Any]], None]
    start: dict[str, Any] | None = None
    rows: SavedRows | None = None
    source: str = "the checkpoint"


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
        events = {
            "snapshot": timeline.snapshot(),
            "fired": list(timeline.fired),
            "notes": [*timeline.handed, *timeline.notes],
        }
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
    """Put ``state`` (:func:`capture`'s) into the initialised instances and the master.
    Raises ValueError (one line) for a state that is not this run's shape (read from a file:
    :func:`misfit`) or that an FMU refuses."""
    reason = misfit(state, order, z, timeline)
    if reason is not None:
        raise ValueError(reason)
    for slave in order:
        try:
            fmu_state = slave.fmu.deSerializeFMUstate(state["fmu_states"][slave.name])
            try:
                slave.fmu.setFMUstate(fmu_state)
            finally:
                slave.fmu.freeFMUstate(fmu_state)
        except FMICallException as exc:
            slave.failed(exc.status)
            raise ValueError(describe(slave, exc.function, exc.status, 0.0)) from None
        rates = state["input_rates"][slave.name]
        if slave.input_rates is not None and rates is not None:
            slave.input_rates.restore(rates)
    z[:] = state["z"]
    events = state["timeline"]
    if timeline is not None and events is not None:
        try:
            timeline.fired[:] = events["fired"]
            timeline.restore(events["snapshot"])
            # handed to the sinks again with the rows before the checkpoint (replayed)
            timeline.notes[:] = events.get("notes", [])
        except (TypeError, ValueError, KeyError, IndexError, AttributeError):
            raise ValueError("its timeline (events and faults) is not this run's") from None


_COUNT = 1 << 62  # beyond any count of steps or epochs a run reaches


def misfit(
    state: dict[str, Any], order: Sequence[Slave], z: np.ndarray, timeline: Timeline | None
) -> str | None:
    """What makes ``state`` (read from a file anyone may edit) not a state of this run, or
    None: each instance's FMU state as bytes, ``z`` of this run's shape, each
    instance's input history as its own (:meth:`InputRates.snapshot`'s shape, finite, its
    counts whole numbers from 0), a timeline where the run has one."""
    names = {slave.name for slave in order}
    states, rates = state.get("fmu_states"), state.get("input_rates")
    for what, table in (("fmu_states", states), ("input_rates", rates)):
        if not isinstance(table, dict) or set(table) != names:
            return f"its {what} are not of this run's instances ({', '.join(sorted(names))})"
    assert isinstance(states, dict) and isinstance(rates, dict)
    for slave in order:
        if not isinstance(states[slave.name], bytes):
            return f"the FMU state of instance {slave.name!r} is not bytes"
        own = slave.input_rates.snapshot() if slave.input_rates is not None else None
        if not _rates_fit(rates[slave.name], own):
            return f"the input history of instance {slave.name!r} is not this run's"
    saved = state.get("z")
    if not isinstance(saved, np.ndarray) or saved.dtype != z.dtype or saved.shape != z.shape:
        return f"its values z are not this run's {len(z)} doubles"
    events = state.get("timeline")
    if (events is None) != (timeline is None):
        return "its timeline (events and faults) is not this run's (one where it has none, or none)"
    if timeline is not None:
        if not isinstance(events, dict) or not isinstance(events.get("fired"), list):
            return "its timeline (events and faults) is not this run's"
        snapshot = events.get("snapshot")
        reason = timeline.misfit(snapshot)
        if reason is not None:
            return reason
        assert isinstance(snapshot, tuple)
        fired = events["fired"]
        if len(fired) != snapshot[0] or not all(map(_fired_fits, fired)):
            return (
                f"its timeline's events fired are not {snapshot[0]} tables of a name, a "
                "finite time (s) and the values set"
            )
        notes = events.get("notes", [])
        if not isinstance(notes, list) or not all(map(_note_fits, notes)):
            return "its timeline's notes are not pairs of a finite time (s) and a text"
    return None


def _note_fits(entry: Any) -> bool:
    """``entry`` is a note of the events log: (a finite time in s, a text)."""
    return (
        isinstance(entry, tuple) and len(entry) == 2
        and _finite(entry[0]) and isinstance(entry[1], str)
    )  # fmt: skip


def _fired_fits(entry: Any) -> bool:
    """``entry`` is one of :attr:`Timeline.fired`'s: a name, a finite time (s) and the
    values it set (variable -> a finite number, a bool or a text), as summary.json lists."""
    if not isinstance(entry, dict) or set(entry) != {"name", "time", "set"}:
        return False
    values = entry["set"]
    return (
        isinstance(entry["name"], str) and _finite(entry["time"]) and isinstance(values, dict)
        and all(isinstance(k, str) for k in values)
        and all(_finite(v) or isinstance(v, (bool, int, str)) for v in values.values())
    )  # fmt: skip


def _rates_fit(saved: Any, own: tuple[Any, ...] | None) -> bool:
    """Whether ``saved`` is an input history shaped as the instance's own (``own``, None:
    the instance extrapolates none) with finite values and counts from 0."""
    if own is None or saved is None:
        return own is None and saved is None
    if not isinstance(saved, tuple) or len(saved) != len(own):
        return False
    past, times, count, epoch, sent_at = saved
    return (
        isinstance(past, np.ndarray) and past.dtype == own[0].dtype
        and past.shape == own[0].shape and bool(np.isfinite(past).all())
        and isinstance(times, list) and len(times) == len(own[1])
        and all(_finite(t) for t in times)
        and all(type(c) is int and 0 <= c < _COUNT for c in (count, epoch))
        and (sent_at is None or _finite(sent_at))
    )  # fmt: skip


def _finite(value: Any) -> bool:
    return isinstance(value, float) and math.isfinite(value)


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
