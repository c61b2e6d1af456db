"""Every claim of ``docs/reproduction.md``, section by section, in the page's order."""

from __future__ import annotations

from collections.abc import Callable, Mapping

from cosim.analysis.reference_values import Reference
from cosim.reproduction.chapter6 import equation_6_3_19, moving_mass_servo
from cosim.reproduction.depth_plane import depth_plane
from cosim.reproduction.lateral import example_5_3
from cosim.reproduction.low_speed import low_speed
from cosim.reproduction.model_choices import model_choices
from cosim.reproduction.open_loop import (
    coefficient_claims,
    example_5_1,
    example_5_2,
    fin_factors,
    phase_portraits,
)
from cosim.reproduction.record import Claim, Section
from cosim.reproduction.roll_torque import moving_mass, roll_torque
from cosim.reproduction.scenarios import closed_loop

SECTIONS: tuple[Callable[[Mapping[str, Reference]], Section], ...] = (
    example_5_1,
    coefficient_claims,
    example_5_2,
    phase_portraits,
    fin_factors,
    example_5_3,
    roll_torque,
    moving_mass,
    moving_mass_servo,
    equation_6_3_19,
    low_speed,
    depth_plane,
    closed_loop,
    model_choices,
)


def catalogue(refs: Mapping[str, Reference]) -> list[Section]:
    """The sections of the page, their claims built on the printed values ``refs``."""
    return [build(refs) for build in SECTIONS]


def all_claims(refs: Mapping[str, Reference]) -> list[Claim]:
    """Every claim, in the page's order."""
    return [claim for section in catalogue(refs) for claim in section.claims]
