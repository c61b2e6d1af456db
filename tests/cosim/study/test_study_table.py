"""runs.csv: appended row by row, a torn last line dropped on reopening, in the study's
order at the end, with runs.parquet holding the same rows."""

from __future__ import annotations

import csv
import subprocess
from collections.abc import Callable
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from cosim.study.design import PlannedRun, plan, run_id
from cosim.study.spec import StudyError
from cosim.study.table import RunsTable
from cosim.study.task import RunRecord

FACTORS = ["plant.v_0", "plant.ideal_fluid"]
METRICS = ["yaw_settling_time_s", "final.plant.yaw"]


def planned(v0: float, ideal: bool = False) -> PlannedRun:
    values = {"plant.v_0": v0, "plant.ideal_fluid": ideal}
    return PlannedRun(run_id(values), values)


RUNS = [planned(v / 10) for v in range(-3, 4)] + [planned(0.1, True)]


def record(run: PlannedRun) -> RunRecord:
    if run.values["plant.ideal_fluid"]:
        return RunRecord("failed", 'plant: doStep returned Error: "bad", really', {}, 0.5, 0.0)
    v0 = run.values["plant.v_0"]
    metrics = {"yaw_settling_time_s": None if v0 == 0 else 3.0 * v0, "final.plant.yaw": v0 / 3}
    return RunRecord("complete", None, metrics, 1.25 + v0, 1.0)


def rows_of(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def test_rows_are_appended_as_runs_finish(tmp_path: Path) -> None:
    path = tmp_path / "runs.csv"
    table = RunsTable.create(path, FACTORS, METRICS)
    for run in RUNS[:3]:
        table.append(run, record(run))
        assert len(rows_of(path)) == len(table.done)  # on disk at once, not at the end
    first = rows_of(path)[0]
    assert list(first) == [
        "run",
        *FACTORS,
        *METRICS,
        "status",
        "error",
        "wall_clock_s",
        "point",
        "sample",
    ]
    assert first["plant.v_0"] == "-0.3" and first["plant.ideal_fluid"] == "false"
    assert float(first["final.plant.yaw"]) == -0.3 / 3  # shortest round-trip text


def test_reopen_drops_a_torn_last_line_and_keeps_every_whole_one(tmp_path: Path) -> None:
    path = tmp_path / "runs.csv"
    table = RunsTable.create(path, FACTORS, METRICS)
    for run in RUNS[:4]:
        table.append(run, record(run))
    whole = path.read_bytes()
    with path.open("ab") as f:  # a kill in the middle of a write
        f.write(b"deadbeef00000000,0.2,fal")
    reopened = RunsTable.reopen(path, FACTORS, METRICS, RUNS)
    assert path.read_bytes() == whole
    assert reopened.done == {run.id for run in RUNS[:4]}
    assert reopened.rows == table.rows  # the same values, parsed back exactly
    for run in RUNS[4:]:
        reopened.append(run, record(run))
    resumed = reopened.finish(RUNS)

    straight = RunsTable.create(tmp_path / "straight.csv", FACTORS, METRICS)
    for run in reversed(RUNS):  # another order of completion
        straight.append(run, record(run))
    assert straight.finish(RUNS) == resumed
    assert (tmp_path / "straight.csv").read_text() == path.read_text()


def test_finish_puts_the_rows_in_the_studys_order_and_the_same_in_parquet(
    tmp_path: Path,
) -> None:
    """Whatever the order the runs finished in, the table lists them as the study does
    (a grid's points in order: v0 = -0.3 to 0.3 here), not by their hashed ids."""
    path = tmp_path / "runs.csv"
    table = RunsTable.create(path, FACTORS, METRICS)
    for run in reversed(RUNS):
        table.append(run, record(run))
    rows = table.finish(RUNS)
    assert [r["run"] for r in rows_of(path)] == [run.id for run in RUNS]
    assert [r["plant.v_0"] for r in rows_of(path)][:7] == ["-0.3", "-0.2", "-0.1", "0.0",
                                                            "0.1", "0.2", "0.3"]  # fmt: skip
    failed = next(r for r in rows_of(path) if r["status"] == "failed")
    assert failed["error"] == 'plant: doStep returned Error: "bad", really'
    assert failed["yaw_settling_time_s"] == ""
    parquet = pq.read_table(tmp_path / "runs.parquet")
    assert parquet.to_pylist() == rows
    assert str(parquet.schema.field("plant.ideal_fluid").type) == "bool"
    assert str(parquet.schema.field("yaw_settling_time_s").type) == "double"


def test_parquet_columns_carry_their_units_for_pyarrow_and_pandas(tmp_path: Path) -> None:
    """runs.csv's header names no unit (its names are what --resume, ``collect`` and
    ``overlay`` match), so runs.parquet carries them: each factor's and metric's unit as
    its field's ``unit`` metadata (``wall_clock_s`` in s; ``run``, ``status`` and
    ``error`` none), and all of them as ``units`` in the frame ``pd.read_parquet`` gives."""
    table = RunsTable.create(tmp_path / "runs.csv", FACTORS, METRICS)
    for run in RUNS:
        table.append(run, record(run))
    units = {"plant.v_0": "m/s", "plant.ideal_fluid": "1", "yaw_settling_time_s": "s",
             "final.plant.yaw": "rad"}  # fmt: skip
    table.finish(RUNS, units)
    schema = pq.read_schema(tmp_path / "runs.parquet")
    found = {f.name: (f.metadata or {}).get(b"unit", b"").decode() for f in schema}
    places = {"point": "1", "sample": "1"}  # numbers in the study's design
    assert found == {**units, "wall_clock_s": "s", **places, "run": "", "status": "", "error": ""}
    frame = pd.read_parquet(tmp_path / "runs.parquet")
    assert frame.attrs["units"] == {**units, "wall_clock_s": "s", **places}
    assert list(frame.columns) == table.columns


def test_parquet_column_types_do_not_depend_on_whether_a_run_failed(tmp_path: Path) -> None:
    """A study whose runs all completed typed its ``error`` column ``null`` (every value
    None), one with a failed run ``string``: the two tables did not concatenate
    (``pa.concat_tables``: "Schema ... was different"). Every study's table now has the
    same types: strings for run, status and error, doubles for the metrics."""
    complete, failed = tmp_path / "complete", tmp_path / "failed"
    for folder, runs in ((complete, RUNS[:3]), (failed, RUNS[-2:])):
        folder.mkdir()
        table = RunsTable.create(folder / "runs.csv", FACTORS, METRICS)
        for run in runs:
            table.append(run, record(run))
        table.finish(runs)
    tables = [pq.read_table(folder / "runs.parquet") for folder in (complete, failed)]
    assert tables[0].schema == tables[1].schema
    assert str(tables[0].schema.field("error").type) == "string"
    assert pa.concat_tables(tables).column("status").to_pylist() == [
        *["complete"] * 4,
        "failed",
    ]


def test_a_whole_number_metric_reads_the_same_in_a_resumed_table(tmp_path: Path) -> None:
    """A metric that comes as a whole number (a survey's ``legs_completed``) was written
    ``0`` by a study that ran straight through, but ``0.0`` for the rows a resumed study
    read back from runs.csv: the same study gave two different tables. It is a float in
    every row, so both tables are the same text."""
    runs = RUNS[:3]

    def whole(run: PlannedRun) -> RunRecord:
        metrics = {"yaw_settling_time_s": 2, "final.plant.yaw": 0}  # ints, as JSON gives them
        return RunRecord("complete", None, metrics, 1.0, 1.0)

    straight = RunsTable.create(tmp_path / "straight.csv", FACTORS, METRICS)
    for run in runs:
        straight.append(run, whole(run))
    straight.finish(runs)
    path = tmp_path / "runs.csv"
    killed = RunsTable.create(path, FACTORS, METRICS)
    killed.append(runs[0], whole(runs[0]))
    resumed = RunsTable.reopen(path, FACTORS, METRICS, runs)
    for run in runs[1:]:
        resumed.append(run, whole(run))
    resumed.finish(runs)
    assert path.read_text() == (tmp_path / "straight.csv").read_text()
    assert [row["final.plant.yaw"] for row in rows_of(path)] == ["0.0"] * 3


def test_reopen_refuses_another_studys_table(tmp_path: Path) -> None:
    path = tmp_path / "runs.csv"
    table = RunsTable.create(path, FACTORS, METRICS)
    table.append(RUNS[0], record(RUNS[0]))
    with pytest.raises(StudyError, match="are not this study's"):
        RunsTable.reopen(path, FACTORS, ["final.plant.yaw"], RUNS)
    with pytest.raises(StudyError, match="line 2: not a row of this study's runs"):
        RunsTable.reopen(path, FACTORS, METRICS, RUNS[1:])


@pytest.mark.skipif(not hasattr(__import__("signal"), "pthread_sigmask"), reason="POSIX signals")
@pytest.mark.parametrize(
    ("plant", "victim_text"),
    [
        ("symbolic link", "line one\nsecret without a line end"),  # its last line was cut off
        ("symbolic link", "no line end at all"),  # it was replaced by the table's header
        ("hard link", "line one\nsecret without a line end"),
    ],
)
def test_resuming_a_table_that_is_a_link_leaves_the_file_it_names(
    plant: str, victim_text: str, tmp_path: Path
) -> None:
    """``--resume`` of a study folder from elsewhere (or one others can write) whose
    runs.csv is a link to one of the user's files: the reopening cut that file after its
    last line end, or wrote the header over a file with none, before it found the
    columns were not a study's. The link is refused, naming it; the file is untouched."""
    path, victim = tmp_path / "runs.csv", tmp_path / "victim.txt"
    victim.write_text(victim_text)
    if plant == "hard link":
        path.hardlink_to(victim)
    else:
        path.symlink_to(victim)
    with pytest.raises(StudyError, match=f"{path}: a {plant}, not a runs table") as refused:
        RunsTable.reopen(path, FACTORS, METRICS, RUNS)
    assert "\n" not in str(refused.value)
    assert victim.read_text() == victim_text


def test_a_stop_signal_right_after_a_row_is_written_counts_the_row(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C arriving just after a row reached runs.csv, before the table counted it:
    the study said it kept nothing and discarded the folder holding that row (a flaky
    "interrupted (Ctrl-C)" without "1 finished runs kept" under load). The row and its
    count are now one step, the signal delivered after it, also with another thread
    beside the main one (the client's Dask event loop), which the kernel may hand the
    signal to."""
    import signal
    import threading
    import time

    from cosim.study.signals import StudyStopped, stop_study_on_signals

    path = tmp_path / "runs.csv"
    table = RunsTable.create(path, FACTORS, METRICS)
    opened = Path.open

    def open_then_signal(self: Path, *args: object, **kwargs: object):  # type: ignore[no-untyped-def]
        file = opened(self, *args, **kwargs)
        close = file.close

        def close_and_signal() -> None:
            close()  # the row is on disk, not yet counted: the signal comes now, to the
            signal.pthread_kill(beside.ident, signal.SIGINT)  # thread the kernel chose,
            time.sleep(0.05)  # and the main thread runs its handler in the meantime

        file.close = close_and_signal  # type: ignore[method-assign]
        return file

    done = threading.Event()
    beside = threading.Thread(target=done.wait, daemon=True)
    beside.start()
    monkeypatch.setattr(Path, "open", open_then_signal)
    try:
        with pytest.raises(StudyStopped), stop_study_on_signals():
            table.append(RUNS[0], record(RUNS[0]))
    finally:
        done.set()
        beside.join()
    monkeypatch.setattr(Path, "open", opened)
    assert table.done == {RUNS[0].id} and len(rows_of(path)) == 1


def test_a_study_folder_named_in_bytes_not_utf8_gets_its_parquet(tmp_path: Path) -> None:
    """A study folder named in Latin-1 (Python reads the byte 0xff as the surrogate
    U+DCFF): pyarrow encodes a path it is given as strict UTF-8, and the study failed at
    its end, "UnicodeEncodeError", with no runs.parquet."""
    import os

    folder = tmp_path / os.fsdecode(b"study-\xff")
    folder.mkdir()
    table = RunsTable.create(folder / "runs.csv", FACTORS, METRICS)
    for run in RUNS:
        table.append(run, record(run))
    rows = table.finish(RUNS)
    with (folder / "runs.parquet").open("rb") as file:  # (so is a name to read)
        assert pq.read_table(file).to_pylist() == rows


class CountingRows(dict):
    """A table's rows that count the rows handed out by iterating over them."""

    handed_out = 0

    def __iter__(self):
        for key in super().__iter__():
            CountingRows.handed_out += 1
            yield key


def test_asking_whether_each_run_is_done_reads_no_other_row(tmp_path: Path) -> None:
    """``--resume`` of a big table asks, for every run of the study, whether it is done:
    each question copied every row's id (a study of n runs read n * n ids: 10^10 for the
    100 000 runs a study may have). Each answer now costs one look-up."""
    runs = [planned(v / 1000) for v in range(300)]
    table = RunsTable.create(tmp_path / "runs.csv", FACTORS, METRICS)
    for run in runs[:200]:
        table.append(run, record(run))
    table.rows = CountingRows(table.rows)
    CountingRows.handed_out = 0
    todo = [run for run in runs if run.id not in table.done]
    assert todo == runs[200:] and len(table.done) == 200
    assert CountingRows.handed_out == 0, f"{CountingRows.handed_out} ids read for 300 questions"


APPEND_UNDER_LIMIT = """
import resource, sys
from pathlib import Path
from test_study_table import FACTORS, METRICS, RUNS, record
from cosim.study.spec import StudyError
from cosim.study.table import RunsTable

table = RunsTable.create(Path(sys.argv[1]), FACTORS, METRICS)
resource.setrlimit(resource.RLIMIT_FSIZE, (600, 600))  # bytes: what a full disk does
for run in RUNS:
    try:
        table.append(run, record(run))
    except StudyError as exc:
        print(type(exc).__name__, len(table.done), exc, sep="|")
        break
"""


def test_a_row_the_disk_refuses_ends_the_study_naming_runs_csv(
    run_python: Callable[..., subprocess.CompletedProcess], tmp_path: Path
) -> None:
    """A full disk under runs.csv ended the study with "OSError: [Errno 28] No space left
    on device", naming no file and not saying that the finished rows were kept; a typed
    StudyError names the file now, the runner adds what was kept, and the table reads
    back with every row written whole."""
    path = tmp_path / "runs.csv"
    test_dir = Path(__file__).parent
    done = run_python(
        f"import sys; sys.path.insert(0, {str(test_dir)!r})\n" + APPEND_UNDER_LIMIT, path
    )
    assert done.returncode == 0, done.stderr
    kind, kept, message = done.stdout.strip().split("|")
    assert kind == "StudyEndedError" and message == f"cannot write {path}: File too large"
    again = RunsTable.reopen(path, FACTORS, METRICS, RUNS)
    assert len(again.done) == len(rows_of(path)) == int(kept) > 0


def test_each_row_names_its_grid_point_and_sample_of_the_design(tmp_path: Path) -> None:
    """runs.csv's rows carried the run's hashed id and factor values but not which of the
    design's grid points and samples it was: rows arriving out of order, or kept by a
    killed study and resumed, could not be tied to the design's sample without matching
    floats. Each row says both (0-based), the same after a resume and in runs.parquet."""
    from cosim.study.design import random_samples
    from cosim.study.spec import study_from_dict

    spec = study_from_dict(
        {
            "scenario": "bs-3",
            "grid": {"plant.v_0": [-0.1, 0.1]},
            "random": {"n": 3, "seed": 1, "plant.current_east": {"uniform": [0.0, 0.3]}},
        },
        "s.toml",
    )
    runs = plan(spec, {"plant.v_0": float, "plant.current_east": float})
    samples = random_samples(spec.random)
    metrics = ["final.plant.yaw"]
    path = tmp_path / "runs.csv"
    killed = RunsTable.create(path, spec.factors, metrics)
    done = RunRecord("complete", None, {"final.plant.yaw": 0.0}, 1.0, 1.0)
    for run in reversed(runs[3:]):  # out of the design's order, then killed
        killed.append(run, done)
    resumed = RunsTable.reopen(path, spec.factors, metrics, runs)
    for run in runs[:3]:
        resumed.append(run, done)
    for rows in (rows_of(path), resumed.finish(runs)):
        for row in rows:
            point, sample = int(row["point"]), int(row["sample"])
            assert float(row["plant.v_0"]) == spec.grid["plant.v_0"][point], row
            assert float(row["plant.current_east"]) == samples[sample]["plant.current_east"]
    parquet = pq.read_table(tmp_path / "runs.parquet").to_pylist()
    assert [(r["point"], r["sample"]) for r in parquet] == [
        (p, s) for p in range(2) for s in range(3)
    ]


def test_a_table_an_older_version_wrote_is_resumed_with_each_runs_place(tmp_path: Path) -> None:
    """A killed study's runs.csv of a version before ``point`` and ``sample`` resumes (its
    rows are the same runs'), rewritten with both columns from the study's design."""
    runs = [PlannedRun(run.id, run.values, k, None) for k, run in enumerate(RUNS)]
    path = tmp_path / "runs.csv"
    old = ["run", *FACTORS, *METRICS, "status", "error", "wall_clock_s"]
    with path.open("w", encoding="utf-8", newline="") as f:
        writer = csv.writer(f, lineterminator="\n")
        writer.writerow(old)
        writer.writerow([runs[2].id, "-0.1", "false", "", "0.5", "complete", "", "1.0"])
    table = RunsTable.reopen(path, FACTORS, METRICS, runs)
    assert table.done == {runs[2].id}
    (row,) = rows_of(path)
    assert (row["point"], row["sample"], row["final.plant.yaw"]) == ("2", "", "0.5")
