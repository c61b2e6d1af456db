"""A claim of the dissertation as a record, and the one function that evaluates it.

A :class:`Claim` holds what the dissertation says (the claim, where it says it, the value
as printed, its unit), the tolerance we accept, and the function computing ours; the
function returns a :class:`Finding` and :func:`evaluate` turns the two into a :class:`Row`
of the report with its verdict. See ``docs/reproduction.md``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Literal, Protocol

from cosim.reproduction.context import Context, NotRunError

if TYPE_CHECKING:
    from cosim.analysis.reference_values import Reference

Verdict = Literal["agrees", "differs (explained)", "differs", "not run"]
ZERO_TOLERANCE = 1e-3  # a bare printed "0" beside figures with 3-4 decimals


class Cost(Enum):
    """What computing ours takes: what the tests may afford."""

    INSTANT = "instant"  # linearisations and equilibria: under a second
    SWEEP = "sweep"  # continuations and phase portraits: seconds
    SCENARIO = "scenario"  # a closed-loop run of the two FMUs: tens of seconds


def decimals(text: str) -> int:
    """Digits after the decimal point of a printed number ("1.282" -> 3)."""
    mantissa = text.lower().split("e")[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


class Tolerance(Protocol):
    """When ours agrees with a printed number; ``str()`` says it in the table."""

    def accepts(self, printed: str, ours: float) -> bool: ...


@dataclass(frozen=True)
class LastDigit:
    """Within one unit of the last printed digit (a bare 0: within 1e-3), because the
    dissertation rounds what it prints."""

    def accepts(self, printed: str, ours: float) -> bool:
        value = float(printed)
        if value == 0.0 and decimals(printed) == 0:
            return abs(ours) <= ZERO_TOLERANCE
        return abs(ours - value) <= 10.0 ** (-decimals(printed)) * (1 + 1e-9)

    def __str__(self) -> str:
        return "last digit"


@dataclass(frozen=True)
class Relative:
    """Within ``fraction`` of the printed value (the last-digit rule for a printed 0)."""

    fraction: float

    def accepts(self, printed: str, ours: float) -> bool:
        value = float(printed)
        if value == 0.0:
            return LastDigit().accepts(printed, ours)
        return abs(ours - value) <= self.fraction * abs(value)

    def __str__(self) -> str:
        return f"{100 * self.fraction:g} %"


@dataclass(frozen=True)
class Absolute:
    """Within ``bound`` of the printed value (the value's own unit)."""

    bound: float

    def accepts(self, printed: str, ours: float) -> bool:
        return abs(ours - float(printed)) <= self.bound

    def __str__(self) -> str:
        return f"+- {self.bound:g}"


@dataclass(frozen=True)
class SlightlyAbove:
    """The text's "slightly larger than": ``printed < |ours| < printed + width``."""

    width: float

    def accepts(self, printed: str, ours: float) -> bool:
        return float(printed) < abs(ours) < float(printed) + self.width

    def __str__(self) -> str:
        return f"above it, by < {self.width:g}"


@dataclass(frozen=True)
class Finding:
    """Ours for one claim.

    Attributes:
        values: numbers compared entry by entry with the claim's printed numbers (or with
            ``against``) under its tolerance; empty for a claim with no number.
        shown: ours as the table shows it; default: ``values`` to one more digit than
            printed.
        holds: the qualitative part of the claim (counts, stability, signs).
        against: the numbers to compare with (as text, with their digits) when they are
            not the printed ones: a formula the dissertation states (Example 5.6's
            sin(phi0) = Q / (W z_g)), or a sum of printed matrices.
        note: what the reader should know about ours.
    """

    values: tuple[float, ...] = ()
    shown: str = ""
    holds: bool = True
    against: tuple[str, ...] | None = None
    note: str = ""


@dataclass(frozen=True)
class Claim:
    """One claim of the dissertation and how we check it.

    Attributes:
        claim: what the dissertation says, in a few words.
        source: where: "Ex. 5.3", "(6.3.19)", "Figs. 6.13-6.14 (lqr-2)".
        printed: the printed numbers (strings, with their digits), or one statement.
        unit: the unit of the printed numbers ("1" dimensionless, "-" none).
        ours: computes ours from the shipped model or a run.
        tolerance: when ours agrees with a printed number.
        cost: what computing ours takes.
        explained: why ours differs, for a known difference ("" if none is known).
        note: how the claim is read or computed.
    """

    claim: str
    source: str
    printed: tuple[str, ...] | str
    unit: str
    ours: Callable[[Context], Finding]
    tolerance: Tolerance = LastDigit()
    cost: Cost = Cost.INSTANT
    explained: str = ""
    note: str = ""

    @property
    def printed_text(self) -> str:
        """The printed value as the table shows it."""
        if isinstance(self.printed, str):
            return self.printed
        text = ", ".join(self.printed)
        return text if len(self.printed) == 1 else f"[{text}]"


@dataclass(frozen=True)
class Row:
    """An evaluated claim: the record, ours as shown, the verdict, the notes, and whether
    numbers were compared under the claim's tolerance."""

    claim: Claim
    ours: str
    verdict: Verdict
    note: str = ""
    compared: bool = False


def evaluate(claim: Claim, context: Context) -> Row:
    """Compute ours for ``claim`` and judge it; a failing computation is a row, not a
    crash (``differs``, with the exception), a skipped one is ``not run``."""
    try:
        finding = claim.ours(context)
    except NotRunError as exc:
        return Row(claim, "-", "not run", str(exc))
    except Exception as exc:  # a broken check is reported in the table
        return Row(claim, f"{type(exc).__name__}: {exc}", "differs", "the check failed")
    ok = finding.holds and _within(claim, finding)
    verdict: Verdict = "agrees" if ok else "differs (explained)" if claim.explained else "differs"
    note = " ".join(n for n in (claim.note, finding.note) if n)
    if not ok and claim.explained:
        note = " ".join(n for n in (claim.explained, finding.note) if n)
    shown = finding.shown or _shown(claim.printed, finding.values)
    return Row(claim, shown, verdict, note, compared=bool(finding.values))


def _within(claim: Claim, finding: Finding) -> bool:
    """Every number of ``finding`` within the tolerance of its printed (or stated) one."""
    if not finding.values:
        return True
    if finding.against is not None:
        expected = list(finding.against)
    elif isinstance(claim.printed, str):
        raise ValueError(f"claim {claim.claim!r}: numbers to compare but no printed numbers")
    else:
        expected = list(claim.printed)
    if len(expected) != len(finding.values):
        return False
    return all(claim.tolerance.accepts(p, o) for p, o in zip(expected, finding.values, strict=True))


def _shown(printed: Sequence[str] | str, values: Sequence[float]) -> str:
    """``values`` with one more decimal than printed (three decimals for a statement)."""
    digits = [3] * len(values)
    if not isinstance(printed, str) and len(printed) == len(values):
        digits = [decimals(p) for p in printed]
    text = ", ".join(f"{v:.{max(d, 1) + 1}f}" for v, d in zip(values, digits, strict=True))
    return text if len(values) == 1 else f"[{text}]"


@dataclass(frozen=True)
class Figure:
    """A figure of the report: its file name under ``figures/`` and what draws it."""

    name: str
    draw: Callable[[Context, Path], None]
    cost: Cost = Cost.SWEEP


@dataclass(frozen=True)
class Section:
    """A table of the report: its claims and the figures shown under it."""

    title: str
    claims: tuple[Claim, ...]
    figures: tuple[Figure, ...] = ()


def printed(reference: Reference, pick: Sequence[int] | None = None) -> tuple[str, ...]:
    """A printed value's numbers as strings (flattened), or those at ``pick``."""
    text = reference.text
    flat = [text] if isinstance(text, str) else list(_flatten(text))
    return tuple(flat[i] for i in pick) if pick is not None else tuple(flat)


def unit_text(reference: Reference, pick: Sequence[int] | None = None) -> str:
    """A printed value's unit(s) as the table shows them."""
    if isinstance(reference.unit, str):
        return reference.unit
    units = [reference.unit[i] for i in pick] if pick is not None else list(reference.unit)
    return ", ".join(units) if len(set(units)) > 1 else units[0]


def _flatten(items: list) -> Iterator[str]:
    for item in items:
        if isinstance(item, list):
            yield from _flatten(item)
        else:
            yield item
