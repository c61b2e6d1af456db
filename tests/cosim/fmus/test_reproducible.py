"""Reproducible FMU files: the same sources build the same bytes, whenever and in whatever
time zone they are built; ``SOURCE_DATE_EPOCH`` dates the entries and the description."""

from __future__ import annotations

import sys
import time
import zipfile
from collections.abc import Iterator
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from cosim.errors import CosimError
from cosim.fmus import build, bytecode, reproducible
from fmu_runtime.entry import RECORD_FILE

DESCRIPTION = (
    b'<?xml version="1.0" encoding="UTF-8"?>\n<fmiModelDescription fmiVersion="2.0" '
    b'modelName="M" guid="g" generationDateAndTime="2001-02-03T04:05:06+00:00">'
    b'<CoSimulation modelIdentifier="M"/><ModelVariables/><ModelStructure/>'
    b"</fmiModelDescription>"
)


@pytest.fixture
def other_time_zone(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """A local time zone nine hours from UTC (or from it, if this one is already there),
    for this process and the ones it starts; the old one back afterwards."""
    zone = "Etc/GMT+9" if time.timezone == -9 * 3600 else "Etc/GMT-9"
    monkeypatch.setenv("TZ", zone)
    time.tzset()
    yield zone
    monkeypatch.undo()
    time.tzset()


def _entries(fmu: Path) -> dict[str, tuple[tuple[int, ...], int, bytes]]:
    with zipfile.ZipFile(fmu) as archive:
        return {
            i.filename: (i.date_time, i.external_attr, archive.read(i)) for i in archive.infolist()
        }


@pytest.mark.slow
def test_two_builds_of_the_same_sources_are_the_same_bytes(fmu_paths, tmp_path, other_time_zone):
    """Built again later, in another time zone: the same FMU file, byte for byte (the zip
    entries were dated by the clock and the time zone, the description by the clock, so a
    rebuild changed the FMU's hash that a study records and an SSP export embeds)."""
    again = build.build_fmu("AuvPlant", tmp_path, force=True)
    first, second = _entries(fmu_paths["AuvPlant"]), _entries(again)
    differing = [name for name in first if first[name] != second.get(name)]
    assert differing == [], f"entries differing between two builds ({other_time_zone}): {differing}"
    assert again.read_bytes() == fmu_paths["AuvPlant"].read_bytes()


def _zip(path: Path) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        archive.writestr("modelDescription.xml", DESCRIPTION)
        tool = zipfile.ZipInfo("binaries/linux64/M.so", date_time=(2024, 5, 6, 7, 8, 10))
        tool.external_attr = 0o100775 << 16
        archive.writestr(tool, b"\x7fELF")
    return path


def test_source_date_epoch_dates_every_entry(tmp_path, monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")  # 2023-11-14 22:13:20 UTC
    fmu = _zip(tmp_path / "M.fmu")
    reproducible.normalize(fmu)
    entries = _entries(fmu)
    assert {when for when, _, _ in entries.values()} == {(2023, 11, 14, 22, 13, 20)}
    assert entries["binaries/linux64/M.so"][1] >> 16 == 0o100755  # still executable
    assert entries["modelDescription.xml"][1] >> 16 == 0o100644
    assert entries["binaries/linux64/M.so"][2] == b"\x7fELF"


def test_without_source_date_epoch_entries_carry_the_first_zip_date(tmp_path, monkeypatch):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    fmu = _zip(tmp_path / "M.fmu")
    reproducible.normalize(fmu)
    assert {when for when, _, _ in _entries(fmu).values()} == {(1980, 1, 1, 0, 0, 0)}


def test_a_date_before_zip_dates_begin_is_held_at_their_first(monkeypatch):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "0")
    assert reproducible.zip_date() == (1980, 1, 1, 0, 0, 0)
    assert reproducible.generation_date() == "1970-01-01T00:00:00Z"


@pytest.mark.parametrize("value", ["yesterday", "-5", "1.5", "9" * 30])
def test_a_source_date_epoch_that_is_no_time_is_refused_naming_it(monkeypatch, value):
    monkeypatch.setenv("SOURCE_DATE_EPOCH", value)
    with pytest.raises(CosimError, match=r"^SOURCE_DATE_EPOCH=.*expected a whole number") as err:
        reproducible.zip_date()
    assert value[:20] in str(err.value) and "\n" not in str(err.value)


def test_the_description_is_dated_by_source_date_epoch_or_not_at_all(monkeypatch):
    monkeypatch.delenv("SOURCE_DATE_EPOCH", raising=False)
    undated = ET.fromstring(build.complete_model_description(DESCRIPTION, "g"))
    assert "generationDateAndTime" not in undated.attrib  # pythonfmu's build time left out
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    dated = ET.fromstring(build.complete_model_description(DESCRIPTION, "g"))
    assert dated.get("generationDateAndTime") == "2023-11-14T22:13:20Z"


def test_an_fmu_built_under_another_source_date_epoch_is_built_again(fmu_paths, monkeypatch):
    """The build's record says what it was dated with: a packager's SOURCE_DATE_EPOCH
    never takes an FMU dated otherwise as up to date."""
    folder = fmu_paths["AuvPlant"].parent
    assert build.out_of_date(folder) == []  # as the session built them
    other = "1700000001" if reproducible.stamp() == "1700000000" else "1700000000"
    monkeypatch.setenv("SOURCE_DATE_EPOCH", other)
    assert build.out_of_date(folder) == list(build.FMUS)


def test_the_guid_is_the_same_whichever_python_builds_it(monkeypatch, tmp_path):
    """The build's Python (a virtual environment's path) was part of the GUID: the same
    model built in two checkouts' environments, or by a release and by a user checking
    it, had two GUIDs, so a summary.json's GUID named no release."""
    files = build.shipped_files()
    here = build.guid("AuvPlant", build.source_hash(files))
    monkeypatch.setattr(sys, "executable", str(tmp_path / "elsewhere" / "bin" / "python"))
    assert build.guid("AuvPlant", build.source_hash(files)) == here


def _python_elsewhere(folder: Path) -> Path:
    """A Python executable at another path that runs this one (a script handing over)."""
    script = folder / "bin" / "python"
    script.parent.mkdir(parents=True)
    script.write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    script.chmod(0o755)
    return script


def _machine_paths(fmu: Path, paths: list[str]) -> list[str]:
    """The entries of ``fmu`` holding any of ``paths`` (their bytes, as UTF-8)."""
    with zipfile.ZipFile(fmu) as archive:
        return [
            f"{info.filename}: {path}"
            for info in archive.infolist()
            for path in paths
            if path.encode() in archive.read(info)
        ]


@pytest.mark.slow
def test_a_portable_build_names_no_path_of_the_machine_and_is_the_same_anywhere(
    fmu_paths, monkeypatch, tmp_path
):
    """FMUs to publish recorded the build's Python (``build_python=/home/.../.venv/bin/
    python`` in resources/fmu_runtime.txt): the build machine's folders and user name in
    every FMU, and a verifier building the release's sources in their own environment
    got other bytes. A portable build records none: the same bytes from two Pythons at
    two paths, and the GUID of the FMU the session built (the same model)."""
    first = build.build_fmu("AuvPlant", tmp_path / "first", portable=True)
    monkeypatch.setattr(sys, "executable", str(_python_elsewhere(tmp_path / "elsewhere")))
    second = build.build_fmu("AuvPlant", tmp_path / "second", portable=True)
    assert first.read_bytes() == second.read_bytes()
    with zipfile.ZipFile(first) as archive:
        record = archive.read(f"resources/{RECORD_FILE}").decode()
        guid = ET.fromstring(archive.read("modelDescription.xml")).get("guid")
    assert "build_python=\n" in record
    with zipfile.ZipFile(fmu_paths["AuvPlant"]) as archive:
        assert ET.fromstring(archive.read("modelDescription.xml")).get("guid") == guid
    paths = [str(tmp_path), sys.prefix, str(Path(sys.executable).parent), f"{Path.home()}/"]
    paths += [str(Path(build.__file__).parents[2])]  # the source tree it was built from
    assert _machine_paths(first, paths) == []


def test_the_compiled_code_is_the_same_whatever_the_building_process_did_before():
    """The ``.pyc`` files were compiled in the building process, where marshal writes a
    string that process also holds (one it interned since) another way: the same sources
    gave other bytes after other code had run (``cosim.build_fmus`` in a notebook after a
    run; a rebuild in a test session after other tests)."""
    resources = {"m.py": "mark = '\u00a7'\n".encode()}  # a one-character string
    before = bytecode.compiled(resources)
    sys.intern("\u00a7")  # the process now holds that string as code it imports would
    assert bytecode.compiled(resources) == before
