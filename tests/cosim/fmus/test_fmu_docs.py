"""The documentation page inside each FMU (``cosim.fmus.docs``)."""

from __future__ import annotations

import shutil
import zipfile
from html.parser import HTMLParser
from pathlib import Path

import pytest
from chromium import CHROMIUM, headless_chromium
from fmpy import read_model_description
from fmpy.validation import validate_fmu
from page_structure import problems, read_page

from cosim.fmus.docs import DOC_ENTRY, add_documentation, documentation_html, value_range


class _Cells(HTMLParser):
    """Table rows of the page as lists of cell texts, and the tags left open."""

    def __init__(self) -> None:
        super().__init__()
        self.rows: list[list[str]] = []
        self.open: list[str] = []
        self._cell: list[str] | None = None

    def handle_starttag(self, tag: str, attrs: list) -> None:
        if tag not in ("meta", "br"):
            self.open.append(tag)
        if tag == "tr":
            self.rows.append([])
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag: str) -> None:
        assert self.open and self.open[-1] == tag, f"</{tag}> closes {self.open[-1:]}"
        self.open.pop()
        if tag in ("td", "th") and self._cell is not None:
            self.rows[-1].append("".join(self._cell).strip())
            self._cell = None

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)


@pytest.fixture(scope="module", params=["AuvPlant", "AuvAutopilot", "AuvGuidance"])
def documented(
    request: pytest.FixtureRequest, fmu_paths: dict[str, Path], tmp_path_factory
) -> Path:
    """A copy of a built FMU with its documentation page added."""
    fmu = tmp_path_factory.mktemp("doc") / f"{request.param}.fmu"
    shutil.copyfile(fmu_paths[request.param], fmu)
    add_documentation(fmu)
    return fmu


def test_page_lists_every_variable_with_its_unit_and_description(documented: Path) -> None:
    with zipfile.ZipFile(documented) as archive:
        page = archive.read(DOC_ENTRY).decode("utf-8")
    parser = _Cells()
    parser.feed(page)
    assert parser.open == [], "unbalanced HTML"
    rows = {row[0]: row for row in parser.rows if len(row) == 7 and row[0] != "name"}
    md = read_model_description(str(documented))
    assert set(rows) == {v.name for v in md.modelVariables}
    for v in md.modelVariables:
        _name, kind, unit, start, declared, _variability, description = rows[v.name]
        assert kind == v.type
        assert unit == (v.unit or (v.declaredType.unit if v.declaredType else "") or "")
        assert description == (v.description or "")
        assert start == ("" if v.start is None else str(v.start))
        assert declared == value_range(v)
    known = {
        "variant": "0 .. 2",
        "m": ">= 0.0",
        "heading_mode": "0 .. 3",
        "lqr_r": ">= 0.0",
        "lookahead": ">= 0.0",
    }
    shown = {name: rows[name][4] for name in known if name in rows}
    assert shown and shown == {name: known[name] for name in shown}
    assert "Dynamics and Control of Autonomous Underwater Vehicles with Internal" in page
    for rule in ("Load, reload, free.", "Several builds per process.", "FMI 2.0 call sequence."):
        assert rule in page  # what a host may and may not do
    assert md.coSimulation.modelIdentifier in page


def test_documented_fmu_is_still_valid_and_otherwise_unchanged(
    documented: Path, fmu_paths: dict[str, Path]
) -> None:
    assert validate_fmu(str(documented)) == []
    original = fmu_paths[documented.stem]
    with zipfile.ZipFile(original) as a, zipfile.ZipFile(documented) as b:
        before = {i.filename: a.read(i) for i in a.infolist() if i.filename != DOC_ENTRY}
        after = {i.filename: b.read(i) for i in b.infolist() if i.filename != DOC_ENTRY}
    assert after == before


def test_adding_the_page_twice_replaces_it(documented: Path, tmp_path: Path) -> None:
    copy = tmp_path / documented.name
    shutil.copyfile(documented, copy)
    add_documentation(copy)
    with zipfile.ZipFile(copy) as archive:
        assert [i.filename for i in archive.infolist()].count(DOC_ENTRY) == 1
        assert archive.read(DOC_ENTRY).decode() == documentation_html(documented)
    assert [p.name for p in tmp_path.iterdir()] == [documented.name]  # no temporary left


def test_built_fmus_carry_their_documentation(fmu_paths: dict[str, Path]) -> None:
    """``cosim.fmus.build`` adds the page: what an importer (or a zip tool) finds in the FMU."""
    for fmu in fmu_paths.values():
        with zipfile.ZipFile(fmu) as archive:
            assert archive.read(DOC_ENTRY).decode("utf-8") == documentation_html(fmu)


def test_the_page_reads_to_a_screen_reader(documented: Path) -> None:
    """The tables had no caption and their header cells no scope: a screen reader read a
    parameter's unit without saying it is the unit column."""
    page = documentation_html(documented)
    assert problems(page) == []
    tables = read_page(page).tables
    assert all(set(t.scopes) == {"col"} for t in tables[1:])  # the variables' columns
    assert set(tables[0].scopes) == {"row"}  # the facts: a header per row


# The page's width and what sticks out of it; each table's width and its box's: whether the
# box scrolls, can be reached by the keyboard (tabindex) and is named for a screen reader.
WIDTHS = """() => ({
    page: [document.documentElement.scrollWidth, document.documentElement.clientWidth],
    tables: [...document.querySelectorAll('table')].map(t => {
        const box = t.parentElement, style = getComputedStyle(box);
        return {table: t.getBoundingClientRect().width, box: box.clientWidth,
                scrolls: ['auto', 'scroll'].includes(style.overflowX),
                reachable: box.tabIndex >= 0 && !!box.getAttribute('aria-label')};
    })})"""
PHONE_PX = 375  # a phone's width in CSS pixels
PAPER_PX = 718  # A4's width less 1 cm margins, at 96 CSS pixels per inch


@pytest.mark.slow
@pytest.mark.viewer  # starts a browser
@pytest.mark.skipif(CHROMIUM is None, reason="needs Debian's chromium (apt, .ci/run)")
def test_the_page_fits_a_phone_and_paper(fmu_paths: dict[str, Path], tmp_path: Path) -> None:
    """At 375 px the whole AuvPlant page scrolled sideways (the parameters' table is 840
    px wide), and on paper that table ran past the page's edge. Now a wide table scrolls
    in a box of its own, which the keyboard reaches, and in print it wraps to the page."""
    pytest.importorskip("playwright.sync_api", reason="needs playwright (test extra)")
    page_file = tmp_path / "index.html"
    page_file.write_text(documentation_html(fmu_paths["AuvPlant"]), "utf-8")
    (tmp_path / "profile").mkdir()
    with headless_chromium(tmp_path / "profile") as browser:
        seen = {}
        for media, width in (("screen", PHONE_PX), ("print", PAPER_PX)):
            page = browser.new_page(viewport={"width": width, "height": 800})
            page.emulate_media(media=media)
            page.goto(page_file.as_uri(), wait_until="load")
            seen[media] = page.evaluate(WIDTHS)
            page.close()
    phone, paper = seen["screen"], seen["print"]
    assert phone["page"][0] <= phone["page"][1], phone
    wide = [t for t in phone["tables"] if t["table"] > t["box"] + 1]
    assert wide, f"no table wider than {PHONE_PX} px: the test shows nothing"
    assert all(t["scrolls"] and t["reachable"] for t in wide), wide
    assert paper["page"][0] <= paper["page"][1], paper
    assert all(t["table"] <= t["box"] + 1 for t in paper["tables"]), paper
