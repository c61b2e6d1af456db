"""Ctrl-C in ``cosim.run`` before its first step (the FMUs built or loaded): a
KeyboardInterrupt, as Ctrl-C is anywhere in Python, never a CosimError."""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest

import cosim
import cosim.runner
from cosim.errors import CosimError


def _ctrl_c_while_loading(monkeypatch: pytest.MonkeyPatch) -> None:
    """The terminal's Ctrl-C (a notebook's stop button) as the next run loads its scenario
    and FMUs, before its first step."""
    loaded = cosim.runner._checked_scenario

    def interrupted(*args: Any, **kwargs: Any) -> Any:
        os.kill(os.getpid(), signal.SIGINT)
        return loaded(*args, **kwargs)

    monkeypatch.setattr(cosim.runner, "_checked_scenario", interrupted)


@pytest.mark.parametrize("kept", [False, True], ids=["in-memory", "out"])
def test_ctrl_c_before_the_first_step_is_a_keyboard_interrupt(
    kept: bool, tmp_path: Path, fmu_dir: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C before the first step raised the runner's NotStartedError, a CosimError: a
    loop going on after a failed run (``except CosimError: continue``) swallowed the stop
    and started the next run. It is a KeyboardInterrupt saying that nothing ran, and a
    folder's earlier run is kept as it was."""
    out = tmp_path / "run" if kept else None
    if out is not None:
        cosim.run("bs-3", stop_time=0.05, fmu_dir=fmu_dir, out=out, recording=False)
        before = (out / "results.csv").read_bytes()
    _ctrl_c_while_loading(monkeypatch)
    with pytest.raises(KeyboardInterrupt) as raised:
        try:
            cosim.run("bs-3", stop_time=0.05, fmu_dir=fmu_dir, out=out, overwrite=True)
        except CosimError as error:  # what the loop swallowed
            pytest.fail(f"{type(error).__name__}: {error}")
    message = str(raised.value)
    assert message.startswith("interrupted (Ctrl-C) before the first step"), message
    assert "\n" not in message
    if out is not None:
        assert (out / "results.csv").read_bytes() == before
