"""Variable names of FMUs nobody here wrote -- Modelica's ``der(y, 2)``, ``frame_a.r_0[1]``,
quoted names -- work as themselves in a scenario's connections, start values and events,
and reach results.csv and the recording as one column and one entity each, whatever
commas, quotes, slashes, brackets or spaces they hold."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np
import pandas as pd
import pytest
import rerun as rr
from repo_paths import TESTS
from rerun.chunk import RrdReader

from cosim.outputs.results import read_csv

FEEDTHROUGH = TESTS / "data" / "reference-fmus" / "Feedthrough.fmu"
DAHLQUIST = TESTS / "data" / "reference-fmus" / "Dahlquist.fmu"
RENAMED = {  # Feedthrough's names -> names FMI 2.0 allows and Modelica tools write
    "Float64_continuous_input": "body.frame_a.r_0[1]",
    "Float64_continuous_output": "der(y, 2)",
    "Float64_tunable_parameter": 'k/x "gain", A[1,2]',
}


def renamed_feedthrough(folder: Path) -> Path:
    """Feedthrough.fmu with its variables renamed in its model description (the binary
    knows them by value reference only)."""
    path = folder / "renamed.fmu"
    with zipfile.ZipFile(FEEDTHROUGH) as source, zipfile.ZipFile(path, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                for old, new in RENAMED.items():
                    text = text.replace(f'name="{old}"', f"name={quoteattr(new)}")
                data = text.encode()
            target.writestr(item, data)
    return path


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    """The run's folder and what it printed on stderr (in a process of its own: Rerun's
    warnings are printed once per process)."""
    folder = tmp_path_factory.mktemp("foreign-names")
    fmu = renamed_feedthrough(folder)
    scenario = folder / "names.toml"
    scenario.write_text(
        f"stop_time = 0.5\n[coupling]\nstep = 0.1\n"
        f'[instances.src]\nfmu = "{DAHLQUIST}"\n[instances.ft]\nfmu = "{fmu}"\n'
        f"[instances.ft.start]\n{rr_key(RENAMED['Float64_tunable_parameter'])} = 2.5\n"
        '[connections]\nadd = [{ from = "src.x", to = "ft.body.frame_a.r_0[1]" }]\n'
        '[output]\nrecord = ["src.x", "ft.der(y, 2)", '
        f"{rr_key('ft.' + RENAMED['Float64_tunable_parameter'])}]\n"
        '[[events]]\nname = "raise"\nwhen = "ft.der(y, 2) < 0.7"\n'
        f"set = {{ {rr_key('ft.' + RENAMED['Float64_tunable_parameter'])} = 3.0 }}\n"
    )
    command = [sys.executable, "-m", "cosim.cli", "run", str(scenario), "--out", "run", "--quiet"]
    done = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    return folder / "run", done.stderr


def rr_key(text: str) -> str:
    """``text`` as a TOML literal string (it holds double quotes, no single one)."""
    return f"'{text}'"


COLUMNS = ["time", "src.x", "ft.der(y, 2)", 'ft.k/x "gain", A[1,2]']


def test_results_csv_has_one_column_per_variable_for_any_csv_reader(run_folder) -> None:
    out, _ = run_folder
    with open(out / "results.csv", newline="") as file:
        assert next(csv.reader(file)) == COLUMNS
    table = pd.read_csv(out / "results.csv")
    assert list(table.columns) == COLUMNS
    names, values = read_csv(out / "results.csv")
    assert names == COLUMNS
    np.testing.assert_array_equal(values[:, 1], values[:, 2])  # fed through
    fired = json.loads((out / "summary.json").read_text())["events"]
    assert [(e["name"], e["time"]) for e in fired] == [("raise", pytest.approx(0.4))]
    np.testing.assert_array_equal(values[:, 3], np.where(values[:, 0] < 0.35, 2.5, 3.0))


def test_the_recording_has_one_entity_per_variable_and_no_warning(run_folder) -> None:
    out, stderr = run_folder
    assert "WARN" not in stderr, stderr
    entities = set(RrdReader(out / "recording.rrd").stream().collect().schema().entity_paths())
    for column in COLUMNS[2:]:
        instance, variable = column.split(".", 1)
        assert f"/other/{instance}/{rr.escape_entity_path_part(variable)}" in entities, entities
