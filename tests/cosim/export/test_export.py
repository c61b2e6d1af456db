"""``auv-cosim export``: the SSP archive and the OSP system structure hold the scenario the
master runs, are valid against the schemas, and a failed export leaves nothing behind.

(That libcosim and ecos run the exports like our master is ``tests/cosim/export/test_interop.py``.)
"""

from __future__ import annotations

import re
import shlex
import shutil
import zipfile
from pathlib import Path

import fmpy
import pytest
from fmpy import read_model_description
from lxml import etree

from cosim import cli
from cosim.errors import CosimError
from cosim.export import OSP_FILE, PARAMETER_SET, export_osp, export_ssp
from cosim.export.command import export_scenario
from cosim.export.files import EXPORT_RECORD
from cosim.scenario.spec import Scenario, load_scenario

NS = {
    "ssd": "http://ssp-standard.org/SSP1/SystemStructureDescription",
    "ssc": "http://ssp-standard.org/SSP1/SystemStructureCommon",
    "ssv": "http://ssp-standard.org/SSP1/SystemStructureParameterValues",
    "osp": "http://opensimulationplatform.com/SSP/OSPAnnotations",
    "oms": "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd",
    "o": "http://opensimulationplatform.com/MSMI/OSPSystemStructure",
}

PLANT_ALONE = """\
id = "plant-alone"
stop_time = 2.0
[coupling]
step = 0.01
step_multiples = {{ plant = 2 }}
[instances.plant]
fmu = "{fmu}"
[instances.plant.start]
variant = 1
ideal_fluid = false
vehicle = "remus100"
v_0 = -0.1
thrust = 9.0
"""


@pytest.fixture(scope="module")
def bs3(fmu_dir: Path) -> Scenario:
    return load_scenario("bs-3", fmu_dir)


@pytest.fixture(scope="module")
def plant_alone(fmu_paths: dict[str, Path], tmp_path_factory: pytest.TempPathFactory) -> Scenario:
    """The plant alone, stepping every 2 h, with every FMI type among its start values."""
    path = tmp_path_factory.mktemp("scenario") / "plant-alone.toml"
    path.write_text(PLANT_ALONE.format(fmu=fmu_paths["AuvPlant"]))
    return load_scenario(path)


def _ssd(archive: Path) -> etree._Element:
    with zipfile.ZipFile(archive) as z:
        return etree.fromstring(z.read("SystemStructure.ssd"))


def _typed(element: etree._Element) -> bool | int | float | str:
    kind, text = etree.QName(element).localname, element.get("value")
    if kind == "Real":
        return float(text)
    if kind in ("Integer", "Enumeration"):
        return int(text)
    if kind == "Boolean":
        assert text in ("true", "false"), f"xs:boolean literal expected, got {text!r}"
        return text == "true"
    return text


def _units(fmu: Path) -> dict[str, str | None]:
    md = read_model_description(str(fmu))
    return {
        v.name: v.unit or (v.declaredType.unit if v.declaredType else None)
        for v in md.modelVariables
    }


def _base_units(fmu: Path) -> dict[str, dict[str, float]]:
    """SI exponents of each unit as the FMU's own UnitDefinitions declare them."""
    md = read_model_description(str(fmu))
    result = {}
    for unit in md.unitDefinitions:
        base = unit.baseUnit
        result[unit.name] = {
            k: float(getattr(base, k)) for k in ("kg", "m", "s", "A", "K", "mol", "cd", "rad")
            if base is not None and getattr(base, k)
        }  # fmt: skip
    return result


# --- SSP ---------------------------------------------------------------------------------


def test_ssp_archive_holds_the_scenario(bs3: Scenario, tmp_path: Path) -> None:
    archive = export_ssp(bs3, tmp_path / "bs-3.ssp")
    with zipfile.ZipFile(archive) as z:
        names = set(z.namelist())
        fmus = {name: z.read(name) for name in names if name.startswith("resources/")}
    assert names == {"SystemStructure.ssd", "resources/AuvPlant.fmu", "resources/AuvAutopilot.fmu"}
    for inst in bs3.instances.values():
        assert fmus[f"resources/{inst.fmu_path.name}"] == inst.fmu_path.read_bytes()

    root = _ssd(archive)
    assert root.get("version") == "1.0"
    components = {
        c.get("name"): c for c in root.iterfind("ssd:System/ssd:Elements/ssd:Component", NS)
    }
    assert set(components) == {"plant", "controller"}
    connections = {
        (c.get("startElement"), c.get("startConnector"), c.get("endElement"), c.get("endConnector"))
        for c in root.iterfind("ssd:System/ssd:Connections/ssd:Connection", NS)
    }
    assert connections == {
        (c.source_instance, c.source_variable, c.target_instance, c.target_variable)
        for c in bs3.connections
    }
    assert len(connections) >= 10  # the autopilot reads about a dozen plant outputs
    for name, inst in bs3.instances.items():
        component = components[name]
        assert component.get("source") == f"resources/{inst.fmu_path.name}"
        units = _units(inst.fmu_path)
        binding = "ssd:ParameterBindings/ssd:ParameterBinding/ssd:ParameterValues"
        sets = component.findall(f"{binding}/ssv:ParameterSet", NS)
        assert [s.get("name") for s in sets] == [PARAMETER_SET]
        values = {}
        for parameter in sets[0].iterfind("ssv:Parameters/ssv:Parameter", NS):
            (value,) = parameter
            values[parameter.get("name")] = _typed(value)
            if etree.QName(value).localname == "Real":  # every Real with the FMU's unit
                assert value.get("unit") == (units[parameter.get("name")] or "1")
        assert values == dict(inst.start)
        # connectors: every input and output of the FMU, with the FMU's units
        connectors = {
            c.get("name"): c for c in component.iterfind("ssd:Connectors/ssd:Connector", NS)
        }
        md = read_model_description(str(inst.fmu_path))
        for v in md.modelVariables:
            if v.causality in ("input", "output"):
                assert connectors[v.name].get("kind") == v.causality
                real = connectors[v.name].find("ssc:Real", NS)
                assert real is not None and real.get("unit") == units[v.name]

    experiment = root.find("ssd:DefaultExperiment", NS)
    assert float(experiment.get("startTime")) == 0.0
    assert float(experiment.get("stopTime")) == bs3.stop_time
    osp_step = experiment.find(".//osp:Algorithm/osp:FixedStepAlgorithm", NS)
    assert float(osp_step.get("baseStepSize")) == bs3.coupling.step
    oms_step = root.find("ssd:System/ssd:Annotations//oms:FixedStepMaster", NS)
    assert float(oms_step.get("stepSize")) == bs3.coupling.step


def test_ssp_declares_each_unit_it_uses_as_the_fmus_define_it(
    bs3: Scenario, tmp_path: Path
) -> None:
    root = _ssd(export_ssp(bs3, tmp_path / "bs-3.ssp"))
    declared = {}
    for unit in root.iterfind("ssd:Units/ssc:Unit", NS):
        base = unit.find("ssc:BaseUnit", NS)
        declared[unit.get("name")] = {k: float(v) for k, v in base.attrib.items()}
    used = {e.get("unit") for e in root.iter() if e.get("unit")}
    assert used == set(declared)
    fmu_units: dict[str, dict[str, float]] = {"1": {}}
    for inst in bs3.instances.values():
        fmu_units |= _base_units(inst.fmu_path)
    assert declared == {name: fmu_units[name] for name in declared}
    # and they are the SI definitions
    assert declared["N"] == {"kg": 1, "m": 1, "s": -2}
    assert declared["rad/s"] == {"rad": 1, "s": -1}


@pytest.mark.slow
def test_ssp_is_valid_against_the_ssp_schemas(bs3: Scenario, tmp_path: Path) -> None:
    """Two independent validators: pyssp-standard's and fmpy's bundled SSP 1.0 schemas."""
    from fmpy.ssp.ssd import read_ssd
    from pyssp_standard.ssd import SSD
    from pyssp_standard.standard import ModelicaStandard

    archive = export_ssp(bs3, tmp_path / "bs-3.ssp")
    with zipfile.ZipFile(archive) as z:
        z.extract("SystemStructure.ssd", tmp_path)
    SSD(tmp_path / "SystemStructure.ssd").check_compliance(
        ModelicaStandard.schemas["ssd"], ModelicaStandard.namespaces
    )
    ssd = read_ssd(str(archive), validate=True)
    assert [c.name for c in ssd.system.elements] == list(bs3.instances)


def test_step_multiples_reach_both_formats(plant_alone: Scenario, tmp_path: Path) -> None:
    """An instance stepping every k h: libcosim's StepSizeHint (SSP) and stepSize (OSP)."""
    root = _ssd(export_ssp(plant_alone, tmp_path / "p.ssp"))
    hint = root.find("ssd:System/ssd:Elements/ssd:Component[@name='plant']//osp:StepSizeHint", NS)
    assert float(hint.get("value")) == pytest.approx(0.02, rel=1e-15)
    osp = etree.parse(str(export_osp(plant_alone, tmp_path / "p-osp"))).getroot()
    (simulator,) = osp.iterfind("o:Simulators/o:Simulator", NS)
    assert float(simulator.get("stepSize")) == pytest.approx(0.02, rel=1e-15)
    assert float(osp.findtext("o:BaseStepSize", namespaces=NS)) == 0.01


def test_every_fmi_type_is_written_as_its_ssp_type(plant_alone: Scenario, tmp_path: Path) -> None:
    root = _ssd(export_ssp(plant_alone, tmp_path / "p.ssp"))
    kinds = {
        p.get("name"): etree.QName(p[0]).localname for p in root.iterfind(".//ssv:Parameter", NS)
    }
    assert kinds == {"variant": "Integer", "ideal_fluid": "Boolean", "vehicle": "String",
                     "v_0": "Real", "thrust": "Real"}  # fmt: skip


# --- OSP ---------------------------------------------------------------------------------


def test_osp_structure_holds_the_scenario(bs3: Scenario, tmp_path: Path) -> None:
    xml = export_osp(bs3, tmp_path / "bs-3-osp")
    assert xml == (tmp_path / "bs-3-osp" / OSP_FILE).resolve()
    assert sorted(p.name for p in xml.parent.iterdir()) == sorted(
        [OSP_FILE, "AuvAutopilot.fmu", "AuvPlant.fmu", EXPORT_RECORD]
    )
    root = etree.parse(str(xml)).getroot()
    assert root.tag == f"{{{NS['o']}}}OspSystemStructure" and root.get("version") == "0.1"
    assert float(root.findtext("o:BaseStepSize", namespaces=NS)) == bs3.coupling.step
    assert float(root.findtext("o:EndTime", namespaces=NS)) == bs3.stop_time
    simulators = {s.get("name"): s for s in root.iterfind("o:Simulators/o:Simulator", NS)}
    assert set(simulators) == {"plant", "controller"}
    for name, inst in bs3.instances.items():
        simulator = simulators[name]
        assert (xml.parent / simulator.get("source")).read_bytes() == inst.fmu_path.read_bytes()
        values = {
            v.get("variable"): _typed(v[0])
            for v in simulator.iterfind("o:InitialValues/o:InitialValue", NS)
        }
        assert values == dict(inst.start)
    connections = set()
    for c in root.iterfind("o:Connections/o:VariableConnection", NS):
        a, b = c.iterfind("o:Variable", NS)
        connections.add(
            (f"{a.get('simulator')}.{a.get('name')}", f"{b.get('simulator')}.{b.get('name')}")
        )
    assert connections == {(c.source, c.target) for c in bs3.connections}


def test_same_scenario_exports_to_the_same_bytes(plant_alone: Scenario, tmp_path: Path) -> None:
    first = export_ssp(plant_alone, tmp_path / "a.ssp").read_bytes()
    assert export_ssp(plant_alone, tmp_path / "b.ssp").read_bytes() == first
    one = export_osp(plant_alone, tmp_path / "a").read_bytes()
    assert export_osp(plant_alone, tmp_path / "b").read_bytes() == one


def test_export_replaces_an_earlier_export(plant_alone: Scenario, tmp_path: Path) -> None:
    ssp = tmp_path / "p.ssp"
    export_ssp(plant_alone, ssp)
    ssp.touch()  # an earlier export, still recognised as one
    export_ssp(plant_alone, ssp)
    assert zipfile.is_zipfile(ssp)
    folder = tmp_path / "osp"
    export_osp(plant_alone, folder)
    (folder / "AuvPlant.fmu").unlink()  # a file of the earlier export gone: still one
    export_osp(plant_alone, folder)
    assert (folder / "AuvPlant.fmu").read_bytes() == plant_alone.instances[
        "plant"
    ].fmu_path.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["osp", "p.ssp"]  # no temporaries left


def test_export_never_replaces_a_file_it_did_not_write(
    plant_alone: Scenario, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """`export bs-3 --ssp base/results.csv` replaced another run's results with a zip
    (now refused for its name, even with --force); an .ssp of another tool's is kept
    unless --force."""
    results = tmp_path / "results.csv"
    results.write_text("time,plant.yaw\n0,0\n")
    code, err = _export(capsys, plant_alone.source, "--ssp", results, "--force")
    assert code == 1 and err.count("\n") == 1 and "name ends in '.ssp'" in err
    theirs = tmp_path / "theirs.ssp"
    theirs.write_bytes(b"an archive another tool wrote")
    code, err = _export(capsys, plant_alone.source, "--ssp", theirs)
    assert code == 1 and err.count("\n") == 1
    assert f"cannot write --ssp {theirs}: it exists and is not an archive" in err
    assert "--force" in err
    assert results.read_text() == "time,plant.yaw\n0,0\n"
    assert theirs.read_bytes() == b"an archive another tool wrote"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv", "theirs.ssp"]
    assert cli.main(["export", str(plant_alone.source), "--ssp", str(theirs), "--force"]) == 0
    assert zipfile.is_zipfile(theirs)


def test_osp_export_never_removes_a_file_it_did_not_write(
    plant_alone: Scenario, tmp_path: Path
) -> None:
    folder = tmp_path / "osp"
    export_osp(plant_alone, folder)
    (folder / "notes.txt").write_text("mine\n")
    with pytest.raises(CosimError, match=r"notes.txt is not a file an export wrote"):
        export_osp(plant_alone, folder)
    assert (folder / "notes.txt").read_text() == "mine\n"


# --- failures: a clear message and nothing written -----------------------------------------


def _export(capsys: pytest.CaptureFixture, *args: str) -> tuple[int, str]:
    code = cli.main(["export", *map(str, args)])
    return code, capsys.readouterr().err


def test_unknown_scenario_fails_and_writes_nothing(
    tmp_path: Path, fmu_dir: Path, capsys: pytest.CaptureFixture
) -> None:
    code, err = _export(
        capsys, "no-such-scenario", "--ssp", tmp_path / "x.ssp", "--fmu-dir", fmu_dir
    )
    assert code == 1
    assert "unknown scenario 'no-such-scenario'" in err
    code, err = _export(capsys, "no-such-scenario", "--osp", tmp_path / "osp", "--fmu-dir", fmu_dir)
    assert code == 1 and "no-such-scenario" in err
    assert list(tmp_path.iterdir()) == []


def test_unwritable_paths_fail_and_write_nothing(
    plant_alone: Scenario, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    scenario_file = str(plant_alone.source)
    code, err = _export(capsys, scenario_file, "--ssp", blocker / "x.ssp")
    assert code == 1 and f"cannot write --ssp {blocker / 'x.ssp'}" in err
    code, err = _export(capsys, scenario_file, "--osp", blocker / "osp")
    assert code == 1 and f"cannot write --osp {blocker / 'osp'}" in err
    code, err = _export(capsys, scenario_file, "--ssp", tmp_path)  # a folder, not a file
    assert code == 1 and "it is a folder" in err
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    code, err = _export(capsys, scenario_file, "--osp", foreign)
    assert code == 1 and "not empty" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a-file", "foreign"]
    assert [p.name for p in foreign.iterdir()] == ["notes.txt"]


def test_a_failure_while_writing_leaves_nothing(
    plant_alone: Scenario, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import cosim.export.osp
    import cosim.export.ssp

    def disk_full(*_args: object) -> None:
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(cosim.export.ssp, "_add_bytes", disk_full)
    monkeypatch.setattr(cosim.export.osp.shutil, "copyfile", disk_full)
    with pytest.raises(CosimError, match="No space left on device"):
        export_ssp(plant_alone, tmp_path / "p.ssp")
    with pytest.raises(CosimError, match="No space left on device"):
        export_osp(plant_alone, tmp_path / "osp")
    assert list(tmp_path.iterdir()) == []


def test_a_connection_the_fmus_lack_fails_and_writes_nothing(
    bs3: Scenario, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """The controller swapped for the plant FMU: its yaw is an output, not an input."""
    wrong = {"controller": fmu_paths["AuvPlant"]}
    with pytest.raises(CosimError) as failure:
        export_ssp(bs3, tmp_path / "bs-3.ssp", fmu_paths=wrong)
    message = str(failure.value)
    assert "connection plant.yaw -> controller.yaw" in message
    assert "it is output in AuvPlant.fmu, expected input" in message
    with pytest.raises(CosimError, match=r"connection plant\.yaw -> controller\.yaw"):
        export_osp(bs3, tmp_path / "osp", fmu_paths=wrong)
    assert list(tmp_path.iterdir()) == []


def test_an_fmu_packaged_instead_must_offer_the_variables_the_scenario_uses(
    plant_alone: Scenario, bs3: Scenario, fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """The scenario's checked connections and start values are reused; a replacement FMU
    only has to offer the same variables (a copy does; the autopilot is no plant)."""
    copy = tmp_path / "elsewhere" / "AuvAutopilot.fmu"
    copy.parent.mkdir()
    shutil.copyfile(fmu_paths["AuvAutopilot"], copy)
    archive = export_ssp(bs3, tmp_path / "bs-3.ssp", fmu_paths={"controller": copy})
    with zipfile.ZipFile(archive) as z:
        assert z.read("resources/AuvAutopilot.fmu") == copy.read_bytes()
    wrong = {"plant": fmu_paths["AuvAutopilot"]}
    with pytest.raises(CosimError, match=r"start value plant\.variant: AuvAutopilot\.fmu has no"):
        export_osp(plant_alone, tmp_path / "osp", fmu_paths=wrong)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bs-3.ssp", "elsewhere"]


def test_a_scenario_file_naming_a_missing_variable_fails(
    fmu_paths: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    scenario = tmp_path / "bad.toml"
    scenario.write_text(
        PLANT_ALONE.format(fmu=fmu_paths["AuvPlant"])
        + '[connections]\nadd = [{ from = "plant.yaw", to = "plant.no_such_input" }]\n'
    )
    code, err = _export(capsys, scenario, "--ssp", tmp_path / "bad.ssp")
    assert code == 1 and "no_such_input" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.toml"]


def test_export_needs_exactly_one_target(
    plant_alone: Scenario, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """Neither or both of --ssp and --osp is a command line that cannot be parsed: exit 2
    with the usage, as every such command line (it was exit 1, as a failed export)."""
    for targets, why in [
        ([], "one of the arguments --ssp --osp is required"),
        (["--ssp", tmp_path / "a.ssp", "--osp", tmp_path / "b"], "not allowed with argument"),
    ]:
        with pytest.raises(SystemExit) as exit_:
            _export(capsys, plant_alone.source, *targets)
        assert exit_.value.code == 2
        assert why in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(CosimError, match="exactly one of --ssp FILE or --osp DIR"):
        export_scenario(plant_alone.source, ssp=None, osp=None, fmu_dir=tmp_path)  # as the API


def test_cli_export_writes_and_reports_the_archive(
    plant_alone: Scenario, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    assert cli.main(["export", str(plant_alone.source), "--ssp", str(tmp_path / "p.ssp")]) == 0
    out, err = capsys.readouterr()
    assert f"SSP archive: {tmp_path / 'p.ssp'}" in out
    assert zipfile.ZipFile(tmp_path / "p.ssp").testzip() is None
    # the scenario couples Gauss-Seidel (the default), which neither format can express:
    # the note gives the command that runs it as they do, and that command works here
    (command,) = re.findall(r"compare with `(auv-cosim run [^`]+)`", err)
    assert shlex.split(command)[2:] == [
        str(plant_alone.source), "--algorithm", "jacobi", "--extrapolation", "none"
    ]  # fmt: skip
    options = ["--out", str(tmp_path / "run"), "--stop-time", "0.1", "--no-rrd", "--quiet"]
    assert cli.main([*shlex.split(command)[1:], *options]) == 0


def test_export_prints_what_it_wrote_on_stdout_and_its_notes_on_stderr(
    plant_alone: Scenario, tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """``path=$(auv-cosim export S --ssp x.ssp)`` read the notes with the archive's line:
    they went to stdout, where a script reads what the command wrote. stdout names the
    file, one line; each note is a message on stderr naming the command, as build's are."""
    archive = tmp_path / "p.ssp"
    assert cli.main(["export", str(plant_alone.source), "--ssp", str(archive)]) == 0
    out, err = capsys.readouterr()
    assert out == f"SSP archive: {archive}\n", out
    assert err.startswith("auv-cosim export: note: ") and "compare with `" in err, err


def test_a_custom_vehicle_set_travels_inline_in_both_formats(
    fmu_paths: dict[str, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`vehicle = "myveh.toml"` was packed into the SSP as resources/plant/myveh.toml and
    named by that relative path, which the plant looked for in the host's working
    directory (libcosim died, ecos ran on zeros), and the OSP named the absolute path of
    this machine. Both now carry the set's TOML text, which the plant loads from anywhere."""
    from plant_fmu.model.parameters import load_vehicle

    folder = tmp_path / "mission"
    folder.mkdir()
    (folder / "myveh.toml").write_text('base = "remus100"\nm = 31.0\n')
    text = PLANT_ALONE.format(fmu=fmu_paths["AuvPlant"]).replace("remus100", "myveh.toml")
    (folder / "custom.toml").write_text(text)
    archive = tmp_path / "custom.ssp"
    assert cli.main(["export", str(folder / "custom.toml"), "--ssp", str(archive)]) == 0
    assert cli.main(["export", str(folder / "custom.toml"), "--osp", str(tmp_path / "osp")]) == 0
    with zipfile.ZipFile(archive) as z:
        assert not [n for n in z.namelist() if n.endswith("myveh.toml")]
    (ssp,) = _ssd(archive).iterfind(".//ssv:Parameter[@name='vehicle']/ssv:String", NS)
    osp = etree.parse(str(tmp_path / "osp" / OSP_FILE)).getroot()
    (initial,) = osp.iterfind(".//o:InitialValue[@variable='vehicle']/o:String", NS)
    (folder / "myveh.toml").unlink()  # the exports need the file no more
    monkeypatch.chdir(tmp_path)
    for value in (ssp.get("value"), initial.get("value")):
        assert "\n" in value and load_vehicle(value).m == 31.0


def test_the_note_on_other_masters_says_held_inputs_in_words(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The note read "runs gauss-seidel with none extrapolation"."""
    from cosim.cli import main

    argv = ["export", "lqr-1", "--ssp", str(tmp_path / "lqr-1.ssp"), "--fmu-dir", str(fmu_dir)]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert "runs gauss-seidel with held inputs in auv-cosim" in err, err


def test_a_summary_with_a_double_dash_is_a_valid_osp_comment(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """A summary with "--" ended the OSP export in lxml's "Comment may not contain '--'"."""
    text = PLANT_ALONE.format(fmu=fmu_paths["AuvPlant"])
    path = tmp_path / "dashes.toml"
    path.write_text('summary = "heavier -- and slower---"\n' + text)
    xml = export_osp(load_scenario(path), tmp_path / "osp")
    root = etree.parse(str(xml)).getroot()
    (comment,) = [c for c in root.iter(etree.Comment) if "heavier" in c.text]
    assert "--" not in comment.text and "heavier - - and slower- - -" in comment.text


def test_an_fmu_file_name_a_uri_would_misread_is_packaged_plainly(
    fmu_paths: dict[str, Path], tmp_path: Path
) -> None:
    """`Plant#1.fmu` was written as source="resources/Plant#1.fmu": libcosim took "#1.fmu"
    for a URI fragment (and ecos split a %20); the file is packaged as Plant_1.fmu."""
    odd = tmp_path / "Plant#1 ü%20.fmu"
    shutil.copy2(fmu_paths["AuvPlant"], odd)
    path = tmp_path / "odd.toml"
    path.write_text(PLANT_ALONE.format(fmu=odd))
    scenario = load_scenario(path)
    archive = export_ssp(scenario, tmp_path / "odd.ssp")
    (component,) = _ssd(archive).iterfind(".//ssd:Component", NS)
    assert component.get("source") == "resources/Plant_1___20.fmu"
    with zipfile.ZipFile(archive) as z:
        assert z.read("resources/Plant_1___20.fmu") == odd.read_bytes()
    xml = export_osp(scenario, tmp_path / "osp")
    (simulator,) = etree.parse(str(xml)).getroot().iterfind(".//o:Simulator", NS)
    assert simulator.get("source") == "Plant_1___20.fmu"
    assert (xml.parent / "Plant_1___20.fmu").read_bytes() == odd.read_bytes()


def test_the_note_says_a_step_multiple_reads_differently_in_libcosim(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """With step multiples libcosim and auv-cosim differ by 30 % of bs-3's yaw at 10 s,
    and the export said nothing (an instance whose outputs nothing reads gets no note)."""
    text = (Path(cli.__file__).parent / "scenarios" / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace("\nstep = 0.01", "\nstep = 0.01\nstep_multiples = { controller = 5 }")
    path = tmp_path / "slow.toml"
    path.write_text(text)
    argv = ["export", str(path), "--osp", str(tmp_path / "osp"), "--fmu-dir", str(fmu_dir)]
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    assert "note: controller steps every 5 h: libcosim hands a slow instance's outputs" in err


def test_the_note_says_an_adaptive_scenario_is_exported_at_its_first_step(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An adaptive scenario was exported at a fixed step of its first step, coupling.step,
    and the note spoke only of the coupling: nothing said its step no longer follows
    the error."""
    text = (Path(cli.__file__).parent / "scenarios" / "bs-3.toml").read_text(encoding="utf-8")
    path = tmp_path / "adaptive.toml"
    path.write_text(text.replace('algorithm = "gauss-seidel"', 'algorithm = "adaptive"'))
    argv = ["export", str(path), "--osp", str(tmp_path / "osp"), "--fmu-dir", str(fmu_dir)]
    assert cli.main(argv) == 0
    err = capsys.readouterr().err
    assert (
        "note: SSP and OSP have no error-controlled step: adaptive exported at the fixed "
        "step coupling.step = 0.01 s (its first step)" in err
    ), err


def _ball_without_base_units(folder: Path, start: str = "") -> Path:
    """BouncingBall.fmu in ``folder`` with `<Unit name="m"></Unit>` (no base units), and a
    scenario of it with the ``start`` table text; returns the scenario's path."""
    ball = Path(__file__).parents[2] / "data" / "reference-fmus" / "BouncingBall.fmu"
    bare = folder / "BouncingBall.fmu"
    with zipfile.ZipFile(ball) as old, zipfile.ZipFile(bare, "w") as new:
        for item in old.infolist():
            data = old.read(item)
            if item.filename == "modelDescription.xml":
                data, count = re.subn(rb'(<Unit name="m">)\s*<BaseUnit m="1"/>\s*', rb"\1", data)
                assert count == 1
            new.writestr(item, data)
    scenario = folder / "ball.toml"
    scenario.write_text(
        'stop_time = 1.0\n[coupling]\nstep = 0.01\n[instances.ball]\nfmu = "BouncingBall.fmu"\n'
        + (f"[instances.ball.start]\n{start}" if start else "")
    )
    return scenario


def test_a_unit_an_fmu_gives_no_base_units_is_left_off_the_connector(tmp_path: Path) -> None:
    """BouncingBall with `<Unit name="m"></Unit>` runs and validates, yet its SSP export
    was refused ("declares no SI base units for unit 'm' ...; an SSP unit needs them"),
    though a unit is optional on an SSP connector."""
    scenario = _ball_without_base_units(tmp_path)
    archive = export_ssp(load_scenario(scenario), tmp_path / "ball.ssp")
    connectors = {c.get("name"): c for c in _ssd(archive).iterfind(".//ssd:Connector", NS)}
    (height,) = connectors["h"]
    assert height.get("unit") is None
    (speed,) = connectors["v"]
    assert speed.get("unit") == "m/s"


def test_a_start_value_in_a_unit_without_base_units_is_written_without_it(
    tmp_path: Path,
) -> None:
    """The ball dropped from 2 m (``h``, in a unit "m" its FMU gives no base units): the
    parameter value is written without a unit, as its connector is, and the SSD is valid
    (the export failed with a traceback, "TypeError: Argument must be bytes or unicode,
    got 'NoneType'")."""
    scenario = _ball_without_base_units(tmp_path, "h = 2.0\n")
    archive = export_ssp(load_scenario(scenario), tmp_path / "ball.ssp")
    root = _ssd(archive)
    (value,) = root.iterfind(".//ssv:Parameter[@name='h']/ssv:Real", NS)
    assert (value.get("value"), value.get("unit")) == ("2.0", None)
    assert {u.get("name") for u in root.iterfind("ssd:Units/ssc:Unit", NS)} == {"m/s"}
    schema = Path(fmpy.__file__).parent / "ssp" / "schema" / "SystemStructureDescription.xsd"
    assert etree.XMLSchema(etree.parse(str(schema))).validate(etree.ElementTree(root))


def test_the_note_names_enumerations_written_as_integers(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Enumeration connectors and start values are written as Integer; libcosim then
    refused the file ("No such variable: b:Enumeration_input") and the export said
    nothing."""
    feedthrough = Path(__file__).parents[2] / "data" / "reference-fmus" / "Feedthrough.fmu"
    shutil.copy2(feedthrough, tmp_path)
    path = tmp_path / "enums.toml"
    path.write_text(
        'stop_time = 1.0\n[coupling]\nstep = 0.01\nalgorithm = "jacobi"\n'
        '[instances.a]\nfmu = "Feedthrough.fmu"\n[instances.b]\nfmu = "Feedthrough.fmu"\n'
        "[connections]\nsame_names = false\n"
        'add = [{ from = "a.Enumeration_output", to = "b.Enumeration_input" }]\n'
    )
    assert cli.main(["export", str(path), "--ssp", str(tmp_path / "enums.ssp")]) == 0
    err = capsys.readouterr().err
    assert "note: a.Enumeration_output, b.Enumeration_input: Enumeration, written as" in err


@pytest.mark.parametrize("flag", ["--ssp", "--osp"])
def test_the_note_names_a_debug_log_the_export_cannot_carry(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], flag: str
) -> None:
    """An instance's debug_logging and log_categories keys have no place in SSP or OSP:
    the export dropped them and said nothing, so the system ran without the debug log
    the scenario asked for."""
    text = (Path(cli.__file__).parent / "scenarios" / "bs-3.toml").read_text(encoding="utf-8")
    text = text.replace('fmu = "AuvPlant"', 'fmu = "AuvPlant"\ndebug_logging = true', 1)
    text = text.replace(
        'fmu = "AuvAutopilot"', 'fmu = "AuvAutopilot"\nlog_categories = ["logStatusError"]', 1
    )
    path = tmp_path / "logged.toml"
    path.write_text(text)
    target = tmp_path / ("logged.ssp" if flag == "--ssp" else "osp")
    assert cli.main(["export", str(path), flag, str(target), "--fmu-dir", str(fmu_dir)]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "debug log" in line]
    assert len(notes) == 1, notes
    assert "plant (every category)" in notes[0], notes
    assert "controller (logStatusError)" in notes[0], notes
    assert "not carried" in notes[0], notes


def _build_python(fmu: Path) -> str:
    """The build Python an FMU file records (``resources/fmu_runtime.txt``), "" for none."""
    with zipfile.ZipFile(fmu) as archive:
        record = archive.read("resources/fmu_runtime.txt").decode()
    return dict(line.split("=", 1) for line in record.splitlines())["build_python"]


@pytest.mark.slow
def test_an_export_of_portable_fmus_hands_them_on_portable(
    tmp_path: Path, capsys: pytest.CaptureFixture
) -> None:
    """FMUs built with ``auv-cosim build --portable`` and exported from their folder stay
    portable: neither the export nor the folder names this machine's Python (the export
    rebuilt them without --portable, the record then naming the build's venv)."""
    fmus = tmp_path / "fmus"
    assert cli.main(["build", "--portable", "--out", str(fmus)]) == 0
    before = {fmu.name: _build_python(fmu) for fmu in fmus.glob("*.fmu")}
    assert set(before.values()) == {""}
    code, err = _export(capsys, "bs-3", "--osp", tmp_path / "osp", "--fmu-dir", fmus)
    assert code == 0, err
    assert {fmu.name: _build_python(fmu) for fmu in fmus.glob("*.fmu")} == before
    for name in ("AuvPlant.fmu", "AuvAutopilot.fmu"):
        assert _build_python(tmp_path / "osp" / name) == ""
