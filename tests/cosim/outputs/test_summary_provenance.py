"""summary.json says what produced its run's files: the unit of every results.csv column
(results.csv's own header has none, and its bytes stay as they are) and the versions of
the tool, fmpy, Python and each FMU (by its GUID) that ran it, from the start of the run;
and docs/runs.md names every key it holds."""

from __future__ import annotations

import importlib.metadata
import json
import platform
import re
from pathlib import Path

import fmpy
import pytest
from repo_paths import ROOT

import cosim
from cosim.fmus.interface import read_interface
from cosim.outputs.results import header_columns, running_summary
from cosim.scenario.spec import load_scenario


@pytest.fixture(scope="module")
def run_dir(fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("bs-3") / "run"
    cosim.run("bs-3", stop_time=0.05, out=out, recording=False, fmu_dir=fmu_dir)
    return out


def _summary(run_dir: Path) -> dict:
    return json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))


def test_summary_gives_the_unit_of_every_results_column_in_its_order(
    run_dir: Path, fmu_dir: Path
) -> None:
    """An analyst reading results.csv finds each column's unit in summary.json: the same
    names in the same order, ``time`` in s, each variable in the unit its FMU declares.
    The scenario is read with the session's FMUs: the default folder (build/fmus under the
    working directory) had the FMUs built into the repository's clone, and failed where
    that folder could not be made."""
    header = (run_dir / "results.csv").read_text(encoding="utf-8").split("\n", 1)[0]
    units = _summary(run_dir)["units"]
    assert list(units) == header_columns(header)
    assert units["time"] == "s"
    scenario = load_scenario(run_dir / "scenario.toml", fmu_dir=fmu_dir)
    for column in header_columns(header)[1:]:
        instance, _, variable = column.partition(".")
        declared = scenario.instances[instance].interface.variables[variable].unit
        assert units[column] == (declared or "1"), column
    assert (units["plant.yaw"], units["controller.tunnel_force"]) == ("rad", "N")
    assert (units["plant.kinetic_energy"], units["plant.quat_w"]) == ("J", "1")


def test_summary_names_the_versions_and_fmus_that_made_the_run(
    run_dir: Path, fmu_dir: Path
) -> None:
    """The tool, fmpy and Python versions, and each instance's FMU by its GUID (a function
    of the FMU's content) and its file, so two runs' files can be told apart by what
    produced them."""
    summary = _summary(run_dir)
    assert summary["versions"] == {
        "auv-cosim": importlib.metadata.version("auv-cosim"),
        "fmpy": fmpy.__version__,
        "python": platform.python_version(),
    }
    for instance, fmu in (("plant", "AuvPlant"), ("controller", "AuvAutopilot")):
        interface = read_interface(fmu_dir / f"{fmu}.fmu")
        assert summary["fmus"][instance] == {
            "model": interface.model_identifier,
            "guid": interface.guid,
            "path": str(interface.path),
        }


def test_a_killed_runs_summary_already_has_the_units_and_versions(
    fmu_dir: Path, tmp_path: Path
) -> None:
    """The running summary (all a killed run leaves) carries both from the start."""
    scenario = load_scenario("bs-3", fmu_dir=fmu_dir)
    running = running_summary(scenario, {"results": tmp_path / "results.csv"}, tmp_path)
    assert list(running["units"]) == ["time", *scenario.columns]
    assert set(running["fmus"]) == set(scenario.instances)
    assert set(running["versions"]) == {"auv-cosim", "fmpy", "python"}


def _named(doc: str) -> set[str]:
    """The names a page gives in backticks (``key``, ``key.sub``: both parts)."""
    text = (ROOT / "docs" / doc).read_text(encoding="utf-8")
    return {part for name in re.findall(r"`([^`\s]+)`", text) for part in name.split(".")}


def test_every_key_of_a_runs_summary_is_named_in_the_docs(run_dir: Path, fmu_dir: Path) -> None:
    """An analyst who meets a key in summary.json finds it by name in docs/runs.md: every
    top-level key, key figure and start-up phase, and every ``coupling`` key of a fixed-step
    and of an adaptive run (or in docs/coupling.md, which explains the adaptive step)."""
    summary = _summary(run_dir)
    adaptive = cosim.run("bs-3", stop_time=0.05, algorithm="adaptive", fmu_dir=fmu_dir).summary
    runs = _named("runs.md")
    keys = {*summary, *summary["key_figures"], *summary["startup_s"]}
    assert sorted(keys - runs) == []
    coupling = {*summary["coupling"], *adaptive["coupling"]}
    assert sorted(coupling - runs - _named("coupling.md")) == []


def _documented_key_order() -> list[str]:
    """The top-level keys docs/runs.md's summary.json table lists, in its rows' order
    (a row may name two: `stop_time`, `step`)."""
    text = (ROOT / "docs" / "runs.md").read_text(encoding="utf-8")
    table = text.split("\n## summary.json\n", 1)[1].split("\n## ", 1)[0]
    rows = [line.split("|")[1] for line in table.splitlines() if line.startswith("| `")]
    return [key for cell in rows for key in re.findall(r"`([^`]+)`", cell)]


def test_a_runs_summary_has_its_keys_in_the_order_the_docs_list_them(run_dir: Path) -> None:
    """docs/runs.md lists summary.json's keys "in the order the file has them": a reader
    following the table down the file finds each key where the table puts it
    (``recording_error`` beside ``error``, not after the FMUs)."""
    summary = _summary(run_dir)
    documented = _documented_key_order()
    assert sorted(set(summary) - set(documented)) == []
    assert list(summary) == [key for key in documented if key in summary]
