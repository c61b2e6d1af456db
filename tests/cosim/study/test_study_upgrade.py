"""Study folders an older auv-cosim wrote, and studies of FMUs it built, under this
version's `auv-cosim sweep`: resumed where the rows would be the same, refused in one line
naming what differs otherwise (the fixtures: tests/data/upgrade/README.md)."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

import pytest
from sweep_helpers import table
from upgrade_files import (
    OLD_BUILTIN_STUDY,
    OLD_STUDY,
    old_plant_fmu,
    old_study,
    plant_scenario,
)

from cosim.cli import main

pytestmark = pytest.mark.usefixtures("no_early_cluster")  # refusals wait for no cluster
COMPARED = ("run", "osc.mu", "final.osc.x0", "final.osc.x1", "status")  # not wall_clock_s


def old_rows() -> dict[str, dict[str, str]]:
    """The rows the old version's killed study had written, by run id."""
    with (OLD_STUDY / "study" / "runs.csv").open(newline="", encoding="utf-8") as file:
        return {row["run"]: {k: row[k] for k in COMPARED} for row in csv.DictReader(file)}


@pytest.mark.cluster
@pytest.mark.slow
def test_a_study_an_older_version_killed_resumes_with_rows_this_version_makes_too(
    tmp_path: Path,
) -> None:
    """Its study.json lacks what later versions record (the scenario's files; the
    coupling's extrapolation, which its master always held): --resume refused it as
    "another study" though nothing that makes its rows had changed. The rows this
    version makes afresh are the old version's, so the resumed table is one study's."""
    study, out = old_study(tmp_path)
    assert main(["sweep", str(study), "--out", str(out), "--resume", "--workers", "1"]) == 0
    rows = {row["run"]: row for row in table(out)}
    assert len(rows) == 8 and {row["status"] for row in rows.values()} == {"complete"}
    kept = old_rows()
    assert {run: {k: rows[run][k] for k in COMPARED} for run in kept} == kept
    fresh = tmp_path / "fresh"
    assert main(["sweep", str(study), "--out", str(fresh), "--workers", "1"]) == 0
    again = {row["run"]: {k: row[k] for k in COMPARED} for row in table(fresh)}
    assert {run: again[run] for run in kept} == kept


def test_resuming_an_older_study_names_the_default_that_changed_since(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The old study's scenario names no algorithm: this version resolves it to
    quadratic extrapolation, the old one held the values. The refusal said "absent in
    the folder" and named the files, which had not changed."""
    study, out = old_study(tmp_path)
    scenario = tmp_path / "oscillator.toml"
    text = scenario.read_text(encoding="utf-8")
    scenario.write_text(text.replace('algorithm = "gauss-seidel"\n', ""), encoding="utf-8")
    assert main(["sweep", str(study), "--out", str(out), "--resume"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert (
        'differs from this one in: scenario (coupling.extrapolation: "none" in the folder, '
        '"quadratic" now)' in err
    ), err


@pytest.mark.cluster  # the old code started the study's workers
def test_a_study_of_an_fmu_built_before_build_packages_is_refused_at_once(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A study of such an FMU started its workers and failed every run with the FMU's
    instantiation error, one row each."""
    fmu = old_plant_fmu(tmp_path)
    scenario = plant_scenario(tmp_path, fmu)
    study = tmp_path / "study.toml"
    study.write_text(f'scenario = "{scenario}"\n[grid]\n"plant.u_0" = [1.0, 1.5]\n')
    out = tmp_path / "study"
    assert main(["sweep", str(study), "--workers", "1", "--out", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{fmu}: built by an older auv-cosim" in err, err
    assert not out.exists()


def test_resuming_a_study_of_the_fmus_an_older_version_built_says_they_were_rebuilt(
    fmu_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A study of the built-in FMUs, killed before an upgrade: the upgrade rebuilds them,
    so its rows are not this version's to continue. The refusal said only that the
    folder "holds another study" differing in "fmus", though the study file was the same."""
    shutil.copytree(OLD_BUILTIN_STUDY, tmp_path, dirs_exist_ok=True)
    study, out = tmp_path / "bs-2-study.toml", tmp_path / "study"
    argv = ["sweep", str(study), "--out", str(out), "--fmu-dir", str(fmu_dir), "--resume"]
    assert main(argv) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert "fmus (controller, plant: not the builds its runs used, as after an upgrade" in err
