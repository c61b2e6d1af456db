"""Times in the engine's messages as the run's grid has them (``cosim.errors.seconds``, as
the report names them): ``%.6g`` printed t = 20000.05 s of a long run as 20000 s, a
time that is not where the failure was."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from cosim.engine.points import check_finite
from cosim.engine.slave import DISCARD, Slave, describe
from cosim.errors import CosimError

LATE = 20000.05  # s, a communication point of a long run at h = 0.05 s


def test_a_failed_call_late_in_a_long_run_names_its_time() -> None:
    """A doStep's Discard with a partial step, 20000.05 s into a run."""
    plant = SimpleNamespace(name="plant", state="stepping", partial_step=lambda: LATE + 0.01,
                            messages=["[Error] the current at the vehicle ..."])  # fmt: skip
    assert describe(plant, "fmi2DoStep", DISCARD, LATE) == (  # type: ignore[arg-type]
        "plant: fmi2DoStep returned Discard at t = 20000.05 s: a partial step, to "
        "t = 20000.06 s: [Error] the current at the vehicle ..."
    )


def test_a_non_finite_value_late_in_a_long_run_names_its_time() -> None:
    with pytest.raises(CosimError) as refused:
        check_finite(np.array([np.nan]), {"plant.u": 0}, LATE)
    assert str(refused.value).startswith("non-finite value at t = 20000.05 s: "), refused.value


def test_a_warning_late_in_a_long_run_names_its_time() -> None:
    plant = SimpleNamespace(messages=[], logged=0)
    Slave.note_warning(plant, "fmi2DoStep", LATE)  # type: ignore[arg-type]
    assert plant.messages == ["[Warning] fmi2DoStep returned Warning at t = 20000.05 s"]
