"""Files an older auv-cosim wrote, used by this one: each is run, resumed or refused in one
line that names what is old about it and what to do (the fixtures and the versions that
made them: tests/data/upgrade/README.md)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from upgrade_files import OLD_RUN, old_plant_fmu, old_study, plant_scenario

from cosim.cli import main


def test_an_fmu_built_before_build_packages_is_refused_naming_the_rebuild(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An FMU built before each build's code went under a package of its own ships the
    top-level packages fmu_runtime and plant_fmu; this process runs its own modules of
    those names, so the old FMU's code called this version's (a TypeError from deep in
    the FMU's instantiation, or this version's code run as the old FMU's)."""
    fmu = old_plant_fmu(tmp_path)
    scenario = plant_scenario(tmp_path, fmu)
    assert main(["run", str(scenario), "--out", str(tmp_path / "run"), "--no-rrd"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert f"{fmu}: built by an older auv-cosim" in err, err
    assert "fmu_runtime, plant_fmu" in err and "`auv-cosim build`" in err, err


def test_validate_names_an_fmu_built_before_build_packages(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """`auv-cosim validate` of such an FMU said its smoke run's process died (exit code
    -11) or a step failed, naming no cause and nothing to do."""
    fmu = old_plant_fmu(tmp_path)
    assert main(["validate", str(fmu)]) == 1
    out = capsys.readouterr().out
    assert f"{fmu}: built by an older auv-cosim" in out, out


def test_a_run_folder_an_older_version_wrote_is_refused_naming_the_version(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A run folder from before runs listed their files cannot be replaced (nothing in it
    is known to be the run's); the refusal named a missing file, not that an older
    auv-cosim wrote the folder, and left the user to guess how it got that way."""
    old_study(tmp_path)  # for its scenario of a reference FMU: no FMU is built
    out = tmp_path / "runs" / "bs-2"
    shutil.copytree(OLD_RUN, out)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    argv = ["run", str(tmp_path / "oscillator.toml"), "--out", str(out), "--overwrite"]
    assert main([*argv, "--no-rrd"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "an earlier run (scenario 'bs-2', status 'complete') that an older auv-cosim" in err
    assert "move the folder away" in err, err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
