"""What a test can leave in its pytest process that later tests inherit: the dispositions
of the stop signals and the ignored or blocked signals (a process started later inherits
an ignored or blocked signal: a Ctrl-C test's child then ignored Ctrl-C and timed out),
and child processes still running. Read cheaply (a few /proc files, no process scan),
for ``tests/conftest.py``'s guard around every test and ``tests/leak_check.py``."""

from __future__ import annotations

import os
import re
import signal
from contextlib import suppress
from pathlib import Path

WATCHED_SIGNALS = tuple(
    name for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGCHLD", "SIGPIPE") if hasattr(signal, name)
)


def _signal_names(mask: str) -> set[str]:
    """The names of the signals in a hexadecimal mask of /proc/<pid>/status."""
    bits = int(mask, 16)
    names = set()
    for number in range(1, 65):
        if bits >> (number - 1) & 1:
            try:
                names.add(signal.Signals(number).name)
            except ValueError:  # a real-time signal
                names.add(f"SIG{number}")
    return names


def _handler(handler: object) -> str:
    if isinstance(handler, signal.Handlers):
        return handler.name
    if handler is None:
        return "a handler not set from Python"
    name = getattr(handler, "__qualname__", type(handler).__qualname__)
    return f"{getattr(handler, '__module__', None) or ''}.{name}".lstrip(".")


def signal_state() -> dict[str, str]:
    """``{signal name: its handler}`` of :data:`WATCHED_SIGNALS` (those this platform has)
    and ``{"ignored": ..., "blocked": ...}``, the signals this process (its main thread)
    ignores and blocks, as /proc/self/status lists them (Linux only)."""
    state = {name: _handler(signal.getsignal(getattr(signal, name))) for name in WATCHED_SIGNALS}
    with suppress(OSError):
        for line in Path("/proc/self/status").read_text().splitlines():
            key, _, value = line.partition(":")
            if key in ("SigIgn", "SigBlk"):
                names = _signal_names(value.strip())
                state["ignored" if key == "SigIgn" else "blocked"] = " ".join(sorted(names))
    return state


def child_processes(pid: int | None = None) -> dict[int, str]:
    """``{pid: "[state] command line"}`` of the descendants of ``pid`` (this process if
    None) that have not ended (zombies, ended and not yet waited for, left out), from
    ``/proc/<pid>/task/<tid>/children`` (Linux only; empty elsewhere)."""
    found: dict[int, str] = {}
    todo = [os.getpid() if pid is None else pid]
    while todo:
        parent = todo.pop()
        with suppress(OSError):
            for tid in os.listdir(f"/proc/{parent}/task"):
                with suppress(OSError):
                    children = Path(f"/proc/{parent}/task/{tid}/children").read_text()
                    todo.extend(map(int, children.split()))
                    found.update(dict.fromkeys(map(int, children.split()), ""))
    return {child: said for child in found if (said := running(child)) is not None}


# the standard library's helpers, the process's rather than a test's (docs/api.md): the fork
# server a local study's workers come from, kept for the next study, and its resource tracker
PROCESS_HELPERS = re.compile(r"from multiprocessing\.(forkserver|resource_tracker) import main")


def new_children(before: dict[int, str]) -> dict[int, str]:
    """:func:`child_processes` not in ``before``, the multiprocessing helpers left out
    (matched on the whole command line: ``-W`` options, passed on to them, make it long)."""
    found = child_processes()
    return {
        p: c
        for p, c in found.items()
        if p not in before and not PROCESS_HELPERS.search(command_line(p))
    }


def command_line(pid: int) -> str:
    """The whole command line of process ``pid`` ("" if it ended): what a match on it
    reads, where :func:`running` cuts it short for a message."""
    with suppress(OSError):
        return (
            Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        )
    return ""


def running(pid: int) -> str | None:
    """``"[state] command line"`` of process ``pid``, None if it ended (or is a zombie,
    ended and not yet waited for)."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
        command = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ")
    except OSError:
        return None
    state = stat.rpartition(")")[2].split()[0]
    if state in ("Z", "X"):
        return None
    return f"[{state}] {command.decode(errors='replace').strip()[:160]}"


def changed(before: dict, after: dict) -> dict[str, str]:
    """``{key: "old -> new"}`` of the keys whose value differs between two states."""
    return {
        str(key): f"{before.get(key)} -> {after.get(key)}"
        for key in before.keys() | after.keys()
        if before.get(key) != after.get(key)
    }


def signal_changes(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """What changed between two :func:`signal_state`, in words: ``SIGINT's handler:
    default_int_handler -> SIG_IGN``, ``SIGINT newly ignored``, ``SIGTERM no longer
    blocked``."""
    said = [
        f"{name}'s handler: {before[name]} -> {after[name]}"
        for name in WATCHED_SIGNALS
        if before[name] != after[name]
    ]
    for key in ("ignored", "blocked"):
        old, new = (set(state.get(key, "").split()) for state in (before, after))
        said += [f"{name} newly {key}" for name in sorted(new - old)]
        said += [f"{name} no longer {key}" for name in sorted(old - new)]
    return said
