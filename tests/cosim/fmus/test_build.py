"""The build step: what the FMU ships and how it lays it out, the content GUID, the
content-hash cache, and the completion of modelDescription.xml (units, capability flags,
InitialUnknowns by the FMI 2.0 rule)."""

from __future__ import annotations

import importlib.metadata
import importlib.util
import json
import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest
from repo_paths import ROOT

from cosim.errors import CosimError
from cosim.fmus import build, native, reproducible, staging
from fmu_runtime.entry import RECORD_FILE
from plant_fmu.auv_plant import AuvPlant


@pytest.mark.parametrize(
    ("unit", "exponents"),
    [
        ("1", {}),
        ("1/s", {"s": -1}),
        ("kg.m2", {"kg": 1, "m": 2}),
        ("m/s2", {"m": 1, "s": -2}),
        ("N.m", {"kg": 1, "m": 2, "s": -2}),
        ("N.m/rad", {"kg": 1, "m": 2, "s": -2, "rad": -1}),
        ("N.m.s", {"kg": 1, "m": 2, "s": -1}),
        ("J", {"kg": 1, "m": 2, "s": -2}),
        ("furlong/fortnight", None),
    ],
)
def test_base_units(unit, exponents):
    assert build.base_units(unit) == exponents


def test_every_plant_unit_has_si_base_units():
    root = AuvPlant(instance_name="units").to_xml()
    units = {real.get("unit") for real in root.iter("Real")}
    assert None not in units
    assert all(build.base_units(unit) is not None for unit in units), units


def test_every_fmu_ships_the_packages_whole_with_pythonfmu_and_data_but_no_caches():
    files = build.shipped_files()
    assert files["plant_fmu/auv_plant.py"] == build.script_path("AuvPlant")
    for expected in (
        "fmu_runtime/safe_slave.py",
        "controller_fmu/auv_guidance.py",
        "plant_fmu/model/vehicles/remus100.toml",
        "pythonfmu/fmi2slave.py",
        "pythonfmu/LICENSE",
        "LICENSE",
    ):
        assert expected in files
    assert not any("__pycache__" in name or name.endswith(".pyc") for name in files)
    assert not any(name.startswith("pythonfmu/") and "/" in name[10:] for name in files)


def _resources(fmu: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(fmu) as archive:
        return {
            name.removeprefix("resources/"): archive.read(name)
            for name in archive.namelist()
            if name.startswith("resources/")
        }


def test_built_fmu_holds_the_shipped_sources_under_the_build_package(fmu_paths):
    """Every shipped file under auvfmu_<hash> (its imports renamed, every line where it
    was), pythonfmu's entry named after the package, and the runtime's two records."""
    files = build.shipped_files()
    shipped = {name: path.read_bytes() for name, path in files.items()}
    package = staging.package_name(shipped)
    resources = _resources(fmu_paths["AuvPlant"])
    entry = resources.pop("slavemodule.txt").decode()
    assert re.fullmatch(r"auvfmu_[0-9a-f]{12}", package) and entry == f"{package}_auv_plant"
    assert (
        f"from {package}.plant_fmu.auv_plant import AuvPlant"
        in resources.pop(f"{entry}.py").decode()
    )
    record = dict(line.split("=", 1) for line in resources.pop(RECORD_FILE).decode().splitlines())
    assert record["package"] == package and record["class"] == "AuvPlant"
    assert record["module"] == f"{package}.plant_fmu.auv_plant"
    assert record["build_python"] == sys.executable
    assert record["interpolates_inputs"] == "1"  # the plant takes input derivatives
    assert b" R input continuous " in resources.pop(native.VARIABLES_FILE)
    assert resources.pop(f"{package}/__init__.py").startswith(b'"""The Python code of')
    for name in [name for name in resources if name.endswith(".pyc")]:  # their own test
        del resources[name]
    assert sorted(resources) == sorted(f"{package}/{name}" for name in shipped)
    for name, data in shipped.items():
        built = resources[f"{package}/{name}"]
        if name.endswith(".py"):
            assert built.count(b"\n") == data.count(b"\n"), name
            assert built.replace(f"{package}.".encode(), b"") == data, name
        else:
            assert built == data, name


def test_every_module_an_fmu_ships_comes_compiled_for_the_build_python(fmu_paths):
    """A checked-hash .pyc (PEP 552) of this Python beside every .py of resources/, where
    its import looks, holding the hash of that very source: importing the FMU's code
    after any extraction compiles nothing, and an edited source is never run stale."""
    resources = _resources(fmu_paths["AuvPlant"])
    sources = [name for name in resources if name.endswith(".py")]
    assert len(sources) > 40
    compiled = {name for name in resources if name.endswith(".pyc")}
    expected = {Path(importlib.util.cache_from_source(name)).as_posix() for name in sources}
    assert compiled == expected
    for name in sources:
        pyc = resources[Path(importlib.util.cache_from_source(name)).as_posix()]
        assert pyc[:4] == importlib.util.MAGIC_NUMBER, name
        assert int.from_bytes(pyc[4:8], "little") == 0b11, name  # hash-based, checked
        assert pyc[8:16] == importlib.util.source_hash(resources[name]), name


def test_an_extracted_fmus_code_imports_without_compiling(fmu_paths, tmp_path):
    """In a fresh Python that may not write bytecode, every module of the FMU's package is
    loaded from the FMU's own .pyc files (the cached file each module names exists and
    was shipped, not written here)."""
    with zipfile.ZipFile(fmu_paths["AuvPlant"]) as archive:
        archive.extractall(tmp_path)
        shipped = {name for name in archive.namelist() if name.endswith(".pyc")}
    record = dict(
        line.split("=", 1)
        for line in (tmp_path / "resources" / RECORD_FILE).read_text().splitlines()
    )
    script = (
        "import importlib, sys, json; sys.path.insert(0, sys.argv[1]); "
        f"importlib.import_module({record['module']!r}); "
        f"print(json.dumps([m.__cached__ for n, m in sys.modules.items() "
        f"if n.startswith({record['package']!r}) and getattr(m, '__cached__', None)]))"
    )
    done = subprocess.run(
        [sys.executable, "-B", "-c", script, str(tmp_path / "resources")],
        capture_output=True, text=True, timeout=120, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    cached = [Path(name) for name in json.loads(done.stdout)]
    assert len(cached) > 10
    for path in cached:
        assert path.is_file(), path  # -B: only a shipped file can be there
        assert path.relative_to(tmp_path).as_posix() in shipped


def test_the_three_fmus_ship_one_package(fmu_paths):
    """So a process running them together imports one copy of the code."""
    packages = {
        name: dict(
            line.split("=", 1)
            for line in _resources(fmu_paths[name])[RECORD_FILE].decode().splitlines()
        )["package"]
        for name in build.FMUS
    }
    assert len(set(packages.values())) == 1, packages


def test_the_guid_is_a_name_based_uuid_of_the_sources(fmu_paths):
    digest = build.source_hash(build.shipped_files())
    for name in build.FMUS:
        with zipfile.ZipFile(fmu_paths[name]) as archive:
            guid = ET.fromstring(archive.read("modelDescription.xml")).get("guid")
        assert guid == build.guid(name, digest)
        assert guid[14] == "5"  # version 5: a SHA-1 of a name, no MAC address, no time
        record = _resources(fmu_paths[name])[RECORD_FILE].decode()
        assert f"guid={guid}\n" in record
    assert build.guid("AuvPlant", digest) != build.guid("AuvPlant", "0" * 64)


@pytest.mark.slow
def test_two_builds_of_the_same_sources_have_the_same_guid_and_package(fmu_paths, tmp_path):
    again = build.build_fmu("AuvPlant", tmp_path, force=True)
    first, second = (
        (ET.fromstring(zipfile.ZipFile(f).read("modelDescription.xml")).get("guid"),
         _resources(f)[RECORD_FILE])
        for f in (fmu_paths["AuvPlant"], again)
    )  # fmt: skip
    assert first == second


UP_TO_DATE_CHECK = """
import sys
from pathlib import Path
from cosim.fmus.build import build_fmu
built = build_fmu("AuvPlant", Path(sys.argv[1]))
print(sorted(m for m in sys.modules if m.split(".")[0] == "pythonfmu"))
"""


def test_checking_an_fmu_is_up_to_date_imports_no_pythonfmu(fmu_paths, run_python):
    """Every run and study checks its FMUs are up to date before its first step; finding
    the folder of each package the FMUs ship imported it, pythonfmu's builder with it
    (~0.03 s of the client's CPU before a study's workers could run)."""
    done = run_python(UP_TO_DATE_CHECK, fmu_paths["AuvPlant"].parent)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip().splitlines()[-1] == "[]"


@pytest.mark.slow
def test_up_to_date_fmu_is_reused_and_a_stale_one_rebuilt(fmu_paths, tmp_path):
    source = fmu_paths["AuvPlant"]
    fmu = tmp_path / source.name
    hash_file = tmp_path / (source.name + build.HASH_SUFFIX)
    shutil.copy2(source, fmu)
    shutil.copy2(source.with_name(hash_file.name), hash_file)
    digest = build.source_hash(build.shipped_files())
    recorded = {
        "source": digest,
        "fmu": build.file_hash(fmu),
        "date": reproducible.stamp(),
        "python": build.recorded_python(portable=False),
    }
    assert build.recorded_hashes(hash_file) == recorded
    before = fmu.stat().st_ino
    assert build.build_fmu("AuvPlant", tmp_path) == fmu
    assert fmu.stat().st_ino == before
    hash_file.write_text("stale\n")
    build.build_fmu("AuvPlant", tmp_path)
    assert fmu.stat().st_ino != before  # a new build, written beside it and renamed
    assert build.recorded_hashes(hash_file) == recorded  # the same bytes: the same sources


@pytest.mark.slow
def test_a_built_fmu_failing_its_integrity_check_is_rebuilt(fmu_paths, tmp_path):
    """Regression: a truncated FMU beside an up-to-date source hash was used as it was."""
    source = fmu_paths["AuvPlant"]
    fmu = tmp_path / source.name
    shutil.copy2(source.with_name(source.name + build.HASH_SUFFIX), tmp_path)
    fmu.write_bytes(source.read_bytes()[:1000])  # truncated
    assert build.build_fmu("AuvPlant", tmp_path) == fmu
    assert zipfile.ZipFile(fmu).testzip() is None  # a whole FMU again
    assert build.recorded_hashes(fmu.with_name(fmu.name + build.HASH_SUFFIX))["fmu"] == (
        build.file_hash(fmu)
    )


def test_source_hash_changes_with_any_shipped_byte(tmp_path):
    files = {}
    for name, path in build.shipped_files().items():
        copy = tmp_path / name
        copy.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, copy)
        files[name] = copy
    original = build.source_hash(files)
    toml = files["plant_fmu/model/vehicles/remus100.toml"]
    toml.write_text(toml.read_text().replace("m = 30.5", "m = 30.6"))
    assert build.source_hash(files) != original


@pytest.mark.slow
def test_missing_script_fails_the_build_with_its_path(monkeypatch, tmp_path):
    monkeypatch.setitem(build.FMUS, "Ghost", build.FmuSource("plant_fmu", "ghost.py"))
    with pytest.raises(CosimError, match=r"Ghost\.fmu: .*plant_fmu/ghost\.py does not exist"):
        build.build_fmus(tmp_path)
    with pytest.raises(CosimError, match="unknown FMU 'Nope'"):
        build.build_fmu("Nope", tmp_path)


def test_an_output_folder_that_is_a_file_is_refused_before_building(tmp_path):
    taken = tmp_path / "AuvPlant.fmu"
    taken.write_text("a file, not a folder", encoding="utf-8")
    expected = f"cannot build AuvPlant.fmu into {taken}: expected a folder that exists or can "
    with pytest.raises(CosimError, match=re.escape(expected + "be made (it is not a folder)")):
        build.build_fmu("AuvPlant", taken)
    assert taken.read_text(encoding="utf-8") == "a file, not a folder"


def _no_build(*args: object) -> None:
    raise AssertionError("built an FMU into a folder it cannot be installed in")


def test_an_fmu_folder_that_cannot_be_written_is_refused_before_building(monkeypatch, tmp_path):
    """A shared FMU folder installed read-only (built by the administrator), out of date
    for the auv-cosim now installed: every user's run built each FMU (15 s and more)
    and only then failed with "cannot write .../AuvPlant.fmu: Permission denied". It is
    refused before the build, naming the folder and the option that names another."""
    shared = tmp_path / "fmus"
    shared.mkdir()
    access = os.access  # as another user sees it: root may write any folder

    def denied(path: object, mode: int, **kwargs: object) -> bool:
        return False if Path(str(path)) == shared else access(path, mode, **kwargs)

    monkeypatch.setattr(build.os, "access", denied)
    monkeypatch.setattr(build, "_run_pythonfmu", _no_build)
    with pytest.raises(CosimError) as refused:
        build.build_fmu("AuvPlant", shared)
    said = str(refused.value)
    assert f"cannot build AuvPlant.fmu into {shared}: " in said and "--fmu-dir" in said, said
    assert list(shared.iterdir()) == []


def test_an_fmu_folder_that_cannot_be_made_names_the_option_that_moves_it(monkeypatch, tmp_path):
    """``auv-cosim run bs-3`` in a working folder the user cannot write (the default FMU
    folder is build/fmus there): the refusal names the folder, and now the option that
    names another, which it did not."""
    blocker = tmp_path / "a-file"  # no folder can be made under a file, not even by root
    blocker.write_text("")
    monkeypatch.setattr(build, "_run_pythonfmu", _no_build)
    with pytest.raises(CosimError) as refused:
        build.build_fmu("AuvPlant", blocker / "build" / "fmus")
    said = str(refused.value)
    assert str(blocker / "build" / "fmus") in said and "--fmu-dir" in said, said


def test_a_full_disk_names_the_fmu_it_could_not_write_and_leaves_no_half_file(
    monkeypatch, tmp_path
):
    """The copy into the output folder fails (a full disk): the message names the FMU's
    path there (shutil's names the file it read) and no part of the copy is left."""

    def full(source, destination):
        Path(destination).write_bytes(b"PK\x03\x04 half an FMU")
        raise OSError(28, "No space left on device", str(source))

    monkeypatch.setattr(build.shutil, "copyfile", full)
    out = tmp_path / "fmus"
    target = out / "AuvGuidance.fmu"
    with pytest.raises(CosimError, match=re.escape(f"cannot write {target}: No space left")):
        build.build_fmu("AuvGuidance", out)
    assert [p.name for p in out.iterdir()] == [".AuvGuidance.fmu.lock"]  # the build's lock


MINIMAL = b"""<?xml version="1.0" encoding="UTF-8"?>
<fmiModelDescription fmiVersion="2.0" modelName="M" guid="g">
  <CoSimulation modelIdentifier="M" needsExecutionTool="true"/>
  <LogCategories><Category name="logAll"/></LogCategories>
  <ModelVariables>
    <ScalarVariable name="a" valueReference="0" causality="input" variability="continuous">
      <Real start="0" unit="N"/></ScalarVariable>
    <ScalarVariable name="b" valueReference="1" causality="output" variability="continuous"
      initial="calculated"><Real unit="m/s"/></ScalarVariable>
    <ScalarVariable name="c" valueReference="2" causality="calculatedParameter"
      variability="fixed" initial="calculated"><Real unit="furlong"/></ScalarVariable>
    <ScalarVariable name="d" valueReference="3" causality="output" variability="continuous"
      initial="exact"><Real start="0" unit="m"/></ScalarVariable>
  </ModelVariables>
  <ModelStructure><Outputs><Unknown index="2" dependencies="1"/><Unknown index="4"
    dependencies=""/></Outputs></ModelStructure>
</fmiModelDescription>"""


def test_model_description_completion_is_generic_and_idempotent():
    once = build.complete_model_description(MINIMAL, "4f2e3a1c-0000-5000-8000-000000000000")
    assert build.complete_model_description(once) == once
    root = ET.fromstring(once)
    assert root.get("guid") == "4f2e3a1c-0000-5000-8000-000000000000"
    assert [child.tag for child in root][:3] == ["CoSimulation", "UnitDefinitions", "LogCategories"]
    cosim = root.find("CoSimulation")
    assert cosim.get("needsExecutionTool") == "false"
    assert cosim.get("canGetAndSetFMUstate") == cosim.get("canSerializeFMUstate") == "true"
    units = {u.get("name"): u.find("BaseUnit") for u in root.iter("Unit")}
    assert sorted(units) == ["N", "furlong", "m", "m/s"]
    assert units["furlong"] is None  # unknown symbol: declared by name only
    assert units["m/s"].attrib == {"m": "1", "s": "-1"}
    initial = [u.get("index") for u in root.iterfind("ModelStructure/InitialUnknowns/Unknown")]
    assert initial == ["2", "3"]  # the calculated output and the calculated parameter
    outputs = [u.get("dependencies") for u in root.iterfind("ModelStructure/Outputs/Unknown")]
    assert outputs == ["1", ""]  # the slave's declaration is kept


@pytest.mark.parametrize(
    ("stdout", "when"), [("", "during the checks"), ("[]\n", "at exit, after the checks ran")]
)
def test_smoke_run_reports_a_dead_host_and_when_it_died(monkeypatch, stdout, when):
    """A host killed by SIGABRT is a validation problem, never a pass, and the report says
    whether the FMU calls themselves or the process teardown crashed."""
    from cosim.fmus import validation

    def aborted(argv, **kwargs):
        return subprocess.CompletedProcess(argv, -6, stdout, "corrupted double-linked list\n")

    monkeypatch.setattr(validation.subprocess, "run", aborted)
    assert validation.smoke_run({"AuvPlant": Path("AuvPlant.fmu")}) == [
        f"smoke run: the host process died {when} (exit code -6): corrupted double-linked list"
    ]


def test_validating_a_corrupt_fmu_is_one_line(fmu_paths, tmp_path):
    """Regression: `validate` on a truncated FMU ended in a traceback."""
    from cosim.fmus.validation import validate_fmus

    broken = tmp_path / "AuvPlant.fmu"
    broken.write_bytes(fmu_paths["AuvPlant"].read_bytes()[:5000])
    (problem,) = validate_fmus({"AuvPlant": broken})
    assert problem.startswith(f"AuvPlant: {broken} is not a readable FMU (BadZipFile: ")
    assert "\n" not in problem


def test_validation_reports_a_dependencies_kind_of_another_length(fmu_paths, tmp_path):
    """An output whose dependenciesKind lists more entries than its dependencies (here
    one for none) is a problem, whichever fmpy validates (fmpy checks it from 0.3.29 on)."""
    from cosim.fmus.validation import validate_fmus

    source = fmu_paths["AuvPlant"]
    broken = tmp_path / source.name
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(broken, "w") as new:
        for item in old.infolist():
            data = old.read(item)
            if item.filename == "modelDescription.xml":
                root = ET.fromstring(data)
                unknown = root.find("ModelStructure/Outputs/Unknown")
                assert unknown is not None and unknown.get("dependencies") == ""
                unknown.set("dependenciesKind", "dependent")
                data = ET.tostring(root, encoding="UTF-8", xml_declaration=True)
            new.writestr(item, data)
    problems = validate_fmus({"AuvPlant": broken})
    assert any("dependenciesKind" in p for p in problems), problems


@pytest.mark.slow
@pytest.mark.parametrize("damage", ["truncate", "flip"])
def test_validate_reports_a_damaged_fmu_and_builds_nothing(fmu_paths, tmp_path, capsys, damage):
    """`validate --fmu-dir DIR` rebuilt a truncated or bit-flipped FMU over itself and
    printed "every FMU is valid"."""
    from cosim.cli import main

    for name in build.FMUS:
        source = fmu_paths[name]
        shutil.copy2(source, tmp_path)
        shutil.copy2(source.with_name(source.name + build.HASH_SUFFIX), tmp_path)
    data = bytearray(fmu_paths["AuvPlant"].read_bytes())
    if damage == "truncate":
        data = data[:5000]
    else:
        data[len(data) // 2] ^= 0x01
    (tmp_path / "AuvPlant.fmu").write_bytes(bytes(data))
    assert main(["validate", "--fmu-dir", str(tmp_path)]) == 1
    captured = capsys.readouterr()
    assert "AuvPlant: " in captured.out and "is not the file the build wrote" in captured.out
    assert "every FMU is valid" not in captured.out
    assert (tmp_path / "AuvPlant.fmu").read_bytes() == bytes(data)  # left as it was


@pytest.mark.slow
def test_validate_prints_per_fmu_what_was_checked(fmu_paths, capsys):
    from cosim.cli import main

    assert main(["validate", "--fmu-dir", str(fmu_paths["AuvPlant"].parent)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == "every FMU is valid"
    for name in build.FMUS:
        (line,) = [text for text in lines if text.startswith(f"{name} ({name}.fmu): ")]
        assert "fmpy's validation" in line and "variables described" in line
        assert "Reals with a unit" in line and "finite Real outputs" in line


def test_validate_refuses_a_missing_folder_and_creates_nothing(tmp_path, capsys):
    from cosim.cli import main

    missing = tmp_path / "nowhere"
    assert main(["validate", "--fmu-dir", str(missing)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--fmu-dir {missing}: no such folder" in err
    assert not missing.exists()


def test_every_fmu_says_which_version_built_it_and_its_licence(fmu_paths):
    """What an FMI tool shows of an FMU it loads: the model's version and licence, and a
    generation tool naming this package (pythonfmu's own said only "PythonFMU x.y")."""
    from fmpy import read_model_description

    version = importlib.metadata.version("auv-cosim")
    for name, path in fmu_paths.items():
        md = read_model_description(str(path))
        assert (md.version, md.license) == (version, "MIT"), name
        assert md.generationTool.startswith(f"auv-cosim {version} (PythonFMU "), name


def test_every_fmu_carries_the_licence_text_of_the_code_it_ships(fmu_paths):
    """An FMU ships this project's MIT-licensed code, whose licence asks that its text go
    with every copy: an FMU carried pythonfmu's licence text but not the project's own."""
    licence = (ROOT / "LICENSE").read_bytes()
    record = _resources(fmu_paths["AuvPlant"])[RECORD_FILE].decode()
    package = dict(line.split("=", 1) for line in record.splitlines())["package"]
    for name, path in fmu_paths.items():
        assert _resources(path).get(f"{package}/LICENSE") == licence, name


def test_a_file_no_build_wrote_is_never_built_over(tmp_path, capsys):
    """A user's own AuvPlant.fmu in --fmu-dir (no .sha256 record beside it) was replaced
    by a build without a word."""
    from cosim.cli import main

    mine = tmp_path / "AuvPlant.fmu"
    mine.write_bytes(b"my own FMU\n")
    argv = ["run", "lqr-1", "--stop-time", "0.1", "--no-rrd", "--out", str(tmp_path / "run")]
    assert main([*argv, "--fmu-dir", str(tmp_path)]) == 1
    err = capsys.readouterr().err
    assert f"{mine} is not a file a build wrote (no AuvPlant.fmu.sha256 beside it)" in err
    assert err.count("\n") == 1 and mine.read_bytes() == b"my own FMU\n"
    assert not (tmp_path / "run").exists()
    assert main(["validate", "--fmu-dir", str(tmp_path)]) == 1  # validate builds nothing
    assert mine.read_bytes() == b"my own FMU\n"
