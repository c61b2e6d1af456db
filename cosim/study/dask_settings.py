"""Dask's settings a study's cluster and client read, checked before either starts.

Dask reads ``DASK_*`` environment variables (and its YAML files) into its configuration
without checking their values: its schema types a duration as any string, so
``DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT=abc`` surfaced as a KeyError traceback from
deep in the client once the cluster had started, and
``DASK_DISTRIBUTED__WORKER__MEMORY__TARGET=lots`` as every worker failing to start
("Nanny failed to start"). Each setting listed here is read with ``dask.config.get`` and
parsed with Dask's own parsers (``parse_timedelta``, ``parse_bytes``), as Dask will; the
first it cannot use is refused in one line naming the variable (or the setting, when it
comes from a file) and what was expected.

The list is hand-written: Dask keeps no table of which settings hold durations, sizes or
fractions (its JSON schema says "string" for all three).
"""

from __future__ import annotations

import os
from collections.abc import Callable

import dask.config
from dask.utils import parse_bytes, parse_timedelta

from cosim.errors import shown
from cosim.study.spec import StudyError

DURATION = "a duration such as 30s, 500ms or 5 minutes"
SIZE = "a size such as 64MiB or 10MB"
FRACTION = "a fraction of the memory limit, a number from 0 to 1, or False"
COUNT = "a whole number >= 0"

# the settings read while a study's client connects, its local cluster starts and its runs
# run (connections, retries, heartbeats, the scheduler's patience with a silent worker, a
# worker's memory thresholds); the ones cluster_settings sets are set there, not read
DURATIONS = (
    "distributed.comm.timeouts.connect",
    "distributed.comm.timeouts.tcp",
    "distributed.comm.retry.delay.min",
    "distributed.comm.retry.delay.max",
    "distributed.scheduler.worker-ttl",
    "distributed.scheduler.idle-timeout",
    "distributed.scheduler.no-workers-timeout",
    "distributed.scheduler.work-stealing-interval",
    "distributed.admin.tick.limit",
    "distributed.client.heartbeat",
    "distributed.client.scheduler-info-interval",
    "distributed.deploy.lost-worker-timeout",
    "distributed.worker.lifetime.duration",
    "distributed.worker.lifetime.stagger",
)
SIZES = ("distributed.comm.shard", "distributed.comm.offload")
FRACTIONS = (
    "distributed.worker.memory.target",
    "distributed.worker.memory.spill",
    "distributed.worker.memory.pause",
    "distributed.worker.memory.terminate",
)
COUNTS = ("distributed.comm.retry.count", "distributed.scheduler.allowed-failures")


def check_dask_settings() -> None:
    """Raise :class:`StudyError` naming the first listed Dask setting whose value Dask
    could not use (a duration, a size, a memory fraction or a count)."""
    checks: list[tuple[tuple[str, ...], Callable[[object], bool], str]] = [
        (DURATIONS, _is_duration, DURATION),
        (SIZES, _is_size, SIZE),
        (FRACTIONS, _is_fraction, FRACTION),
        (COUNTS, _is_count, COUNT),
    ]
    for keys, usable, expected in checks:
        for key in keys:
            value = dask.config.get(key, None)
            if not usable(value):
                raise StudyError(f"{_source(key)}={shown(value)}: expected {expected}")


def _is_duration(value: object) -> bool:
    """None (no limit), a number of seconds or a string ``parse_timedelta`` reads."""
    if value is None:
        return True
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return False
    try:
        parse_timedelta(value, default="seconds")
    except (KeyError, ValueError, TypeError):
        return False
    return True


def _is_size(value: object) -> bool:
    """A number of bytes or a string ``parse_bytes`` reads (False: none, as Dask takes)."""
    if value is False:
        return True
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        return False
    try:
        parse_bytes(value)
    except (ValueError, TypeError):
        return False
    return True


def _is_fraction(value: object) -> bool:
    """False (the threshold off) or a number from 0 to 1."""
    if value is False:
        return True
    return isinstance(value, int | float) and not isinstance(value, bool) and 0 <= value <= 1


def _is_count(value: object) -> bool:
    """A whole number >= 0."""
    return isinstance(value, int) and not isinstance(value, bool) and value >= 0


def _source(key: str) -> str:
    """The environment variable that set ``key`` (``DASK_A__B_C`` sets ``a.b-c``: Dask
    takes ``_`` and ``-`` in a key for the same), else the setting's own name (a Dask
    configuration file set it)."""
    wanted = key.replace("_", "-")
    for name in sorted(os.environ):
        if not name.startswith("DASK_"):
            continue
        if name[5:].lower().replace("__", ".").replace("_", "-") == wanted:
            return name
    return f"Dask setting {key}"
