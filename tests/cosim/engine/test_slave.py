"""What one process keeps between runs (cosim.engine.slave): each FMU file's extraction and
each FMU's loaded library, so that the many runs of a study's worker do not pay for them
again -- and a reused library runs exactly like a fresh one."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from scenario_factory import loop_toml
from zip_bombs import declaring_archive

from cosim.engine import master, slave
from cosim.errors import CosimError
from cosim.scenario.spec import scenario_from_toml
from cosim.scratch import SCRATCH_DIR


def test_later_runs_reuse_the_loaded_libraries_and_give_the_same_rows(
    test_fmu_dir: Path, monkeypatch
) -> None:
    first = master.run(scenario_from_toml(loop_toml(), base_dir=test_fmu_dir))
    loaded: list[str] = []
    fmu2slave = slave.FMU2Slave

    def counted(**kwargs):
        loaded.append(kwargs["instanceName"])
        return fmu2slave(**kwargs)

    monkeypatch.setattr(slave, "FMU2Slave", counted)
    failing = loop_toml(plant_start="fail_at = 0.5")  # a run that stops on an FMU failure
    failed = master.run(scenario_from_toml(failing, base_dir=test_fmu_dir))
    again = master.run(scenario_from_toml(loop_toml(), base_dir=test_fmu_dir))
    assert loaded == []  # neither run loaded a library again
    assert not failed.complete and "injected failure" in failed.error
    assert again.complete
    np.testing.assert_array_equal(again.values, first.values)
    # instance names are part of what an instance is: another name gets its own library
    renamed = loop_toml().replace("instances.plant", "instances.vehicle")
    renamed = renamed.replace('"plant"]', '"vehicle"]')
    master.run(scenario_from_toml(renamed, base_dir=test_fmu_dir))
    assert loaded == ["vehicle"]


def test_a_copy_of_an_fmu_file_reuses_its_extraction(test_fmu_dir: Path, tmp_path: Path) -> None:
    original = test_fmu_dir / "CosimTestIntegrator.fmu"
    other = test_fmu_dir / "CosimTestGain.fmu"
    copy = tmp_path / "uploaded" / original.name  # as a study's worker receives it
    copy.parent.mkdir()
    shutil.copyfile(original, copy)
    assert slave.unzipped(copy) == slave.unzipped(original)
    shutil.copyfile(other, copy)  # the same path, another content: extracted on its own
    assert slave.unzipped(copy) == slave.unzipped(other) != slave.unzipped(original)


def test_an_extraction_removed_under_the_process_is_extracted_again(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """A long-lived process (a notebook's kernel) kept using its extraction after the
    temporary folder lost it (a cleaner of old files in /tmp, a TMPDIR removed): every
    later run failed with "fmi2Instantiate refused: .../resources/fmu_runtime.txt is
    missing or incomplete". A folder missing any of the FMU's files is extracted again."""
    fmu = tmp_path / "CosimTestIntegrator.fmu"
    shutil.copyfile(test_fmu_dir / fmu.name, fmu)
    first = slave.unzipped(fmu)
    (first / "modelDescription.xml").unlink()  # one file aged out
    again = slave.unzipped(fmu)
    assert again != first and (again / "modelDescription.xml").is_file()
    shutil.rmtree(again)  # the whole folder
    third = slave.unzipped(fmu)
    assert third not in (first, again)
    assert sorted(zipfile.ZipFile(fmu).namelist()) == sorted(
        p.relative_to(third).as_posix() for p in third.rglob("*") if p.is_file()
    )
    assert slave.unzipped(fmu) == third  # kept while whole


def test_an_fmu_the_temporary_folder_cannot_hold_is_named_and_leaves_nothing(
    run_python: Callable[..., subprocess.CompletedProcess], tmp_path: Path
) -> None:
    """Under ``ulimit -f`` (or on a full disk) the extraction into TMPDIR failed as
    "OSError: [Errno 27] File too large", naming neither the FMU nor the folder, and left
    the partly extracted folder in TMPDIR; then as "File too large" alone, which reads as
    the disk's free space (docs/runs.md: the line names the file-size limit)."""
    fmu = tmp_path / "Big.fmu"  # fmpy extracts any zip: 1 MiB that does not compress
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr("modelDescription.xml", "<fmiModelDescription/>")
        archive.writestr("binaries/linux64/Big.so", os.urandom(1 << 20))
    temp = tmp_path / "tmp"
    temp.mkdir()
    code = """
        import resource, sys, tempfile
        from pathlib import Path
        from cosim.engine.slave import unzipped
        from cosim.errors import CosimError
        tempfile.tempdir = sys.argv[2]
        resource.setrlimit(resource.RLIMIT_FSIZE, (1 << 16, 1 << 16))  # 64 KiB a file
        try:
            unzipped(Path(sys.argv[1]))
        except CosimError as exc:
            print(exc)
    """
    done = run_python(code, fmu, temp)
    assert done.returncode == 0, done.stderr
    expected = (
        f"cannot extract {fmu} into the temporary folder {temp} (TMPDIR): File too large: "
        "the file-size limit of this process, 65536 bytes (ulimit -f), stopped it: "
        "raise it (ulimit -f unlimited)"
    )
    assert done.stdout == expected + "\n"
    scratch = temp / SCRATCH_DIR  # the scratch folders' base and its lock stay
    assert sorted(temp.rglob("*")) == [scratch, scratch / "global.lock"]


def test_an_fmu_larger_than_the_free_space_is_refused_before_extracting(
    tmp_path: Path, monkeypatch
) -> None:
    """An FMU declaring more bytes than the temporary folder's disk has free (a zip bomb,
    or a large FMU on a small /tmp) was extracted until the shared disk was full; it is
    refused, naming the FMU, the bytes and the free space, before a byte is written."""
    fmu, description = tmp_path / "Big.fmu", "<fmiModelDescription/>"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("modelDescription.xml", description)
        archive.writestr("resources/zeros.bin", bytes(1 << 20))  # 1 MiB in ~1 kB
    size = (1 << 20) + len(description)
    usage = shutil.disk_usage(tmp_path)
    monkeypatch.setattr(shutil, "disk_usage", lambda path: usage._replace(free=1 << 19))
    monkeypatch.setattr(slave, "_unzipped_dirs", {})
    before = set(slave.process_folder().iterdir())
    with pytest.raises(CosimError, match=rf"unpacks to {size} bytes.* 524288 bytes free") as e:
        slave.unzipped(fmu)
    assert str(e.value).startswith(f"{fmu}: ") and "\n" not in str(e.value)
    assert set(slave.process_folder().iterdir()) == before  # nothing left behind


def test_an_fmu_declaring_a_tebibyte_is_refused_before_extracting(
    tmp_path: Path, monkeypatch
) -> None:
    """The extraction itself refuses an archive over the size limit (a zip bomb), whoever
    calls it: no FMU of ours or of the FMI world unpacks to a TiB."""
    bomb = declaring_archive(tmp_path / "Bomb.fmu", {"resources/table.bin": 1 << 40})
    monkeypatch.setattr(slave, "_unzipped_dirs", {})
    before = set(slave.process_folder().iterdir())
    with pytest.raises(CosimError, match=r"unpacks to 1099511[0-9]+ bytes; at most"):
        slave.unzipped(bomb)
    assert set(slave.process_folder().iterdir()) == before


def _rebuilt(fmu: Path, guid: str) -> None:
    """Replace ``fmu`` as a build from other sources does: a new file, renamed over it,
    whose modelDescription.xml has another GUID."""
    new = fmu.with_name(".rebuilt.fmu")
    with zipfile.ZipFile(fmu) as old, zipfile.ZipFile(new, "w") as out:
        for info in old.infolist():
            data = old.read(info)
            if info.filename == "modelDescription.xml":
                data = re.sub(rb'guid="[^"]*"', f'guid="{guid}"'.encode(), data)
            out.writestr(info, data)
    os.replace(new, fmu)


def test_an_fmu_replaced_after_the_scenario_was_loaded_is_refused(
    test_fmu_dir: Path, tmp_path: Path
) -> None:
    """A scenario loaded (a notebook's, or a run starting) while another process builds
    its FMU again from changed sources ran the new FMU's code through the old FMU's
    description (value references and all) without a word. The run refuses it, naming
    the file and what to do."""
    for name in ("CosimTestIntegrator.fmu", "CosimTestGain.fmu"):
        shutil.copyfile(test_fmu_dir / name, tmp_path / name)
    scenario = scenario_from_toml(loop_toml(), base_dir=tmp_path)
    _rebuilt(tmp_path / "CosimTestIntegrator.fmu", "{00000000-0000-0000-0000-000000000001}")
    with pytest.raises(CosimError, match=r"CosimTestIntegrator\.fmu changed after .* loaded"):
        master.run(scenario)
    again = master.run(scenario_from_toml(loop_toml(), base_dir=tmp_path))  # loaded again
    assert again.complete


def test_the_guid_of_an_extraction_is_read_from_the_root_alone(tmp_path: Path) -> None:
    """The check that an extraction is the FMU the scenario loaded parsed its whole model
    description for the root's GUID: with 10^5 variables, seconds of every run's start.
    It reads the root's start tag alone, so what follows it (here bytes that are no XML)
    is never read, whatever the description's size."""
    body = b"<ScalarVariable " * 200_000  # 3.2 MB that no XML parser accepts
    (tmp_path / "modelDescription.xml").write_bytes(
        b'<?xml version="1.0"?>\n<fmiModelDescription fmiVersion="2.0" guid="{1-2}">' + body
    )
    assert slave.extracted_guid(tmp_path) == "{1-2}"
