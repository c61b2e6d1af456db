"""`auv-cosim validate FILE.fmu ...`: any FMU a scenario may name is checked for what a
run needs of it, and each one that a run would refuse is named with the reason and, where
fmpy can mend it, the command that does."""

from __future__ import annotations

import os
import re
import shutil
import tempfile
import zipfile
from pathlib import Path

import pytest

from cosim.cli import main

REFERENCE = Path(__file__).parents[2] / "data" / "reference-fmus"


def _rewritten(source: Path, target: Path, *, drop: str = "", cut: str = "") -> Path:
    """A copy of ``source`` without the members under ``drop`` and with the elements
    matching the regular expression ``cut`` taken out of its modelDescription.xml."""
    with zipfile.ZipFile(source) as old, zipfile.ZipFile(target, "w") as new:
        for item in old.infolist():
            if drop and item.filename.startswith(drop):
                continue
            data = old.read(item)
            if cut and item.filename == "modelDescription.xml":
                data, count = re.subn(cut.encode(), b"", data, flags=re.S)
                assert count == 1
            new.writestr(item, data)
    return target


def test_fmus_nobody_here_wrote_are_validated_one_line_each(capsys):
    fmus = [REFERENCE / f"{name}.fmu" for name in ("BouncingBall", "Dahlquist", "Feedthrough")]
    assert main(["validate", *map(str, fmus)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[-1] == "every FMU is valid"
    for fmu in fmus:
        (line,) = [text for text in lines if text.startswith(f"{fmu}: ")]
        assert "fmpy's validation; FMI 2.0 co-simulation" in line
    # Dahlquist has one Real output, BouncingBall and Feedthrough two: said in words
    assert [line.rsplit(" with ", 1)[1] for line in lines[:3]] == [
        "2 finite Real outputs",
        "1 finite Real output",
        "2 finite Real outputs",
    ]


def test_validate_leaves_no_extracted_fmu_behind(tmp_path, capsys, monkeypatch):
    """The smoke run's process extracted each FMU into a temporary folder of its own and
    exited without removing it: every ``auv-cosim validate`` left one folder per FMU
    (2.2 MB each of ours) in the temporary folder."""
    temporary = tmp_path / "tmp"
    temporary.mkdir()
    monkeypatch.setenv("TMPDIR", str(temporary))  # the smoke run's process
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))  # this one
    fmus = [REFERENCE / f"{name}.fmu" for name in ("BouncingBall", "Dahlquist")]
    assert main(["validate", *map(str, fmus)]) == 0
    assert capsys.readouterr().out.strip().endswith("every FMU is valid")
    assert sorted(p.name for p in temporary.iterdir()) == []


def test_an_fmu_a_run_would_refuse_is_named_with_the_command_that_mends_it(tmp_path, capsys):
    """Without a binary for this platform (it ships C sources) and with model exchange
    only, as a run refuses them: `fmpy compile` and `fmpy add-cswrapper` are named."""
    ball = REFERENCE / "BouncingBall.fmu"
    no_binary = _rewritten(ball, tmp_path / "NoBinary.fmu", drop="binaries/")
    exchange = _rewritten(ball, tmp_path / "Exchange.fmu", cut=r"<CoSimulation.*?</CoSimulation>")
    assert main(["validate", str(no_binary), str(exchange), str(ball)]) == 1
    captured = capsys.readouterr()
    lines = captured.out.strip().splitlines()
    assert len(lines) == 2, lines
    assert lines[0].startswith(f"{no_binary}: no binaries/linux64/BouncingBall.so in the FMU")
    assert "(binaries for: none)" in lines[0]
    assert f"`fmpy compile {no_binary}` builds one" in lines[0]
    assert lines[1].startswith(f"{exchange}: not a co-simulation FMU (model exchange only")
    assert "fmpy add-cswrapper" in lines[1]
    assert "every FMU is valid" not in captured.out
    assert captured.err == "auv-cosim validate: 2 problem(s) found in the FMUs\n"


def test_what_is_not_an_fmu_file_is_named(tmp_path, capsys):
    text = tmp_path / "notes.fmu"
    text.write_text("not a zip", encoding="utf-8")
    missing = tmp_path / "missing.fmu"
    pipe = tmp_path / "pipe.fmu"  # it was "no such file"
    os.mkfifo(pipe)
    assert main(["validate", str(text), str(missing), str(tmp_path), str(pipe)]) == 1
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines == [
        f"{text}: not a valid FMU: File is not a zip file",
        f"{missing}: no such file",
        f"{tmp_path}: is a folder: give its .fmu files, or --fmu-dir for the built FMUs in it",
        f"{pipe}: not a file: a pipe or a device",
    ]


@pytest.mark.parametrize("version", ["1.0", "3.0"])
def test_an_fmu_of_another_fmi_version_is_named_in_one_line_as_a_run_names_it(
    tmp_path, capsys, version
):
    """An FMU whose description says FMI 1.0 or 3.0 gets the run's one line naming the
    version and what was expected, not fmpy's schema report (three and seven lines of
    schema errors, none naming the version)."""
    fmu = tmp_path / "Oscillator.fmu"
    with zipfile.ZipFile(REFERENCE / "VanDerPol.fmu") as old, zipfile.ZipFile(fmu, "w") as new:
        for item in old.infolist():
            data = old.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'fmiVersion="2.0"', f'fmiVersion="{version}"'.encode())
            new.writestr(item, data)
    assert main(["validate", str(fmu)]) == 1
    captured = capsys.readouterr()
    line = f"{fmu}: fmiVersion '{version}': expected an FMI 2.0 FMU"
    assert captured.out.strip().splitlines() == [line]
    scenario = tmp_path / "oscillator.toml"
    scenario.write_text(
        'stop_time = 1.0\n[coupling]\nstep = 0.01\n[instances.v]\nfmu = "Oscillator.fmu"\n',
        encoding="utf-8",
    )
    assert main(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-rrd"]) == 1
    where = f"scenario file {scenario}: key 'instances.v.fmu'"  # as a missing FMU is named
    assert capsys.readouterr().err == f"auv-cosim run: {where}: {line}\n"


def test_files_and_a_folder_of_built_fmus_are_not_asked_for_together(tmp_path, capsys):
    fmu = shutil.copy2(REFERENCE / "Dahlquist.fmu", tmp_path)
    assert main(["validate", str(fmu), "--fmu-dir", str(tmp_path)]) == 1
    assert capsys.readouterr().err == (
        "auv-cosim validate: give FMU files or --fmu-dir DIR, not both\n"
    )


@pytest.mark.parametrize("refused", ["no_binary", "model_exchange"])
def test_a_run_names_the_same_mend_as_validate(tmp_path, capsys, refused):
    """A scenario naming an FMU without this platform's binary or without co-simulation
    is refused with the reason `validate` gives."""
    ball = REFERENCE / "BouncingBall.fmu"
    if refused == "no_binary":
        fmu = _rewritten(ball, tmp_path / "Ball.fmu", drop="binaries/")
        expected = f"`fmpy compile {fmu}` builds one"
    else:
        fmu = _rewritten(ball, tmp_path / "Ball.fmu", cut=r"<CoSimulation.*?</CoSimulation>")
        expected = "not a co-simulation FMU (model exchange only: `fmpy add-cswrapper"
    scenario = tmp_path / "ball.toml"
    scenario.write_text(
        'stop_time = 1.0\n[coupling]\nstep = 0.01\n[instances.ball]\nfmu = "Ball.fmu"\n',
        encoding="utf-8",
    )
    assert main(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-rrd"]) == 1
    assert expected in capsys.readouterr().err
