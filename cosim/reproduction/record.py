"""A claim of the dissertation as a record, and the one function that evaluates it.

A :class:`Claim` holds what the dissertation says (the claim, where it says it, the value
as printed, its unit), the tolerance we accept, and the function computing ours; the
function returns a :class:`Finding` and :func:`evaluate` turns the two into a :class:`Row`
of the report with its verdict. See ``docs/reproduction.md``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from decimal import Decimal
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, Protocol

from cosim.reproduction.context import Context, NotRunError

if TYPE_CHECKING:
    from cosim.analysis.reference_values import Reference

Verdict = Literal["agrees", "differs (explained)", "differs", "not run"]
ZERO_TOLERANCE = 1e-3  # a bare printed "0" beside figures with 3-4 decimals


class Cost(Enum):
    """What computing ours takes: what the tests may afford."""

    INSTANT = "instant"  # linearisations and equilibria: under a second
    SWEEP = "sweep"  # continuations and phase portraits: seconds
    SCENARIO = "scenario"  # closed-loop runs of the two FMUs: tens of seconds


def decimals(text: str) -> int:
    """Digits after the decimal point of a printed number ("1.282" -> 3)."""
    mantissa = text.lower().split("e")[0]
    return len(mantissa.split(".")[1]) if "." in mantissa else 0


def resolution(text: str) -> float:
    """One unit of the last printed digit of ``text`` ("1.282" -> 0.001, "20" -> 1; a
    bare "0" beside figures with decimals: ``ZERO_TOLERANCE``): the printed precision."""
    if float(text) == 0.0 and decimals(text) == 0:
        return ZERO_TOLERANCE
    exponent = Decimal(text).as_tuple().exponent
    if not isinstance(exponent, int):
        raise ValueError(f"printed value {text!r}: expected a finite number")
    return float(Decimal(1).scaleb(exponent))


class Tolerance(Protocol):
    """When ours agrees with a printed number; ``str()`` says it in the table."""

    def accepts(self, printed: str, ours: float) -> bool: ...

    def width(self, printed: str) -> float:
        """How far beyond the printed value ours may lie and still agree (the printed
        precision, or less, unless the row says why)."""
        ...


@dataclass(frozen=True)
class LastDigit:
    """Within one unit of the last printed digit (a bare 0: within 1e-3), because the
    dissertation rounds what it prints: the printed precision."""

    def accepts(self, printed: str, ours: float) -> bool:
        return abs(ours - float(printed)) <= self.width(printed) * (1 + 1e-9)

    def width(self, printed: str) -> float:
        return resolution(printed)

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

    def width(self, printed: str) -> float:
        value = float(printed)
        return resolution(printed) if value == 0.0 else self.fraction * abs(value)

    def __str__(self) -> str:
        return f"{100 * self.fraction:g} %"


@dataclass(frozen=True)
class Absolute:
    """Within ``bound`` of the printed value (the value's own unit)."""

    bound: float

    def accepts(self, printed: str, ours: float) -> bool:
        return abs(ours - float(printed)) <= self.bound

    def width(self, printed: str) -> float:
        return self.bound

    def __str__(self) -> str:
        return f"+- {self.bound:.3g}"


@dataclass(frozen=True)
class SlightlyAbove:
    """The text's "slightly larger than": ``printed < |ours| < printed + width``."""

    above: float

    def accepts(self, printed: str, ours: float) -> bool:
        return float(printed) < abs(ours) < float(printed) + self.above

    def width(self, printed: str) -> float:
        return self.above

    def __str__(self) -> str:
        return f"above it, by < {self.above:g}"


@dataclass(frozen=True)
class AtMost:
    """The text's "within N seconds", "less than": ``ours <= printed``, nothing beyond."""

    def accepts(self, printed: str, ours: float) -> bool:
        return ours <= float(printed)

    def width(self, printed: str) -> float:
        return 0.0

    def __str__(self) -> str:
        return "at most"


def tolerance_of(reference: Reference) -> Tolerance:
    """The tolerance ``docs/dissertation-values.toml`` gives a printed value: its
    ``tolerance`` table (``absolute``, ``relative``, ``slightly_above`` or ``at_most``), or
    the printed precision (:class:`LastDigit`) when it gives none."""
    spec = reference.tolerance
    if not spec:
        return LastDigit()
    ((kind, amount),) = spec.items()
    if kind == "absolute":
        return Absolute(float(amount))
    if kind == "relative":
        return Relative(float(amount))
    if kind == "slightly_above":
        return SlightlyAbove(float(amount))
    return AtMost()


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
        errors: the numerical error of each of ``values`` (a closed-loop run's coupling
            error), empty if none is measured; a value whose error reaches the printed
            precision cannot be judged and makes the row differ.
        note: what the reader should know about ours.
    """

    values: tuple[float, ...] = ()
    shown: str = ""
    holds: bool = True
    against: tuple[str, ...] | None = None
    errors: tuple[float, ...] = ()
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
        explained: why ours differs, for a known difference whose cause is known.
        unexplained: what is known of a difference whose cause is not.
        note: how the claim is read or computed.
        reference: the key of the printed numbers in ``docs/dissertation-values.toml``
            ("" when ours is compared with a formula the text states, not a number).
        tolerance_reason: why the tolerance is wider than the printed precision (shown
            next to the row; "" when it is not).
    """

    claim: str
    source: str
    printed: tuple[str, ...] | str
    unit: str
    ours: Callable[[Context], Finding]
    tolerance: Tolerance = LastDigit()
    cost: Cost = Cost.INSTANT
    explained: str = ""
    unexplained: str = ""
    note: str = ""
    reference: str = ""
    tolerance_reason: str = ""

    @classmethod
    def of(
        cls, reference: Reference, claim: str, ours: Callable[[Context], Finding], **details: Any
    ) -> Claim:
        """The claim of one printed value whole: its source, numbers, unit and key from
        ``reference`` (its entry in ``docs/dissertation-values.toml``); ``details``, the
        fields from ``tolerance`` on, as :class:`Claim` takes them."""
        source, numbers, unit = reference.source, printed(reference), unit_text(reference)
        return cls(claim, source, numbers, unit, ours, reference=reference.key, **details)

    @property
    def printed_text(self) -> str:
        """The printed value as the table shows it."""
        if isinstance(self.printed, str):
            return self.printed
        text = ", ".join(self.printed)
        return text if len(self.printed) == 1 else f"[{text}]"

    @property
    def known_difference(self) -> str:
        """What the page says of a difference we know of ("" if ours should agree)."""
        return self.explained or self.unexplained


@dataclass(frozen=True)
class Row:
    """An evaluated claim: the record, ours as shown, the verdict, the notes, whether
    numbers were compared under the claim's tolerance, and by how much they differ."""

    claim: Claim
    ours: str
    verdict: Verdict
    note: str = ""
    compared: bool = False
    size: str = ""


def evaluate(claim: Claim, context: Context) -> Row:
    """Compute ours for ``claim`` and judge it; a failing computation is a row, not a
    crash (``differs``, with the exception), a skipped one is ``not run``."""
    try:
        finding = claim.ours(context)
    except NotRunError as exc:
        return Row(claim, "-", "not run", str(exc))
    except Exception as exc:  # a broken check is reported in the table
        return Row(claim, f"{type(exc).__name__}: {exc}", "differs", "the check failed")
    expected = _expected(claim, finding)
    unconverged = _unconverged(expected, finding)
    ok = finding.holds and not unconverged and _within(claim, expected, finding.values)
    verdict: Verdict = "agrees"
    if not ok:
        verdict = "differs (explained)" if claim.explained else "differs"
    notes = [claim.note, finding.note]
    if not ok and claim.known_difference:
        notes = [claim.known_difference, finding.note]
    if unconverged:
        notes.append(unconverged)
    shown = finding.shown or _shown(claim.printed, finding.values)
    size = "" if ok else _size(expected, finding.values)
    note = " ".join(n for n in notes if n)
    return Row(claim, shown, verdict, note, compared=bool(finding.values), size=size)


def _expected(claim: Claim, finding: Finding) -> list[str]:
    """The numbers ``finding`` is compared with: ``against``, else the printed ones."""
    if not finding.values:
        return []
    if finding.against is not None:
        return list(finding.against)
    if isinstance(claim.printed, str):
        raise ValueError(f"claim {claim.claim!r}: numbers to compare but no printed numbers")
    return list(claim.printed)


def _within(claim: Claim, expected: list[str], values: tuple[float, ...]) -> bool:
    """Every number of ``values`` within the tolerance of its printed (or stated) one."""
    if len(expected) != len(values):
        return False
    return all(claim.tolerance.accepts(p, o) for p, o in zip(expected, values, strict=True))


def _unconverged(expected: list[str], finding: Finding) -> str:
    """Why a value cannot be judged: its numerical error reaches the printed precision."""
    bad = [
        f"{e:.2g} (printed precision {resolution(p):g})"
        for p, e in zip(expected, finding.errors, strict=False)
        if not e < resolution(p)
    ]
    return f"Not converged: numerical error {', '.join(bad)}." if bad else ""


def _size(expected: list[str], values: tuple[float, ...]) -> str:
    """By how much ours differs: 'by 0.014 (0.19 %)' for one number, 'by up to 0.23 %'
    (the largest relative difference) for several."""
    if not values or len(expected) != len(values):
        return ""
    if len(values) == 1:
        printed, gap = float(expected[0]), abs(values[0] - float(expected[0]))
        return f"by {gap:.2g}" + (f" ({100 * gap / abs(printed):.2g} %)" if printed else "")
    relative = [
        abs(o - float(p)) / abs(float(p)) for p, o in zip(expected, values, strict=True) if float(p)
    ]
    return f"by up to {100 * max(relative):.2g} %" if relative else ""


def _shown(printed: Sequence[str] | str, values: Sequence[float]) -> str:
    """``values`` with one more decimal than printed (three decimals for a statement)."""
    digits = [3] * len(values)
    if not isinstance(printed, str) and len(printed) == len(values):
        digits = [decimals(p) for p in printed]
    text = ", ".join(f"{v:.{max(d, 1) + 1}f}" for v, d in zip(values, digits, strict=True))
    return text if len(values) == 1 else f"[{text}]"


@dataclass(frozen=True)
class Figure:
    """A figure of the report: its file name under ``figures/``, what draws it, and its
    ``alt`` text: what it plots against what, with units (the page's image text)."""

    name: str
    draw: Callable[[Context, Path], None]
    cost: Cost = Cost.SWEEP
    alt: str = field(default="", kw_only=True)


@dataclass(frozen=True)
class Choice:
    """A choice of our model where the dissertation's differs or is silent, and what it
    changes, computed (a Chapter 6 figure at a converged step, :mod:`.runs`).

    Attributes:
        choice: what we chose, in a few words.
        dissertation: what the dissertation does, and where.
        why: why ours.
        effect: computes what the choice changes, as the page shows it.
        cost: what computing the effect takes.
    """

    choice: str
    dissertation: str
    why: str
    effect: Callable[[Context], str]
    cost: Cost = Cost.INSTANT


def effect_of(choice: Choice, context: Context) -> str:
    """What ``choice`` changes, or why it was not computed."""
    try:
        return choice.effect(context)
    except NotRunError as exc:
        return f"not run ({exc})"
    except Exception as exc:  # a broken computation is reported on the page
        return f"not computed: {type(exc).__name__}: {exc}"


@dataclass(frozen=True)
class Section:
    """A part of the report: a table of claims (or of model choices) and the figures shown
    under it."""

    title: str
    claims: tuple[Claim, ...]
    figures: tuple[Figure, ...] = ()
    choices: tuple[Choice, ...] = ()


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
