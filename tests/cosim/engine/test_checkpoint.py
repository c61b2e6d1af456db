"""A checkpoint's state as JSON and back, exactly, and the runs whose state it cannot hold
whole (:mod:`cosim.engine.checkpoint`)."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace
from typing import Any, cast

import numpy as np
import pytest

from cosim.engine.checkpoint import from_json, refusal, to_json
from cosim.scenario.spec import Scenario


def test_every_kind_of_value_comes_back_with_its_type_and_bits() -> None:
    """What the master's state holds (timeline snapshots: tuples, sets, dicts keyed by
    tuples; extrapolation histories: arrays; FMU states: bytes) survives a JSON text."""
    state = {
        "z": np.array([0.1, -0.0, math.inf, math.nan, 5e-324]),
        "ints": np.arange(3, dtype=np.int64).reshape(3, 1),
        "fmu": b"\x00\xffstate",
        "snapshot": (3, None, True, [1.5, "x"], {("a", 1): {2, 3}}, np.float64(1 / 3)),
    }
    back = from_json(json.loads(json.dumps(to_json(state))))
    assert back["z"].tobytes() == state["z"].tobytes()
    assert back["ints"].dtype == np.int64 and back["ints"].shape == (3, 1)
    assert back["fmu"] == state["fmu"]
    assert back["snapshot"] == (3, None, True, [1.5, "x"], {("a", 1): {2, 3}}, 1 / 3)


def test_an_unknown_entry_is_refused() -> None:
    with pytest.raises(ValueError, match="unknown entry"):
        from_json({"q": 1})


def _scenario(**coupling: Any) -> Scenario:
    cs = SimpleNamespace(canGetAndSetFMUstate=True, canSerializeFMUstate=True)
    plant = SimpleNamespace(
        model_description=SimpleNamespace(coSimulation=cs), fmu_path=SimpleNamespace(name="P.fmu")
    )
    settings = {"algorithm": "gauss-seidel", "step_multiples": {"plant": 1}, **coupling}
    return cast(
        Scenario, SimpleNamespace(instances={"plant": plant}, coupling=SimpleNamespace(**settings))
    )


def test_a_fixed_step_run_can_be_checkpointed() -> None:
    assert refusal(_scenario(), paced_or_live=False) is None


def test_an_fmu_that_cannot_serialize_its_state_is_named() -> None:
    scenario = _scenario()
    scenario.instances["plant"].model_description.coSimulation.canSerializeFMUstate = False
    assert refusal(scenario, False) == (
        "instance 'plant' (P.fmu) cannot serialize its state (canSerializeFMUstate is false)"
    )


@pytest.mark.parametrize(
    ("coupling", "live", "said"),
    [
        ({"algorithm": "adaptive"}, False, "algorithm 'adaptive'"),
        ({"step_multiples": {"plant": 2}}, False, "multi-rate instances (plant)"),
        ({}, True, "a paced or live run"),
    ],
)
def test_a_master_state_not_captured_whole_is_refused(
    coupling: dict[str, Any], live: bool, said: str
) -> None:
    reason = refusal(_scenario(**coupling), live)
    assert reason is not None and reason.startswith(said)
