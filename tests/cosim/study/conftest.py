"""Study fixtures: Dask's scratch space in a temporary folder, and one
small reference study (grid x Latin hypercube, 12 runs of 1 s) run once with 2 workers,
which the determinism, resume and distributed tests compare against."""

from __future__ import annotations

from pathlib import Path

import dask
import pytest
from sweep_helpers import SMALL_RUNS, SMALL_STUDY, complete_table


@pytest.fixture
def no_early_cluster(monkeypatch: pytest.MonkeyPatch) -> None:
    """`auv-cosim sweep` without the local cluster it starts while the study is checked
    (for tests of refusals: a refused study would wait for that cluster to start and stop;
    tests/cosim/study/test_worker_warm_up.py tests the early start itself)."""
    from contextlib import nullcontext

    from cosim.study import execution

    monkeypatch.setattr(execution, "early_client", lambda *args, **kw: nullcontext(None))


@pytest.fixture(scope="session", autouse=True)
def dask_scratch(tmp_path_factory: pytest.TempPathFactory) -> None:
    """Local clusters keep their worker space (and lock files) in a temporary folder."""
    with dask.config.set({"temporary-directory": str(tmp_path_factory.mktemp("dask"))}):
        yield


@pytest.fixture(scope="session")
def small_study(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("study") / "small.toml"
    path.write_text(SMALL_STUDY, encoding="utf-8")
    return path


@pytest.fixture(scope="session")
def small_reference(
    small_study: Path, fmu_dir: Path, tmp_path_factory: pytest.TempPathFactory
) -> list[dict[str, str]]:
    """The small study's table run with 2 local workers, without wall_clock_s."""
    return complete_table(small_study, tmp_path_factory.mktemp("reference"), fmu_dir, SMALL_RUNS)
