"""Files an older auv-cosim wrote, used by this one: each is run, resumed or refused in one
line that names what is old about it and what to do (the fixtures and the versions that
made them: tests/data/upgrade/README.md)."""

from __future__ import annotations

from pathlib import Path

import pytest
from upgrade_files import old_plant_fmu, plant_scenario

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
