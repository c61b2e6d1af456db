"""What an export says of the hosts that will run it, and where it can be written.

A system that libcosim or ecos would run otherwise than ``auv-cosim run SYSTEM
--algorithm jacobi --extrapolation none`` gets a note on stderr naming what differs (an
instance passing a connected input on to an output within a step, a start value libcosim
skips); an archive no host can load (a name without ``.ssp``) or a folder an export
cannot replace (the working folder) is refused with a one-line reason, writing nothing.
Built only from the reference FMUs (tests/data/reference-fmus): no FMU of ours is built.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from repo_paths import TESTS

from cosim import cli
from cosim.errors import CosimError
from cosim.export import export_osp, export_ssp
from cosim.scenario.spec import load_scenario

REFERENCE_FMUS = TESTS / "data" / "reference-fmus"

RELAY = """\
id = "relay"
stop_time = 1.0
[coupling]
step = 0.01
algorithm = "jacobi"
[instances.source]
fmu = "Dahlquist.fmu"
[instances.relay]
fmu = "Feedthrough.fmu"
[connections]
same_names = false
add = [{ from = "source.x", to = "relay.Float64_continuous_input" }]
"""

BALL = """\
id = "ball"
stop_time = 1.0
[coupling]
step = 0.01
algorithm = "jacobi"
[instances.ball]
fmu = "BouncingBall.fmu"
[instances.ball.start]
h = 1.5
e = 0.8
"""


def _scenario(folder: Path, text: str, *fmus: str) -> Path:
    for fmu in fmus:
        shutil.copy2(REFERENCE_FMUS / fmu, folder)
    path = folder / "system.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _notes(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert cli.main(["export", *argv]) == 0
    return capsys.readouterr().err


@pytest.mark.parametrize("fmt", ["--ssp", "--osp"])
def test_the_note_names_a_feedthrough_other_masters_pass_on_a_step_late(
    fmt: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A Feedthrough between two instances hands on its input of the same point in
    auv-cosim, even under Jacobi, the previous step's to the instances it drives in
    libcosim and ecos (bs-3 with the thruster command relayed so: 1.2 N apart in 3 s);
    docs/hosts.md said the export names it, and it said nothing."""
    path = _scenario(tmp_path, RELAY, "Dahlquist.fmu", "Feedthrough.fmu")
    target = tmp_path / ("relay.ssp" if fmt == "--ssp" else "relay-osp")
    err = _notes([str(path), fmt, str(target)], capsys)
    assert (
        "note: relay passes relay.Float64_continuous_input on to Float64_continuous_output "
        "within a step (direct feedthrough)" in err
    ), err


def test_no_feedthrough_note_for_an_input_nothing_drives(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only a connected input fed through differs between the masters: the relay's other
    inputs hold their start values in all of them."""
    text = RELAY.replace("Float64_continuous_input", "Float64_discrete_input")
    path = _scenario(tmp_path, text, "Dahlquist.fmu", "Feedthrough.fmu")
    err = _notes([str(path), "--ssp", str(tmp_path / "relay.ssp")], capsys)
    assert "relay.Float64_discrete_input on to Float64_discrete_output" in err
    assert "Float64_continuous_input" not in err


def test_the_note_names_an_output_start_value_libcosim_skips_in_an_ssp(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The ball dropped from h = 1.5 m (an output with initial "exact"): libcosim's SSP
    loader applies a parameter set to parameters and inputs only and dropped it with a
    log line (the ball fell from 1 m, 0.8 m below ours), and the export said nothing;
    its OSP loader sets it, so an OSP export gets no such note."""
    path = _scenario(tmp_path, BALL, "BouncingBall.fmu")
    err = _notes([str(path), "--ssp", str(tmp_path / "ball.ssp")], capsys)
    assert "note: ball.h (output): a start value libcosim skips in an SSP" in err, err
    assert "ball.e" not in err  # a parameter: every host sets it
    err = _notes([str(path), "--osp", str(tmp_path / "ball-osp")], capsys)
    assert "ball.h" not in err


@pytest.mark.parametrize("name", ["ball", "ball.zip", "ball.SSP"])
def test_an_archive_not_named_ssp_is_refused_before_writing(name: str, tmp_path: Path) -> None:
    """libcosim unpacks only a file named *.ssp ("Validation of .../ball failed" for any
    other) and SSP 1.0 names its archives so; the export wrote one all the same."""
    scenario = load_scenario(_scenario(tmp_path, BALL, "BouncingBall.fmu"))
    with pytest.raises(CosimError, match=rf"cannot write .*{name}: .*'\.ssp'"):
        export_ssp(scenario, tmp_path / name)
    assert not (tmp_path / name).exists()


def test_the_working_folder_as_osp_target_is_refused_clearly(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--osp .`` failed with "cannot write .: Device or resource busy" (an export
    replaces its folder as a whole, and the working folder cannot be): the message says
    why and what to give instead, and the folder stays empty."""
    scenario = load_scenario(_scenario(tmp_path, BALL, "BouncingBall.fmu"))
    here = tmp_path / "here"
    here.mkdir()
    monkeypatch.chdir(here)
    with pytest.raises(CosimError, match="is the working folder") as refused:
        export_osp(scenario, ".")
    assert "Device or resource busy" not in str(refused.value)
    assert list(here.iterdir()) == []


def test_an_osp_export_to_a_full_path_needs_no_working_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Looking for the working folder (to refuse it as a target) must not refuse a full
    path when the working folder was removed since."""
    scenario = load_scenario(_scenario(tmp_path, BALL, "BouncingBall.fmu"))
    gone = tmp_path / "gone"
    gone.mkdir()
    monkeypatch.chdir(gone)
    gone.rmdir()
    xml = export_osp(scenario, tmp_path / "osp")
    assert xml == tmp_path / "osp" / "OspSystemStructure.xml"


def test_an_osp_folder_named_through_dot_dot_is_written_where_it_points(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--osp ../osp/inner/..`` failed with "cannot write ../osp/inner/..: Device or
    resource busy" (its temporary folder went beside a folder named ``..``): a name is
    taken as the folder it points to."""
    scenario = load_scenario(_scenario(tmp_path, BALL, "BouncingBall.fmu"))
    (tmp_path / "work" / "sub").mkdir(parents=True)
    monkeypatch.chdir(tmp_path / "work" / "sub")
    xml = export_osp(scenario, "../osp/inner/..")
    assert xml == (tmp_path / "work" / "osp" / "OspSystemStructure.xml")
    assert sorted(p.name for p in (tmp_path / "work").iterdir()) == ["osp", "sub"]


def test_the_note_says_libcosim_skips_an_enumeration_start_value_in_an_ssp(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An Enumeration start value in an SSP is skipped by libcosim with a log line ("No
    such variable: relay:Enumeration_input"), the system loads and runs without it; the
    note said libcosim refuses the file."""
    text = RELAY + "[instances.relay.start]\nEnumeration_input = 2\n"
    path = _scenario(tmp_path, text, "Dahlquist.fmu", "Feedthrough.fmu")
    err = _notes([str(path), "--ssp", str(tmp_path / "relay.ssp")], capsys)
    assert "relay.Enumeration_input: Enumeration, written as Integer" in err
    assert "skips an SSP start value of one" in err, err


CONTROL = """\
id = "control"
summary = "{summary}"
stop_time = 1.0
[coupling]
step = 0.01
[instances.relay]
fmu = "Feedthrough.fmu"
[instances.relay.start]
String_input = "{value}"
"""


@pytest.mark.parametrize(
    ("summary", "value", "named"),
    [
        ("plain", "a\\u0001b", "relay.String_input = 'a\\x01b'"),
        ("bell \\u0007 here", "plain", "summary = 'bell \\x07 here'"),
    ],
)
def test_a_string_xml_cannot_carry_is_refused_naming_it(
    summary: str, value: str, named: str, tmp_path: Path
) -> None:
    """A control character in a String start value or the summary (the master runs it)
    ended both exports in "ValueError: All strings must be XML compatible", naming
    neither the value nor the character; nothing is written."""
    text = CONTROL.format(summary=summary, value=value)
    scenario = load_scenario(_scenario(tmp_path, text, "Feedthrough.fmu"))
    for export, target in ((export_ssp, "c.ssp"), (export_osp, "c-osp")):
        with pytest.raises(CosimError, match=r"XML 1\.0 cannot carry") as refused:
            export(scenario, tmp_path / target)
        assert named in str(refused.value)
        assert not (tmp_path / target).exists()


@pytest.mark.parametrize(
    ("fmt", "written"),
    [("--ssp", "resources/relay/cfg.toml"), ("--osp", "written as relay-cfg.toml, a path")],
)
def test_the_note_says_where_a_start_value_naming_a_file_is_found(
    fmt: str, written: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A String start value naming a file (``cfg.toml`` beside the scenario) of an FMU
    that takes no file inline: the SSP packs it but names it by a path relative to the
    archive, which libcosim and ecos resolve from their working folder; the OSP export
    copies it beside the system structure. Both said nothing of it once: a system moved
    to another folder or machine ran without its file."""
    text = RELAY + '[instances.relay.start]\nString_input = "cfg.toml"\n'
    path = _scenario(tmp_path, text, "Dahlquist.fmu", "Feedthrough.fmu")
    (tmp_path / "cfg.toml").write_text("a = 1\n", encoding="utf-8")
    target = tmp_path / ("files.ssp" if fmt == "--ssp" else "files-osp")
    err = _notes([str(path), fmt, str(target)], capsys)
    assert "note: relay.String_input names a file" in err, err
    assert written in err, err


def test_an_osp_export_copies_a_file_a_start_value_names_beside_the_system(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The OSP export wrote the absolute path of this machine's file as the start value
    and copied nothing, so the exported folder, moved, named a file that was not there:
    the file is copied beside OspSystemStructure.xml, the start value names the copy
    (relative, found from the folder), and a second export over the first is taken as
    its own (the copy is in its record)."""
    text = RELAY + '[instances.relay.start]\nString_input = "cfg.toml"\n'
    path = _scenario(tmp_path, text, "Dahlquist.fmu", "Feedthrough.fmu")
    (tmp_path / "cfg.toml").write_text("a = 1\n", encoding="utf-8")
    target = tmp_path / "files-osp"
    for _ in range(2):  # the second replaces the first
        _notes([str(path), "--osp", str(target)], capsys)
    assert (target / "relay-cfg.toml").read_text(encoding="utf-8") == "a = 1\n"
    xml = (target / "OspSystemStructure.xml").read_text(encoding="utf-8")
    assert 'value="relay-cfg.toml"' in xml, xml
    assert str(tmp_path / "cfg.toml") not in xml
