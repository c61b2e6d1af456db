"""The dissertation's numbering, derived once from its text: which equations, figures,
tables, examples and sections exist, so that a test (``tests/test_citations.py``) refuses
a citation of one that does not.

The dissertation (B. Li, *Dynamics and Control of Autonomous Underwater Vehicles with
Internal Actuators*, FAU 2016) is not part of the repository; give this script its text
(as ``pdftotext`` extracts it from the PDF):

    python scripts/dissertation_numbering.py DISSERTATION.txt           # print the file
    python scripts/dissertation_numbering.py DISSERTATION.txt --write   # rewrite it

It writes ``tests/data/dissertation_numbering.toml``. The dissertation numbers its
equations within each section (Eqs. 6.3.1 to 6.3.79), its figures, tables and examples
within each chapter, each from 1 without a gap (the script checks that and stops naming a
gap), so the file keeps only the last number of each; and the section numbers of its
table of contents.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections import defaultdict
from collections.abc import Iterable
from pathlib import Path

OUTPUT = Path(__file__).resolve().parent.parent / "tests" / "data" / "dissertation_numbering.toml"

# An equation number as printed after its equation, (6.3.13), or in the appendix, (A.62).
EQUATION = re.compile(r"\((\d\.\d+|A)\.(\d+)\)")
# A caption: "Figure 6.14: ...", "Table 6.3: ..." (the lists of figures and tables have
# no colon); an example opens with "Example 5.3." or "Example 5.3 (Continued).".
CAPTION = re.compile(r"\b(Figure|Table) (\d)\.(\d+):")
EXAMPLE = re.compile(r"\bExample (\d)\.(\d+)[. ]")
# A table-of-contents entry: "6.3.1 Linear Control Design ...... 155", "A.2 Hydro...".
CONTENTS_ENTRY = re.compile(r"(?<![\d.])((?:\d|A)\.\d+(?:\.\d+)?) [A-Z\d][^.]*?\.{3,}")

HEADER = """\
# The numbering of B. Li, "Dynamics and Control of Autonomous Underwater Vehicles with
# Internal Actuators", FAU 2016, derived from its text by scripts/dissertation_numbering.py:
# do not edit by hand. Each kind runs from 1 to the last number given here, without a gap.
# tests/test_citations.py refuses a citation in the repository of a number not in it.
"""


def last_numbers(pairs: Iterable[tuple[str, int]], kind: str) -> dict[str, int]:
    """The last number within each group of ``pairs`` (group, number), after checking
    that every group runs from 1 to its last number without a gap.

    Raises:
        ValueError: a group has a gap, naming the kind, the group and the missing numbers.
    """
    seen: dict[str, set[int]] = defaultdict(set)
    for group, number in pairs:
        seen[group].add(number)
    for group, numbers in seen.items():
        missing = sorted(set(range(1, max(numbers) + 1)) - numbers)
        if missing:
            raise ValueError(f"{kind} of {group}: no {missing}, expected 1 to {max(numbers)}")
    return {group: max(seen[group]) for group in sorted(seen, key=_order)}


def _order(number: str) -> tuple[int, ...]:
    """Sort key of a chapter, section or group number: the appendix "A" after chapter 7."""
    return tuple(99 if part == "A" else int(part) for part in number.split("."))


def contents_sections(text: str) -> list[str]:
    """The section numbers of the table of contents (everything before "LIST OF TABLES"),
    in order.

    Raises:
        ValueError: the text has no "LIST OF TABLES", so no table of contents was found.
    """
    end = text.find("LIST OF TABLES")
    if end < 0:
        raise ValueError("no table of contents: expected it before 'LIST OF TABLES'")
    found = dict.fromkeys(CONTENTS_ENTRY.findall(text[:end]))
    return sorted(found, key=_order)


def numbering(text: str) -> dict[str, dict[str, int] | list[str]]:
    """Every kind of number the dissertation's ``text`` gives: the last equation of each
    section, the last figure, table and example of each chapter, and the sections."""
    captions = CAPTION.findall(text)
    return {
        "equations": last_numbers(((g, int(n)) for g, n in EQUATION.findall(text)), "equations"),
        "figures": last_numbers(((c, int(n)) for k, c, n in captions if k == "Figure"), "figures"),
        "tables": last_numbers(((c, int(n)) for k, c, n in captions if k == "Table"), "tables"),
        "examples": last_numbers(((c, int(n)) for c, n in EXAMPLE.findall(text)), "examples"),
        "sections": contents_sections(text),
    }


def render(numbers: dict[str, dict[str, int] | list[str]]) -> str:
    """The TOML file: one table per kind, group -> last number, and the section list."""
    comments = {
        "equations": 'section ("A": the appendix) -> its last equation: "6.3" = 79 is (6.3.79)',
        "figures": "chapter -> its last figure",
        "tables": "chapter -> its last table",
        "examples": "chapter -> its last example",
    }
    lines = [HEADER]
    for kind, comment in comments.items():
        lines.append(f"[{kind}]  # {comment}")
        groups = numbers[kind]
        assert isinstance(groups, dict)
        lines += [f'"{group}" = {last}' for group, last in groups.items()]
        lines.append("")
    sections = ", ".join(f'"{number}"' for number in numbers["sections"])
    lines += ["[contents]  # the sections of the table of contents", f"sections = [{sections}]"]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """Print or (``--write``) rewrite the numbering file from the dissertation's text."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("text", type=Path, help="the dissertation's text (pdftotext)")
    parser.add_argument("--write", action="store_true", help=f"rewrite {OUTPUT.name}")
    args = parser.parse_args(argv)
    try:
        content = render(numbering(args.text.read_text(encoding="utf-8")))
    except (OSError, ValueError) as error:
        print(f"dissertation_numbering: {error}", file=sys.stderr)
        return 1
    if args.write:
        OUTPUT.write_text(content, encoding="utf-8")
        print(f"wrote {OUTPUT}")
    else:
        sys.stdout.write(content)
    return 0


if __name__ == "__main__":
    sys.exit(main())
