"""The FMU build's record (``<Name>.fmu.sha256``) not written: one line naming the file
and the cause (the file-size limit, a path over the system's limit), as the FMU's own
file is named. The builder is replaced by one writing a few bytes."""

from __future__ import annotations

import errno
import os
import pathlib
import resource
from pathlib import Path

import pytest

from cosim.errors import CosimError
from cosim.fmus import build
from cosim.fmus.build import build_fmu

NAME = "AuvGuidance"


@pytest.fixture(autouse=True)
def fake_build(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(build.kept_builds.OFF_VARIABLE, "1")  # every folder builds its own

    def write(name: str, files: object, digest: str, target: Path, portable: bool) -> None:
        target.write_bytes(f"{name} built from {digest}".encode())

    monkeypatch.setattr(build, "_build", write)


def test_a_record_past_the_file_size_limit_names_the_file_and_the_limit(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The record past ``ulimit -f`` said "PATH: File too large", naming no limit, where
    the FMU's own file names it."""
    written = pathlib.Path.write_text

    def limited(self: Path, *args: object, **kwargs: object) -> int:
        if ".sha256." in self.name:
            raise OSError(errno.EFBIG, os.strerror(errno.EFBIG))
        return written(self, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(pathlib.Path, "write_text", limited)
    monkeypatch.setattr(resource, "getrlimit", lambda which: (65536, resource.RLIM_INFINITY))
    with pytest.raises(CosimError) as refused:
        build_fmu(NAME, tmp_path / "fmus")
    message = str(refused.value)
    record = tmp_path / "fmus" / f"{NAME}.fmu.sha256"
    assert message.startswith(f"cannot write {record}: File too large: "), message
    assert "65536 bytes" in message and "\n" not in message, message


def test_a_path_too_long_for_the_temporary_file_names_the_limit(tmp_path: Path) -> None:
    """A folder whose FMU's path fits the system's limit but not the record's, written
    first under a longer temporary name beside it: "File name too long" for a path the
    user sees is shorter than the limit, which it named no figure of."""
    limit = os.pathconf(tmp_path, "PC_PATH_MAX")
    folder = tmp_path
    while len(str(folder)) < limit - 220:
        folder = folder / ("d" * 200)
    record = f"{NAME}.fmu.sha256"  # its path 4 characters short of the limit
    folder = folder / ("e" * (limit - len(str(folder)) - 1 - 1 - len(record) - 4))
    folder.mkdir(parents=True)
    with pytest.raises(CosimError) as refused:
        build_fmu(NAME, folder)
    message = str(refused.value)
    assert "File name too long" in message and f"limit of {limit - 1} bytes" in message, message
    assert "the temporary file written first beside it" in message, message
    assert "\n" not in message
