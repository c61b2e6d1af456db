"""A run's ``checkpoint.json``: its state at a communication point, to resume it from
(``auv-cosim run --checkpoint-every SECONDS``, ``--resume OUT``; docs/runs.md).

The file holds ``format``, the ``version`` of auv-cosim that wrote it, the scenario's id
and the SHA-256 of the resolved scenario (``scenario_sha256``: its scenario.toml, the
header comment aside), each instance's FMU file's SHA-256 (``fmus``) and each other file
the run reads, by path (``files``: vehicle sets, event series), ``every_s`` (the
interval asked for, s; null: only where a signal stopped the run), the point it holds
(``step``, ``time`` in s), ``rows`` (the rows of results.csv up to it, t = 0 included)
and ``state`` (:mod:`cosim.engine.checkpoint`: the FMU states and the master's). It is
written whole or not at all: a temporary file, ``fsync``, a rename, the folder synced.

:func:`read_checkpoint` refuses, in one line, a checkpoint that is missing or damaged, of
a run that completed, or one whose scenario, FMUs or auv-cosim version differ from what
would resume it (:meth:`Checkpoint.check`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.engine.checkpoint import from_json, to_json
from cosim.errors import FLAGS, CosimError, OptionNames
from cosim.limits import unwritten
from cosim.outputs.folder import RESULTS_FILE, SUMMARY_FILE, RunFolder
from cosim.outputs.results import read_csv
from cosim.scenario.spec import FILE_SUFFIXES, Scenario
from cosim.version import version
from cosim.whole_file import fresh_file

CHECKPOINT_FILE = "checkpoint.json"
FORMAT = 1


def scenario_digest(scenario: Scenario) -> str:
    """SHA-256 of the resolved scenario (:meth:`Scenario.to_toml`) without its header
    comment, which names the file it was read from: the same run read back from its run
    folder's scenario.toml has the same digest."""
    lines = scenario.to_toml().splitlines(keepends=True)
    body = "".join(lines[next(i for i, s in enumerate(lines) if not s.startswith("#")) :])
    return hashlib.sha256(body.encode("utf-8")).hexdigest()


def fmu_digests(scenario: Scenario) -> dict[str, str]:
    """Each instance's FMU file's SHA-256."""
    return {name: _sha256(inst.fmu_path) for name, inst in scenario.instances.items()}


def read_file_digests(scenario: Scenario) -> dict[str, str]:
    """The SHA-256 of each file the scenario names and a run reads (by absolute path):
    the vehicle sets among the start values and the events' series. scenario.toml names
    them, so its digest stays the same when one of them is edited."""
    paths = [
        Path(value)
        for inst in scenario.instances.values()
        for value in inst.start.values()
        if isinstance(value, str) and value.endswith(FILE_SUFFIXES) and Path(value).is_file()
    ]
    paths += [event.series.path for event in scenario.events if event.series is not None]
    return {str(path): _sha256(path) for path in sorted(set(paths))}


def _sha256(path: Path) -> str:
    sha = hashlib.sha256()
    with open(path, "rb") as file:
        while block := file.read(1 << 20):
            sha.update(block)
    return sha.hexdigest()


@dataclass
class CheckpointWriter:
    """Writes the engine's states into ``folder``'s checkpoint.json (recorded in its
    manifest: a run replacing this one removes it)."""

    folder: RunFolder
    scenario: Scenario
    every_s: float | None

    def __post_init__(self) -> None:
        self.header = {
            "format": FORMAT,
            "version": version(),
            "scenario": self.scenario.id,
            "scenario_sha256": scenario_digest(self.scenario),
            "fmus": fmu_digests(self.scenario),
            "files": read_file_digests(self.scenario),
            "every_s": self.every_s,
        }

    def __call__(self, state: dict[str, Any]) -> None:
        """Write ``state`` (:func:`cosim.engine.checkpoint.capture`'s). Raises
        :class:`CosimError` naming the file."""
        step = int(state["step"])
        data = {**self.header, "step": step, "time": step * self.scenario.coupling.step,
                "rows": int(state["rows"]), "state": to_json(state)}  # fmt: skip
        path = self.folder.path / CHECKPOINT_FILE
        try:
            _write_synced(path, json.dumps(data).encode("utf-8"))
        except OSError as exc:
            raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
        self.folder.wrote(path)


def _write_synced(path: Path, data: bytes) -> None:
    """``data`` into ``path`` whole or not at all, on disk when this returns: a temporary
    file beside it, fsync, rename, fsync of the folder (a reboot right after keeps it)."""
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        fresh_file(tmp)
        with open(tmp, "r+b") as file:
            file.write(data)
            file.flush()
            os.fsync(file.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    with contextlib.suppress(OSError):  # (a folder cannot be opened on Windows)
        fd = os.open(path.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@dataclass
class Checkpoint:
    """A read checkpoint.json (:func:`read_checkpoint`)."""

    path: Path
    data: dict[str, Any]

    @property
    def every_s(self) -> float | None:
        every = self.data.get("every_s")
        return float(every) if isinstance(every, (int, float)) else None

    def check(self, scenario: Scenario) -> None:
        """Refuse (one line) resuming with another scenario, other FMUs or another
        version of auv-cosim than the checkpoint's."""
        if self.data.get("version") != version():
            raise CosimError(
                f"{self.path}: written by auv-cosim {self.data.get('version')}, this is "
                f"{version()}: resume it with that version"
            )
        if self.data.get("scenario_sha256") != scenario_digest(scenario):
            raise CosimError(
                f"{self.path}: the scenario differs from the one checkpointed "
                f"({self.data.get('scenario')!r}): was scenario.toml beside it edited?"
            )
        digests, saved = fmu_digests(scenario), self.data.get("fmus") or {}
        for name, digest in digests.items():
            if saved.get(name) != digest:
                path = scenario.instances[name].fmu_path
                raise CosimError(
                    f"{self.path}: instance {name!r} would load {path}, not the FMU the run "
                    "was checkpointed with (rebuilt since?)"
                )
        saved = self.data.get("files") or {}
        for file, digest in read_file_digests(scenario).items():
            if saved.get(file) != digest:
                raise CosimError(
                    f"{self.path}: {file} is not the file the run was checkpointed with "
                    "(edited since?): resume it with that file as it was"
                )

    def state(self) -> dict[str, Any]:
        """The engine state (:func:`cosim.engine.checkpoint.restore` takes it)."""
        try:
            state = from_json(self.data["state"])
            if not isinstance(state, dict) or state["rows"] != self.data["rows"]:
                raise ValueError("rows")
            return state
        except (KeyError, TypeError, ValueError):
            raise CosimError(f"{self.path}: damaged (its state does not read)") from None

    def rows(self, columns: tuple[str, ...]) -> np.ndarray:
        """The values of results.csv's rows up to the checkpoint ((rows, columns), time
        left out). Raises :class:`CosimError` if results.csv holds fewer or other columns."""
        results = self.path.with_name(RESULTS_FILE)
        try:
            header, table = read_csv(results)
        except (OSError, ValueError) as exc:
            raise CosimError(f"cannot resume from {results}: {exc}") from None
        wanted = int(self.data["rows"])
        if header != ["time", *columns]:
            raise CosimError(f"{results}: its columns are not the scenario's")
        if len(table) < wanted:
            raise CosimError(
                f"{results}: holds {len(table)} rows, the checkpoint needs the first {wanted}"
            )
        return table[:wanted, 1:]


def read_checkpoint(out_dir: Path, names: OptionNames = FLAGS) -> Checkpoint:
    """The checkpoint of the run in ``out_dir``. Raises :class:`CosimError` (one line,
    naming the options as ``names`` does) for a folder without one, a damaged one, or a
    run that completed."""
    path = Path(out_dir) / CHECKPOINT_FILE
    asked = names.given("resume", out_dir)
    try:
        data = json.loads(path.read_bytes())
    except FileNotFoundError:
        raise CosimError(
            f"{asked}: no {CHECKPOINT_FILE} there (run with "
            f"{names.option('checkpoint_every')} SECONDS to write one)"
        ) from None
    except (OSError, ValueError) as exc:
        raise CosimError(f"{path}: cannot read it: {exc}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT or "state" not in data:
        raise CosimError(f"{path}: not a checkpoint of format {FORMAT}")
    with contextlib.suppress(OSError, ValueError):
        summary = json.loads((Path(out_dir) / SUMMARY_FILE).read_bytes())
        if isinstance(summary, dict) and summary.get("complete") is True:
            raise CosimError(f"{asked}: the run there is complete: nothing to resume")
    return Checkpoint(path, data)
