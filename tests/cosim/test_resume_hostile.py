"""A checkpoint.json is a file users copy, edit and receive from others: ``--resume`` reads
it as hostile input. Whatever it holds (not JSON, JSON of the wrong shape at any level,
numbers out of range, NaN, states of another instance or cut short, values edited, nested
without end, a FIFO, a device or a link in its place, a file of hundreds of MB), resuming
either refuses in one line naming the file, with the run folder left as it was, or runs
the run that was interrupted."""

from __future__ import annotations

import base64
import json
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from deadline import deadline
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cosim.errors import CosimError
from cosim.outputs.checkpoint_file import CHECKPOINT_FILE
from cosim.outputs.run_files import read_manifest
from cosim.runner import RunOptions, RunOutcome, resume_run, run_scenario

Edit = Callable[[dict[str, Any]], object]


@pytest.fixture(scope="module")
def stopped(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short bs-3 run with a checkpoint at t = 0.4 s (step 40) of 0.5 s."""
    out = tmp_path_factory.mktemp("stopped") / "run"
    run_scenario("bs-3", out, stop_time=0.5, checkpoint_every=0.2, no_rrd=True, fmu_dir=fmu_dir)
    return out


def _killed(stopped: Path, tmp_path: Path, edit: Edit | None = None) -> Path:
    """A copy of ``stopped`` as a run killed after its checkpoint leaves it (its summary
    says running; its manifest records the copies, as the run would have), the checkpoint
    changed by ``edit`` (given the JSON data) where one is given."""
    out = tmp_path / "run"
    out.mkdir()
    for name in ("results.csv", "scenario.toml", "summary.json", CHECKPOINT_FILE):
        (out / name).write_bytes((stopped / name).read_bytes())
    summary = json.loads((out / "summary.json").read_text())
    summary.update(status="running", complete=False)
    (out / "summary.json").write_text(json.dumps(summary))
    manifest = read_manifest(stopped)
    manifest.folder = out
    for name in ("results.csv", "scenario.toml", "summary.json", CHECKPOINT_FILE):
        manifest.record(out / name)
    if edit is not None:
        data = json.loads((out / CHECKPOINT_FILE).read_text())
        edit(data)
        (out / CHECKPOINT_FILE).write_text(json.dumps(data))
    return out


def _files(out: Path) -> dict[str, object]:
    """The folder's files: their bytes (their size and time beyond 1 MB: not read)."""
    files: dict[str, object] = {}
    for path in out.iterdir():
        if path.is_file() and not path.is_symlink():
            info = path.stat()
            big = info.st_size > 1 << 20
            files[path.name] = (info.st_size, info.st_mtime_ns) if big else path.read_bytes()
    return files


def _refused(out: Path, fmu_dir: Path, match: str) -> None:
    """Resuming ``out`` is refused in one line naming checkpoint.json, matching ``match``,
    within 60 s, and leaves the folder's files as they were."""
    before = _files(out)
    with pytest.raises(CosimError, match=match) as refused, deadline(60, "no refusal"):
        resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    said = str(refused.value)
    assert "\n" not in said and str(out / CHECKPOINT_FILE) in said, said
    assert _files(out) == before


def _entry(data: dict[str, Any], key: str) -> Any:
    """The state's entry ``key`` (its JSON: the state is a tagged table of pairs)."""
    return next(pair for pair in data["state"]["d"] if pair[0] == key)


def _set(key: str, value: Any) -> Edit:
    return lambda data: _entry(data, key).__setitem__(1, value)


def _z(change: Callable[[np.ndarray], None]) -> Edit:
    def edit(data: dict[str, Any]) -> None:
        saved = _entry(data, "z")[1]
        z = np.frombuffer(base64.b64decode(saved["a"]), dtype=saved["dtype"]).copy()
        change(z)
        saved["a"] = base64.b64encode(z.tobytes()).decode()

    return edit


def _fmu_states(change: Callable[[list[list[Any]]], None]) -> Edit:
    return lambda data: change(_entry(data, "fmu_states")[1]["d"])


def _swap(pairs: list[list[Any]]) -> None:
    (a, sa), (b, sb) = pairs
    pairs[:] = [[a, sb], [b, sa]]


def _cut(pairs: list[list[Any]]) -> None:
    state = pairs[0][1]
    state["b"] = base64.b64encode(base64.b64decode(state["b"])[:40]).decode()


def _rates(index: int, value: Any) -> Edit:
    """The controller's input history's field ``index`` (past, times, count, epoch, sent_at)."""
    return lambda data: _entry(data, "input_rates")[1]["d"][0][1]["t"].__setitem__(index, value)


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (lambda d: d.__setitem__("fmus", ["a"]), r'fmus is \["a"\], expected a table'),
        (lambda d: d.__setitem__("every_s", -1), "every_s is -1, expected a positive number"),
        (lambda d: d.__setitem__("every_s", 10**400), "every_s is 1000.*, expected a positive"),
        (lambda d: d.__setitem__("every_s", True), "every_s is true, expected a positive"),
        (_set("step", -3), "step is -3, expected a whole number from 0 to 50"),
        (_set("step", 500), "step is 500, expected a whole number from 0 to 50"),
        (_set("step", "40"), 'step is "40", expected a whole number'),
        (_set("step", 30), r"rows is 41 .*expected step \+ 1 = 31"),
        (_set("z", None), "its values z are not this run's 35 doubles"),
        (_z(lambda z: z.__setitem__(3, np.nan)), "its values z are not all finite"),
        (_z(lambda z: z.__setitem__(0, z[0] + 1.0)), "not those of the last row of results.csv"),
        (_fmu_states(_swap), "fmi2DeSerializeFMUstate refused: a state of another FMU"),
        (_fmu_states(_cut), "fmi2DeSerializeFMUstate refused: these 40 bytes are not a state"),
        (_fmu_states(lambda pairs: pairs.pop()), "its fmu_states are not of this run's instances"),
        (_rates(2, -7), "the input history of instance 'controller' is not this run's"),
        (_rates(2, 10**30), "the input history of instance 'controller' is not this run's"),
        (_rates(1, [{"f": "nan"}, {"f": "0x1p-2"}]), "the input history of instance 'controller'"),
        (_set("timeline", {"d": [["fired", 1]]}), "its timeline .* is not this run's"),
    ],
    ids=[
        "fmus-list",
        "every-negative",
        "every-huge-int",
        "every-bool",
        "step-negative",
        "step-beyond-stop",
        "step-text",
        "step-not-rows",
        "z-missing",
        "z-nan",
        "z-edited",
        "states-swapped",
        "state-cut",
        "state-missing",
        "count-negative",
        "count-huge",
        "time-nan",
        "timeline-invented",
    ],
)
def test_a_checkpoint_of_the_wrong_shape_is_refused_in_one_line(
    stopped: Path, fmu_dir: Path, tmp_path: Path, edit: Edit, said: str
) -> None:
    _refused(_killed(stopped, tmp_path, edit), fmu_dir, said)


def _open_on(path: Path) -> list[int]:
    """This process's file descriptors open on ``path`` (Linux's /proc)."""
    fds = Path("/proc/self/fd")
    return [int(fd.name) for fd in fds.iterdir() if os.path.realpath(fd) == str(path.resolve())]


@pytest.mark.skipif(not Path("/proc/self/fd").is_dir(), reason="needs Linux's /proc")
@pytest.mark.parametrize("every", [-1, True])
def test_a_resume_refused_for_its_interval_leaves_results_csv_closed(
    stopped: Path, fmu_dir: Path, tmp_path: Path, every: object
) -> None:
    """A checkpoint's every_s is read after results.csv is opened for the replay: its
    refusal left the file open until the garbage collector found it (a ResourceWarning
    then, in whichever test ran; a library user's long-lived process held it)."""
    out = _killed(stopped, tmp_path, lambda d: d.__setitem__("every_s", every))
    _refused(out, fmu_dir, "every_s is ")
    assert _open_on(out / "results.csv") == []


ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def vehicled(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """bs-3 on a vehicle file of its own (its checkpoint's ``files`` has an entry),
    checkpointed at t = 0.4 s of 0.5 s."""
    folder = tmp_path_factory.mktemp("vehicled")
    vehicle = folder / "vehicle.toml"
    vehicle.write_bytes((ROOT / "plant_fmu/model/vehicles/remus100.toml").read_bytes())
    text = (ROOT / "cosim/scenarios/bs-3.toml").read_text(encoding="utf-8")
    scenario = folder / "bs-3-vehicle.toml"
    start = "[instances.plant.start]\n"
    scenario.write_text(text.replace(start, f'{start}vehicle = "vehicle.toml"\n'), "utf-8")
    out = folder / "run"
    run_scenario(scenario, out, stop_time=0.5, checkpoint_every=0.2, no_rrd=True, fmu_dir=fmu_dir)
    assert json.loads((out / CHECKPOINT_FILE).read_text())["files"], "no file recorded"
    return out


@pytest.mark.parametrize("odd", [["x"], "x", 3, True])
def test_a_checkpoint_whose_files_are_no_table_is_refused_in_one_line(
    vehicled: Path, fmu_dir: Path, tmp_path: Path, odd: object
) -> None:
    """The SHA-256s of the files a run read (its vehicle file) made a list, a text or a
    number: a resume ended in a traceback (AttributeError: 'list' object has no attribute
    'get') where a table of other shape (``fmus``) was refused naming it."""
    edit = lambda data: data.__setitem__("files", odd)  # noqa: E731
    _refused(_killed(vehicled, tmp_path, edit), fmu_dir, "files is .*, expected a table")


@pytest.fixture(scope="module")
def faulted(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short mass-jam run (a fault: its run has a timeline) checkpointed at t = 2.8 s."""
    out = tmp_path_factory.mktemp("faulted") / "run"
    run_scenario("mass-jam", out, stop_time=3.0, checkpoint_every=0.7, no_rrd=True,
                 fmu_dir=fmu_dir)  # fmt: skip
    return out


@pytest.mark.parametrize("odd", ["x", -4, 10**30])
def test_a_timeline_count_that_is_no_count_is_refused(
    faulted: Path, fmu_dir: Path, tmp_path: Path, odd: object
) -> None:
    """The epoch of the timeline's snapshot (the 4th entry) made text, negative or huge."""
    edit = lambda data: _entry(data, "timeline")[1]["d"][0][1]["t"].__setitem__(3, odd)  # noqa: E731
    _refused(_killed(faulted, tmp_path, edit), fmu_dir, "its timeline's counts .* are not")


def _fifo(path: Path) -> None:
    os.mkfifo(path)


@pytest.mark.parametrize(
    ("make", "said"),
    [
        (_fifo, "cannot read it: it is not a regular file"),
        (lambda path: path.symlink_to("/dev/zero"), "cannot read it: it is a link"),
        (lambda path: path.mkdir(), "cannot read it: it is not a regular file"),
        (lambda path: os.truncate(_touch(path), 300 << 20), "holds 314572800 bytes, more than"),
        (lambda path: path.write_text("[" * 100_000), "nested too deep to be a checkpoint"),
    ],
    ids=["fifo", "link-to-dev-zero", "folder", "sparse-300-MB", "nested"],
)
def test_a_checkpoint_that_is_no_small_file_is_refused_without_hanging(
    stopped: Path, fmu_dir: Path, tmp_path: Path, make: Callable[[Path], object], said: str
) -> None:
    out = _killed(stopped, tmp_path)
    (out / CHECKPOINT_FILE).unlink()
    make(out / CHECKPOINT_FILE)
    _refused(out, fmu_dir, said)


def _touch(path: Path) -> Path:
    path.touch()
    return path


def test_the_checkpoint_as_written_resumes_the_run(
    stopped: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """The copies _killed makes are resumable: the refusals above are the edits'."""
    out = _killed(stopped, tmp_path)
    resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert (out / "results.csv").read_bytes() == (stopped / "results.csv").read_bytes()


def _leaves(value: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """The paths to every scalar inside ``value`` (keys and list indices)."""
    if isinstance(value, dict):
        return [p for k, v in value.items() for p in _leaves(v, (*path, k))]
    if isinstance(value, list):
        return [p for i, v in enumerate(value) for p in _leaves(v, (*path, i))]
    return [path]


ODD = [None, True, -1, 0, 2**63, 10**30, 1.5, -0.0, 1e308, "", "x", "nan", "0x1p0", "AAAA", "!!",
       [], {}, [1], {"f": "nan"}, {"f": "inf"}, {"b": "AA=="}, {"t": []}, {"d": [[1]]}]  # fmt: skip


@pytest.mark.slow
@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=st.data())
def test_any_one_value_of_a_checkpoint_changed_is_refused_or_resumes_exactly(
    stopped: Path, fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    """One value anywhere in checkpoint.json replaced by an odd one: resuming refuses in
    one line, the folder as it was, or writes the results of the run never interrupted."""
    saved = json.loads((stopped / CHECKPOINT_FILE).read_text())
    where = data.draw(st.sampled_from(_leaves(saved)))
    odd = data.draw(st.sampled_from(ODD))
    out, outcome = _resumed_with(stopped, tmp_path_factory.mktemp("odd"), where, odd, fmu_dir)
    if outcome is not None:
        assert (out / "results.csv").read_bytes() == (stopped / "results.csv").read_bytes()


def _resumed_with(
    source: Path, tmp_path: Path, where: tuple[Any, ...], odd: object, fmu_dir: Path
) -> tuple[Path, RunOutcome | None]:
    """``source``'s killed copy (:func:`_killed`) with the checkpoint's value at ``where``
    made ``odd``, resumed: its folder and outcome, the outcome None where the resume was
    refused in one line with the folder left as it was."""

    def edit(checkpoint: dict[str, Any]) -> None:
        parent = checkpoint
        for key in where[:-1]:
            parent = parent[key]
        parent[where[-1]] = odd

    out = _killed(source, tmp_path, edit)
    before = _files(out)
    try:
        with deadline(60, "no answer"):
            return out, resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    except CosimError as exc:
        assert "\n" not in str(exc)
        assert _files(out) == before
        return out, None


EVENTS = """
[[events]]
name = "turn"
time = 1.0
set = { "controller.yaw_setpoint" = 0.3 }
ramp = 8.0

[[faults]]
name = "fuzz"
kind = "noise"
target = "plant.mass_position_cmd"
start = 0.5
std = 0.001
seed = 3
"""


@pytest.fixture(scope="module")
def evented(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """bs-3 with a heading ramp from t = 1 s over 8 s and a seeded noise fault from
    t = 0.5 s, checkpointed at t = 2 s of 2.5 s: a timeline with a ramp running, an event
    fired and a random generator's state."""
    base = tmp_path_factory.mktemp("evented")
    scenario = base / "evented.toml"
    text = (Path(__file__).parents[2] / "cosim" / "scenarios" / "bs-3.toml").read_text()
    scenario.write_text(text + EVENTS)
    out = base / "run"
    run_scenario(scenario, out, stop_time=2.5, checkpoint_every=1.0, no_rrd=True,
                 fmu_dir=fmu_dir)  # fmt: skip
    return out


def _snapshot(change: Callable[[list[Any], list[Any]], object]) -> Edit:
    """``change`` given the timeline snapshot's entries and the events fired (JSON)."""

    def edit(data: dict[str, Any]) -> None:
        timeline = dict(_entry(data, "timeline")[1]["d"])
        change(timeline["snapshot"]["t"], timeline["fired"])

    return edit


def _notes(change: Callable[[list[Any]], object]) -> Edit:
    """``change`` given the timeline's notes of the events log (JSON)."""

    def edit(data: dict[str, Any]) -> None:
        change(dict(_entry(data, "timeline")[1]["d"])["notes"])

    return edit


def _ramp(index: int, value: Any) -> Edit:
    """The running ramp's field ``index`` (from, to, start, duration) replaced."""
    return _snapshot(lambda snap, _: snap[5]["d"][0][1]["t"].__setitem__(index, value))


def _fault(index: int, value: Any) -> Edit:
    """The noise fault's state's field ``index`` (history, n_last, last, before, draw,
    held, rng) replaced."""
    return _snapshot(lambda snap, _: snap[6][0]["t"].__setitem__(index, value))


def _rng(change: Callable[[list[list[Any]]], object]) -> Edit:
    return _snapshot(lambda snap, _: change(snap[6][0]["t"][6]["d"]))


@pytest.mark.parametrize(
    ("edit", "said"),
    [
        (_ramp(0, "x"), "its timeline's ramps are not"),
        (_ramp(3, {"f": "-0x1p0"}), "its timeline's ramps are not"),
        (_snapshot(lambda snap, _: snap[5]["d"][0].__setitem__(0, "plant.nope")), "ramps are"),
        (_snapshot(lambda snap, _: snap[5]["d"][0].__setitem__(1, [1])), "ramps are not"),
        (_fault(4, "junk"), "the state of fault 'fuzz': its history or draw is not finite"),
        (_fault(1, -5), "the state of fault 'fuzz': its point -5 is not a whole number"),
        (_fault(0, [{"f": "nan"}, {"f": "0x0p0"}]), "fault 'fuzz': its history is not a list"),
        (_fault(6, None), "the state of fault 'fuzz': its random generator's state is not"),
        (_rng(lambda pairs: pairs.__setitem__(0, ["bit_generator", "MT19937"])), "generator"),
        (_fault(6, {"d": [["x", 1]]}), "its random generator's state is not one of its kind"),
        (_fault(5, True), "its last, before or held value is neither null nor"),
        (_snapshot(lambda snap, _: snap.__setitem__(4, [[1, 2]])), "event states are not 0"),
        (_snapshot(lambda snap, _: snap.__setitem__(8, {"d": [["x.y", 1]]})), "assigned values"),
        (_snapshot(lambda snap, _: snap.__setitem__(9, {"d": [["ghost", {"s": []}]]})), "restarts"),
        (_snapshot(lambda snap, _: snap.__setitem__(10, {"d": [["plant", -1]]})), "restarts"),
        (_snapshot(lambda _, fired: fired.__setitem__(0, 5)), "its timeline's events fired are"),
        (_snapshot(lambda _, fired: fired.append(fired[0])), "events fired are not 1 tables"),
        (_snapshot(lambda _, fired: fired[0]["d"][1].__setitem__(1, {"b": "AA=="})), "fired"),
        (_notes(lambda notes: notes[0]["t"].__setitem__(0, "x")), "notes are not pairs"),
        (_notes(lambda notes: notes.append(5)), "its timeline's notes are not pairs"),
    ],
    ids=[
        "ramp-from-text",
        "ramp-negative-duration",
        "ramp-of-no-event",
        "ramp-list",
        "fault-draw-text",
        "fault-point-negative",
        "fault-history-nan",
        "fault-rng-dropped",
        "fault-rng-other-kind",
        "fault-rng-junk",
        "fault-held-bool",
        "event-states-invented",
        "assigned-unknown",
        "restart-unknown-instance",
        "restarts-negative",
        "fired-number",
        "fired-twice",
        "fired-time-bytes",
        "note-time-text",
        "note-number",
    ],
)
def test_a_timeline_entry_of_the_wrong_type_is_refused_in_one_line(
    evented: Path, fmu_dir: Path, tmp_path: Path, edit: Edit, said: str
) -> None:
    """Guards the timeline's content beyond its counts: an entry of a ramp, a fault's
    state, an event fired or a note of the events log holding junk refuses the resume,
    naming it, before a step."""
    _refused(_killed(evented, tmp_path, edit), fmu_dir, said)


def test_the_evented_checkpoint_as_written_resumes_the_run(
    evented: Path, fmu_dir: Path, tmp_path: Path
) -> None:
    """The timeline's refusals above are the edits': the copy as written resumes exactly."""
    out = _killed(evented, tmp_path)
    resume_run(out, RunOptions(no_rrd=True, fmu_dir=fmu_dir))
    assert (out / "results.csv").read_bytes() == (evented / "results.csv").read_bytes()


def _timeline_leaves(saved: dict[str, Any]) -> list[tuple[Any, ...]]:
    """The paths to the scalars of the state's timeline entry."""
    at = next(i for i, pair in enumerate(saved["state"]["d"]) if pair[0] == "timeline")
    return [p for p in _leaves(saved) if p[:4] == ("state", "d", at, 1)]


@pytest.mark.slow
@settings(max_examples=30, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])  # fmt: skip
@given(data=st.data())
def test_any_one_timeline_value_changed_is_refused_or_resumes_a_whole_run(
    evented: Path, fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    """One value of the checkpoint's timeline (ramps, faults' states and generators,
    events fired, counts) replaced by an odd one: resuming refuses in one line, the folder
    as it was, or runs to the stop (an edit of the right type -- another held value, say
    -- resumes the run it describes; one that changes nothing gives the same results)."""
    saved = json.loads((evented / CHECKPOINT_FILE).read_text())
    where = data.draw(st.sampled_from(_timeline_leaves(saved)))
    odd = data.draw(st.sampled_from(ODD))
    out, outcome = _resumed_with(evented, tmp_path_factory.mktemp("odd"), where, odd, fmu_dir)
    if outcome is not None:
        assert outcome.result.complete, outcome.result.error
        rows = (out / "results.csv").read_bytes()
        assert rows.count(b"\n") == (evented / "results.csv").read_bytes().count(b"\n")
        unchanged = json.loads((out / CHECKPOINT_FILE).read_text()) == saved
        assert not unchanged or rows == (evented / "results.csv").read_bytes()


@pytest.mark.parametrize("entry", [5, "runs/x.rrd", "/tmp/evil.sh", ["recording.rrd"]])
def test_a_recording_that_is_no_recording_path_is_refused(
    stopped: Path, fmu_dir: Path, tmp_path: Path, entry: object
) -> None:
    """The checkpoint's recording, which a resume without --rrd or --no-rrd writes again,
    is null, the folder's recording.rrd or an absolute .rrd path: anything else refuses
    the resume in one line, before a file is written."""
    out = _killed(stopped, tmp_path, lambda data: data.__setitem__("recording", entry))
    before = _files(out)
    with pytest.raises(CosimError, match=r"recording is .*, expected null") as refused:
        resume_run(out, RunOptions(fmu_dir=fmu_dir))
    assert "\n" not in str(refused.value) and str(out / CHECKPOINT_FILE) in str(refused.value)
    assert _files(out) == before
