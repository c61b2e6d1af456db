"""distributed's GC diagnosis (a ``gc.callbacks`` entry its scheduler and workers register
as they start) and a study's threads: registered from a local cluster's IO-loop thread
while a full collection ran on another thread (the client importing or checking its
study), the collection's "stop" reached a callback that never saw its "start", and
distributed printed "Exception ignored in: <bound method GCDiagnosis._gc_callback ...>"
(``assert start is not None``). A study registers it from its own thread first, so the
cluster's start and close only count its users."""

from __future__ import annotations

import gc
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from distributed import gc as dask_gc
from sweep_helpers import sweep

from cosim.study import collector


class _Finalised:
    """A cycle whose finaliser, run inside a full collection, lets another thread run."""

    def __init__(self, entered: threading.Event) -> None:
        self.entered, self.me = entered, self

    def __del__(self) -> None:
        self.entered.set()
        time.sleep(0.05)  # the GIL released inside the collection


def _enabled_during_a_collection() -> list[Any]:
    """A thread enables and disables the diagnosis while this one is inside a full
    collection (as a local cluster's scheduler starts and stops); what was raised in the
    collector's callbacks meanwhile."""
    raised: list[Any] = []
    before, hook = sys.unraisablehook, raised.append
    sys.unraisablehook = hook
    entered = threading.Event()

    def cluster_thread() -> None:
        entered.wait(10)
        dask_gc.enable_gc_diagnosis()
        dask_gc.disable_gc_diagnosis()

    thread = threading.Thread(target=cluster_thread)
    thread.start()
    try:
        _Finalised(entered)
        gc.collect()
    finally:
        thread.join()
        sys.unraisablehook = before
    return raised


def test_the_cluster_s_diagnosis_mid_collection_raises_nothing_once_registered_here() -> None:
    callbacks = list(gc.callbacks)
    with collector.gc_diagnosis_registered():
        raised = _enabled_during_a_collection()
    assert [str(r.exc_value) or type(r.exc_value).__name__ for r in raised] == []
    assert gc.callbacks == callbacks, "the diagnosis was left registered"


@pytest.mark.cluster
@pytest.mark.slow
def test_a_local_study_registers_the_diagnosis_from_its_own_thread(
    tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The in-process sweep (as the API and the tests run it) registered distributed's
    callback from the cluster's IO-loop thread, while its own thread imported."""
    threads: list[str] = []
    enable = dask_gc.GCDiagnosis.enable

    def recorded(self: dask_gc.GCDiagnosis) -> None:
        threads.append(threading.current_thread().name)
        enable(self)

    monkeypatch.setattr(dask_gc.GCDiagnosis, "enable", recorded)
    study = tmp_path / "study.toml"
    study.write_text('scenario = "bs-3"\nstop_time = 0.2\n[grid]\n"plant.v_0" = [0.1]\n')
    sweep(study, tmp_path / "out", fmu_dir, "--workers", "1")
    assert threads == [threading.current_thread().name]
    assert dask_gc._gc_diagnosis_users == 0 and not dask_gc._gc_diagnosis.enabled
