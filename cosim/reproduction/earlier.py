"""What ``auv-cosim reproduce --skip-scenarios`` keeps of the earlier page.

Without the closed-loop runs (Ch. 6) their claims, the model choices' effects that need a
run and the runs' figures cannot be computed. Rather than writing "not run" over the
results of the last full run (and removing its figures), the page keeps those from the
earlier ``docs/reproduction.md``: its rows, effects and figures are read back here and
stand in for what was not run, so a page regenerated with nothing changed is the same,
byte for byte. A claim, choice or figure the earlier page lacks still reads "not run".
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path

from cosim.reproduction.page import COLUMNS, Evaluated
from cosim.reproduction.record import Claim, Row, Verdict

# Longest first: "differs (explained)" begins with "differs".
VERDICTS: tuple[Verdict, ...] = ("differs (explained)", "differs", "agrees", "not run")
NOT_RUN_EFFECT = "not run ("


@dataclass
class EarlierPage:
    """The rows (claim, source, printed, unit -> table cells), the model choices' effects
    (choice, dissertation -> effect: a choice's 'why ours' is prose, and rewording it
    changes no run) and the reasons of the differences list (row number -> text) of an
    earlier page, unescaped as the page's cells were written."""

    rows: dict[tuple[str, str, str], list[list[str]]] = field(default_factory=dict)
    effects: dict[tuple[str, str], str] = field(default_factory=dict)
    reasons: dict[str, str] = field(default_factory=dict)

    def row(self, claim: Claim) -> Row | None:
        """``claim``'s row as the earlier page showed it, if it did and it was run."""
        for cells in self.rows.get((claim.source, claim.printed_text, claim.unit), []):
            number, text, tolerance, ours, shown = cells[0], cells[1], *cells[5:]
            if text.startswith(claim.claim) and not shown.startswith("not run"):
                return _row(claim, number, text, tolerance != "-", ours, shown, self.reasons)
        return None


def _row(
    claim: Claim,
    number: str,
    text: str,
    compared: bool,
    ours: str,
    shown: str,
    reasons: dict[str, str],
) -> Row | None:
    """The :class:`Row` whose rendering is the earlier page's: its verdict cell is
    'verdict[, size]'; an agreeing row's note follows its claim in parentheses, another's
    stands in the differences list."""
    verdict = next((v for v in VERDICTS if shown == v or shown.startswith(f"{v}, ")), None)
    if verdict is None:
        return None
    size = shown[len(verdict) + 2 :]
    if verdict == "agrees":
        note = text[len(claim.claim) + 2 : -1]
    else:
        prefix = f"- **#{number} {claim.claim}** ({shown}): "
        note = reasons.get(number, "").removeprefix(prefix)
    return Row(claim, ours, verdict, note, compared=compared, size=size)


def read_earlier(page: Path) -> EarlierPage:
    """The earlier page's rows, effects and differences (none if it does not exist)."""
    earlier = EarlierPage()
    if not page.is_file():
        return earlier
    for line in page.read_text(encoding="utf-8").splitlines():
        if line.startswith("- **#"):
            earlier.reasons[line[5:].split(" ", 1)[0]] = line
        elif line.startswith("| ") and line.endswith(" |"):
            cells = [c.replace("\\|", "|") for c in line[2:-2].split(" | ")]
            if len(cells) == len(COLUMNS) and cells[0].isdigit():
                earlier.rows.setdefault((cells[2], cells[3], cells[4]), []).append(cells)
            elif len(cells) == 4:
                earlier.effects[(cells[0], cells[1])] = cells[3]
    return earlier


def explanation_changed(row: Row) -> bool:
    """Whether a kept row's text no longer begins with what its claim now says of it (the
    explanation of a known difference, or the note of a row that agrees): the claim's
    prose changed after the run the earlier page shows."""
    claim = row.claim
    prose = claim.note
    if row.verdict != "agrees" and claim.known_difference:
        prose = claim.known_difference
    return bool(prose) and not row.note.startswith(prose)


def keep_earlier(part: Evaluated, earlier: EarlierPage) -> tuple[Evaluated, int, list[str]]:
    """``part`` with each row that was not run, and each effect, taken from the earlier
    page where it has them; how many rows and effects were kept; and the claims of the
    kept rows whose explanation has changed since (the page keeps the earlier one)."""
    rows, kept, changed = [], 0, []
    for row in part.rows:
        found = earlier.row(row.claim) if row.verdict == "not run" else None
        rows.append(found or row)
        kept += found is not None
        if found is not None and explanation_changed(found):
            changed.append(row.claim.claim)
    effects = []
    for choice, effect in zip(part.section.choices, part.effects, strict=True):
        found_effect = None
        if effect.startswith(NOT_RUN_EFFECT):
            key = (choice.choice, choice.dissertation)
            found_effect = earlier.effects.get(key)
            if found_effect is not None and found_effect.startswith(NOT_RUN_EFFECT):
                found_effect = None
        effects.append(found_effect or effect)
        kept += found_effect is not None
    return replace(part, rows=tuple(rows), effects=tuple(effects)), kept, changed
