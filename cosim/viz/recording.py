"""Rerun recordings of a run: the sink the master feeds, and ``auv-cosim view``.

The master hands over rows of results (``add_rows``, a few hundred steps at a time); the
sink buffers them (a second of wall time or 2,000 rows at most) and sends each group of
signals as columns (``send_columns``) on the ``sim_time`` timeline (a duration, s), then
flushes the file, so a killed run leaves a recording readable up to its last flush (it
lacks only the footer ``rerun rrd verify`` asks for; ``rerun rrd migrate`` adds one). A
file that cannot be written (disk full) raises ``OSError`` at the next send, which ends
the run. One ``rr.log`` per signal per step would cost 30-60x more
(``scripts/bench_recording.py``), so there are none. What the recording shows is laid out
in :mod:`cosim.viz.layout` (plots, colours, blueprint) and :mod:`cosim.viz.scene` (the 3D
scene). Each sink owns its own ``rr.RecordingStream`` (two with a file and a viewer: see
``VIEWER_SEND_INTERVAL``), so several runs in one process never mix.

The file gets the default blueprint (``set_sinks(..., default_blueprint=...)``), the
scenario id as a property and, with where the file is (:func:`recording_name`), as the
recording's name, the versions of what ran it and each instance's FMU GUID as properties
(``versions``, ``fmu_guids``, as summary.json records them), and the resolved scenario
TOML as a static text document at ``/scenario``; a scenario with a waypoint guidance gets its
planned path and waypoints in the 3D scene (:func:`cosim.viz.mission.mission_waypoints`),
and an events entry whenever the recorded waypoint it steers for changes.
What the 3D scene needs to know about the run -- the vehicle parameter set, whether depth
control is on -- is read from the :class:`~cosim.scenario.spec.Scenario` itself.
"""

from __future__ import annotations

import contextlib
import errno
import math
import os
import re
import shlex
import shutil
import socket
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
import rerun as rr

from cosim.engine.rows import RUN_INCOMPLETE
from cosim.errors import CosimError
from cosim.limits import FILE_SIZE_LIMIT, unwritten
from cosim.outputs.folder import RECORDING_FILE
from cosim.outputs.missing_run import missing_run_hint
from cosim.outputs.results import column_units, versions
from cosim.paths import path_text
from cosim.scenario.spec import Scenario
from cosim.viz.display_units import on_turn_of
from cosim.viz.fleet import drawn_roots, pairs
from cosim.viz.layout import (
    NOTES_ENTITY,
    PlannedPanel,
    build_blueprint,
    plan_panels,
    series_sources,
    series_style,
    time_index,
)
from cosim.viz.mission import mission_waypoints
from cosim.viz.ports import FILE_PORT, WEB_PORT
from cosim.viz.rrd_file import (
    OVERLAY_FILE,
    STUDY_FILE,
    RrdFile,
    drop_closed_streams,
    file_sink,
    pumped,
    set_sinks,
)
from cosim.viz.scene import (
    TARGET_COLUMNS,
    SceneVehicle,
    SceneWriter,
    log_static_scene,
    scene_legend,
)
from cosim.viz.viewer_version import version_problem
from cosim.viz.web_viewer import ended, serve
from plant_fmu.model.parameters import VehicleParameterError, VehicleParameters, load_vehicle

APPLICATION_ID = "auv-cosim"
RRD_MAGIC = b"RRF"  # the first bytes of an .rrd file (RRF2 in rerun 0.41)
# then the writer's version (4 bytes) and its encoding options (4 bytes): the compression
# (0 none, 1 LZ4), the serializer (1 MessagePack, 2 Protobuf) and two zero bytes
RRD_HEADER_BYTES = 12
_COMPRESSIONS, _SERIALIZERS = (0, 1), (1, 2)
# Each send costs ~25 send_columns calls of ~70 us whatever their length, and each send to
# a file leaves ~100 kB in memory until the file is closed (measured on vert-2: the chunk
# index of rerun-sdk 0.41's file footer), so rows are buffered: sent once BATCH_BYTES of
# them have gathered (times and values as float64: ~1.2 MB of bs-3's file, 1,800 rows), or
# once the send interval has passed since the last send. A file that fails (a full disk)
# is cut back to its last send's flush, so a fast run loses at most the last BATCH_BYTES of
# rows: with sends every 5,000 rows (~3.2 MB of bs-3's file), ``auv-cosim run bs-3
# --stop-time 120`` under ``ulimit -f 3072`` kept 183 KB of its recording (no row), 2.7 MB
# now; the sink's share of that run (scripts/bench_recording.py --rows 12000, (c)) is the
# same within its noise. Sending at every hand-off of rows would cost a send per 200 rows,
# nine times as many as now. For the file that is
# FILE_SEND_INTERVAL, and SEND_INTERVAL_GROWTH of the time the sink has been open once that
# is longer, so the sends of a long run grow with the logarithm of its duration, and the
# memory with them, not in proportion (scripts/bench_memory.py). A viewer (``--connect``)
# is fed by a stream of its own every VIEWER_SEND_INTERVAL however long the run has gone on
# (a gRPC sink keeps no index): it sees the run advance about once a second (in one stream
# with the file it lagged 12 s behind a live run after 10 minutes, 50 s after 45). A sink
# fed from a thread (cosim.outputs.background) also sends what is due when no rows come
# (:meth:`RerunSink.send_due`), so a paused run shows where it paused.
BATCH_BYTES = 512 * 1024  # of rows gathered, as float64 times and values
VIEWER_SEND_INTERVAL = 1.0  # s of wall-clock time
FILE_SEND_INTERVAL = 5.0  # s of wall-clock time
SEND_INTERVAL_GROWTH = 0.02
FLUSH_TIMEOUT = 10.0  # s to wait for a viewer to take the last rows on close


def recording_name(scenario_id: str, rrd_path: Path | None) -> str:
    """The name the viewer lists a recording by: the scenario's id, and where the file is
    when that is not the scenario's own run folder (``runs/<id>/recording.rrd``): its
    folder's name (``bs-3 (bs-3-coarse)``, a run with ``--out``) or, for a file not named
    ``recording.rrd`` (``--rrd``), its own name; so two runs of one scenario opened side
    by side are told apart."""
    if rrd_path is None:
        return scenario_id
    where = rrd_path.parent.name if rrd_path.name == RECORDING_FILE else rrd_path.name
    return scenario_id if where in ("", scenario_id) else f"{scenario_id} ({path_text(where)})"


def _disconnect_all(channels: list[_Channel]) -> None:
    """Disconnect each channel's stream from its sinks."""
    for channel in channels:
        channel.rec.disconnect()


def note_level(text: str) -> rr.TextLogLevel:
    """The log level a note is shown with: ERROR for the end of a run that did not
    complete (:data:`cosim.engine.rows.RUN_INCOMPLETE`), INFO for anything else."""
    return rr.TextLogLevel.ERROR if text.startswith(RUN_INCOMPLETE) else rr.TextLogLevel.INFO


class RerunSink:
    """Stream a run's results to a ``.rrd`` file and/or a running Rerun viewer.

    Args:
        scenario: the resolved scenario: its id names the recording, its TOML is stored as
            text, its ``vehicle`` start value (or the FMU's default) picks the geometry of
            the 3D body and its ``depth_mode`` whether the depth setpoint is drawn; its
            ``columns`` are those of the value rows given to :meth:`add_rows`
            (``plant.yaw``, ...; any may be missing).
        rrd_path: the recording file to write (its folder is created), or None.
        connect_url: a viewer's gRPC URL (``rerun+http://127.0.0.1:9876/proxy``), or None.
        on_flushed: called with the file's size each time everything sent is in the file
            (a message boundary; the run folder's tail guard cuts a killed run's file there).

    Raises:
        ValueError: neither a file nor a URL, duplicate columns, a malformed URL or no
            viewer listening there.
        OSError: the file cannot be created.
    """

    def __init__(
        self,
        scenario: Scenario,
        rrd_path: Path | None = None,
        connect_url: str | None = None,
        on_flushed: Callable[[int], None] | None = None,
    ) -> None:
        if rrd_path is None and connect_url is None:
            raise ValueError("RerunSink needs an rrd_path, a connect_url or both; got neither")
        columns = list(scenario.columns)
        if len(set(columns)) != len(columns):
            duplicates = sorted({c for c in columns if columns.count(c) > 1})
            raise ValueError(f"recorded columns must be unique, got duplicates {duplicates}")
        self._columns = list(columns)
        self._index = {name: i for i, name in enumerate(columns)}
        fleet = pairs(scenario.key_vehicles)
        self._panels = plan_panels(self._columns, column_units(scenario), fleet)
        self._closed = False
        self._opened = time.monotonic()
        self._rrd_path = None if rrd_path is None else Path(rrd_path)
        self._on_flushed = on_flushed
        self._file: RrdFile | None = None
        self._viewer_warned = False
        self._channels: list[_Channel] = []

        self._drawn = drawn_vehicles(scenario)
        first = self._drawn[0].vehicle if self._drawn else None
        self._vehicle = first or _vehicle_of(scenario, scenario.key_instances["plant"])
        depth_control = _depth_control(scenario, SceneVehicle(*_first_roles(scenario)))
        roots = [drawn.who.root for drawn in self._drawn]
        blueprint = build_blueprint(self._panels, depth_control=depth_control, roots=roots)

        viewer = None if connect_url is None else _viewer_sink(connect_url)
        try:
            if viewer is not None:
                self._add_channel(viewer, blueprint, VIEWER_SEND_INTERVAL, None)
            if self._rrd_path is not None:
                file = self._open_file(self._rrd_path)
                growth = SEND_INTERVAL_GROWTH
                self._add_channel(file, blueprint, FILE_SEND_INTERVAL, growth)
            for channel in self._channels:
                self._log_static(channel, scenario)
            self._flush(self._channels)  # the static part is on disk before the first step
        except BaseException:
            with contextlib.suppress(OSError):  # the first failure is the one to report
                self._disconnect()
            raise

    def _add_channel(
        self, sink: Any, blueprint: Any, interval: float, growth: float | None
    ) -> None:
        """A stream of its own to ``sink``, sending every ``interval`` s (and ``growth`` of
        the sink's age, if given); every stream of the sink has the first one's recording id
        (the file and the viewer show one recording)."""
        same = self._channels[0].rec.get_recording_id() if self._channels else None
        rec = rr.RecordingStream(APPLICATION_ID, recording_id=same)
        self._channels.append(_Channel(rec, interval, growth, self._opened))
        try:
            set_sinks(rec, APPLICATION_ID, sink, blueprint)
        except RuntimeError as exc:  # rerun-sdk's error for a file it cannot create
            raise OSError(f"cannot write the recording {self._rrd_path}: {exc}") from None

    def _open_file(self, path: Path) -> Any:
        """The sink writing ``path`` (through :class:`RrdFile` where possible)."""
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            if not pumped():
                return file_sink(path)
            self._file = RrdFile(path)
        except OSError as exc:
            raise OSError(f"cannot write the recording {path}: {exc.strerror or exc}") from None
        return self._file.sink()

    def _log_static(self, channel: _Channel, scenario: Scenario) -> None:
        """The recording's name and properties, the scenario text, styles and the scene."""
        scenario_id, columns, toml = scenario.id, self._columns, scenario.to_toml()
        vehicle = self._vehicle
        rec = channel.rec
        rec.send_recording_name(recording_name(scenario_id, self._rrd_path))
        rec.send_property(
            "scenario", rr.AnyValues(id=scenario_id, vehicle=vehicle.name, columns=len(columns))
        )
        # what ran it, as summary.json records it: a recording alone traces to its release
        known = {name: value for name, value in versions().items() if value is not None}
        rec.send_property("versions", rr.AnyValues(drop_untyped_nones=True, **known))
        guids = {name: inst.interface.guid for name, inst in scenario.instances.items()}
        rec.send_property("fmu_guids", rr.AnyValues(drop_untyped_nones=True, **guids))
        rec.log(
            "scenario",
            rr.TextDocument(
                f"# Scenario `{scenario_id}`\n\n{scene_legend()}\n"
                f"## Resolved scenario\n\n```toml\n{toml}\n```\n",
                media_type=rr.MediaType.MARKDOWN,
            ),
            static=True,
        )
        for panel in self._panels:
            rec.log(panel.entity, series_style(panel), series_sources(panel), static=True)
        waypoints = mission_waypoints(toml)  # None without a waypoint guidance
        for k, drawn in enumerate(self._drawn):  # the earth frame and mission once, first
            who, depth = drawn.who, drawn.depth
            log_static_scene(
                rec, drawn.vehicle, who.canonical(columns), show_depth_setpoint=depth,
                waypoints=waypoints, root=who.root, world=k == 0,
            )  # fmt: skip
            writer = SceneWriter(
                rec, drawn.vehicle, show_depth_setpoint=depth, root=who.root, target=k == 0
            )
            channel.scenes.append((writer, who))

    def add_rows(self, times: np.ndarray, values: np.ndarray) -> None:
        """Queue k rows: ``times`` (k,) in s, ``values`` (k, len(columns)) in SI units.

        Rows are sent once ``BATCH_BYTES`` of them have gathered or the send interval has passed
        since the last send (see ``BATCH_BYTES``), and the rest on :meth:`close`.
        """
        if self._closed:
            raise ValueError("add_rows on a closed RerunSink")
        times = np.asarray(times, dtype=float)
        values = np.asarray(values, dtype=float)
        if times.ndim != 1 or values.shape != (len(times), len(self._columns)):
            raise ValueError(
                f"expected times of shape (k,) and values of shape (k, {len(self._columns)}), "
                f"got {times.shape} and {values.shape}"
            )
        if len(times) == 0:
            return
        times, values = times.copy(), values.copy()
        for channel in self._channels:
            channel.times.append(times)
            channel.values.append(values)
            channel.rows += len(times)
        self.send_due()

    def send_due(self) -> None:
        """Send the rows of every stream whose send is due (see ``BATCH_BYTES``); what a
        sink fed from a thread calls when no rows have come for a while."""
        if self._closed:
            return
        now = time.monotonic()
        due = [channel for channel in self._channels if channel.due(now)]
        for channel in due:
            self._send_pending(channel)
            channel.last_send = now
        if due:
            self._flush(due)

    def add_notes(self, notes: Sequence[tuple[float, str]]) -> None:
        """Log what happened at a time -- an event fired, a fault started or stopped
        (:mod:`cosim.engine.timeline`), how the run ended -- as ``rr.TextLog`` entries under
        :data:`NOTES_ENTITY` at their ``sim_time`` (s), at the level :func:`note_level`
        gives; the master hands them over before the rows they precede."""
        if self._closed:
            raise ValueError("add_notes on a closed RerunSink")
        if not notes:
            return
        times = np.asarray([t for t, _ in notes], dtype=float)
        texts = [text for _, text in notes]
        levels = [note_level(text) for text in texts]
        columns = rr.TextLog.columns(text=texts, level=levels)
        for channel in self._channels:
            channel.rec.send_columns(NOTES_ENTITY, indexes=time_index(times), columns=columns)

    def close(self) -> None:
        """Send what is queued, flush and close the file; safe to call twice.

        Raises OSError if the file could not be completed (disk full). A viewer that went
        away during the run does not make this raise: it warns.
        """
        if self._closed:
            return
        self._closed = True
        try:
            self._send_all_pending()
            self._flush(self._channels)
        finally:
            self._disconnect()

    def _send_all_pending(self) -> None:
        """Send what every channel has queued (a helper, so that no loop variable of
        :meth:`close` holds a stream past :meth:`_disconnect`)."""
        for channel in self._channels:
            self._send_pending(channel)

    def _disconnect(self) -> None:
        """Let go of the sinks (rerun writes the file's footer) and of the streams (their
        threads end), then close the file; raises OSError if the file failed."""
        channels, self._channels = self._channels, []
        viewer = any(not channel.is_file for channel in channels)
        _disconnect_all(channels)
        del channels
        try:
            drop_closed_streams()
        except RuntimeError as exc:
            # a stream flushed to a viewer gone away: this sink's, or another sink's let go
            # of (a run's viewer sink beside its file's, whose own flush warned); a file's
            # failure is its writer's, raised by its close below
            if viewer:
                self._viewer_gone(exc)
        if self._file is not None:
            file, self._file = self._file, None
            file.close(timeout=FLUSH_TIMEOUT)

    def _flush(self, channels: Sequence[_Channel]) -> None:
        """Wait until what was sent to ``channels`` is written; a file that failed raises
        OSError."""
        for channel in channels:
            try:
                channel.rec.flush(timeout_sec=FLUSH_TIMEOUT)
            except RuntimeError as exc:  # the bindings' error for a sink that failed
                if channel.is_file and self._rrd_path is not None and self._file is None:
                    raise OSError(_write_failure(self._rrd_path, exc)) from None  # rerun's writer
                self._viewer_gone(exc)
        if self._file is not None and any(channel.is_file for channel in channels):
            try:
                size = self._file.sync(FLUSH_TIMEOUT)
            except OSError as exc:
                raise OSError(_with_free_space(str(exc), self._file.path)) from None
            if self._on_flushed is not None:
                self._on_flushed(size)

    def _viewer_gone(self, exc: RuntimeError) -> None:
        """Warn, once, that the viewer went away: the run and its file go on without it."""
        if not self._viewer_warned:
            self._viewer_warned = True
            warnings.warn(f"Rerun viewer: {exc}", stacklevel=5)

    def __enter__(self) -> RerunSink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _send_pending(self, channel: _Channel) -> None:
        if not channel.rows:
            return
        times = np.concatenate(channel.times)
        values = np.concatenate(channel.values)
        channel.times.clear()
        channel.values.clear()
        channel.rows = 0
        index = time_index(times)
        for panel in self._panels:
            with np.errstate(over="ignore"):  # 1e308 rad set live, in deg: shown as inf
                shown = _on_turns(values, panel, self._index) * np.asarray(panel.scales)
            channel.rec.send_columns(
                panel.entity, indexes=index, columns=rr.Scalars.columns(scalars=shown)
            )

        def column(name: str) -> np.ndarray | None:
            i = self._index.get(name)
            return None if i is None else values[:, i]

        for writer, who in channel.scenes:
            writer.send(index, len(times), who.columns(column))
        self._mark_targets(channel, times, column)

    def _mark_targets(
        self, channel: _Channel, times: np.ndarray, column: Callable[[str], np.ndarray | None]
    ) -> None:
        """An events entry at each row (times in s) where the waypoint a guidance steers for
        (:data:`cosim.viz.scene.TARGET_COLUMNS`, m) changes, the run's first row included:
        the guidance switches the set-points inside its FMU, where no event marks it."""
        parts = [part for name in TARGET_COLUMNS if (part := column(name)) is not None]
        if len(parts) < len(TARGET_COLUMNS):
            return
        points = np.column_stack(parts)
        before = np.vstack([points[:1] if channel.target is None else channel.target, points[:-1]])
        changed = np.any(points != before, axis=1)
        changed[0] |= channel.target is None
        channel.target = points[-1:].copy()
        rows = np.flatnonzero(changed)
        if len(rows) == 0:
            return
        texts = [
            f"guidance steers for the waypoint north {n:g} m, east {e:g} m, down {d:g} m"
            for n, e, d in points[rows]
        ]
        channel.rec.send_columns(
            NOTES_ENTITY,
            indexes=time_index(times[rows]),
            columns=rr.TextLog.columns(text=texts, level=[rr.TextLogLevel.INFO] * len(texts)),
        )


@dataclass
class _Channel:
    """One recording stream of a sink (to the file, or to a viewer) and its unsent rows."""

    rec: rr.RecordingStream
    interval: float  # s of wall-clock time between sends
    growth: float | None  # the fraction of the sink's age the interval grows to (a file)
    opened: float  # time.monotonic() when the sink opened
    last_send: float = field(init=False)
    scenes: list[tuple[SceneWriter, SceneVehicle]] = field(default_factory=list)
    target: np.ndarray | None = None  # (1, 3) the last row's guidance waypoint, m
    times: list[np.ndarray] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    rows: int = 0

    def __post_init__(self) -> None:
        self.last_send = self.opened

    @property
    def is_file(self) -> bool:
        return self.growth is not None

    def due(self, now: float) -> bool:
        """Whether the rows gathered are to be sent at ``now``."""
        if not self.rows:
            return False
        interval = self.interval
        if self.growth is not None:
            interval = max(interval, self.growth * (now - self.opened))
        gathered = self.rows * (1 + self.values[-1].shape[1]) * 8  # bytes: times, values
        return gathered >= BATCH_BYTES or now - self.last_send >= interval


def _viewer_sink(url: str) -> rr.GrpcSink:
    """A sink streaming to the viewer at ``url``, checked to be listening now.

    Without the check a run streaming to no viewer would retry for ~10 s at its end and
    lose the stream silently; better to refuse before the run starts.
    """
    try:
        sink = rr.GrpcSink(url)
    except RuntimeError as exc:  # rerun-sdk's error for a malformed URL
        raise ValueError(
            f"--connect URL {url!r}: {exc}; expected rerun+http://HOST:PORT/proxy (`rerun` "
            "listens on rerun+http://127.0.0.1:9876/proxy)"
        ) from None
    parts = urlsplit(url)
    if parts.hostname and parts.port:
        try:
            answers = _answers_http2(parts.hostname, parts.port)
        except OSError as exc:
            raise ValueError(
                f"no Rerun viewer listens at {url} ({exc.strerror or exc}): start one with "
                f"`rerun` (it listens on rerun+http://127.0.0.1:9876/proxy) or drop --connect"
            ) from None
        if not answers:
            raise ValueError(
                f"something listens at {url} but does not answer as a Rerun viewer (gRPC) "
                f"within {VIEWER_ANSWER_S:g} s: rerun-sdk would wait for it for ever, deaf "
                "to Ctrl-C; check the port, or drop --connect"
            )
    return sink


VIEWER_ANSWER_S = 2.0  # s a viewer has to answer the connection's first bytes
# the magic line, then an empty SETTINGS frame: length 0 (3 bytes), type 4, flags 0,
# stream 0 (4 bytes)
_HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + b"\x00\x00\x00" + b"\x04\x00" + bytes(4)


def _answers_http2(host: str, port: int) -> bool:
    """Whether the server at ``host:port`` speaks HTTP/2, as a Rerun viewer's gRPC server
    does: to the client's connection preface (RFC 9113, section 3.4: the magic line and
    an empty SETTINGS frame) it answers with a SETTINGS frame (type 4) of its own. Written
    by hand: a TCP connect alone passes any listener, and rerun-sdk's sink then blocks
    the run, signals included, on one that never answers. Raises OSError if nothing
    listens."""
    with socket.create_connection((host, port), timeout=VIEWER_ANSWER_S) as connection:
        connection.sendall(_HTTP2_PREFACE)
        header = b""
        try:
            while len(header) < 4:
                chunk = connection.recv(9 - len(header))
                if not chunk:
                    return False
                header += chunk
        except TimeoutError:
            return False
    return header[3] == 4


def _on_turns(values: np.ndarray, panel: PlannedPanel, index: dict[str, int]) -> np.ndarray:
    """The rows' columns of ``panel`` (SI), each angle that names a column to follow
    (``Series.turn_of``, when recorded) moved by whole turns to within half a turn of it."""
    columns = values[:, panel.indices]
    for j, series in enumerate(panel.series):
        reference = index.get(series.turn_of) if series.turn_of else None
        if reference is not None:
            columns[:, j] = on_turn_of(columns[:, j], values[:, reference], 2.0 * math.pi)
    return columns


@dataclass(frozen=True)
class DrawnVehicle:
    """A vehicle of the 3D scene: its instances and entity (``who``), its parameter set
    (the geometry) and whether its depth set-point is drawn (``depth``)."""

    who: SceneVehicle
    vehicle: VehicleParameters
    depth: bool


def drawn_vehicles(scenario: Scenario) -> list[DrawnVehicle]:
    """The vehicles the 3D scene draws: each plant the key figures describe
    (``Scenario.key_vehicles``) with a recorded column, with the autopilot joined to it;
    one vehicle's shapes under ``world`` (its entities as :mod:`cosim.viz.scene` lists
    them, whatever its instances are named), each of several under ``world/<plant>``
    (:func:`cosim.viz.fleet.drawn_roots`). A plant without a recorded column is not drawn (no
    hull standing at the origin)."""
    found = []
    for vehicle, root in drawn_roots(scenario.key_vehicles, scenario.columns):
        plant = vehicle.roles["plant"]
        who = SceneVehicle(plant, vehicle.roles["controller"], root)
        found.append(DrawnVehicle(who, _vehicle_of(scenario, plant), _depth_control(scenario, who)))
    return found


def _first_roles(scenario: Scenario) -> tuple[str, str]:
    """The plant and autopilot of a run's one vehicle: the instances the key figures read
    (``Scenario.key_instances``: by model, else named plant and controller)."""
    roles = scenario.key_instances
    return roles["plant"], roles["controller"]


def _depth_control(scenario: Scenario, who: SceneVehicle) -> bool:
    """Whether the vehicle's depth set-point is drawn: its autopilot's depth set-point and
    its plant's depth are recorded, and its ``depth_mode`` (if it has one) is not off."""
    columns = set(scenario.columns)
    has_depth = who.column("controller.depth_setpoint") in columns and (
        who.column("plant.down") in columns
    )
    depth_mode = _first_value(scenario, "depth_mode", prefer=who.controller)
    return has_depth if not isinstance(depth_mode, int) else depth_mode != 0 and has_depth


def _vehicle_of(scenario: Scenario, plant: str) -> VehicleParameters:
    """The vehicle (for the 3D geometry): the ``vehicle`` parameter of instance ``plant``
    (else of the first instance that has one), as set or by the FMU's default; remus100
    with a warning if it cannot be loaded, or without one if no instance has that
    parameter."""
    vehicle_of = _first_value(scenario, "vehicle", prefer=plant)
    name = vehicle_of if isinstance(vehicle_of, str) else "remus100"
    try:
        return load_vehicle(name)
    except (VehicleParameterError, OSError) as exc:
        warnings.warn(f"vehicle {name!r} not loadable ({exc}); drawing remus100", stacklevel=4)
        return load_vehicle("remus100")


def _first_value(scenario: Scenario, variable: str, prefer: str) -> Any:
    """``variable``'s start value in instance ``prefer``, else in the first that has it."""
    names = sorted(scenario.instances, key=lambda name: name != prefer)
    for name in names:
        value = scenario.start_value(name, variable)
        if value is not None:
            return value
    return None


def _write_failure(path: Path, exc: Exception) -> str:
    """The reason rerun's own file writer failed, with the free space of its disk, or
    the file-size limit that stopped it (:func:`cosim.limits.unwritten`)."""
    if isinstance(exc, OSError) and exc.errno == errno.EFBIG:
        return f"cannot write the recording {path}: {unwritten(exc)}"
    return _with_free_space(f"cannot write the recording {path}: {exc}", path)


def _with_free_space(reason: str, path: Path) -> str:
    if FILE_SIZE_LIMIT in reason:  # the limit stopped it, not the disk (unwritten)
        return reason
    try:
        stat = os.statvfs(path.parent)
        return f"{reason} ({stat.f_bavail * stat.f_frsize} bytes free on its disk)"
    except (OSError, AttributeError):  # statvfs: POSIX only
        return reason


def rerun_executable() -> str | None:
    """The ``rerun`` viewer binary: beside this Python (a venv's bin/, where it comes with
    the rerun-sdk that writes the recordings), else on PATH."""
    beside = Path(sys.executable).with_name("rerun")
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    return shutil.which("rerun")


def view_run(
    run_dir: Path,
    web: bool = False,
    open_browser: bool = False,
    web_port: int = WEB_PORT,
    file_port: int = FILE_PORT,
) -> int:
    """Open a run's ``recording.rrd``, a study's ``overlay.rrd`` (RUN_DIR is the folder)
    or the ``.rrd`` given, in the native viewer or the web viewer, or say how to open it.

    With ``web``, serves it to Rerun's web viewer on 127.0.0.1 and prints the one URL
    that opens it (:func:`cosim.viz.web_viewer.serve`; ``open_browser`` opens it), until
    Ctrl-C. Else, with a display (:func:`display_problem`: on Linux a display server
    answering at ``WAYLAND_DISPLAY`` or ``DISPLAY``; Windows and macOS have their own) and
    the ``rerun`` binary found, runs the viewer on the file (its gRPC server on 127.0.0.1
    only, as ``--web``'s) and returns 0, or 1 with a line naming its status or signal and
    saying to use ``--web`` when it failed. A viewer of a version that may not read the
    file (older than the Rerun that wrote it, or newer by more than one version) is named
    first, with both versions, on one line (:func:`cosim.viz.viewer_version.version_problem`).

    Raises:
        CosimError: the folder holds no recording, the file is not a Rerun recording, or
            there is no display (the one line says to use ``--web``).
    """
    rrd = recording_in(Path(run_dir))
    executable = rerun_executable()
    if web:
        if executable is None:
            raise CosimError("the `rerun` binary is not on PATH (it comes with rerun-sdk)")
        _warn_of_version(executable, rrd)
        return serve(executable, rrd, web_port, file_port, open_browser)
    folder, file = shlex.quote(str(run_dir)), shlex.quote(str(rrd))  # for commands to paste
    web_hint = f"use `auv-cosim view {folder} --web` to serve the recording to a browser"
    reason = display_problem()
    if reason is None and executable is not None:
        _warn_of_version(executable, rrd)
        print(f"opening {rrd} in the Rerun viewer", flush=True)
        code = subprocess.call([executable, "--bind", "127.0.0.1", str(rrd)])
        if code != 0:  # a failed command (1): the viewer's own status means other things
            print(
                f"auv-cosim view: the Rerun viewer {ended(code)}; if it could not open a "
                f"window, {web_hint}",
                file=sys.stderr,
            )
            return 1
        return 0
    if reason is None:
        reason = "the `rerun` viewer is not on PATH (it comes with `pip install rerun-sdk`)"
    raise CosimError(
        f"cannot open a viewer here: {reason}; {web_hint} (or `rerun {file}` on a machine "
        "with a display)"
    )


def _warn_of_version(executable: str, rrd: Path) -> None:
    """One line on stderr if the viewer ``executable`` may not read ``rrd`` (its version)."""
    problem = version_problem(executable, rrd)
    if problem is not None:
        print(f"auv-cosim view: {problem}", file=sys.stderr, flush=True)


X11_SOCKETS = Path("/tmp/.X11-unix")  # a local X server's sockets: X<display number>
X11_TCP_BASE = 6000  # an X server on a host listens on this port + its display number
_X11_DISPLAY = re.compile(r"(?P<host>[^:]*):(?P<number>\d+)(?:\.\d+)?")


def display_problem() -> str | None:
    """Why the native viewer cannot open a window here, or None if it can (as far as can
    be told: a display named in a form not understood here is left to the viewer).

    On Linux, a display is a server answering at ``WAYLAND_DISPLAY`` (a socket in
    ``XDG_RUNTIME_DIR``) or ``DISPLAY`` (``:N`` a local X server's socket, ``HOST:N`` TCP
    port 6000 + N, as ssh's X forwarding gives): a ``DISPLAY`` left over from another
    session made the viewer fail after a screen of its own log. Windows and macOS always
    have their own."""
    if sys.platform in ("win32", "darwin"):
        return None
    wayland, x11 = os.environ.get("WAYLAND_DISPLAY"), os.environ.get("DISPLAY")
    if not wayland and not x11:
        return "no display (DISPLAY / WAYLAND_DISPLAY unset)"
    if (wayland and _wayland_answers(wayland)) or (x11 and _x11_answers(x11)):
        return None
    given = (("WAYLAND_DISPLAY", wayland), ("DISPLAY", x11))
    named = " or ".join(f"{name}={value}" for name, value in given if value)
    return f"no display (no display server answers at {named})"


def _wayland_answers(name: str) -> bool:
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    path = Path(name) if Path(name).is_absolute() else None
    if path is None and runtime:
        path = Path(runtime) / name
    return path is not None and _unix_answers(str(path))


def _x11_answers(display: str) -> bool:
    match = _X11_DISPLAY.fullmatch(display)
    if match is None:
        return True  # a form not understood here: the viewer will say
    host, number = match["host"], int(match["number"])
    if host in ("", "unix"):
        socket_path = str(X11_SOCKETS / f"X{number}")
        return _unix_answers(socket_path) or (
            sys.platform.startswith("linux") and _unix_answers("\0" + socket_path)
        )
    try:
        with socket.create_connection((host, X11_TCP_BASE + number), timeout=2.0):
            return True
    except OSError:
        return False


def _unix_answers(path: str) -> bool:
    """Whether something listens on the Unix socket ``path`` (a leading NUL: Linux's
    abstract namespace, where X servers listen too)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        probe.settimeout(2.0)
        try:
            probe.connect(path)
        except OSError:
            return False
    return True


def recording_in(path: Path) -> Path:
    """The recording ``path`` names: the file itself (any path ending in ``.rrd`` that is
    no folder), else the folder's ``recording.rrd`` (a run) or ``overlay.rrd`` (a study).

    Raises:
        CosimError: there is none, the file is no regular file, or it is not a Rerun
            recording.
    """
    rrd = path
    if path.suffix == ".rrd" and not path.is_dir():  # a file named: not a folder's file
        if path.exists() and not path.is_file():
            raise CosimError(
                f"{path}: not a regular file (a pipe, a device?): expected a .rrd file a "
                "run wrote, or a run folder"
            )
    elif not path.is_file():
        found = [path / name for name in (RECORDING_FILE, OVERLAY_FILE) if (path / name).is_file()]
        rrd = found[0] if found else path / RECORDING_FILE
    if not rrd.is_file() and (path / STUDY_FILE).is_file():  # a study drawn without one
        raise CosimError(
            f"{path} is a study folder without {OVERLAY_FILE}: `auv-cosim sweep STUDY --out "
            f"{path} --resume --overlay N` draws N of its runs into one"
        )
    if not rrd.is_file():
        raise CosimError(
            f"no recording at {rrd}{missing_run_hint(path)}: "
            f"expected a run folder holding {RECORDING_FILE} "
            f"(written by `auv-cosim run` unless --no-rrd), a study folder holding "
            f"{OVERLAY_FILE}, or a .rrd file"
        )
    if not is_recording(rrd):
        raise CosimError(
            f"{rrd} is not a Rerun recording (it does not start like an .rrd file): expected "
            f"a run folder holding {RECORDING_FILE} or a .rrd file"
        )
    return rrd


def is_recording(path: Path) -> bool:
    """Whether ``path`` starts like a Rerun .rrd file: its magic bytes and, where its
    whole header is there (a file cut shorter is a recording cut short), encoding options
    rerun writes; junk after the magic is no recording, not a version that wrote it."""
    try:
        with open(path, "rb") as f:
            header = f.read(RRD_HEADER_BYTES)
    except OSError:
        return False
    if not header.startswith(RRD_MAGIC):
        return False
    if len(header) < RRD_HEADER_BYTES:
        return True
    compression, serializer, *padding = header[8:RRD_HEADER_BYTES]
    return compression in _COMPRESSIONS and serializer in _SERIALIZERS and padding == [0, 0]
