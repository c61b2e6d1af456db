"""The runtime's probe of a candidate Python (a subprocess: fmu_runtime/native/platform_posix.c,
probe.c) inside a host process it must neither be thrown by nor disturb: in a host that
catches signals without SA_RESTART, as CPython's handlers are installed, a signal landing in
a blocking call makes it fail with EINTR, which the runtime takes as "again"; where memory
runs out, the subprocess is not started at all; a host splitting a string with strtok
around fmi2Instantiate keeps its place. Seen from C hosts with a library preloaded
(``hosts/alarm_preload.c``: SIGALRM every 10 ms; ``hosts/spawn_enomem_preload.c``:
posix_spawn's file actions fail) or a strtok loop (``hosts/strtok_host.c``), in a clean
environment; for the first two the extraction is moved so that only the candidate under
test (``AUV_FMU_PYTHON``) is asked."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest
from c_hosts import compiled_host, moved, run_clean

from cosim.fmus.native import OVERRIDE_VARIABLE

pytestmark = pytest.mark.slow  # builds and extracts the FMUs

HOSTS = Path(__file__).parent / "hosts"
CANDIDATE = re.compile(r"no Python for this FMU: 2\. (.*)$", re.M)


def _preload(source: Path, folder: Path) -> Path:
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("no C compiler (cc) to build the preloaded library")
    library = folder / f"{source.stem}.so"
    flags = ["-shared", "-fPIC", "-O1", "-Wall", "-Wextra", "-Werror"]
    subprocess.run([cc, *flags, "-o", library, source], check=True)
    return library


def _probe_line(host, extracted, folder: Path, home: Path, fake: Path, preload: Path):
    """What the runtime says of candidate 2 (the fake), and the host's run."""
    done = run_clean(
        [host, moved(extracted["AuvPlant"], folder), "AuvPlant", "cycles", 1, 2],
        home,
        PATH="/nonexistent",
        LD_PRELOAD=str(preload),
        **{OVERRIDE_VARIABLE: str(fake)},
    )
    return CANDIDATE.findall(done.stdout), done


def _fake(folder: Path, script: str) -> Path:
    fake = folder / "python3"
    fake.write_text(f"#!/bin/sh\n{script}")
    fake.chmod(0o755)
    return fake


def test_a_signal_while_the_probe_is_awaited_does_not_lose_how_it_ended(
    host, extracted, tmp_path, clean_home
):
    """A candidate that closes its output, then exits with status 5 half a second later:
    the runtime waits for it through the signals and says how it ended. waitpid's EINTR
    was taken for an answer: the line said "did not answer" and the child was never
    reaped (a zombie for as long as the host ran)."""
    fake = _fake(tmp_path, "exec >&- 2>&-\n/bin/sleep 0.5\nexit 5\n")
    preload = _preload(HOSTS / "alarm_preload.c", tmp_path)
    said, done = _probe_line(host, extracted, tmp_path, clean_home, fake, preload)
    expected = f"{OVERRIDE_VARIABLE}={fake}: exited with status 5 before answering"
    assert said == [expected], done.stdout + done.stderr


def test_a_probe_whose_output_cannot_be_redirected_is_not_started(
    host, extracted, tmp_path, clean_home
):
    """posix_spawn's file actions failing (out of memory): the candidate is not run, and
    the line says why. Their results were not checked: the probe ran with the host's own
    stdout, where its answer went (and the runtime said "gave no answer")."""
    fake = _fake(tmp_path, "echo version=3.99.0\nexit 0\n")
    preload = _preload(HOSTS / "spawn_enomem_preload.c", tmp_path)
    said, done = _probe_line(host, extracted, tmp_path, clean_home, fake, preload)
    assert "version=" not in done.stdout + done.stderr
    expected = f"{OVERRIDE_VARIABLE}={fake}: could not be run (Cannot allocate memory)"
    assert said == [expected], done.stdout + done.stderr


def test_a_host_splitting_with_strtok_around_instantiate_keeps_its_place(
    extracted, tmp_path, clean_home
):
    """Three instances named in one strtok loop, the first of which probes the build's
    Python: all three are made. The probe split its answer with strtok, which left the
    host's next strtok(NULL, ...) reading the probe's freed buffer: the host's loop ended
    after the first."""
    host = compiled_host(HOSTS / "strtok_host.c", tmp_path)
    folder = extracted["AuvPlant"]
    guid = ET.parse(folder / "modelDescription.xml").getroot().get("guid")
    library = folder / "binaries" / "linux64" / "AuvPlant.so"
    done = run_clean(
        [host, library, f"file://{folder / 'resources'}", guid, "one,two,three"], clean_home
    )
    assert (done.returncode, done.stdout.splitlines()[-1:]) == (0, ["instances: 3"]), (
        f"exit {done.returncode}\n{done.stdout}{done.stderr[-2000:]}"
    )
