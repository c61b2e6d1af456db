"""The files an older auv-cosim wrote (tests/data/upgrade/, README.md there), laid out in
a test's folder as the user who upgrades has them."""

from __future__ import annotations

import shutil
import zipfile
from pathlib import Path

import fmpy
import pytest
import pythonfmu
from repo_paths import TESTS

UPGRADE = TESTS / "data" / "upgrade"
OLD_STUDY = UPGRADE / "study-5ca3066"
OLD_RUN = UPGRADE / "run-5ca3066"
OLD_BUILTIN_STUDY = UPGRADE / "study-a4f9b94"  # of bs-2, with the FMUs that version built
# where the study's FMU was when the old version ran it (study.json records the path)
OLD_STUDY_FMU = "/tmp/upg/fx/VanDerPol.fmu"
PYTHONFMU_BINARY = (
    Path(pythonfmu.__file__).parent
    / "resources"
    / "binaries"
    / fmpy.platform
    / f"libpythonfmu-export{fmpy.sharedLibraryExtension}"
)


def old_plant_fmu(folder: Path) -> Path:
    """The trimmed AuvPlant.fmu of an older build in ``folder``, with pythonfmu's binary
    put back (the same file that build shipped, left out of the fixture for its size)."""
    if not PYTHONFMU_BINARY.is_file():
        pytest.skip(f"pythonfmu ships no {fmpy.platform} binary")
    fmu = folder / "AuvPlant.fmu"
    fmu.write_bytes((UPGRADE / "AuvPlant-5ca3066.fmu").read_bytes())
    with zipfile.ZipFile(fmu, "a") as archive:
        member = f"binaries/{fmpy.platform}/AuvPlant{fmpy.sharedLibraryExtension}"
        archive.write(PYTHONFMU_BINARY, member)
    return fmu


def plant_scenario(folder: Path, fmu: Path) -> Path:
    """A scenario of the plant ``fmu`` alone, two steps long, in ``folder``."""
    scenario = folder / "old-fmu.toml"
    scenario.write_text(
        f'stop_time = 0.02\n[coupling]\nstep = 0.01\n[instances.plant]\nfmu = "{fmu}"\n'
    )
    return scenario


def old_study(folder: Path) -> tuple[Path, Path]:
    """The old version's study file, scenario, FMU and killed study folder (3 of its 8
    runs done) in ``folder``, the FMU's path in study.json moved to where it now is:
    (study file, study folder)."""
    for name in ("oscillator.toml", "oscillator-study.toml"):
        shutil.copy(OLD_STUDY / name, folder / name)
    shutil.copy(TESTS / "data" / "reference-fmus" / "VanDerPol.fmu", folder / "VanDerPol.fmu")
    out = folder / "study"
    shutil.copytree(OLD_STUDY / "study", out)
    marker = out / "study.json"
    text = marker.read_text(encoding="utf-8")
    assert OLD_STUDY_FMU in text
    marker.write_text(text.replace(OLD_STUDY_FMU, str(folder / "VanDerPol.fmu")), "utf-8")
    return folder / "oscillator-study.toml", out
