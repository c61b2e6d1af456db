"""A local study's FMUs are extracted once, by the client (their Python code comes compiled
in the FMU), and a worker uses that folder instead of extracting its own; a folder gone (or never
there: a remote worker) is not used."""

from __future__ import annotations

import errno
import shutil
import zipfile
from pathlib import Path

import pytest

from cosim.engine import slave
from cosim.errors import CosimError
from cosim.study.unpacked import unpack, use_unpacked


@pytest.fixture
def clean_slave(monkeypatch: pytest.MonkeyPatch) -> None:
    """This process's record of extracted FMUs, emptied for the test and restored."""
    monkeypatch.setattr(slave, "_shared_dirs", {})
    monkeypatch.setattr(slave, "_unzipped_dirs", {})


def test_workers_use_the_clients_extraction(fmu_paths, tmp_path: Path, clean_slave) -> None:
    paths = {"plant": fmu_paths["AuvPlant"], "autopilot": fmu_paths["AuvAutopilot"]}
    unpacked = unpack(paths, tmp_path)
    assert len(unpacked) == 2 and all(Path(f).parent == tmp_path for f in unpacked.values())
    # the code each FMU ships is compiled: a worker importing it compiles nothing
    assert list(Path(unpacked[next(iter(unpacked))]).glob("resources/*/__pycache__/*.pyc"))
    stamp = {f: (Path(f) / "modelDescription.xml").stat().st_mtime_ns for f in unpacked.values()}
    assert unpack(paths, tmp_path) == unpacked  # once per content
    assert stamp == {f: (Path(f) / "modelDescription.xml").stat().st_mtime_ns for f in stamp}
    use_unpacked(unpacked)
    assert {str(slave.unzipped(p)) for p in paths.values()} == set(unpacked.values())
    assert slave._unzipped_dirs == {}  # nothing extracted in this process


def test_a_folder_that_is_gone_is_not_used(fmu_paths, tmp_path: Path, clean_slave) -> None:
    plant = fmu_paths["AuvPlant"]
    unpacked = unpack({"plant": plant}, tmp_path / "client")
    use_unpacked({**unpacked, "0" * 64: str(tmp_path / "elsewhere")})  # not on this disk
    assert list(slave._shared_dirs) == list(unpacked)
    shutil.rmtree(tmp_path / "client")
    own = slave.unzipped(plant)  # extracted here instead
    assert own.parent != tmp_path / "client" and (own / "modelDescription.xml").is_file()
    shutil.rmtree(own)


LOCAL = """
import sys, tempfile
from pathlib import Path
from cosim.study.design import PlannedRun
from cosim.study.execution import execute, make_job, open_client
from cosim.study.task import prepare
from cosim.study.unpacked import unpack

def extracted():
    from cosim.engine import slave
    return len(slave._unzipped_dirs), sorted(map(str, slave._shared_dirs.values()))

if __name__ == "__main__":
    base, _ = prepare("bs-3", 1.0, Path(sys.argv[1]))
    with tempfile.TemporaryDirectory() as folder:
        unpacked = unpack(base.fmu_paths, Path(folder))
        job, plugin = make_job(base, {}, "none", unpacked=unpacked)
        with open_client(2) as client:
            done = []
            runs = [PlannedRun(f"r{k}", {}) for k in range(4)]
            execute(client, job, plugin, runs, lambda run, record: done.append(record.status))
            found = list(client.run(extracted).values())
    print(done == ["complete"] * 4, found == [(0, sorted(unpacked.values()))] * 2)
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_local_workers_run_from_the_clients_extraction(fmu_paths, run_python, tmp_path) -> None:
    script = tmp_path / "local.py"
    script.write_text(LOCAL, encoding="utf-8")
    done = run_python(
        "import runpy, sys; sys.argv[1:] = [sys.argv[1]]; "
        f"runpy.run_path({str(script)!r}, run_name='__main__')",
        fmu_paths["AuvPlant"].parent,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "True True"


WORKER_EXTRACTS = """
import sys
from pathlib import Path
from cosim.study.execution import open_client

def extract(path):
    from cosim.engine import slave
    return str(slave.unzipped(Path(path)))

if __name__ == "__main__":
    with open_client(1) as client:
        folder = client.submit(extract, sys.argv[1], pure=False).result()
        print(folder, Path(folder).is_dir())
"""


@pytest.mark.slow
@pytest.mark.cluster
def test_a_worker_removes_the_fmus_it_extracted_when_it_ends(fmu_paths, run_python, tmp_path):
    """A worker extracts its FMUs where it has no client's folder to use (a remote worker);
    Dask's worker processes end by ``os._exit``, past ``atexit``, and each left its
    extraction of every FMU in the temporary folder, for every worker started."""
    script = tmp_path / "worker_extracts.py"
    script.write_text(WORKER_EXTRACTS, encoding="utf-8")
    done = run_python(
        "import os, runpy, sys; os.environ['TMPDIR'] = sys.argv[2]; sys.argv[1:] = sys.argv[1:2]; "
        f"runpy.run_path({str(script)!r}, run_name='__main__')",
        str(fmu_paths["AuvPlant"]),
        str(tmp_path),
    )
    assert done.returncode == 0, done.stderr[-2000:]
    folder, was_there = done.stdout.split()[-2:]
    assert Path(folder).is_relative_to(tmp_path) and was_there == "True"
    assert not Path(folder).exists(), f"the worker left {folder}"
    assert not Path(folder).parent.exists(), "the worker left its scratch folder"


def test_the_clients_extraction_refuses_an_fmu_over_the_free_space(
    fmu_paths, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The client extracted a study's FMUs into the study folder whatever their declared
    size (a zip bomb filled that disk); one larger than the free space there is refused,
    naming it, before anything is written."""
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=1024))
    with pytest.raises(CosimError, match=r"bytes; .* has 1024 bytes free"):
        unpack({"plant": fmu_paths["AuvPlant"]}, tmp_path / "unpacked")
    assert not any((tmp_path / "unpacked").rglob("*"))


def test_local_workers_load_the_clients_copy_and_are_carried_no_fmu_bytes(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """A local study's plugin carried every FMU's bytes (~4 MB for bs-3) through the
    scheduler to each worker, which wrote them into its local directory, though the
    workers share the client's disk; they load the client's copy of each FMU file (the
    bytes the client extracted), and the plugin carries none. A remote cluster's workers
    are still carried them."""
    from types import SimpleNamespace

    from cosim.study.execution import make_job
    from cosim.study.task import prepare

    base, _ = prepare("bs-3", 1.0, fmu_dir)
    unpacked = unpack(base.fmu_paths, tmp_path / "client")
    _, plugin = make_job(base, {}, "none", unpacked=unpacked)
    assert plugin.files == {}, sorted(plugin.files)
    plugin.setup(SimpleNamespace(local_directory=str(tmp_path / "worker"), address="local"))
    loaded = plugin.fmu_paths()
    assert set(loaded) == set(base.fmu_paths)
    for instance, path in loaded.items():
        assert path.is_relative_to(tmp_path / "client"), path
        assert path.read_bytes() == base.fmu_paths[instance].read_bytes()
    _, remote = make_job(base, {}, "none")
    assert len(remote.files) == len(base.fmu_paths)


def _as_archived(fmu: Path, folder: Path) -> None:
    """Every file of the FMU ``fmu`` is in its extraction ``folder``, byte for byte."""
    with zipfile.ZipFile(fmu) as archive:
        for name in archive.namelist():
            if not name.endswith("/"):
                assert (folder / name).read_bytes() == archive.read(name), name


def test_the_package_the_fmus_share_is_extracted_once(fmu_paths, tmp_path: Path) -> None:
    # our FMUs each ship the same package's subfolders: making their ~120 files again for
    # each FMU took most of the client's extraction (file creation's kernel CPU)
    paths = {name: fmu_paths[name] for name in ("AuvPlant", "AuvAutopilot", "AuvGuidance")}
    unpacked = unpack(paths, tmp_path)
    first, *others = [Path(folder) for folder in unpacked.values()]
    linked = [p for f in others for p in (f / "resources").glob("*/*") if p.is_symlink()]
    assert linked, "each FMU's copy of the shared package was extracted again"
    assert all(p.resolve().is_relative_to(first.resolve()) for p in linked)
    for fmu, folder in zip(paths.values(), unpacked.values(), strict=True):
        _as_archived(fmu, Path(folder))


def test_without_links_the_shared_package_is_extracted_for_each_fmu(
    fmu_paths, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def refuse(*args: object, **kwargs: object) -> None:
        raise OSError(errno.EPERM, "symbolic links not permitted")

    monkeypatch.setattr(Path, "symlink_to", refuse)
    paths = {name: fmu_paths[name] for name in ("AuvPlant", "AuvAutopilot")}
    unpacked = unpack(paths, tmp_path)
    for fmu, folder in zip(paths.values(), unpacked.values(), strict=True):
        _as_archived(fmu, Path(folder))
