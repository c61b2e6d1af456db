"""The workers' fork server, given the command's FMU folder, imports the Python package
those FMUs ship before it forks a worker: each worker finds it imported (its warm-up then
loads only the libraries, kernels and instances) and runs as before."""

from __future__ import annotations

import pytest

from cosim.study import fork_server

PRELOAD = """
import sys
import zipfile
from pathlib import Path
from cosim.study.fork_fmus import package_of, preload

fmu_dir, other = Path(sys.argv[1]), Path(sys.argv[2])
(other / "broken.fmu").write_bytes(b"not a zip")
with zipfile.ZipFile(other / "foreign.fmu", "w") as archive:
    archive.writestr("modelDescription.xml", "<fmiModelDescription/>")
print(preload(other), package_of(other / "foreign.fmu"))  # nothing, and no exception
packages = preload(fmu_dir)
print(packages, [package_of(p) for p in sorted(fmu_dir.glob("*.fmu"))][0] in packages)
print(preload(fmu_dir), len([n for n in sys.modules if n.startswith(packages[0] + ".")]) > 10)
"""


def test_the_package_is_imported_once_and_a_foreign_fmu_is_skipped(
    fmu_paths, run_python, tmp_path
) -> None:
    done = run_python(PRELOAD, fmu_paths["AuvPlant"].parent, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    skipped, imported, again = done.stdout.strip().splitlines()[-3:]
    assert skipped == "[] None"
    assert imported.startswith("['auvfmu_") and imported.endswith("] True"), imported
    assert again == "[] True"


FORKED = """
import sys
from pathlib import Path
from cosim.study import fork_server
from cosim.study.design import PlannedRun
from cosim.study.execution import execute, make_job, open_client
from cosim.study.fork_fmus import package_of
from cosim.study.task import prepare

def imported(package):
    return package in sys.modules

if __name__ == "__main__":
    fmu_dir = Path(sys.argv[1])
    fork_server.start(fmu_dir)
    base, _ = prepare("bs-3", 1.0, fmu_dir)
    job, plugin = make_job(base, {}, "none")
    package = package_of(base.fmu_paths["plant"])
    with open_client(2) as client:
        print(sorted(client.run(imported, package).values()))  # before any task
        records = []
        runs = [PlannedRun(f"r{k}", {}) for k in range(4)]
        execute(client, job, plugin, runs, lambda run, record: records.append(record.status))
        print(records)
"""


@pytest.mark.slow
@pytest.mark.cluster
@pytest.mark.skipif(not fork_server.available(), reason="no fork server on this platform")
def test_workers_are_forked_with_the_fmus_package_imported(fmu_paths, run_python, tmp_path):
    script = tmp_path / "forked.py"
    script.write_text(FORKED, encoding="utf-8")
    fmu_dir = fmu_paths["AuvPlant"].parent
    done = run_python(
        f"import runpy, sys; sys.argv[1:] = [{str(fmu_dir)!r}]; "
        f"runpy.run_path({str(script)!r}, run_name='__main__')"
    )
    assert done.returncode == 0, done.stderr[-2000:]
    before, records = done.stdout.strip().splitlines()[-2:]
    assert before == "[True, True]"
    assert records == str(["complete"] * 4)
