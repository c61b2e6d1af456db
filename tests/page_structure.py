"""What a screen reader gets from an HTML page the project writes, read with the standard
library's parser: the title and language, the headings in order, each figure's alt text,
each table's caption and header cells with their scope, each link's text.

:func:`problems` lists what a reader misses (an empty list for a page that passes), in the
spirit of axe-core's rules, without a browser: ``document-title``, ``html-has-lang``,
``page-has-heading-one``, ``heading-order``, ``image-alt`` (and an alt that is the file's
name says nothing), ``td-has-header`` / ``th-has-scope``, ``table-caption``,
``link-name``; and a block element (``<details>``, ``<div>``, ``<table>``, ...) opened inside
a ``<p>``, which a browser's parser takes as the paragraph's end: what follows it in the
source is no longer the paragraph's (the sentence breaks where the source reads on).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import PurePosixPath


@dataclass
class Table:
    """One ``<table>``: its caption's text, and each header cell's scope (None if absent)."""

    caption: str = ""
    scopes: list[str | None] = field(default_factory=list)
    data_cells: int = 0


@dataclass
class Page:
    """What :class:`_Reader` found in a page."""

    title: str = ""
    lang: str = ""
    headings: list[int] = field(default_factory=list)
    images: list[tuple[str, str | None]] = field(default_factory=list)  # (src, alt)
    tables: list[Table] = field(default_factory=list)
    links: list[str] = field(default_factory=list)  # each link's text (an image's alt)
    blocks_in_p: list[str] = field(default_factory=list)  # block tags opened inside a <p>


# the elements whose start tag closes an open <p> (the HTML standard's parsing rules)
CLOSES_P = frozenset(
    ("address", "article", "aside", "blockquote", "details", "dialog", "div", "dl", "fieldset",
     "figcaption", "figure", "footer", "form", "h1", "h2", "h3", "h4", "h5", "h6", "header",
     "hgroup", "hr", "main", "menu", "nav", "ol", "p", "pre", "section", "table", "ul")
)  # fmt: skip


class _Reader(HTMLParser):
    def __init__(self) -> None:
        super().__init__(convert_charrefs=True)
        self.page = Page()
        self._text: list[str] | None = None  # the text being collected (title, caption, link)
        self._into = ""
        self._in_p = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        at = dict(attrs)
        if self._in_p and tag in CLOSES_P:
            self.page.blocks_in_p.append(tag)
        if tag == "p":
            self._in_p = True
        elif tag in CLOSES_P:
            self._in_p = False
        if tag == "html":
            self.page.lang = at.get("lang") or ""
        elif tag in ("h1", "h2", "h3", "h4", "h5", "h6"):
            self.page.headings.append(int(tag[1]))
        elif tag == "img":
            self.page.images.append((at.get("src") or "", at.get("alt")))
            if self._into == "a" and self._text is not None:
                self._text.append(at.get("alt") or "")
        elif tag == "table":
            self.page.tables.append(Table())
        elif tag == "th":
            self.page.tables[-1].scopes.append(at.get("scope"))
        elif tag == "td":
            self.page.tables[-1].data_cells += 1
        if tag in ("title", "caption", "a"):
            self._text, self._into = [], tag

    def handle_endtag(self, tag: str) -> None:
        if tag == "p":
            self._in_p = False
        if tag != self._into or self._text is None:
            return
        text = " ".join("".join(self._text).split())
        if tag == "title":
            self.page.title = text
        elif tag == "caption":
            self.page.tables[-1].caption = text
        else:
            self.page.links.append(text)
        self._text, self._into = None, ""

    def handle_data(self, data: str) -> None:
        if self._text is not None:
            self._text.append(data)


def read_page(text: str) -> Page:
    """The parts of an HTML page a screen reader announces."""
    reader = _Reader()
    reader.feed(text)
    reader.close()
    return reader.page


def problems(text: str) -> list[str]:
    """What a screen-reader user misses on the page ``text``: one line each."""
    page = read_page(text)
    found = []
    if not page.title:
        found.append("no <title>")
    if not page.lang:
        found.append("no lang on <html>")
    if page.headings.count(1) != 1:
        found.append(f"{page.headings.count(1)} <h1>, expected one")
    found += [
        f"heading h{b} follows h{a}"
        for a, b in zip(page.headings, page.headings[1:], strict=False)
        if b > a + 1
    ]
    for src, alt in page.images:
        stem = PurePosixPath(src).stem
        if not alt or alt.strip().lower() in (src.lower(), stem.lower()):
            found.append(f"image {src} has alt {alt!r}: it says nothing of what it shows")
    for k, table in enumerate(page.tables, 1):
        if not table.caption:
            found.append(f"table {k} has no caption")
        if table.data_cells and not table.scopes:
            found.append(f"table {k} has no header cells")
        if any(scope not in ("row", "col", "rowgroup", "colgroup") for scope in table.scopes):
            found.append(f"table {k}: header cells without scope: {table.scopes}")
    found += [f"link {k} has no text" for k, text in enumerate(page.links, 1) if not text]
    found += [f"<{tag}> inside a <p> ends the paragraph early" for tag in page.blocks_in_p]
    return found
