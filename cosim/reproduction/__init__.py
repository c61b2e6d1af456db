"""The reproduction of the dissertation's numbers, ``docs/reproduction.md``.

Each claim is a :class:`Claim` record (where the dissertation makes it, the printed value,
its unit, our tolerance, and the function computing ours) in one of the section modules
(:mod:`.open_loop`, :mod:`.lateral`, :mod:`.roll_torque`, :mod:`.chapter6`,
:mod:`.low_speed`, :mod:`.depth_plane`, :mod:`.scenarios`), listed by :mod:`.catalogue`;
:func:`evaluate` judges one, :func:`reproduce` evaluates them all in one loop and renders
the page (:mod:`.page`), with the model choices the verdicts rest on and what they change
(:mod:`.model_choices`). The printed values and their tolerances come from
``docs/dissertation-values.toml``; the weight convention of each chapter is in
:mod:`.context`, the converged step of the closed-loop runs in :mod:`.runs`.
"""

from cosim.reproduction.catalogue import all_claims, catalogue
from cosim.reproduction.context import Context
from cosim.reproduction.generate import reproduce
from cosim.reproduction.record import Claim, Cost, Finding, Row, Section, evaluate

__all__ = [
    "Claim",
    "Context",
    "Cost",
    "Finding",
    "Row",
    "Section",
    "all_claims",
    "catalogue",
    "evaluate",
    "reproduce",
]
