"""Files an older auv-cosim wrote, used by this one: each is run, resumed or refused in one
line that names what is old about it and what to do (the fixtures and the versions that
made them: tests/data/upgrade/README.md)."""

from __future__ import annotations

import zipfile
from pathlib import Path

import fmpy
import pytest

from cosim.cli import main

DATA = Path(__file__).parents[1] / "data" / "upgrade"
PYTHONFMU_BINARY = (
    Path(__import__("pythonfmu").__file__).parent
    / "resources"
    / "binaries"
    / fmpy.platform
    / f"libpythonfmu-export{fmpy.sharedLibraryExtension}"
)


def old_plant_fmu(tmp_path: Path) -> Path:
    """The trimmed AuvPlant.fmu of an older build, with pythonfmu's binary put back (the
    same file that build shipped, left out of the fixture for its size)."""
    if not PYTHONFMU_BINARY.is_file():
        pytest.skip(f"pythonfmu ships no {fmpy.platform} binary")
    fmu = tmp_path / "AuvPlant.fmu"
    fmu.write_bytes((DATA / "AuvPlant-5ca3066.fmu").read_bytes())
    with zipfile.ZipFile(fmu, "a") as archive:
        member = f"binaries/{fmpy.platform}/AuvPlant{fmpy.sharedLibraryExtension}"
        archive.write(PYTHONFMU_BINARY, member)
    return fmu


def test_an_fmu_built_before_build_packages_is_refused_naming_the_rebuild(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """An FMU built before each build's code went under a package of its own ships the
    top-level packages fmu_runtime and plant_fmu; this process runs its own modules of
    those names, so the old FMU's code called this version's (a TypeError from deep in
    the FMU's instantiation, or this version's code run as the old FMU's)."""
    fmu = old_plant_fmu(tmp_path)
    scenario = tmp_path / "old-fmu.toml"
    scenario.write_text(
        f'stop_time = 0.02\n[coupling]\nstep = 0.01\n[instances.plant]\nfmu = "{fmu}"\n'
    )
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


@pytest.mark.cluster  # the old code started the study's workers
def test_a_study_of_an_fmu_built_before_build_packages_is_refused_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A study of such an FMU started its workers and failed every run with the FMU's
    instantiation error, one row each."""
    fmu = old_plant_fmu(tmp_path)
    scenario = tmp_path / "old-fmu.toml"
    scenario.write_text(
        f'stop_time = 0.02\n[coupling]\nstep = 0.01\n[instances.plant]\nfmu = "{fmu}"\n'
    )
    study = tmp_path / "study.toml"
    study.write_text(f'scenario = "{scenario}"\n[grid]\n"plant.u_0" = [1.0, 1.5]\n')
    out = tmp_path / "study"
    assert main(["sweep", str(study), "--workers", "1", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{fmu}: built by an older auv-cosim" in err, err
    assert not out.exists()
