"""cosim.fmus.interface: an FMU's variables and units, typed, read once per file version,
and the same reading in scenario loading and export."""

from __future__ import annotations

import os
import shutil
import sys
import zipfile
from pathlib import Path

import pytest
from process_group import run_in_group
from zip_bombs import declaring_archive

from cosim.export.components import components
from cosim.fmus import interface
from cosim.fmus.interface import FmuInterfaceError, check_archive, read_interface
from cosim.paths import path_text
from cosim.scenario.spec import load_scenario
from plant_fmu.model.dynamics import INPUT_NAMES, Variant


def test_variables_are_typed_as_the_model_description_declares(fmu_paths) -> None:
    plant = read_interface(fmu_paths["AuvPlant"])
    assert plant.path == fmu_paths["AuvPlant"].resolve()
    assert (plant.fmi_version, plant.model_identifier) == ("2.0", "AuvPlant")
    variant = plant.variables["variant"]
    assert (variant.type, variant.causality, variant.variability) == (
        "Integer",
        "parameter",
        "fixed",
    )
    assert variant.start == int(Variant.FULL) and type(variant.start) is int
    assert plant.variables["ideal_fluid"].start is False
    assert plant.variables["vehicle"].start == "remus100"
    yaw = plant.variables["yaw"]
    assert (yaw.type, yaw.causality, yaw.unit) == ("Real", "output", "rad")
    assert yaw.start is None and yaw.description  # initial="calculated": from yaw_0
    autopilot = read_interface(fmu_paths["AuvAutopilot"]).variables
    fin, setpoint = autopilot["fin_angle"], autopilot["yaw_setpoint"]
    assert (fin.causality, fin.initial, fin.start) == ("output", "calculated", None)
    assert setpoint.start == 0.0 and type(setpoint.start) is float  # start="0": a Real
    assert [v.name for v in plant.with_causality("input")] == list(INPUT_NAMES)
    # The unit definitions as SI base-unit exponents; N is kg m / s^2.
    assert plant.units["N"] == {"kg": 1, "m": 1, "s": -2}
    assert plant.units["rad"] == {"rad": 1}
    # fmpy's own records stay at hand for FMI calls (value references agree).
    assert plant.model_variables["yaw"].valueReference == yaw.value_reference


def test_read_once_per_file_version(fmu_paths, tmp_path: Path) -> None:
    copy = tmp_path / "AuvPlant.fmu"
    shutil.copyfile(fmu_paths["AuvPlant"], copy)
    first = read_interface(copy)
    assert read_interface(str(copy)) is first  # cached, whatever the path's spelling
    stat = copy.stat()
    os.utime(copy, ns=(stat.st_atime_ns, stat.st_mtime_ns + 1_000_000_000))
    again = read_interface(copy)
    assert again is not first and again == first  # re-read after the file changed


def test_missing_or_broken_fmus_are_refused_by_path(tmp_path: Path) -> None:
    missing = tmp_path / "nothing.fmu"
    with pytest.raises(FmuInterfaceError, match=f"FMU {missing} does not exist"):
        read_interface(missing)
    broken = tmp_path / "broken.fmu"
    broken.write_text("not a zip archive")
    with pytest.raises(FmuInterfaceError, match=f"{broken}: not a valid FMU"):
        read_interface(broken)


def test_scenario_and_export_share_one_reading(fmu_paths) -> None:
    scenario = load_scenario("bs-3", fmu_paths["AuvAutopilot"].parent)
    for name, instance in scenario.instances.items():
        assert instance.interface is read_interface(instance.fmu_path), name
        assert instance.variable("yaw").valueReference == (
            instance.interface.variables["yaw"].value_reference
        )
    exported = {c.name: c.interface for c in components(scenario, None)}
    assert all(exported[n] is i.interface for n, i in scenario.instances.items())


def _copy_fmu(source: Path, target: Path, drop: str = "", extra: str = "", fmi: str = "") -> Path:
    """``source`` rewritten: members starting with ``drop`` left out, a member ``extra``
    added, the description's fmiVersion set to ``fmi``."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for name in old.namelist():
            data = old.read(name)
            if drop and name.startswith(drop):
                continue
            if fmi and name == "modelDescription.xml":
                data = data.replace(b'fmiVersion="2.0"', f'fmiVersion="{fmi}"'.encode())
            new.writestr(name, data)
        if extra:
            new.writestr(extra, b"x")
    return target


@pytest.mark.parametrize(
    ("change", "expected"),
    [
        ({"fmi": "1.0"}, "fmiVersion '1.0': expected an FMI 2.0 FMU"),
        ({"extra": "../outside.txt"}, "illegal path '../outside.txt' in the archive"),
        ({"extra": "/etc/x"}, "illegal path '/etc/x' in the archive"),
        ({"drop": "binaries/"}, "no binaries/"),
    ],
)
def test_a_broken_fmu_is_one_line_naming_it(
    change: dict[str, str],
    expected: str,
    fmu_paths,
    tmp_path: Path,
    capsys: pytest.CaptureFixture,
) -> None:
    """An FMU without binaries/ ended in a traceback, one with fmiVersion 1.0 in a 5-line
    schema dump; one with illegal zip paths ran."""
    from cosim.cli import main

    broken = _copy_fmu(fmu_paths["AuvPlant"], tmp_path / "Broken.fmu", **change)
    scenario = tmp_path / "s.toml"
    scenario.write_text(
        f'id = "s"\nstop_time = 0.1\n[coupling]\nstep = 0.1\n[instances.plant]\nfmu = "{broken}"\n'
    )
    assert main(["run", str(scenario), "--out", str(tmp_path / "out"), "--no-rrd"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(broken) in err and expected in err, err
    assert not (tmp_path / "out").exists()


def test_the_fmi_version_is_read_from_the_root_alone_not_the_whole_description(
    tmp_path: Path,
) -> None:
    """The check of an FMU's archive parsed its whole model description to read the root's
    fmiVersion: with 10^5 variables, seconds before fmpy read it all again. It reads the
    root's start tag alone, so what follows it (here bytes that are no XML) is never read,
    whatever the description's size."""
    fmu = tmp_path / "Old.fmu"
    body = b"<ScalarVariable " * 200_000  # 3.2 MB that no XML parser accepts
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr(
            "modelDescription.xml",
            b'<?xml version="1.0"?>\n<fmiModelDescription fmiVersion="1.0" guid="g">' + body,
        )
    with pytest.raises(FmuInterfaceError, match=r"fmiVersion '1\.0': expected an FMI 2\.0 FMU"):
        check_archive(fmu)


def test_another_tools_log_categories_are_read_without_parsing_its_variables(
    tmp_path: Path,
) -> None:
    """The reading of an FMU's log categories and our annotations parsed a third-party
    FMU's whole description a second time, though only ours carry annotations: with 10^5
    variables, seconds. Another tool's description (one that names auv-cosim in a text,
    as our test FMUs do, but has no annotation of its) is read up to its ModelVariables
    (what follows, here bytes that are no XML, never), its categories those directly
    under LogCategories."""
    fmu = tmp_path / "Other.fmu"
    with zipfile.ZipFile(fmu, "w") as archive:
        archive.writestr(
            "modelDescription.xml",
            b'<?xml version="1.0"?>\n<fmiModelDescription fmiVersion="2.0" guid="g" '
            b'description="for the auv-cosim master"><LogCategories><Category name="logAll"/>'
            b'<Category name="logError"/></LogCategories><VendorAnnotations><Tool name="x">'
            b'<Category name="not one"/></Tool></VendorAnnotations>'
            b"<ModelVariables>" + b"<ScalarVariable " * 200_000,
        )
    assert interface._annotations(fmu) == ({}, ("logAll", "logError"))


@pytest.mark.parametrize(
    ("sizes", "expected"),
    [
        ({"resources/table.bin": 1 << 40}, "unpacks to 1099511[0-9]+ bytes"),
        ({"modelDescription.xml": 1 << 30}, "modelDescription.xml is 1073741824 bytes"),
    ],
)
def test_a_zip_bomb_is_refused_before_anything_is_unpacked(
    sizes: dict[str, int], expected: str, fmu_paths, tmp_path: Path
) -> None:
    """An FMU of a few kB declaring a TiB of files (a zip bomb) passed the archive check,
    and a run then filled the temporary folder's disk extracting it; one declaring a GiB
    modelDescription.xml was read into memory whole, three times. Both are refused by what
    the archive declares, naming the FMU and the limit."""
    with zipfile.ZipFile(fmu_paths["AuvPlant"]) as plant:  # a description fmpy accepts
        description = plant.read("modelDescription.xml")
    bomb = declaring_archive(tmp_path / "Bomb.fmu", sizes, description)
    with pytest.raises(FmuInterfaceError, match=expected) as refused:
        read_interface(bomb)
    message = str(refused.value)
    assert message.startswith(f"{bomb}: ") and "at most" in message and "\n" not in message


def test_a_working_folder_named_in_latin1_is_named_not_the_fmu(
    fmu_paths, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From a working folder named in Latin-1 (the byte 0xf6, which Python reads as the
    surrogate U+DCF6), every FMU was refused as "not a valid FMU: 'utf-8' codec can't
    encode characters in position 12-13: surrogates not allowed": lxml, fmpy's XML
    reader, names the model description by the working folder, as UTF-8. The FMU is
    valid; the refusal names the folder and what to do."""
    copy = tmp_path / "AuvPlant.fmu"  # a path not read yet in this process (no cache)
    shutil.copyfile(fmu_paths["AuvPlant"], copy)
    folder = tmp_path / os.fsdecode(b"gr\xf6sse")
    folder.mkdir()
    monkeypatch.chdir(folder)
    with pytest.raises(FmuInterfaceError) as refused:
        read_interface(copy)
    message = str(refused.value)
    assert "not a valid FMU" not in message, message
    assert f"{copy}: cannot read its model description from the working folder " in message
    assert r"gr\xf6sse" in message and "run from another folder" in message
    message.encode("utf-8")  # printable on a strict UTF-8 stream


@pytest.mark.slow
def test_a_working_folder_beyond_ascii_in_an_ascii_locale_says_what_to_set(
    fmu_paths, tmp_path: Path
) -> None:
    """``LC_ALL=C`` with Python's UTF-8 mode off (file names read as ASCII) and a working
    folder named Prüfung: `auv-cosim validate` said the FMU was "not a valid FMU"; it
    names the folder and the setting that lets Python read it."""
    folder = tmp_path / "Prüfung"
    folder.mkdir()
    scenario = folder / "s.toml"
    plant = fmu_paths["AuvPlant"]
    scenario.write_text(
        f'id = "s"\nstop_time = 0.1\n[coupling]\nstep = 0.1\n[instances.plant]\nfmu = "{plant}"\n',
        encoding="utf-8",
    )
    ascii_locale = {"LC_ALL": "C", "PYTHONUTF8": "0", "PYTHONCOERCECLOCALE": "0"}
    env = {key: value for key, value in os.environ.items() if key != "LANG"}
    done = run_in_group(
        [sys.executable, "-m", "cosim", "validate", "s.toml"],
        timeout=120,
        cwd=folder,
        env={**env, **ascii_locale},
    )
    assert done.returncode == 1 and done.stdout.count("\n") == 1, done.stdout + done.stderr
    assert "not a valid FMU" not in done.stdout
    assert "the working folder" in done.stdout and "set PYTHONUTF8=1" in done.stdout
    assert path_text(folder).encode("ascii", "backslashreplace").decode() in done.stdout
