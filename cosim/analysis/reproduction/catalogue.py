"""Every claim of ``docs/reproduction.md``, section by section, in the page's order."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from cosim.analysis.reference_values import Reference
from cosim.analysis.reproduction import chapter6, lateral, open_loop, roll_torque, scenarios
from cosim.analysis.reproduction.record import Claim, Section

SECTIONS: tuple[Callable[[Mapping[str, Reference]], Section], ...] = (
    open_loop.example_5_1,
    open_loop.coefficient_claims,
    open_loop.example_5_2,
    open_loop.phase_portraits,
    open_loop.fin_factors,
    lateral.example_5_3,
    roll_torque.roll_torque,
    roll_torque.moving_mass,
    chapter6.equation_6_3_19,
    chapter6.low_speed,
    scenarios.closed_loop,
)


def catalogue(refs: Mapping[str, Reference]) -> list[Section]:
    """The sections of the page, their claims built on the printed values ``refs``."""
    return [build(refs) for build in SECTIONS]


def all_claims(refs: Mapping[str, Reference]) -> list[Claim]:
    """Every claim, in the page's order."""
    return [claim for section in catalogue(refs) for claim in section.claims]
