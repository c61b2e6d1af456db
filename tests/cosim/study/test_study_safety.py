"""A study never writes over what is not its own, never mixes two studies in one table and
never runs twice at once in one folder: a new study needs a new or empty folder, its
identity covers every file the scenario reads, its folder is locked while it runs, a
study that could not start leaves no folder that refuses the next attempt, and one whose
disk fills at the end keeps every row and says so."""

from __future__ import annotations

import errno
import fcntl
import os
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from sweep_helpers import PLANT_WITH_VEHICLE_FILE, VEHICLE_FILE

from cosim.cli import main
from cosim.study.folder import claim
from cosim.study.spec import StudyError
from cosim.study.table import CSV_NAME

STUDY = 'scenario = "plant.toml"\n[grid]\n"plant.v_0" = [0.0]\n'


@pytest.fixture
def study(tmp_path: Path, fmu_paths: dict[str, Path]) -> Path:
    """A one-run study of the plant alone with a vehicle file beside its scenario."""
    (tmp_path / "myveh.toml").write_text(VEHICLE_FILE)
    (tmp_path / "plant.toml").write_text(PLANT_WITH_VEHICLE_FILE.format(fmu=fmu_paths["AuvPlant"]))
    path = tmp_path / "study.toml"
    path.write_text(STUDY)
    return path


def sweep(study: Path, out: Path, fmu_dir: Path, *args: str) -> int:
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--quiet"]
    return main([*argv, "--workers", "1", *args])


@pytest.mark.cluster
@pytest.mark.slow
def test_a_new_study_refuses_a_folder_holding_other_files(
    study: Path, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """`sweep --out` into an existing folder overwrote the user's index.html and wrote
    into their figures/."""
    out = tmp_path / "mine"
    (out / "figures").mkdir(parents=True)
    (out / "index.html").write_text("<p>my page</p>\n")
    (out / "figures" / "plot.png").write_bytes(b"png")
    assert sweep(study, out, fmu_dir) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "is not empty (figures, index.html) and holds no study" in err
    assert sorted(str(p.relative_to(out)) for p in out.rglob("*")) == [
        "figures",
        "figures/plot.png",
        "index.html",
    ]
    assert (out / "index.html").read_text() == "<p>my page</p>\n"


@pytest.mark.cluster
@pytest.mark.slow
def test_a_resume_after_a_referenced_file_changed_is_refused(
    study: Path, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """A study resumed after the vehicle .toml changed mixed two vehicles in one table."""
    out = tmp_path / "out"
    assert sweep(study, out, fmu_dir) == 0
    (tmp_path / "myveh.toml").write_text('base = "remus100"\nm = 35.0\n')
    capsys.readouterr()
    assert sweep(study, out, fmu_dir, "--resume") == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "holds another study (it differs from this one in: files" in err
    assert f"changed: {(tmp_path / 'myveh.toml').resolve()}" in err


@pytest.mark.cluster
def test_a_study_folder_in_use_is_refused(
    study: Path, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """Two concurrent `sweep --resume` into one folder both ran every remaining run."""
    out = tmp_path / "out"
    out.mkdir()
    fd = os.open(out / ".auv-cosim.lock", os.O_RDWR | os.O_CREAT)
    try:
        os.write(fd, b"4242 auv-cosim sweep study.toml\n")
        fcntl.flock(fd, fcntl.LOCK_EX)  # as the study running there holds it
        assert sweep(study, out, fmu_dir) == 1
        err = capsys.readouterr().err
        assert err.count("\n") == 1
        assert f"study folder {out} is in use by process 4242 (auv-cosim sweep" in err
        assert sorted(p.name for p in out.iterdir()) == [".auv-cosim.lock"]
    finally:
        os.close(fd)


@pytest.mark.parametrize("address", ["tcp://127.0.0.1:1", "tcp://no such host:x"])
def test_an_unreachable_scheduler_leaves_no_study_behind(
    address: str, study: Path, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """`--scheduler tcp://127.0.0.1:1` took 36 s to fail and left a study folder that
    refused the next attempt; a garbage address ended in a TimeoutError traceback."""
    out = tmp_path / "out"
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir)]
    assert main([*argv, "--scheduler", address]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and address in err, err
    assert not out.exists()


@pytest.mark.cluster
def test_a_full_disk_at_the_end_keeps_every_row_and_says_which_file(
    study: Path, tmp_path: Path, fmu_paths: dict[str, Path], monkeypatch, capsys
) -> None:
    """runs.parquet cannot be written (the disk is full, as pyarrow says it without the
    file's name): the study ends naming the file and where its rows are, leaves no half
    file, and --resume writes the rest once it can."""

    def full(table, where, **options):  # what pyarrow does on a full disk (into a file)
        where.write(b"PAR1")
        raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space")

    monkeypatch.setattr(pq, "write_table", full)
    fmu_dir, out = fmu_paths["AuvPlant"].parent, tmp_path / "out"
    assert sweep(study, out, fmu_dir) == 1
    assert (
        f"auv-cosim sweep: cannot write the study's results: {out / 'runs.parquet'}: No space "
        f"left on device; every finished run's row is kept in {out / 'runs.csv'} (1 in all"
    ) in capsys.readouterr().err
    assert sorted(path.name for path in out.iterdir()) == ["runs.csv", "study.json"]
    monkeypatch.undo()
    assert sweep(study, out, fmu_dir, "--resume") == 0
    assert (out / "runs.parquet").is_file() and (out / "index.html").is_file()


@pytest.mark.cluster
@pytest.mark.slow
def test_an_out_that_is_a_file_is_named_so(
    study: Path, tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    """`sweep --out FILE` said "cannot create the study folder: File exists" (`run`'s
    message for the same: "exists and is not a folder")."""
    taken = tmp_path / "taken"
    taken.write_text("mine\n", encoding="utf-8")
    assert sweep(study, taken, fmu_dir) == 1
    err = capsys.readouterr().err
    assert err == (
        f"auv-cosim sweep: --out {taken}: cannot create the study folder: exists and is not "
        "a folder\n"
    )
    assert taken.read_text(encoding="utf-8") == "mine\n"


def test_a_resume_of_a_changed_study_file_names_the_keys_that_changed(tmp_path: Path) -> None:
    """``--resume`` after the study file's seed changed said only "it differs from this
    one in: study", leaving the user to guess which of its keys."""
    identity = {"study": {"random": {"n": 3, "seed": 11}, "stop_time": 2.0}, "fmus": {}}
    claim(tmp_path, identity, False, CSV_NAME)
    changed = {**identity, "study": {"random": {"n": 3, "seed": 12}, "stop_time": 2.0}}
    with pytest.raises(StudyError) as info:
        claim(tmp_path, changed, True, CSV_NAME)
    assert "differs from this one in: study (random.seed: 11 in the folder, 12 now))" in str(
        info.value
    )
    claim(tmp_path, identity, True, CSV_NAME)  # the same study resumes


def test_a_study_folder_whose_lock_file_is_a_link_is_refused(tmp_path: Path) -> None:
    """A study folder from elsewhere holding its lock file as a link to one of the user's
    files: locking it wrote the study's pid and command line over that file."""
    from cosim.outputs.folder import LOCK_FILE
    from cosim.study.folder import lock

    out, victim = tmp_path / "study", tmp_path / "victim.txt"
    out.mkdir()
    victim.write_text("precious line\n")
    (out / LOCK_FILE).symlink_to(victim)
    with pytest.raises(StudyError, match="a symbolic link, not a lock file"), lock(out):
        pass
    assert victim.read_text() == "precious line\n"


@pytest.mark.parametrize(
    ("entry", "plant"),
    [
        ("index.html", "symbolic link"),
        ("figures/yaw_settling_time_s.png", "hard link"),
        ("runs", "symbolic link"),  # a folder: each kept run's files would go there
    ],
)
def test_resuming_a_study_folder_holding_links_is_refused(
    entry: str, plant: str, tmp_path: Path
) -> None:
    """``--resume`` of a study folder from elsewhere holding links where the study writes
    (its page, a figure, the kept runs' folder): the resumed study wrote its page, figures
    and runs over the files (or into the folder) they named. Refused, naming the entry,
    before anything is written."""
    out, victim = tmp_path / "study", tmp_path / "victim"
    out.mkdir()
    identity = {"study": {"stop_time": 2.0}, "fmus": {}}
    claim(out, identity, False, CSV_NAME)
    (out / entry).parent.mkdir(parents=True, exist_ok=True)
    if entry == "runs":
        victim.mkdir()
    else:
        victim.write_text("precious line\n")
    if plant == "hard link":
        (out / entry).hardlink_to(victim)
    else:
        (out / entry).symlink_to(victim)
    with pytest.raises(StudyError, match=f"holds {entry}, a {plant}") as refused:
        claim(out, identity, True, CSV_NAME)
    assert "\n" not in str(refused.value)


def test_a_study_json_the_disk_cannot_hold_leaves_no_part(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study.json that filled the disk was left half written: the next attempt was told
    to add --resume, which then could not read it."""

    def full(path: Path, text: str, *args: object, **kwargs: object) -> int:
        path.write_bytes(text.encode()[:10])
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(Path, "write_text", full)
    with pytest.raises(OSError) as raised:
        claim(tmp_path, {"scenario": "bs-3"}, False, CSV_NAME)
    assert (raised.value.errno, raised.value.filename) == (
        errno.ENOSPC,
        str(tmp_path / "study.json"),
    )
    assert list(tmp_path.iterdir()) == []
