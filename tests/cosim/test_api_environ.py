"""cosim.sweep puts back what its study set in the caller's environment, and only that:
a variable another thread of the caller sets while the study runs is that thread's."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

import cosim
import cosim.study.runner
from cosim.study.spec import StudyError

OTHER = "AUV_COSIM_TEST_OTHER_THREAD"  # what another thread of the caller sets
OURS = "AUV_COSIM_TEST_STUDY_SET"  # what the study itself sets


def _study_meanwhile(*args: object, **options: object) -> None:
    """A study's run that sets a variable of its own (as its cluster sets Dask's
    pre-spawn environment) while another thread of the caller sets one, then fails."""
    from cosim import environ_writes

    environ_writes.set_variable(OURS, "the study's")
    thread = threading.Thread(target=os.environ.__setitem__, args=(OTHER, "the thread's"))
    thread.start()
    thread.join()
    raise StudyError("not run")


def test_a_sweep_keeps_what_another_thread_set_meanwhile(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The study put back the caller's whole environment as it was before it: a variable
    another thread set while it ran was removed again."""
    monkeypatch.delenv(OTHER, raising=False)
    monkeypatch.delenv(OURS, raising=False)
    monkeypatch.setattr(cosim.study.runner, "run_study", _study_meanwhile)
    try:
        with pytest.raises(StudyError, match="not run"):
            cosim.sweep({"scenario": "bs-3"}, out=tmp_path / "study", workers=1)
        assert os.environ.get(OTHER) == "the thread's"
        assert OURS not in os.environ
    finally:
        os.environ.pop(OTHER, None)
