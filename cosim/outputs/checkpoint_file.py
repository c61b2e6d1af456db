"""A run's ``checkpoint.json``: its state at a communication point, to resume it from
(``auv-cosim run --checkpoint-every SECONDS``, ``--resume OUT``; docs/runs.md).

The file holds ``format``, the ``version`` of auv-cosim that wrote it, the scenario's id
and the SHA-256 of the resolved scenario (``scenario_sha256``: its scenario.toml, the
header comment aside), each instance's FMU file's SHA-256 (``fmus``) and each other file
the run reads, by path (``files``: vehicle sets, event series), ``every_s`` (the
interval asked for, s; null: only where a signal stopped the run), ``recording``
(:func:`recording_entry`: the recording the run writes, which a resume writes again
unless told otherwise), the point it holds
(``step``, ``time`` in s), ``rows`` (the rows of results.csv up to it, t = 0 included)
and ``state`` (:mod:`cosim.engine.checkpoint`: the FMU states and the master's). It is
written whole or not at all: a temporary file, ``fsync``, recorded in the run's manifest
(with results.csv as of it), a rename, the folder synced. A run killed between the
manifest's save and the rename leaves the temporary file the manifest records: a resume
renames it into place first (:func:`finish_interrupted_save`); killed before the save, the
folder holds the checkpoint before, which the manifest still records.

:func:`read_checkpoint` refuses, in one line, a checkpoint that is missing or damaged, of
a run that completed, or one whose scenario, FMUs or auv-cosim version differ from what
would resume it (:meth:`Checkpoint.check`).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import math
import os
import stat
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cosim.engine.checkpoint import from_json, to_json
from cosim.errors import FLAGS, CosimError, OptionNames
from cosim.limits import unwritten
from cosim.outputs.folder import RECORDING_FILE, RESULTS_FILE, SUMMARY_FILE, RunFolder
from cosim.outputs.results import CsvRows
from cosim.outputs.run_files import CHECKPOINT_FILE as CHECKPOINT_FILE  # (for its users)
from cosim.outputs.run_files import RunFolderError, read_manifest
from cosim.outputs.tail_guard import file_identity
from cosim.scenario.spec import FILE_SUFFIXES, Scenario
from cosim.version import version
from cosim.whole_file import fresh_file

FORMAT = 1
MAX_BYTES = 256 << 20  # a checkpoint read is refused beyond this size (states are KBs)


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
    manifest with results.csv as of it: a run replacing this one removes it, a resume
    knows results.csv up to it as the run's)."""

    folder: RunFolder
    scenario: Scenario
    every_s: float | None
    recording: Path | None = None  # the recording the run writes (None: none)

    def __post_init__(self) -> None:
        self.header = {
            "recording": recording_entry(self.recording, self.folder.path),
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
            tmp = _written_beside(path, json.dumps(data).encode("utf-8"))
        except OSError as exc:
            raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
        try:  # recorded before it is in place: no kill leaves it there unrecorded
            self.folder.checkpointed(path, data["rows"], content=tmp)
            _renamed_synced(tmp, path)
        except OSError as exc:
            raise CosimError(f"cannot write {path}: {unwritten(exc)}") from None
        finally:
            tmp.unlink(missing_ok=True)  # (gone once renamed)


def recording_entry(rrd: Path | None, folder: Path) -> str | None:
    """The checkpoint's ``recording``: null (the run writes none), the folder's own
    ``recording.rrd`` by that name (a copied folder resumes into its own), or the absolute
    path of a recording written elsewhere (``--rrd``)."""
    if rrd is None:
        return None
    if Path(rrd).absolute() == (folder / RECORDING_FILE).absolute():
        return RECORDING_FILE
    return str(Path(rrd).absolute())


def _pending(path: Path, pid: int) -> Path:
    """The temporary file process ``pid`` writes ``path`` into before renaming it."""
    return path.with_name(f".{path.name}.{pid}.tmp")


def _written_beside(path: Path, data: bytes) -> Path:
    """``data`` in a new temporary file beside ``path`` (:func:`_pending`), on disk when
    this returns (fsync), to be renamed into place by :func:`_renamed_synced`."""
    tmp = _pending(path, os.getpid())
    try:
        fresh_file(tmp)
        with open(tmp, "r+b") as file:
            file.write(data)
            file.flush()
            os.fsync(file.fileno())
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp


def _renamed_synced(tmp: Path, path: Path) -> None:
    """``tmp`` renamed to ``path``, then the folder synced (a reboot right after keeps
    the rename)."""
    os.replace(tmp, path)
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
        """The interval it was written with (s; None: only where a signal stopped the run).
        Raises :class:`CosimError` for one that is not a positive finite number."""
        every = self.data.get("every_s")
        if every is None:
            return None
        if isinstance(every, (int, float)) and not isinstance(every, bool):
            with contextlib.suppress(OverflowError):  # an int beyond any double
                if math.isfinite(every) and every > 0:
                    return float(every)
        raise CosimError(
            f"{self.path}: every_s is {_shown(every)}, expected a positive number of seconds"
        )

    @property
    def keeps_recording(self) -> bool:
        """Whether it says which recording the run wrote (a checkpoint of an auv-cosim
        that did not keep it: a resume records as the scenario says)."""
        return "recording" in self.data

    def recording(self) -> Path | None:
        """The recording the checkpointed run wrote (None: none), where a resume without
        ``--rrd`` or ``--no-rrd`` writes it again. Raises :class:`CosimError` for a
        ``recording`` that is neither null nor a path (the folder's ``recording.rrd`` or
        an absolute one)."""
        entry = self.data.get("recording")
        if entry is None:
            return None
        if entry == RECORDING_FILE:
            return self.path.with_name(RECORDING_FILE)
        if (
            isinstance(entry, str) and "\0" not in entry and entry.endswith(".rrd")
            and Path(entry).is_absolute()
        ):  # fmt: skip
            return Path(entry)  # (a new file, or a recording of ours: check_recording_path)
        raise CosimError(
            f"{self.path}: recording is {_shown(entry)}, expected null, "
            f'"{RECORDING_FILE}" or an absolute path to a .rrd file'
        )

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
        digests, saved = fmu_digests(scenario), self.data.get("fmus")
        if not isinstance(saved, dict):
            raise CosimError(f"{self.path}: fmus is {_shown(saved)}, expected a table of SHA-256s")
        for name, digest in digests.items():
            if saved.get(name) != digest:
                path = scenario.instances[name].fmu_path
                raise CosimError(
                    f"{self.path}: instance {name!r} would load {path}, not the FMU the run "
                    "was checkpointed with (rebuilt since?)"
                )
        saved = self.data.get("files", {})
        if not isinstance(saved, dict):
            raise CosimError(f"{self.path}: files is {_shown(saved)}, expected a table of SHA-256s")
        for file, digest in read_file_digests(scenario).items():
            if saved.get(file) != digest:
                raise CosimError(
                    f"{self.path}: {file} is not the file the run was checkpointed with "
                    "(edited since?): resume it with that file as it was"
                )

    def state(self, scenario: Scenario) -> dict[str, Any]:
        """The engine state (:func:`cosim.engine.checkpoint.restore` takes it). Raises
        :class:`CosimError` for one that does not read, or whose point is not one of
        ``scenario``'s before its stop (``step`` a whole number, 0 <= step <= its steps,
        ``rows`` = step + 1)."""
        try:
            state = from_json(self.data["state"])
        except (KeyError, TypeError, ValueError, RecursionError):
            raise CosimError(f"{self.path}: damaged (its state does not read)") from None
        if not isinstance(state, dict):
            raise CosimError(f"{self.path}: damaged (its state is not a table)")
        step, rows = state.get("step"), state.get("rows")
        if type(step) is not int or not 0 <= step <= scenario.n_steps:
            raise CosimError(
                f"{self.path}: step is {_shown(step)}, expected a whole number from 0 to "
                f"{scenario.n_steps} (the run's points up to its stop)"
            )
        if type(rows) is not int or rows != step + 1 or self.data.get("rows") != rows:
            raise CosimError(
                f"{self.path}: rows is {_shown(self.data.get('rows'))} (its state says "
                f"{_shown(rows)}), expected step + 1 = {step + 1}"
            )
        return state

    def rows(self, columns: tuple[str, ...]) -> SavedRows:
        """The rows of results.csv up to the checkpoint, read a chunk at a time as they
        are replayed (time left out). Raises :class:`CosimError` if results.csv holds fewer
        or other columns."""
        results = self.path.with_name(RESULTS_FILE)
        wanted = int(self.data["rows"])
        try:
            rows = CsvRows(results, wanted)
        except (OSError, ValueError) as exc:
            raise CosimError(f"cannot resume from {results}: {exc}") from None
        if rows.columns != ["time", *columns]:
            rows.close()
            raise CosimError(f"{results}: its columns are not the scenario's")
        if rows.available < wanted:
            rows.close()
            raise CosimError(
                f"{results}: holds {rows.available} rows, the checkpoint needs the first {wanted}"
            )
        return SavedRows(rows)


class SavedRows:
    """:class:`cosim.engine.checkpoint.SavedRows` from a results.csv: its rows up to the
    checkpoint, time left out."""

    def __init__(self, rows: CsvRows) -> None:
        self._rows = rows
        self.last = None if rows.last is None else rows.last[1:]

    def chunks(self) -> Iterator[np.ndarray]:
        try:
            for chunk in self._rows.chunks():
                yield chunk[:, 1:]
        except (OSError, ValueError) as exc:
            raise CosimError(f"cannot resume from {self._rows.path}: {exc}") from None

    def close(self) -> None:
        self._rows.close()


def finish_interrupted_save(out_dir: Path) -> None:
    """Rename into place the checkpoint a run killed between its manifest's save and the
    rename left in its temporary file (:class:`CheckpointWriter`): the one the manifest
    records, by size and SHA-256, while checkpoint.json is not. Nothing else is touched:
    not while that run may still be alive (its process), nor a file the manifest does not
    record (a kill before the save: checkpoint.json is the checkpoint before)."""
    path = Path(out_dir) / CHECKPOINT_FILE
    try:
        manifest = read_manifest(Path(out_dir))
    except RunFolderError:
        return  # (the resume's own checks say what is wrong with the folder)
    recorded = manifest.entries.get(CHECKPOINT_FILE)
    tmp = _pending(path, manifest.pid)
    if recorded is None or not os.path.isfile(tmp) or os.path.islink(tmp):
        return
    if _alive(manifest.pid) or _content(path) == _content_of(recorded):
        return
    if _content(tmp) == _content_of(recorded):
        _renamed_synced(tmp, path)


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs (as this user may see: ``kill(pid, 0)``)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's process: alive
        return True
    return pid != 0


def _content(path: Path) -> tuple[Any, Any] | None:
    """(size, SHA-256) of the regular file at ``path``, None if none."""
    identity = file_identity(path)
    return None if identity is None else _content_of(identity)


def _content_of(identity: dict[str, Any]) -> tuple[Any, Any]:
    return identity.get("size"), identity.get("sha256")


def read_checkpoint(out_dir: Path, names: OptionNames = FLAGS) -> Checkpoint:
    """The checkpoint of the run in ``out_dir`` (one a kill left unrenamed put in place
    first: :func:`finish_interrupted_save`). Raises :class:`CosimError` (one line,
    naming the options as ``names`` does) for a folder without one, a damaged one, or a
    run that completed."""
    with contextlib.suppress(OSError):  # (then refused as it is, below)
        finish_interrupted_save(Path(out_dir))
    path = Path(out_dir) / CHECKPOINT_FILE
    asked = names.given("resume", out_dir)
    if not os.path.lexists(path):
        raise CosimError(
            f"{asked}: no {CHECKPOINT_FILE} there (run with "
            f"{names.takes('checkpoint_every', 'SECONDS')} to write one)"
        )
    try:
        data = json.loads(_read_regular(path))
    except (OSError, ValueError, RecursionError) as exc:
        raise CosimError(f"{path}: cannot read it: {_reason(exc)}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT or "state" not in data:
        raise CosimError(f"{path}: not a checkpoint of format {FORMAT}")
    with contextlib.suppress(OSError, ValueError, RecursionError):
        summary = json.loads(_read_regular(Path(out_dir) / SUMMARY_FILE))
        if isinstance(summary, dict) and summary.get("complete") is True:
            raise CosimError(f"{asked}: the run there is complete: nothing to resume")
    return Checkpoint(path, data)


def _read_regular(path: Path) -> bytes:
    """The bytes of the regular file ``path``, read without following a link, without
    waiting on a FIFO and without reading a device or a file beyond :data:`MAX_BYTES`
    (OSError saying which)."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except OSError as exc:
        if os.path.islink(path):  # ELOOP from O_NOFOLLOW
            raise OSError("it is a link, not a file a run wrote") from None
        raise OSError(exc.strerror or str(exc)) from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise OSError("it is not a regular file (a folder, a FIFO or a device)")
        if info.st_size > MAX_BYTES:
            raise OSError(f"it holds {info.st_size} bytes, more than any checkpoint ({MAX_BYTES})")
        with os.fdopen(os.dup(fd), "rb") as file:
            return file.read(MAX_BYTES + 1)
    finally:
        os.close(fd)


def _reason(exc: BaseException) -> str:
    """Why a checkpoint did not read, in one line."""
    if isinstance(exc, RecursionError):
        return "nested too deep to be a checkpoint"
    return str(exc.args[0]) if isinstance(exc, OSError) and len(exc.args) == 1 else str(exc)


def _shown(value: Any) -> str:
    """``value`` as a checkpoint's JSON would show it, cut short."""
    try:
        text = json.dumps(value)
    except (TypeError, ValueError):
        text = type(value).__name__
    return text if len(text) <= 40 else text[:37] + "..."
