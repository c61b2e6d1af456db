"""What of a scenario's events and faults an export can carry: linear connection faults.

A ``gain`` or ``bias`` fault active over the whole run (start 0, no stop before the stop
time) on a connection is a fixed linear transformation of the value delivered,
``factor * value + offset``:
SSP 1.0 writes it as the connection's ``ssc:LinearTransformation`` and the OSP system
structure as a ``LinearTransformation`` function between the two variables (libcosim reads
both). Several on one connection compose in the scenario's order. Nothing else of the
timeline -- events, other fault kinds, faults limited in time -- has a counterpart in
either format, so :func:`linear_transformations` refuses them, all in one message.
"""

from __future__ import annotations

from cosim.errors import CosimError
from cosim.scenario.spec import Scenario


def linear_transformations(scenario: Scenario, fmt: str) -> dict[str, tuple[float, float]]:
    """Connection target -> (factor, offset) of the scenario's whole-run linear faults.

    Raises:
        CosimError: the scenario has events or other faults; the message lists them all.
    """
    refused = [f"event {e.name!r}" for e in scenario.events]
    transformations: dict[str, tuple[float, float]] = {}
    for fault in scenario.faults:
        whole_run = fault.whole_run(scenario.stop_time)
        if fault.kind not in ("gain", "bias") or not whole_run:
            limited = "" if whole_run else ", not over the whole run"
            refused.append(f"fault {fault.name!r} ({fault.kind} on {fault.target}{limited})")
            continue
        factor, offset = transformations.get(fault.target, (1.0, 0.0))
        value = float(fault.value)  # type: ignore[arg-type]
        if fault.kind == "gain":
            transformations[fault.target] = (factor * value, offset * value)
        else:
            transformations[fault.target] = (factor, offset + value)
    if refused:
        raise CosimError(
            f"cannot export scenario {scenario.id!r} as {fmt}: it has no counterpart for "
            f"{', '.join(refused)}; only gain and bias faults active over the whole run "
            "(start = 0, no stop before the stop time) are exported, as linear transformations "
            "of their connection"
        )
    return transformations
