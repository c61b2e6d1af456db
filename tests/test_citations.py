"""The dissertation's numbers the repository cites exist in the dissertation.

Every equation, figure, table, example and section of B. Li (FAU 2016) cited in the code,
docs, scenarios and tests must be one the dissertation has: its numbering is in
``tests/data/dissertation_numbering.toml``, derived from its text by
``scripts/dissertation_numbering.py``. A citation of a number past the end, equation
6.3.97, Fig. 6.52 or Sec. 6.4, fails here naming the file and the line; so does a bare
"(5.1.1)", which cites a number both a section and an equation have (named, it is one:
"Sec. 5.1.1", "Eq. (5.1.1)").
"""

from __future__ import annotations

import functools
import os
import re
import tomllib
from pathlib import Path

import pytest
from repo_paths import ROOT, TESTS

NUMBERING = tomllib.loads((TESTS / "data" / "dissertation_numbering.toml").read_text("utf-8"))
SKIPPED = {".git", "build", "runs", "auv_cosim.egg-info", "__pycache__", ".pytest_cache", "data"}
# A line that cites another work's numbers (the FMI 2.0 standard's sections, Higham's and
# Fossen's equations and tables) is not checked against the dissertation.
OTHER_WORKS = re.compile(r"\bFMI\b|Higham|Fossen")

_EQUATION = r"(?:[2-7]\.\d+\.\d+|A\.\d+)"
# "(6.3.13)", "(6.3.11-6.3.13)", "(6.3.64, 6.3.72)", "(3.6.2 with viscous terms, 4.3.1)":
# a parenthesis that opens with an equation number, to its closing parenthesis.
EQUATIONS = re.compile(rf"\(({_EQUATION}[^()\n]*)\)")
EQUATION = re.compile(rf"(?<![\w.]){_EQUATION}(?![\w.]|\.\d)")
_LIST = r"(\d\.\d+(?:\.\d+)?(?:\s*(?:-|,|and|/)\s*\d\.\d+(?:\.\d+)?)*)"
# A citation by name, "Figs. 6.13-6.14", "Tables 5.1, 5.4 and 6.1", "Ex. 5.3", "Sec. 6.3.3",
# "equations 6.2.28" (out of parentheses):
# one pattern for every kind, its name telling which (one pass over the text: a pattern
# per kind took four times as long).
NAMED = re.compile(
    r"\b(?:(?P<figures>Fig(?:ure)?s?\.?)|(?P<tables>Tables?)|(?P<examples>Examples?|Exs?\.)"
    r"|(?P<contents>Secs?\.|Sections?|Subsections?)|(?P<equations>Eqs?\.|[Ee]quations?))"
    rf"\s+{_LIST}"
)
KINDS = ("equations", "figures", "tables", "examples", "contents")
NUMBER = re.compile(r"\d\.\d+(?:\.\d+)?")
SECTIONS = frozenset(NUMBERING["contents"]["sections"])
# what names a parenthesis an equation's, just before it: "Eq. (5.1.1)", "equations (5.1.1)"
NAMED_EQUATION = re.compile(r"\b(?:Eqs?\.|[Ee]quations?)\s*$")


def _files() -> list[Path]:
    """The repository's text files that may cite the dissertation (not this test, whose
    examples are wrong on purpose, nor the tests' data)."""
    found = []
    for folder, subfolders, names in os.walk(ROOT):
        here = Path(folder)
        subfolders[:] = [
            name
            for name in subfolders
            if name not in SKIPPED and not (here / name / "pyvenv.cfg").exists()
        ]
        found += [here / n for n in names if n.endswith((".py", ".md", ".toml", ".ipynb"))]
    return sorted(path for path in found if path != Path(__file__).resolve())


@functools.cache
def _cited() -> tuple[tuple[str, int, str, str], ...]:
    """(file, line, kind, number) of every citation in the repository, read once."""
    return tuple(
        (path.relative_to(ROOT).as_posix(), line, kind, number)
        for path in _files()
        for line, kind, number in citations(path.read_text(encoding="utf-8"))
    )


def exists(kind: str, number: str) -> bool:
    """Whether the dissertation has ``number`` of ``kind`` ("equations": "6.3.13" or
    "A.62"; "figures", "tables", "examples": "6.14"; "contents": a section, "6.3.1")."""
    if kind == "contents":
        return number in NUMBERING["contents"]["sections"]
    group, _, last = number.rpartition(".")
    return 1 <= int(last) <= NUMBERING[kind].get(group, 0)


def citations(text: str) -> list[tuple[int, str, str]]:
    """(line, kind, number) of every dissertation number ``text`` cites: the equations,
    then the others, each in the order of the text."""
    found = []
    for pattern in (EQUATIONS, NAMED):
        for match in pattern.finditer(text):
            start = text.rfind("\n", 0, match.start()) + 1
            end = text.find("\n", match.end())
            if OTHER_WORKS.search(text[start : len(text) if end < 0 else end]):
                continue
            kind = next((name for name, got in match.groupdict().items() if got), "equations")
            # a named one by any number's shape: "equation 6.2" is no equation's number
            numbers = EQUATION if pattern is EQUATIONS else NUMBER
            listed = match.group(pattern.groups)  # the last group: the numbers
            line = text.count("\n", 0, match.start()) + 1
            found += [(line, kind, number) for number in numbers.findall(listed)]
    return found


def ambiguous(text: str) -> list[tuple[int, str]]:
    """(line, number) of each number ``text`` cites in parentheses that is a section's as
    well as an equation's ("(5.1.1)": the dissertation's first equation of Sec. 5.1, and
    Sec. 5.1.1), unless the parenthesis is named an equation's ("Eq. (5.1.1)")."""
    found = []
    for match in EQUATIONS.finditer(text):
        start = text.rfind("\n", 0, match.start()) + 1
        end = text.find("\n", match.end())
        if OTHER_WORKS.search(text[start : len(text) if end < 0 else end]):
            continue
        if NAMED_EQUATION.search(text[start : match.start()]):
            continue
        line = text.count("\n", 0, match.start()) + 1
        found += [(line, n) for n in EQUATION.findall(match.group(1)) if n in SECTIONS]
    return found


def test_the_scan_finds_each_kind_and_refuses_a_number_the_dissertation_lacks():
    """The scan reads every form the repository uses, and a number past the end of its
    section or chapter, or a section the contents lack, is refused."""
    # the wrong numbers built, not typed, so that docs tests reading this file's
    # parentheses do not take them for citations
    wrong = "({}), Fig. 6.52, Table 6.4, Example 5.10, Sec. 6.4".format("6.3.97")
    text = (
        "(6.3.11)-(6.3.13), (6.3.64, 6.3.72), (A.62); Figs. 6.13-6.14, Tables 5.1, 5.4 and"
        f" 6.1, Ex. 5.3, Sec. 6.3.3; {wrong}"
    )
    cited = [(kind, number) for _, kind, number in citations(text)]
    assert cited == [
        ("equations", "6.3.11"), ("equations", "6.3.13"), ("equations", "6.3.64"),
        ("equations", "6.3.72"), ("equations", "A.62"), ("equations", "6.3.97"),
        ("figures", "6.13"), ("figures", "6.14"), ("tables", "5.1"), ("tables", "5.4"),
        ("tables", "6.1"), ("examples", "5.3"), ("contents", "6.3.3"), ("figures", "6.52"),
        ("tables", "6.4"), ("examples", "5.10"), ("contents", "6.4"),
    ]  # fmt: skip
    missing = [number for kind, number in cited if not exists(kind, number)]
    assert missing == ["6.3.97", "6.52", "6.4", "5.10", "6.4"]
    assert citations("FMI 2.0, Section 4.2.4; Higham 2005, Table 2.3") == []


def test_an_equation_cited_by_name_is_checked_as_an_equation():
    """An equation cited out of parentheses ("the full two-body equations 6.2.28",
    "Eq. 6.3.13") was not read at all, so a number past the end of its section passed, as
    did a figure's or a section's number cited as an equation's."""
    wrong = "equations {}, Eq. {} and Eqs. {}".format("6.3.97", "6.14", "6.3.1")
    cited = citations(f"the two-body equations 6.2.28; {wrong}")
    assert cited == [
        (1, "equations", "6.2.28"), (1, "equations", "6.3.97"), (1, "equations", "6.14"),
        (1, "equations", "6.3.1"),
    ]  # fmt: skip
    missing = [number for _, kind, number in cited if not exists(kind, number)]
    assert missing == ["6.3.97", "6.14"]


@pytest.mark.parametrize("kind", KINDS)
def test_every_dissertation_number_cited_exists(kind):
    """Every number of ``kind`` the repository cites is one the dissertation has. (A
    number that exists but is the wrong one, as the equation index's 6.3.52 for gains
    defined under 6.3.53 was, is for a reader to catch.)"""
    cited = [(path, line, number) for path, line, k, number in _cited() if k == kind]
    assert len(cited) > 5, f"no {kind} found: the scan no longer reads the citations"
    missing = [
        f"{path}:{line}: {number}" for path, line, number in cited if not exists(kind, number)
    ]
    assert not missing, f"{kind} the dissertation does not have: {missing}"


def test_a_number_both_a_section_and_an_equation_is_cited_as_one_of_them():
    """ "(5.1.1)" reads as an equation, but 5.1.1 is a section's number too, and the scan
    cannot tell which one a writer meant (nor could a reader): a section is cited by name
    ("Sec. 5.1.1"), such an equation as one ("Eq. (5.1.1)"); the bare parenthesis is
    refused. An equation whose number no section has stays bare ("(6.3.13)")."""
    text = "(5.1.1), (6.3.13), (6.3.11-6.3.13)\nSec. 5.1.1, Eq. (5.1.1), equations (5.1.1)"
    assert ambiguous(text) == [(1, "5.1.1")]
    assert ambiguous("(5.1.12, 5.1.1)") == [(1, "5.1.1")]
    found = [
        f"{path.relative_to(ROOT).as_posix()}:{line}: ({number})"
        for path in _files()
        for line, number in ambiguous(path.read_text(encoding="utf-8"))
    ]
    assert not found, f"cite these as Sec. or Eq. (section and equation numbers): {found}"
