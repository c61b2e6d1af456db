"""A build that finds no room for its files (a full disk, a quota, the file-size limit:
``ulimit -f``) in the temporary folder it builds in says so in one line naming that
folder and the limit, and leaves no FMU behind."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim.limits import FILE_SIZE_LIMIT

BUILD_UNDER_LIMIT = """
    import resource, sys, tempfile
    from cosim.cli import main
    tempfile.tempdir = sys.argv[1]
    resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]), resource.RLIM_INFINITY))
    sys.exit(main(["build", "--out", sys.argv[3]]))
"""


@pytest.mark.slow
@pytest.mark.parametrize(
    "size", [20_000, 1_000_000], ids=["staging", "pythonfmu"]
)  # a source file of the staged FMU; the FMU pythonfmu zips
def test_a_build_past_the_file_size_limit_names_the_folder_and_the_limit(
    run_python: Callable[..., subprocess.CompletedProcess], tmp_path: Path, size: int
) -> None:
    """Under ``ulimit -f`` ``auv-cosim build`` said "OSError: [Errno 27] File too large"
    (staging the sources in TMPDIR), or pythonfmu's traceback cut to one line ("...
    zipfile.py ... fp.close() | OSError: [Errno 27] File too large"), naming no folder."""
    temp, out = tmp_path / "tmp", tmp_path / "fmus"
    temp.mkdir()
    done = run_python(BUILD_UNDER_LIMIT, temp, size, out)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    expected = f"auv-cosim build: cannot build AuvPlant.fmu in the temporary folder {temp} (TMPDIR)"
    assert lines[0].startswith(expected), lines[0]
    assert f"File too large: the file-size limit of this process, {size} bytes" in lines[0]
    assert FILE_SIZE_LIMIT in lines[0] and "Errno" not in lines[0], lines[0]
    assert not list(out.glob("*.fmu"))
