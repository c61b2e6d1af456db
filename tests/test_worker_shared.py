"""The session's FMUs built once for all xdist workers (``tests/worker_shared.py``): the
build runs once in a shared folder, a failed build is run again by the next asking, and
two workers take the FMUs in opposite orders."""

from __future__ import annotations

from pathlib import Path
from typing import cast

import pytest
from worker_shared import build_once, in_worker_order, shared_folder


def test_a_build_done_whole_is_not_run_again(tmp_path: Path) -> None:
    builds: list[Path] = []
    build_once(tmp_path, builds.append)
    build_once(tmp_path, builds.append)
    assert builds == [tmp_path]


def test_a_build_that_raised_is_run_again_by_the_next_asking(tmp_path: Path) -> None:
    def broken(folder: Path) -> None:
        raise RuntimeError("no compiler")

    with pytest.raises(RuntimeError, match="no compiler"):
        build_once(tmp_path, broken)
    builds: list[Path] = []
    build_once(tmp_path, builds.append)
    assert builds == [tmp_path]


class _Factory:
    """pytest's TempPathFactory as a worker's (``popen-gw1``) is, in a test's folder."""

    def __init__(self, basetemp: Path) -> None:
        self.basetemp = basetemp
        basetemp.mkdir(parents=True)

    def getbasetemp(self) -> Path:
        return self.basetemp

    def mktemp(self, name: str) -> Path:
        folder = self.basetemp / f"{name}0"
        folder.mkdir()
        return folder


def test_workers_share_a_folder_beside_their_own_and_a_lone_process_has_its_own(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "pytest-7"
    gw0, gw1 = (cast(pytest.TempPathFactory, _Factory(session / f"popen-gw{n}")) for n in (0, 1))
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw1")
    shared = shared_folder(gw1, "fmus")
    assert shared == session / "fmus" and shared.is_dir()
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")
    assert shared_folder(gw0, "fmus") == shared
    monkeypatch.delenv("PYTEST_XDIST_WORKER")
    assert shared_folder(gw0, "fmus") == session / "popen-gw0" / "fmus0"


@pytest.mark.parametrize(("worker", "order"), [("gw0", "abc"), ("gw1", "cba"), ("gw2", "abc")])
def test_every_second_worker_builds_in_the_opposite_order(
    worker: str, order: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PYTEST_XDIST_WORKER", worker)
    assert "".join(in_worker_order("abc")) == order
