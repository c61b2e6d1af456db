"""An export that finds no room for its files (a full disk, a quota, the file-size limit:
``ulimit -f``) says in one line which file or folder could not be written and why, names
the limit, and leaves no part of the export behind."""

from __future__ import annotations

import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from cosim.limits import FILE_SIZE_LIMIT

EXPORT_UNDER_LIMIT = """
    import resource, sys, tempfile
    from cosim.cli import main
    tempfile.tempdir = sys.argv[1]
    resource.setrlimit(resource.RLIMIT_FSIZE, (int(sys.argv[2]), resource.RLIM_INFINITY))
    sys.exit(main(["export", "bs-3", "--fmu-dir", sys.argv[3], *sys.argv[4:]]))
"""


@pytest.mark.parametrize(
    ("size", "flag", "where"),
    [
        (
            2000,
            "--ssp",
            "the system structure into the temporary folder",
        ),  # the SSD pyssp-standard writes first
        (20000, "--ssp", "--ssp"),  # the archive itself
        (2000, "--osp", "--osp"),
    ],
    ids=["ssd", "ssp", "osp"],
)
def test_an_export_past_the_file_size_limit_names_the_file_and_the_limit(
    run_python: Callable[..., subprocess.CompletedProcess],
    fmu_dir: Path,
    tmp_path: Path,
    size: int,
    flag: str,
    where: str,
) -> None:
    """Under ``ulimit -f`` an SSP export said "OSError: [Errno 27] File too large" (the SSD
    pyssp-standard writes into TMPDIR failed), naming no file; the archive or the OSP
    folder said "File too large", naming no limit."""
    temp, out = tmp_path / "tmp", tmp_path / ("exported.ssp" if flag == "--ssp" else "osp")
    temp.mkdir()
    done = run_python(EXPORT_UNDER_LIMIT, temp, size, fmu_dir, flag, out)
    assert done.returncode == 1, done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1, done.stderr
    line = lines[0]
    assert line.startswith(f"auv-cosim export: cannot write {where}"), line
    assert "Errno" not in line and "OSError" not in line, line
    assert f"{size} bytes {FILE_SIZE_LIMIT}" in line, line
    if "temporary" in where:
        assert f"{temp}" in line and "(TMPDIR)" in line, line
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(f".{out.name}")]
    assert not [p for p in temp.iterdir() if p.name.startswith("auv-cosim-ssd-")]
